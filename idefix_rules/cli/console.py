"""The rich console every command prints through (rich is imported only where a command
prints, never to parse the command line)."""

from __future__ import annotations

import os

from rich.console import Console


class StdoutConsole(Console):
    """A rich console on standard output that lets a broken pipe propagate
    (:mod:`idefix_rules.cli.pipes`): rich would end with ``SystemExit(1)`` on its own."""

    def on_broken_pipe(self) -> None:
        self.quiet = True
        raise BrokenPipeError


def make_console() -> Console:
    """Rich console. ``COLUMNS`` sets its width; without it a log (not a terminal) is 150
    columns wide (CI logs), a terminal as wide as it is."""
    console = StdoutConsole(highlight=False)
    if not console.is_terminal and not os.environ.get("COLUMNS", "").isdigit():
        console = StdoutConsole(highlight=False, width=150)
    return console
