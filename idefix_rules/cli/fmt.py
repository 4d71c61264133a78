"""``idefix-verify fmt RULEBOOK…``: rewrite rulebooks in canonical form, in place.

The formatter keeps comments; the formatted text parses to the same rule model (checked before
anything is written). A file keeps its line endings: CRLF stays CRLF, as in the editor
(:func:`idefix_rules.rulebook.format.with_line_endings`). ``--check`` writes nothing and exits
1 when a file would change (for CI); ``--diff`` prints what would change and writes nothing
either (as black's and ruff's do).
"""

from __future__ import annotations

import argparse
import difflib
import os
import shutil
import tempfile
from pathlib import Path

from idefix_rules.errors import Span, UserInputError, error

NAME = "fmt"
HELP = ("Format rulebooks in place (canonical order and layout, comments kept). With --check, "
        "write nothing: list the files that would change and exit 1 if any would "
        "(0 if all are formatted); with --diff, write nothing: print the changes. Exit 2 when "
        "a file cannot be parsed.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("rulebooks", nargs="+", type=Path, metavar="RULEBOOK",
                        help="rulebook files (.rules)")
    parser.add_argument("--check", action="store_true",
                        help="do not write; exit 1 and name the files that would be reformatted")
    parser.add_argument("--diff", action="store_true",
                        help="do not write; print a unified diff of the changes (exit 0, or 1 "
                             "with --check when a file would change)")


def formatted_text(source: str, path: str) -> str:
    """The canonical text of a rulebook; raises ``UserInputError`` on syntax errors
    (:func:`idefix_rules.rulebook.format.formatted_text`, imported when used)."""
    from idefix_rules.rulebook.format import formatted_text as formatted

    return formatted(source, path)


def replace_text(path: Path, text: str) -> None:
    """Write ``text`` over ``path`` atomically: a crash or a full disk leaves the old file.

    The new text goes to a temporary file next to the target (a symlink's target), keeps the
    old file's permissions and is renamed over it.
    """
    target = path.resolve()
    fd, temporary = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as handle:
            handle.write(text)
        shutil.copymode(target, temporary)
        os.replace(temporary, target)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def run(args: argparse.Namespace) -> int:
    from idefix_rules.cli.console import make_console
    from idefix_rules.rulebook import read_source
    from idefix_rules.rulebook.format import with_line_endings

    console = make_console(soft_wrap=True)
    invalid: list[UserInputError] = []
    changed = []
    for path in args.rulebooks:
        name = str(path)
        try:
            source = read_source(path)
            text = formatted_text(source, name)
            original = path.read_bytes()  # as stored: its line endings
        except UserInputError as failure:
            invalid.append(failure)
            continue
        except OSError as failure:  # gone or unreadable since it was read
            invalid.append(UserInputError(error(
                "E002", f"cannot read rulebook file {name}: {failure.strerror or failure}",
                Span(name))))
            continue
        written = with_line_endings(text, original)
        if written.encode("utf-8") == original:
            continue
        changed.append(name)
        if args.diff:
            diff = difflib.unified_diff(source.splitlines(keepends=True),
                                        text.splitlines(keepends=True),
                                        fromfile=name, tofile=f"{name} (formatted)")
            shown = "".join(diff)
            console.print(shown or f"{name}: line endings only\n", markup=False, end="")
        if args.check or args.diff:
            console.print(f"would reformat {name}", markup=False)
        else:
            try:
                replace_text(path, written)
            except OSError as failure:
                invalid.append(UserInputError(error(
                    "E010", f"cannot write {name}: {failure.strerror or failure}; the file is "
                            "unchanged", Span(name))))
                continue
            console.print(f"reformatted {name}", markup=False)
    for problem in invalid:
        console.print(problem.render(), markup=False)
    if invalid:
        return 2
    unchanged = len(args.rulebooks) - len(changed)
    verb = "would be reformatted" if args.check or args.diff else "reformatted"
    console.print(f"{len(changed)} file(s) {verb}, {unchanged} unchanged", markup=False,
                  style="yellow" if changed else "green")
    return 1 if args.check and changed else 0
