"""Loading the rulebook grammar (``grammar/rulebook.lark``) once per process.

The grammar ships as package data of ``idefix_rules.grammar`` (pyproject maps that package to
the repository's top-level ``grammar/`` directory), so an installed wheel finds it. A source
checkout reads its own ``<repo>/grammar/rulebook.lark`` first: the package imported from a
checkout is that checkout's code, even when another checkout is the one installed.

>>> parser = rulebook_parser()
>>> parser is rulebook_parser()
True
"""

from __future__ import annotations

import contextlib
import contextvars
import functools
import hashlib
import importlib.resources
import sys
from collections.abc import Iterator
from pathlib import Path

import lark

from idefix_rules.files import cache_root

GRAMMAR_FILE = "rulebook.lark"
_SOURCE_TREE_GRAMMAR = Path(__file__).resolve().parents[2] / "grammar" / GRAMMAR_FILE


def grammar_text() -> str:
    """The text of ``rulebook.lark``: from the source tree this package sits in, else from
    the installed package."""
    if _SOURCE_TREE_GRAMMAR.is_file():
        return _SOURCE_TREE_GRAMMAR.read_text(encoding="utf-8")
    try:
        resource = importlib.resources.files("idefix_rules.grammar").joinpath(GRAMMAR_FILE)
        if resource.is_file():
            return resource.read_text(encoding="utf-8")
    except ModuleNotFoundError:
        pass
    raise FileNotFoundError(f"no {GRAMMAR_FILE} in the package nor at {_SOURCE_TREE_GRAMMAR}")


# Comments are ignored by the grammar; the lexer hands each one to the list of the parse
# running in this context (see collecting_comments), so the parser can keep them.
_COMMENT_SINK: contextvars.ContextVar[list[lark.Token] | None] = contextvars.ContextVar(
    "rulebook_comment_sink", default=None)


def _keep_comment(token: lark.Token) -> lark.Token:
    sink = _COMMENT_SINK.get()
    if sink is not None:
        sink.append(token)
    return token


@contextlib.contextmanager
def collecting_comments(sink: list[lark.Token]) -> Iterator[list[lark.Token]]:
    """Within the block, every comment the lexer meets is appended to ``sink``."""
    reset = _COMMENT_SINK.set(sink)
    try:
        yield sink
    finally:
        _COMMENT_SINK.reset(reset)


def parser_cache() -> str | bool:
    """Where lark keeps the parser's tables between processes: a file in this user's cache
    folder (:func:`idefix_rules.files.cache_root`, beside the built rover FMU; never a shared
    temporary folder, since lark unpickles it), or False (no cache) when the folder cannot be
    made. The file's name holds a digest of the grammar, so that checkouts of different
    grammars keep a file each instead of building it in turn. Lark stores a hash of the
    grammar, its options and the lark and Python versions in the file and builds the tables
    again when it differs (and when the file cannot be read: half written by another process,
    say), then writes the file anew."""
    folder = cache_root() / "grammar"
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    digest = hashlib.sha256(grammar_text().encode()).hexdigest()[:12]
    return str(folder / f"rulebook-{digest}-lark{lark.__version__}-py{sys.version_info[0]}"
                        f"{sys.version_info[1]}.cache")


@contextlib.contextmanager
def _held(cache: str | bool) -> Iterator[str | bool]:
    """The cache file, locked against the other processes for as long as lark reads or
    writes it (lark writes it in place: two processes building at once could otherwise
    interleave their writes into one file that still unpickles); False (no cache) where no
    lock can be taken. In a folder this user cannot write (a cache prepared for a read-only
    image), a lock file there is opened to read and held shared: the tables are read, and
    lark's attempt to write stale ones fails quietly; were the cache file itself writable
    (a lock file this user cannot write beside it), lark is given no cache at all, since
    under a shared lock it could write into a file other processes read."""
    if not cache:
        yield False
        return
    try:
        import fcntl
    except ImportError:  # no flock (Windows)
        yield False
        return
    mode = fcntl.LOCK_EX
    try:
        handle = open(f"{cache}.lock", "a")  # noqa: SIM115 - closed below, after the yield
    except OSError:
        try:
            handle = open(f"{cache}.lock")  # noqa: SIM115 - closed below, after the yield
            mode = fcntl.LOCK_SH
        except OSError:  # no lock file, and none can be made
            yield False
            return
    with handle:
        try:
            fcntl.flock(handle, mode)
        except OSError:
            yield False
            return
        if mode == fcntl.LOCK_SH and _writable(str(cache)):
            # lark could write stale tables into a file other readers hold: not under a
            # shared lock (a lock file this user cannot write beside a cache file it can)
            yield False
            return
        yield cache  # the lock goes with the handle


def _writable(path: str) -> bool:
    """Whether this process can open an existing ``path`` to write (nothing is written)."""
    try:
        with open(path, "r+b"):
            return True
    except OSError:  # absent, or not writable
        return False


@functools.cache
def rulebook_parser() -> lark.Lark:
    """The LALR parser (contextual lexer, positions on every tree node), built once per
    process; its tables are read from lark's cache (:func:`parser_cache`) when they were built
    before: 0.03 s instead of 0.3 s, what ``check`` on a rulebook spends first."""
    with _held(parser_cache()) as cache:
        return lark.Lark(
            grammar_text(),
            parser="lalr",
            lexer="contextual",
            propagate_positions=True,
            maybe_placeholders=True,
            start="start",
            lexer_callbacks={"COMMENT": _keep_comment},
            cache=cache,
        )


@functools.cache
def terminal_words() -> dict[str, str]:
    """Terminal name → how a message names it (``'const'``, ``a name``, ``a number``)."""
    words = {
        "NAME": "a name",
        "QUANTITY": "a number",
        "STRING": 'a string ("…")',
        "COMPARE": "a comparison (<, <=, >, >=, ==, !=)",
        "$END": "the end of the file",
    }
    for terminal in rulebook_parser().terminals:
        if terminal.name in words:
            continue
        pattern = terminal.pattern
        if isinstance(pattern, lark.lexer.PatternStr):
            words[terminal.name] = f"'{pattern.value}'"
    return words
