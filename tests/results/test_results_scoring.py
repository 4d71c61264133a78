"""Scoring stored runs chunk by chunk: the per-sample values alone are the whole evaluation's,
and read only what they need."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np
import pytest

from idefix_rules.commands import Command
from idefix_rules.results.format import STATUS_COMPLETE, STATUS_FAILED
from idefix_rules.results.scoring import score_chunks
from idefix_rules.rulebook import check_text, compile_rulebook
from idefix_rules.rulebook.derived import DerivedSignals, RunContext

RULEBOOK = """rulebook "t" version "1.0.0"
purpose "test"
settings { tolerance_growth = 5 cm/rad }
index I_pos { value = final over time (drift / tolerance_radius) limit = 1 weight = 1 }
index I_s { value = percentile 95 over time (max over wheels (abs(wheel.slip))) limit = 1
            weight = 1 }
index I_m { value = final over time (abs(x)) limit = 1 m weight = 1
            map = abs(x - mean over runs (x)) }
chance stuck_once = any over time (stuck > 0)
chance far = final over time (mean over runs (x)) > 1 m
verdict ok: require risk <= 70 %
"""
CHAIN = (Command(0.1, 0.2, 0.0), Command(0.1, 0.1, 0.5))


class MemoryRuns:
    """A stored path in memory, as the scoring reads it; remembers which signals it read."""

    def __init__(self, signals: dict[str, np.ndarray], status: np.ndarray) -> None:
        self.signals, self.status, self.read = signals, status, set()

    def run_status(self, name: str) -> np.ndarray:
        return self.status

    def read_runs(self, name: str, selection: slice | np.ndarray,
                  keys: Sequence[str] | None = None) -> dict[str, np.ndarray]:
        wanted = [k for k in (keys or self.signals) if k in self.signals]
        self.read |= set(wanted)
        return {k: self.signals[k][selection] for k in wanted}


def stored_path(runs: int = 7, samples: int = 12) -> tuple[dict[str, np.ndarray], RunContext]:
    rng = np.random.default_rng(3)
    t = np.arange(samples, dtype=float)
    command = np.array([0] * 4 + [1] * 4 + [-1] * (samples - 8), dtype=float)
    signals = {"t": np.tile(t, (runs, 1)), "command": np.tile(command, (runs, 1)),
               "energy": np.cumsum(rng.random((runs, samples)), axis=1),
               "stuck": np.zeros((runs, samples)),
               "wheel.slip": rng.normal(0.2, 0.1, (runs, samples, 4))}
    for name in ("x", "y", "yaw"):
        signals[name] = np.cumsum(rng.normal(0.0, 0.01, (runs, samples)), axis=1)
    reference = {name: values[0] * 0.5 for name, values in signals.items()
                 if name in ("t", "x", "y", "yaw")}
    reference["t"] = t
    return signals, RunContext(CHAIN, initial_position_sigma=0.01, reference=reference)


def test_per_sample_values_alone_are_the_whole_evaluations_chunk_by_chunk():
    evaluator = compile_rulebook(check_text(RULEBOOK, "t.rules").checked)
    signals, context = stored_path()
    status = np.full(7, STATUS_COMPLETE, dtype=np.int8)
    status[2] = STATUS_FAILED
    complete = np.flatnonzero(status == STATUS_COMPLETE)
    whole = evaluator.evaluate({k: v[complete] for k, v in signals.items()}, context)
    scored = list(score_chunks(MemoryRuns(signals, status), "p", [evaluator], context,
                               per_sample=True, chunk_runs=2))
    reader = MemoryRuns(signals, status)
    chunks = list(score_chunks(reader, "p", [evaluator], context, per_sample=True,
                               per_run=False, chunk_runs=2))
    assert np.concatenate([chunk.rows for chunk in chunks]).tolist() == complete.tolist()
    for name, values in whole.per_sample.items():
        joined = np.concatenate([chunk.samples[0][name] for chunk in chunks])
        # the same values as scored with the per-run ones, chunk for chunk
        np.testing.assert_array_equal(
            joined, np.concatenate([chunk.evaluations[0].per_sample[name]
                                    for chunk in scored]), err_msg=name)
        # and the map's mean is over every complete run, not the chunk's (summed by chunk)
        np.testing.assert_allclose(joined, values, rtol=1e-12, atol=1e-15, err_msg=name)
    assert all(chunk.evaluations == [None] for chunk in chunks)
    assert all(isinstance(chunk.sources[0], DerivedSignals) for chunk in chunks)
    # neither the energy nor a signal only a chance reads
    assert reader.read == {"t", "command", "x", "y", "yaw", "wheel.slip"}


def test_scored_per_run_the_chunks_hold_the_evaluation_and_its_derived_signals():
    evaluator = compile_rulebook(check_text(RULEBOOK, "t.rules").checked)
    signals, context = stored_path()
    reader = MemoryRuns(signals, np.full(7, STATUS_COMPLETE, dtype=np.int8))
    chunks = list(score_chunks(reader, "p", [evaluator], context, chunk_runs=3))
    assert all(chunk.samples == [] for chunk in chunks)
    assert all(isinstance(chunk.sources[0], DerivedSignals) for chunk in chunks)
    whole = evaluator.evaluate(signals, context)
    np.testing.assert_array_equal(
        np.concatenate([chunk.evaluations[0].i_max for chunk in chunks]), whole.i_max)
    assert {"energy", "stuck"} <= reader.read


def _ctrl_c_ignored(signals: dict, rows: np.ndarray) -> bool:
    import signal

    return signal.getsignal(signal.SIGINT) is signal.SIG_IGN


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="the checks fork only with two cores")
def test_the_collision_check_workers_leave_ctrl_c_to_the_evaluation() -> None:
    """Ctrl-C while an evaluation checked collisions printed a forked worker's traceback
    (KeyboardInterrupt in concurrent.futures); the parent alone handles it."""
    from idefix_rules.results.collisions import POSE_SIGNALS
    from idefix_rules.results.scoring import with_collisions

    chunks = [(np.arange(1), {key: np.zeros((1, 2)) for key in POSE_SIGNALS})]
    [(_, _, ignored)] = list(with_collisions(chunks, _ctrl_c_ignored, workers=2))
    assert ignored is True
