"""Progress in a log (not a terminal): plain lines, a line per phase with its duration, a line
per 10 % of a path's runs with an ETA, a line when a long phase starts."""

from __future__ import annotations

import io
import threading
import time

import pytest
from rich.console import Console

from idefix_rules.cli.progress import PlainProgress, RichProgress, make_progress, remaining


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def _plain(long_phase: float = 0.0) -> tuple[PlainProgress, Clock, io.StringIO]:
    out = io.StringIO()
    clock = Clock()
    console = Console(file=out, width=80, force_terminal=False, color_system=None)
    return PlainProgress(console, clock, long_phase), clock, out


def test_a_phase_is_one_line_with_its_duration() -> None:
    progress, clock, out = _plain()
    progress.message("compiling the rulebook r.rules")
    clock.now += 0.25
    progress.message("preparing the terrain")
    clock.now += 1.0
    progress.stop()
    assert out.getvalue().splitlines() == ["compiling the rulebook r.rules (0.2 s)",
                                           "preparing the terrain (1.0 s)"]


def test_runs_say_each_tenth_with_elapsed_time_and_eta() -> None:
    progress, clock, out = _plain()
    progress.start_path("a-long-path-name", total=100, done=0)
    for run in range(100):
        clock.now += 0.5
        progress.run_finished("a-long-path-name", ok=run != 3)
    progress.message("evaluating")
    lines = out.getvalue().splitlines()
    tenths = [line for line in lines if line.startswith("a-long-path-name: ")]
    assert len(tenths) == 10  # 10 %, 20 %, … 100 %: no more, no less
    assert tenths[0] == "a-long-path-name: 10/100 runs (10 %), 1 failed, 0:05, ETA 0:45"
    assert tenths[-1] == "a-long-path-name: 100/100 runs (100 %), 1 failed, 0:50"
    assert lines[-1] == "Monte Carlo runs of 1 path(s): 100 runs, 1 failed (50.0 s)"


def test_a_note_while_runs_go_on_ends_nothing() -> None:
    """An adaptive campaign stops a path between looks: the line says so, and the other paths'
    runs go on being counted and said (they were dropped after the first look)."""
    progress, clock, out = _plain()
    progress.start_path("a", total=10, done=0)
    progress.start_path("b", total=10, done=0)
    for _ in range(2):
        clock.now += 1.0
        progress.run_finished("a", ok=True)
        progress.run_finished("b", ok=True)
    progress.note("a: decided after 2 runs: verdict fail")
    for _ in range(3):
        clock.now += 1.0
        progress.run_finished("b", ok=True)
    progress.message("evaluating")
    lines = out.getvalue().splitlines()
    assert lines[4] == "a: decided after 2 runs: verdict fail"
    assert lines[5:] == ["b: 3/10 runs (30 %), 0:03, ETA 0:07",
                         "b: 4/10 runs (40 %), 0:04, ETA 0:06",
                         "b: 5/10 runs (50 %), 0:05, ETA 0:05",
                         "Monte Carlo runs of 2 path(s): 7 runs (5.0 s)"]
    progress, _, out = _plain()
    progress.note("said before any run")  # no runs: a phase, as message
    progress.stop()
    assert out.getvalue().splitlines() == ["said before any run (0.0 s)"]


def test_resumed_runs_are_said_and_the_eta_counts_only_new_runs() -> None:
    progress, clock, out = _plain()
    progress.start_path("p", total=10, done=5)
    clock.now += 2.0
    progress.run_finished("p", ok=True)
    lines = out.getvalue().splitlines()
    assert lines == ["p: 5/10 runs stored already, 5 to simulate",
                     "p: 6/10 runs (60 %), 0:02, ETA 0:08"]
    progress, clock, out = _plain()
    progress.start_path("p", total=10, done=5, failed=2)  # kept: they failed on their own
    clock.now += 2.0
    progress.run_finished("p", ok=False)
    progress.message("evaluating")
    lines = out.getvalue().splitlines()
    assert lines == ["p: 5/10 runs stored already (2 failed), 5 to simulate",
                     "p: 6/10 runs (60 %), 3 failed, 0:02, ETA 0:08",
                     "Monte Carlo runs of 1 path(s): 6 runs, 3 failed (2.0 s)"]


def test_a_phase_that_says_how_far_it_is_gets_an_eta_per_tenth() -> None:
    progress, clock, out = _plain()
    progress.message("writing the report")
    for step in range(1, 5):
        clock.now += 3.0
        progress.advance(step / 4, f"stage {step}")
    progress.advance(0.5, "again")  # no new tenth, no line
    progress.stop()
    assert out.getvalue().splitlines() == [
        "writing the report: 20 % (stage 1), 0:03, ETA 0:09",
        "writing the report: 50 % (stage 2), 0:06, ETA 0:06",
        "writing the report: 70 % (stage 3), 0:09, ETA 0:03",
        "writing the report (12.0 s)"]


def test_a_long_phase_is_announced_when_it_starts_a_short_one_is_not() -> None:
    out = io.StringIO()
    console = Console(file=out, width=80, force_terminal=False, color_system=None)
    progress = PlainProgress(console, long_phase=0.05)
    progress.message("short")
    progress.message("long")
    time.sleep(0.3)
    progress.stop()
    lines = out.getvalue().splitlines()
    assert lines[0].startswith("short (")
    assert lines[1:] == ["long …", lines[2]] and lines[2].startswith("long (")


class Terminal(io.StringIO):
    """What a terminal device answers."""

    def isatty(self) -> bool:
        return True


def test_the_mode_follows_the_output() -> None:
    log = Console(file=io.StringIO(), force_terminal=False)
    terminal = Console(file=Terminal(), force_terminal=True)
    # what rich makes of a log under FORCE_COLOR: a terminal, for colour; bars would be
    # redrawn into the file
    coloured_log = Console(file=io.StringIO(), force_terminal=True)
    assert isinstance(make_progress(log, quiet=False), PlainProgress)
    assert isinstance(make_progress(terminal, quiet=False), RichProgress)
    assert isinstance(make_progress(coloured_log, quiet=False), PlainProgress)
    quiet = make_progress(log, quiet=True)
    quiet.message("nothing")
    quiet.stop()
    assert log.file.getvalue() == ""  # type: ignore[attr-defined]


def test_a_terminal_phase_shows_an_eta_once_it_lasts() -> None:
    out = io.StringIO()
    console = Console(file=out, width=100, force_terminal=True, color_system=None)
    progress = RichProgress(console, quiet=False)
    progress.message("writing the report")
    assert progress.spinner is not None
    task = progress.spinner.tasks[0]
    progress.advance(0.5, "result maps")
    assert task.total == 1.0 and task.completed == 0.5
    assert "result maps" in task.description
    progress.stop()
    assert remaining(1.0, 0.5) is None  # too early to guess
    assert remaining(4.0, 0.5) == 4.0


def test_on_a_terminal_a_note_prints_above_the_bars_and_keeps_them() -> None:
    out = io.StringIO()
    console = Console(file=out, width=100, force_terminal=True, color_system=None)
    progress = RichProgress(console, quiet=False)
    progress.start_path("a", total=4, done=0)
    progress.start_path("b", total=4, done=0)
    progress.note("a: decided after 1 runs: verdict fail")
    bars = progress.bars
    assert bars is not None
    progress.run_finished("b", ok=True)
    assert progress.bars is bars and bars.tasks[1].completed == 1
    progress.stop()
    assert "a: decided after 1 runs: verdict fail" in out.getvalue()


class _ClosedPipe(io.StringIO):
    def write(self, text: str) -> int:
        raise BrokenPipeError


def test_a_reader_gone_while_a_long_phase_is_announced_stops_the_command(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The announcement comes from a timer thread: the broken pipe it meets is the main
    thread's to raise at its next line (the dispatcher then ends quietly, exit 141), not a
    thread's traceback on stderr followed by a command that runs on without a word."""
    from idefix_rules.cli.console import StdoutConsole

    thread_errors: list[type[BaseException]] = []
    monkeypatch.setattr(threading, "excepthook",
                        lambda hook: thread_errors.append(hook.exc_type))
    progress = PlainProgress(StdoutConsole(file=_ClosedPipe(), width=80), long_phase=0.01)
    progress.message("simulating")
    time.sleep(0.3)
    assert thread_errors == []
    with pytest.raises(BrokenPipeError):
        progress.message("evaluating")
