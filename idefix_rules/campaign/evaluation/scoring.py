"""Scoring a campaign's paths with its α budget: each path's statistics with the bounds its
verdict is judged on, and the paired comparisons the decision depends on.

The evaluation stage (:mod:`idefix_rules.campaign.evaluation.evaluate`) and ``diff --results`` read
stored runs through these, so both judge a path the same way.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from idefix_rules.campaign.simulation.processes import is_infrastructure
from idefix_rules.campaign.statistics import pairwise
from idefix_rules.campaign.statistics.bounds import failure_sequence, judged_statistics
from idefix_rules.campaign.statistics.budget import AlphaBudget, recycled, shown_to_fail
from idefix_rules.campaign.statistics.runs_needed import pair_runs_needed

if TYPE_CHECKING:
    from idefix_rules.campaign.evaluation.path_result import PathResult
    from idefix_rules.results.reader import StoredResults


def ranked_paths(store: StoredResults) -> int:
    """How many paths of a results file were simulated (and are ranked): the ``P`` of the
    campaign's α budget."""
    return sum(str(store.path_group(name).attrs.get("status", "")) == "simulated"
               and store.has_runs(name) for name in store.path_names)


def judge_path(evaluator: Any, evaluation: Any, result: PathResult, rows: np.ndarray,
               stop_time: float, budget: AlphaBudget, sequential: bool
               ) -> tuple[Any, np.ndarray]:
    """A path's statistics with the bounds its verdict is judged on, and its runs' failure
    flags in run order (runs lost to the infrastructure are none of the path's)."""
    missing = result.missing
    stats = evaluator.path_statistics(evaluation, failed_runs=result.failed + missing)
    failed_rows = np.array(sorted(run for run, reason in result.failures.items()
                                  if not is_infrastructure(reason)), dtype=np.int64)
    failures = failure_sequence(np.asarray(rows), failed_rows, missing)
    return judged_statistics(evaluation, stats, stop_time, budget, sequential, failures), \
        failures


def failing_paths(evaluator: Any, statistics: Mapping[str, Any],
                  waivers: Sequence[Any] = ()) -> list[str]:
    """The paths whose statistics show them to fail, the campaign's ``waivers`` applied."""
    from idefix_rules.campaign.input.waivers import waive_verdict

    return [name for name, stats in statistics.items()
            if shown_to_fail(waive_verdict(evaluator.verdict(stats), waivers, name)[0])]


def judge_paths(evaluator: Any, paths: Mapping[str, tuple[Any, PathResult, np.ndarray, float]],
                budget: AlphaBudget, sequential: bool, waivers: Sequence[Any] = ()
                ) -> tuple[AlphaBudget, dict[str, tuple[Any, np.ndarray]]]:
    """Every path judged at the budget's levels, raised by the paths shown to fail
    (:func:`~idefix_rules.campaign.statistics.budget.recycled`): the final budget, and each
    path's (statistics, failure flags) at it. ``paths``: name → (evaluation, result, its
    complete rows, stop time); ``waivers``: the campaign's (a waived failure is no failure)."""
    # per level: every level follows from the budget's share per path (budget.py), so a
    # failure past the floor judges nothing again
    judged: dict[float, dict[str, tuple[Any, np.ndarray]]] = {}

    def failing(at: AlphaBudget) -> list[str]:
        found = judged.get(at.per_path)
        if found is None:
            found = judged[at.per_path] = {
                name: judge_path(evaluator, evaluation, result, rows, stop_time, at, sequential)
                for name, (evaluation, result, rows, stop_time) in paths.items()}
        return failing_paths(evaluator, {name: stats for name, (stats, _) in found.items()},
                             waivers)

    final = recycled(budget, failing)
    return final, judged[final.per_path]


def contenders(ranking: Sequence[str], results: Sequence[PathResult]) -> list[str]:
    """The ranked paths that pass (or are waived) or may still pass, best first."""
    by_name = {result.name: result for result in results}
    return [name for name in ranking
            if by_name[name].undecided or bool(by_name[name].passed)]


def decision_pairs(run_risks: Mapping[str, tuple[np.ndarray, np.ndarray]],
                   ranking: Sequence[str], results: Sequence[PathResult], budget: AlphaBudget,
                   margin: float, sequential: bool) -> list[Any]:
    """Every pair of ranked paths in the same worlds, each side at the budget's comparison α,
    marked with whether the decision depends on it; an open one it depends on says how many
    paired runs would settle it at the present spread."""
    pairs = pairwise.mark_needed(
        pairwise.compare_pairs(run_risks, ranking, budget.comparison_alpha, margin, sequential,
                               budget.comparison_tuned),
        contenders(ranking, results))
    return [dataclasses.replace(pair, runs_needed=pair_runs_needed(
                pairwise.paired_differences(run_risks[pair.first], run_risks[pair.second]),
                budget.comparison_alpha, margin, sequential, budget.comparison_tuned))
            if pair.needed and pair.outcome == pairwise.OPEN else pair
            for pair in pairs]
