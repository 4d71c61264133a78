"""Signals used when a run has them (command, done, energy, z) are read from the results file
whenever stored, though a rulebook does not require them of a foreign FMU."""

from __future__ import annotations

from collections.abc import Sequence
from functools import cache
from typing import Any

import numpy as np
from hypothesis import event, given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays as hypothesis_arrays

from idefix_rules.campaign.storage.store import STATUS_COMPLETE
from idefix_rules.commands import Command
from idefix_rules.results.runs import complete_chunks
from idefix_rules.results.scoring import signals_to_read

POSITION_RULEBOOK = ('rulebook "t" version "1.0.0"\npurpose "test"\n'
                     "index I_end { value = final over time (local_error) limit = 5 cm "
                     "weight = 1 }\nverdict ok: require risk <= 70 %\n")


@cache
def _position_rulebook() -> tuple[Any, Any]:
    from idefix_rules.rulebook import compile_rulebook
    from idefix_rules.rulebook.check import check
    from idefix_rules.rulebook.parser import parse_rulebook

    checked = check(parse_rulebook(POSITION_RULEBOOK, "t.rules")).checked
    assert checked is not None
    return checked, compile_rulebook(checked)


class Reads:
    """A stand-in rulebook that requires ``signals`` and reads nothing optionally."""

    def __init__(self, *signals: str) -> None:
        self.required_signals = frozenset(signals)
        self.optional_signals: frozenset[str] = frozenset()


class Stored:
    """A stand-in results file holding every signal of two runs."""

    def __init__(self) -> None:
        names = ("t", "x", "y", "z", "yaw", "command", "energy", "wheel.slip")
        self.signals = {name: np.zeros((2, 5)) for name in names}

    def run_status(self, name: str) -> np.ndarray:
        return np.full(2, STATUS_COMPLETE, dtype=np.int8)

    def read_runs(self, name: str, selection: slice | np.ndarray,
                  keys: Sequence[str] | None = None) -> dict[str, np.ndarray]:
        wanted = self.signals if keys is None else [k for k in keys if k in self.signals]
        return {key: self.signals[key][selection] for key in wanted}


def test_a_rulebook_reading_position_gets_height_run_time_and_energy_when_stored() -> None:
    ((rows, signals),) = complete_chunks(Stored(), "p", signals_to_read([Reads("t", "x", "y")]))
    assert sorted(signals) == ["command", "energy", "t", "x", "y", "z"]
    np.testing.assert_array_equal(rows, [0, 1])


def test_a_rulebook_reading_no_position_reads_no_height() -> None:
    ((_, signals),) = complete_chunks(Stored(), "p", signals_to_read([Reads("t", "wheel.slip")]))
    assert sorted(signals) == ["command", "energy", "t", "wheel.slip"]


def test_the_global_error_adds_height_only_when_the_runs_have_it() -> None:
    from idefix_rules.rulebook.derived import DerivedSignals, RunContext

    t = np.arange(3.0)
    flat = {"t": t[None], "x": np.array([[0.0, 0.3, 0.3]]), "y": np.array([[0.0, 0.0, 0.4]])}
    reference = {"t": t, "x": np.zeros(3), "y": np.zeros(3), "z": np.zeros(3)}
    planar = DerivedSignals(flat, RunContext(reference=reference)).get("global_error")
    np.testing.assert_allclose(planar, [[0.0, 0.3, 0.5]])
    raised = {**flat, "z": np.array([[0.0, 0.0, 1.2]])}
    spatial = DerivedSignals(raised, RunContext(reference=reference)).get("global_error")
    np.testing.assert_allclose(spatial, [[0.0, 0.3, 1.3]])


def test_both_evaluators_time_runs_by_command_then_done_then_stop_time() -> None:
    from idefix_rules.rulebook.derived import RunContext
    from idefix_rules.rulebook.interpret import interpret

    checked, evaluator = _position_rulebook()
    t = np.arange(6.0)
    x = np.array([[0.0, 0.002, 0.004, 0.006, 0.006, 0.006]] * 2)
    base = {"t": np.tile(t, (2, 1)), "x": x, "y": np.zeros((2, 6))}
    context = RunContext(chain=(Command(0.05, 0.015, 0.0),))  # 3 s at 5 mm/s
    cases = [
        ({"command": np.array([[0, 0, 0, -1, -1, -1]] * 2),
          "energy": np.tile(np.arange(6.0), (2, 1))}, 3.0, 3.0),
        ({"done": np.array([[0, 0, 0, 0, 1, 1], [0, 0, 0, 0, 0, 1]])}, [4.0, 5.0], np.nan),
        ({}, 5.0, np.nan),
    ]
    for extra, time, energy in cases:
        signals = {**base, **extra}
        fast = evaluator.evaluate(signals, context)
        slow = interpret(checked, signals, context)
        for result in (fast, slow):
            np.testing.assert_array_equal(result.time, np.broadcast_to(time, (2,)))
            np.testing.assert_array_equal(result.energy, np.broadcast_to(energy, (2,)))
        np.testing.assert_allclose(fast.values["I_end"], slow.values["I_end"])


@given(done=hypothesis_arrays(np.int8, (3, 8), elements=st.integers(0, 1)))
def test_both_evaluators_end_a_run_where_done_is_set_after_it_was_clear(
        done: np.ndarray) -> None:
    from idefix_rules.rulebook.derived import RunContext
    from idefix_rules.rulebook.interpret import interpret

    checked, evaluator = _position_rulebook()
    t = np.arange(8.0) * 0.5
    signals = {"t": np.tile(t, (3, 1)), "x": np.zeros((3, 8)), "y": np.zeros((3, 8)),
               "done": done.astype(float)}
    context = RunContext(chain=(Command(0.05, 0.01, 0.0),))
    # done counts from a sample where it is set after one where it was not: a flag set from
    # the first sample (an "idle" output) is no end before the run drove (chain_end)
    ends = [next((k for k in range(1, 8) if row[k] and not row[:k].all()), None) for row in done]
    event(f"{sum(end is not None for end in ends)} of 3 runs report done")
    event(f"a run set from its first sample: {bool(done[:, 0].any())}")
    expected = np.array([t[-1] if end is None else t[end] for end in ends])
    for result in (evaluator.evaluate(signals, context), interpret(checked, signals, context)):
        np.testing.assert_array_equal(result.time, expected)
        assert np.isnan(result.energy).all()
