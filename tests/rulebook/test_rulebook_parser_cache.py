"""The parser's tables kept between processes (lark's cache, in this user's cache folder)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from idefix_rules.rulebook.format import formatted_text
from idefix_rules.rulebook.grammar import parser_cache, rulebook_parser

SOURCE = """# a rulebook with comments: the cached parser must hand them to the formatter too
rulebook "cached" version "1.0.0"
purpose "A rulebook read through the parser's cache"

const critical_slip = 70 %  # the limit
  because "Slip above 70 % is critical"

index I_s "wheel slip ratio" {
  value  = max over time (max over wheels (abs(wheel.slip)))  # worst wheel
  limit  = critical_slip
  weight = 1
  because "Worst slip of any wheel"
}

verdict acceptable_risk: require risk <= 70 %
  because "Mean risk at most 0.7"
"""


@pytest.fixture
def cache_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A fresh cache folder; every test builds the process's parser again, and the parser
    is built again afterwards under the usual cache."""
    monkeypatch.setenv("IDEFIX_CACHE", str(tmp_path / "cache"))
    rulebook_parser.cache_clear()
    yield tmp_path / "cache"
    rulebook_parser.cache_clear()


def _formatted() -> str:
    rulebook_parser.cache_clear()  # as a new process would
    return formatted_text(SOURCE, "cached.rules")


def test_the_tables_are_written_once_and_read_back_with_the_comments(cache_folder: Path) -> None:
    path = parser_cache()
    assert isinstance(path, str) and Path(path).parent == cache_folder / "grammar"
    assert not Path(path).exists()
    fresh = _formatted()  # built, then written
    written = Path(path).stat().st_mtime_ns, Path(path).read_bytes()
    assert "# the limit" in fresh and "# worst wheel" in fresh
    assert _formatted() == fresh  # read from the file
    # read, not built and written again
    assert (Path(path).stat().st_mtime_ns, Path(path).read_bytes()) == written


def test_a_damaged_or_stale_cache_file_is_built_again(cache_folder: Path) -> None:
    path = Path(str(parser_cache()))
    fresh = _formatted()
    good = path.read_bytes()
    # garbage, half a file (another process still writing it), another grammar's hash
    for damaged in (b"not a cache\n", good[: len(good) // 2], b"0" * 64 + good[64:]):
        path.write_bytes(damaged)
        assert _formatted() == fresh
        rewritten = path.stat().st_mtime_ns, path.read_bytes()
        assert rewritten[1] != damaged and rewritten[1][:64] == good[:64]  # written anew
        assert _formatted() == fresh
        assert (path.stat().st_mtime_ns, path.read_bytes()) == rewritten  # and read from now


def test_without_a_usable_cache_folder_the_parser_is_built_each_time(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("IDEFIX_CACHE", str(blocker))
    try:
        assert parser_cache() is False
        rulebook_parser.cache_clear()
        assert "# the limit" in formatted_text(SOURCE, "cached.rules")
    finally:
        rulebook_parser.cache_clear()


def test_the_cache_file_is_locked_while_lark_reads_or_writes_it(
        cache_folder: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Two processes building at once never write into the same file together: the lark
    call runs under an exclusive lock that another open file cannot take meanwhile."""
    fcntl = pytest.importorskip("fcntl")
    from idefix_rules.rulebook import grammar

    lock = f"{parser_cache()}.lock"
    real = grammar.lark.Lark
    seen: list[bool] = []

    def building(*args: object, **kwargs: object) -> object:
        with open(lock, "a") as other:
            try:
                fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                seen.append(True)  # held by the build
            else:
                seen.append(False)
        return real(*args, **kwargs)

    monkeypatch.setattr(grammar.lark, "Lark", building)
    for _ in range(2):  # built and written, then read
        assert "# the limit" in _formatted()
    assert seen == [True, True]
    with open(lock, "a") as other:  # released afterwards
        fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)


def test_the_file_name_holds_a_digest_of_the_grammar(
        cache_folder: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Two checkouts of different grammars keep a file each instead of building it in turn."""
    from idefix_rules.rulebook import grammar

    ours = parser_cache()
    monkeypatch.setattr(grammar, "grammar_text", lambda: grammar_text_of_another_checkout)
    theirs = parser_cache()
    assert isinstance(ours, str) and isinstance(theirs, str) and ours != theirs
    assert Path(ours).parent == Path(theirs).parent


grammar_text_of_another_checkout = "start: \"x\"\n"


def test_a_cache_in_a_folder_this_user_cannot_write_is_read(
        cache_folder: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A cache prepared for a read-only image: the lock file cannot be opened to append, so it
    is opened to read and held shared, and the tables are read, not built."""
    import builtins

    path = Path(str(parser_cache()))
    fresh = _formatted()  # built and written, with its lock file
    written = path.stat().st_mtime_ns, path.read_bytes()
    real_open = builtins.open
    refused: list[str] = []

    def read_only(file: object, mode: str = "r", *args: object, **kwargs: object) -> object:
        if str(file).startswith(str(cache_folder)) and any(m in mode for m in "aw+"):
            refused.append(str(file))
            raise PermissionError(13, "Permission denied", str(file))
        return real_open(file, mode, *args, **kwargs)  # type: ignore[call-overload]

    monkeypatch.setattr(builtins, "open", read_only)
    from idefix_rules.rulebook import grammar

    built: list[bool] = []
    real_lark = grammar.lark.Lark

    def lark(*args: object, **kwargs: object) -> object:
        built.append(bool(kwargs.get("cache")))  # the cache file handed to lark, not False
        return real_lark(*args, **kwargs)

    monkeypatch.setattr(grammar.lark, "Lark", lark)
    assert _formatted() == fresh
    # the lock file, and the cache file tried for writing (refused: read-only)
    assert built == [True] and refused == [f"{path}.lock", str(path)]
    assert (path.stat().st_mtime_ns, path.read_bytes()) == written


def test_a_writable_cache_file_beside_a_lock_held_shared_is_not_handed_to_lark(
        cache_folder: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The lock file cannot be opened to append but the cache file can be written: under a
    shared lock lark could write stale tables into a file other processes read, so it gets
    no cache (the parser is built in this process) and the file is left as it was."""
    import builtins

    path = Path(str(parser_cache()))
    fresh = _formatted()  # built and written, with its lock file
    written = path.stat().st_mtime_ns, path.read_bytes()
    real_open = builtins.open

    def lock_read_only(file: object, mode: str = "r", *args: object, **kwargs: object
                       ) -> object:
        if str(file) == f"{path}.lock" and any(m in mode for m in "aw+"):
            raise PermissionError(13, "Permission denied", str(file))
        return real_open(file, mode, *args, **kwargs)  # type: ignore[call-overload]

    monkeypatch.setattr(builtins, "open", lock_read_only)
    from idefix_rules.rulebook import grammar

    built: list[object] = []
    real_lark = grammar.lark.Lark

    def lark(*args: object, **kwargs: object) -> object:
        built.append(kwargs.get("cache"))
        return real_lark(*args, **kwargs)

    monkeypatch.setattr(grammar.lark, "Lark", lark)
    assert _formatted() == fresh
    assert built == [False]
    assert (path.stat().st_mtime_ns, path.read_bytes()) == written
