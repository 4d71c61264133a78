"""The rich consoles every command prints through (rich is imported only where a command
prints, never to parse the command line).

One rule for their width, on standard output and standard error alike: ``COLUMNS`` when it
is a width of at least :data:`MIN_COLUMNS`; otherwise a terminal's own width, and a log's
:data:`LOG_COLUMNS`. A smaller ``COLUMNS`` (``0`` from a runner that knows no width, ``1``
by mistake) is ignored rather than obeyed: rich would print nothing at 0 and a character a
line at 1.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from typing import TextIO

from rich.console import Console

# The width of a log (output not a terminal, as in CI) when COLUMNS gives none.
LOG_COLUMNS = 150
# The narrowest COLUMNS obeyed; below it the variable is ignored.
MIN_COLUMNS = 40


class StdoutConsole(Console):
    """A rich console on standard output that lets a broken pipe propagate
    (:mod:`idefix_rules.cli.pipes`): rich would end with ``SystemExit(1)`` on its own."""

    def on_broken_pipe(self) -> None:
        self.quiet = True
        raise BrokenPipeError


def is_tty(stream: object) -> bool:
    """Whether ``stream`` is a terminal device (False for a closed or file-less stream)."""
    isatty = getattr(stream, "isatty", None)
    try:
        return bool(isatty is not None and isatty())
    except ValueError:  # closed
        return False


def interactive(console: Console) -> bool:
    """Whether ``console`` writes to a terminal a person watches, where bars and spinners may
    redraw their line. Rich's ``is_terminal`` alone is not enough: ``FORCE_COLOR`` (and
    ``TTY_COMPATIBLE=1``) make it true for a log too, which asks for colour, not for cursor
    movement."""
    return console.is_terminal and is_tty(console.file)


def console_width(stream: TextIO) -> int | None:
    """The width a console on ``stream`` prints at (the module docstring's rule); None: the
    terminal's own, measured by rich as it prints."""
    columns = os.environ.get("COLUMNS", "")
    if columns.isdigit() and int(columns) >= MIN_COLUMNS:
        return int(columns)
    if not is_tty(stream):
        return LOG_COLUMNS
    if not columns.isdigit():  # rich ignores it too, and follows the terminal's resizing
        return None
    try:  # rich would obey it: the terminal's width, as measured now
        return os.get_terminal_size(stream.fileno()).columns or 80
    except (OSError, ValueError):
        return 80


def make_console(stderr: bool = False, soft_wrap: bool = False) -> Console:
    """The console of a command, on standard output (or ``stderr``), at the width of the
    module's rule. ``soft_wrap``: lines are not wrapped at the width (records a log and grep
    read whole)."""
    width = console_width(sys.stderr if stderr else sys.stdout)
    if stderr:
        return Console(stderr=True, highlight=False, width=width, soft_wrap=soft_wrap)
    return StdoutConsole(highlight=False, width=width, soft_wrap=soft_wrap)


@contextmanager
def status(text: str, quiet: bool = False) -> Iterator[None]:
    """A spinner with ``text`` on standard error while the block runs, on a terminal only:
    in a log (even one ``FORCE_COLOR`` colours) it would be redrawn into the file. Nothing
    with ``quiet``."""
    console = make_console(stderr=True)
    if quiet or not interactive(console):
        yield
        return
    with console.status(text):
        yield


def print_whole(console: Console, line: str, keep: Iterable[str], markup: bool = True) -> None:
    """Print ``line`` wrapped at the console's width as any line is, unless the wrapping would
    break one of ``keep`` that it holds (a path name, ``#1 name``) across lines or fold it:
    then the line is printed unwrapped, longer than the width, so that the name is whole and
    ``grep '#1 name'`` finds it."""
    text = console.render_str(line, markup=markup)
    wanted = [whole for whole in keep if whole and whole in text.plain]
    pieces = [piece.plain for piece in text.wrap(console, console.width)]
    broken = any(not any(whole in piece for piece in pieces) for whole in wanted)
    console.print(text, soft_wrap=broken)
