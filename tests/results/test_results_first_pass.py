"""The first pass over a path's runs (reductions over runs) keeps the chunks it read up to a
fixed budget and reads the rest again: memory bounded whatever the run count, and the same
scores whatever the budget."""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

import numpy as np
import pytest

from idefix_rules.campaign.simulation.prescreen import run_context
from idefix_rules.commands import Command, RoverGeometry
from idefix_rules.results import scoring
from idefix_rules.results.format import STATUS_COMPLETE
from idefix_rules.rulebook import compile_rulebook
from idefix_rules.rulebook.parser import parse_rulebook

RULEBOOK = """\
rulebook "first-pass" version "1.0.0"
purpose "A path-level index and a per-run one"
index I_avg "average drift" {
  value = final over time (abs(mean over runs (x - ref.x))) / 10 cm
  limit = 1
  weight = 1
}
index I_y "lateral drift" {
  value = max over time (abs(y)) / 10 cm
  limit = 1
  weight = 1
}
verdict acceptable_risk: require risk <= 50 %
"""
RUNS, SAMPLES, CHUNK = 10, 6, 2


class Runs:
    """Runs held in memory, counting the rows read of each signal."""

    def __init__(self) -> None:
        rng = np.random.default_rng(4)
        t = np.arange(SAMPLES) * 0.5
        self.signals = {"t": np.tile(t, (RUNS, 1)),
                        "x": 0.01 * t + rng.normal(0.0, 0.02, (RUNS, SAMPLES)),
                        "y": rng.normal(0.0, 0.02, (RUNS, SAMPLES)),
                        "z": np.zeros((RUNS, SAMPLES)),
                        "command": np.tile(np.where(t < 2.0, 0.0, -1.0), (RUNS, 1))}
        self.read: Counter[str] = Counter()

    def run_status(self, name: str) -> np.ndarray:
        return np.full(RUNS, STATUS_COMPLETE, dtype=np.int8)

    def read_runs(self, name: str, selection: slice | np.ndarray,
                  keys: Sequence[str] | None = None) -> dict[str, np.ndarray]:
        chunk = {key: self.signals[key][selection] for key in keys or self.signals
                 if key in self.signals}
        for key, values in chunk.items():
            self.read[key] += len(values)
        return chunk


EVALUATOR = compile_rulebook(parse_rulebook(RULEBOOK, "first-pass.rules"))
# what a chunk of the first pass holds: the stored signals the reduction over runs reads
CHUNK_BYTES = CHUNK * SAMPLES * 8 * len(set(EVALUATOR.across_signals) & set(Runs().signals))


def scored(budget: int, monkeypatch: pytest.MonkeyPatch) -> tuple[dict[str, np.ndarray],
                                                                  Counter[str]]:
    monkeypatch.setattr(scoring, "FIRST_PASS_BYTES", budget)
    evaluator = EVALUATOR
    runs = Runs()
    reference = {key: values[0] for key, values in runs.signals.items()}
    context = run_context([Command(0.05, 0.1, 0.0)], RoverGeometry(), 0.01, reference)
    chunks = list(scoring.score_chunks(runs, "p", [evaluator], context, chunk_runs=CHUNK))
    values = {name: np.concatenate([c.evaluations[0].values[name] for c in chunks])
              for name in evaluator.index_names}
    return values, runs.read


def test_the_scores_do_not_depend_on_how_much_of_the_first_pass_is_kept(
        monkeypatch: pytest.MonkeyPatch) -> None:
    kept_all, _ = scored(1 << 30, monkeypatch)
    for budget in (0, 2 * CHUNK_BYTES):
        values, _ = scored(budget, monkeypatch)
        for name, expected in kept_all.items():
            np.testing.assert_array_equal(values[name], expected, err_msg=name)


def test_the_chunks_past_the_budget_are_read_again(monkeypatch: pytest.MonkeyPatch) -> None:
    _, everything = scored(1 << 30, monkeypatch)
    _, nothing = scored(0, monkeypatch)
    _, two_chunks = scored(2 * CHUNK_BYTES, monkeypatch)
    assert "x" in EVALUATOR.across_signals and "y" not in EVALUATOR.across_signals
    assert everything["y"] == nothing["y"] == RUNS  # not read by the first pass
    for key in sorted(set(EVALUATOR.across_signals) & set(Runs().signals)):
        assert everything[key] == RUNS  # read once
        assert nothing[key] == 2 * RUNS  # read by the first pass and again
        assert two_chunks[key] == 2 * RUNS - 2 * CHUNK  # the first two chunks kept
