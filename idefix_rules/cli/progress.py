"""Progress of a campaign on the console, two ways (the simulation's ``Progress`` protocol).

- :class:`RichProgress`, on a terminal: a spinner with the elapsed time for each phase
  (compile, FMU build, terrain, evaluation, report), with an ETA once a phase has said how far
  it is and has lasted a couple of seconds; then a line saying how long it took. Bars with ETA
  for each path's runs.
- :class:`PlainProgress`, for a log (output not a terminal, as in CI): plain lines only, no
  cursor movement. A line per phase with its duration (and a line when it starts, once it has
  lasted a couple of seconds, so a log is never silent for long), and a line per 10 % of each
  path's runs with the elapsed time and an ETA.

Both take ``advance(fraction, detail)`` for how far the current phase is (the evaluation per
path, the report per stage).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    ProgressColumn,
    SpinnerColumn,
    Task,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Column
from rich.text import Text

from idefix_rules.cli.console import interactive

# A phase shorter than this gets no ETA and, in a log, no line when it starts.
LONG_PHASE = 2.0


def clock_text(seconds: float) -> str:
    """``0:07``, ``1:05``, ``1:02:03``.

    >>> clock_text(65.4), clock_text(3723)
    ('1:05', '1:02:03')
    """
    whole = max(0, round(seconds))
    hours, rest = divmod(whole, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


def remaining(elapsed: float, fraction: float) -> float | None:
    """Seconds left when ``fraction`` of the work took ``elapsed`` (None: no estimate yet).

    >>> remaining(10.0, 0.25)
    30.0
    """
    if fraction <= 0.0 or elapsed < LONG_PHASE:
        return None
    return elapsed * (1.0 - min(fraction, 1.0)) / fraction


class _PhaseEta(ProgressColumn):
    """``ETA 0:12`` once the phase has a fraction done and has lasted a couple of seconds."""

    def render(self, task: Task) -> Text:
        if not task.total:
            return Text("")
        left = remaining(task.elapsed or 0.0, task.completed / task.total)
        return Text("" if left is None else f"ETA {clock_text(left)}", style="cyan")


class RichProgress:
    """Progress on a terminal (see the module docstring)."""

    def __init__(self, console: Console, quiet: bool) -> None:
        self.console = console
        self.quiet = quiet
        self.bars: Progress | None = None
        self.tasks: dict[str, Any] = {}
        self.failed: dict[str, int] = {}
        self.step: tuple[str, float] | None = None
        self.spinner: Progress | None = None
        self.spinner_task: Any = None

    def message(self, text: str) -> None:
        if self.quiet:
            return
        self.stop()
        self.step = (text, time.perf_counter())
        self.spinner = Progress(SpinnerColumn(),
                                TextColumn("{task.description}",
                                           table_column=Column(overflow="fold")),
                                TimeElapsedColumn(), _PhaseEta(), console=self.console,
                                transient=True)
        self.spinner_task = self.spinner.add_task(escape(text), total=None)
        self.spinner.start()

    def note(self, text: str) -> None:
        """A line above the bars while the runs go on (the bars stay)."""
        if self.quiet:
            return
        if self.bars is None:
            self.message(text)
            return
        self.bars.console.print(escape(text))

    def advance(self, fraction: float, detail: str = "") -> None:
        """How far the current phase is (0 … 1), and what it is at."""
        if self.quiet or self.spinner is None or self.step is None:
            return
        text = self.step[0] + (f": {detail}" if detail else "")
        self.spinner.update(self.spinner_task, total=1.0, completed=min(max(fraction, 0.0), 1.0),
                            description=escape(text))

    def _end_step(self) -> None:
        if self.spinner is not None:
            self.spinner.stop()
            self.spinner = None
        if self.step is not None:
            text, began = self.step
            self.step = None
            self.console.print(f"[dim]{escape(text)} ({time.perf_counter() - began:.1f} s)"
                               "[/dim]")

    def start_path(self, name: str, total: int, done: int, failed: int = 0,
                   up_to: bool = False) -> None:
        if self.quiet:
            return
        self._end_step()
        if self.bars is None:
            # A narrow console keeps the bar short so whole path names fit; a name longer
            # than the line folds onto the next one, never cut.
            bar = 10 if self.console.width < 100 else 30
            self.bars = Progress(TextColumn("{task.description}",
                                            table_column=Column(overflow="fold")),
                                 BarColumn(bar_width=bar),
                                 MofNCompleteColumn(), TextColumn("{task.fields[failed]}"),
                                 TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn(),
                                 console=self.console, transient=False)
            self.bars.start()
        self.failed[name] = failed
        self.tasks[name] = self.bars.add_task(escape(name), total=total, completed=done,
                                              failed=self._failed_label(name))

    def run_finished(self, name: str, ok: bool) -> None:
        if self.bars is None or name not in self.tasks:
            return
        if not ok:
            self.failed[name] += 1
        self.bars.update(self.tasks[name], advance=1, failed=self._failed_label(name))

    def _failed_label(self, name: str) -> str:
        return f"[red]{self.failed[name]} failed[/red]" if self.failed[name] else ""

    def stop(self) -> None:
        self._end_step()
        if self.bars is not None:
            self.bars.stop()
            self.bars = None


@dataclass
class _PathRuns:
    total: int
    done: int
    began: float
    started_with: int
    decile: int
    failed: int = 0


class PlainProgress:
    """Progress for a log: plain lines, no cursor movement (see the module docstring).

    ``clock`` is injectable for tests; ``long_phase`` is how long a phase runs before its
    start is announced."""

    def __init__(self, console: Console, clock: Callable[[], float] = time.monotonic,
                 long_phase: float = LONG_PHASE) -> None:
        self.console = console
        self.clock = clock
        self.long_phase = long_phase
        self.lock = threading.Lock()
        self.phase: tuple[str, float] | None = None
        self.decile = 0
        self.timer: threading.Timer | None = None
        self.paths: dict[str, _PathRuns] = {}
        self.runs_began: float | None = None
        self.runs_label = "Monte Carlo runs"  # what the runs are, in the line that ends them
        # stdout's reader went away while the timer thread wrote: the main thread raises it
        self.broken_pipe = False

    def _say(self, text: str) -> None:
        if self.broken_pipe:  # the console is quiet since: it would not raise it again
            raise BrokenPipeError
        self.console.print(text, markup=False, highlight=False, soft_wrap=True)

    def _announce(self, phase: tuple[str, float]) -> None:
        with self.lock:
            if self.phase is phase and self.decile == 0:  # still, and nothing said of it
                try:
                    self._say(f"{phase[0]} …")
                except BrokenPipeError:  # said at the next line, where the command stops
                    self.broken_pipe = True

    def message(self, text: str) -> None:
        self._end_phase()
        self._end_runs()
        phase = (text, self.clock())
        self.phase, self.decile = phase, 0
        if self.long_phase > 0:
            self.timer = threading.Timer(self.long_phase, self._announce, (phase,))
            self.timer.daemon = True
            self.timer.start()

    def note(self, text: str) -> None:
        """A line while the runs go on: the runs' count and their lines go on after it."""
        if self.runs_began is None:
            self.message(text)
            return
        self._say(text)

    def advance(self, fraction: float, detail: str = "") -> None:
        if self.phase is None:
            return
        decile = int(min(max(fraction, 0.0), 1.0) * 10 + 1e-9)
        if decile <= self.decile or decile >= 10:
            return
        with self.lock:
            self.decile = decile
        text, began = self.phase
        elapsed = self.clock() - began
        left = remaining(elapsed, fraction)
        eta = f", ETA {clock_text(left)}" if left is not None else ""
        at = f" ({detail})" if detail else ""
        self._say(f"{text}: {decile * 10} %{at}, {clock_text(elapsed)}{eta}")

    def _end_phase(self) -> None:
        with self.lock:
            if self.timer is not None:
                self.timer.cancel()
                self.timer = None
            if self.phase is not None:
                text, began = self.phase
                self.phase = None
                self._say(f"{text} ({self.clock() - began:.1f} s)")

    def _end_runs(self) -> None:
        if self.runs_began is not None:
            total = sum(p.done for p in self.paths.values())
            failed = sum(p.failed for p in self.paths.values())
            failures = f", {failed} failed" if failed else ""
            self._say(f"{self.runs_label} of {len(self.paths)} path(s): {total} runs{failures} "
                      f"({self.clock() - self.runs_began:.1f} s)")
            self.runs_began = None
            self.paths = {}

    def start_path(self, name: str, total: int, done: int, failed: int = 0,
                   up_to: bool = False) -> None:
        self._end_phase()
        now = self.clock()
        if self.runs_began is None:
            self.runs_began = now
        decile = done * 10 // total if total else 10
        self.paths[name] = _PathRuns(total, done, now, done, decile, failed)
        if done:
            failures = f" ({failed} failed)" if failed else ""
            rest = f"up to {total - done} more as its looks decide" if up_to else \
                f"{total - done} to simulate"
            self._say(f"{name}: {done}/{total} runs stored already{failures}, {rest}")

    def run_finished(self, name: str, ok: bool) -> None:
        runs = self.paths.get(name)
        if runs is None:
            return
        runs.done += 1
        runs.failed += 0 if ok else 1
        decile = runs.done * 10 // runs.total if runs.total else 10
        if decile <= runs.decile:
            return
        runs.decile = decile
        elapsed = self.clock() - runs.began
        fresh = runs.done - runs.started_with
        rest = runs.total - runs.done
        eta = (f", ETA {clock_text(elapsed * rest / fresh)}" if rest and fresh else "")
        failures = f", {runs.failed} failed" if runs.failed else ""
        self._say(f"{name}: {runs.done}/{runs.total} runs ({100 * runs.done // runs.total} %)"
                  f"{failures}, {clock_text(elapsed)}{eta}")

    def stop(self) -> None:
        self._end_phase()
        self._end_runs()


def make_progress(console: Console, quiet: bool) -> RichProgress | PlainProgress:
    """Bars and spinners on a terminal, plain lines in a log (a file or a pipe, coloured by
    ``FORCE_COLOR`` or not: :func:`~idefix_rules.cli.console.interactive`); nothing at all
    with ``quiet``."""
    if quiet or interactive(console):
        return RichProgress(console, quiet)
    return PlainProgress(console)
