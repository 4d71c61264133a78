"""A path's statistics, verdict and runs still needed, filled into its ``PathResult``."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from idefix_rules.campaign.evaluation.path_result import PathResult
from idefix_rules.campaign.evaluation.spread import risk_spread
from idefix_rules.campaign.input.expectations import chance_level
from idefix_rules.campaign.input.wording import runs_needed_text
from idefix_rules.campaign.statistics.budget import AlphaBudget
from idefix_rules.campaign.statistics.runs_needed import runs_needed


def fill_runs_needed(result: PathResult, evaluation: Any, verdict: Any, budget: AlphaBudget,
                     sequential: bool, stop_time: float,
                     failures: np.ndarray | None = None) -> None:
    """Roughly how many runs would settle each verdict rule that is not decided."""
    result.runs_needed = {
        rule.name: runs_needed(rule, evaluation, budget.levels(rule.statistic or ""),
                               sequential, stop_time, failures,
                               budget.tuned_levels(rule.statistic or ""))
        for rule in verdict.rules if not rule.decided}
    shown = {_reason_text(rule): rule.name for rule in verdict.rules if not rule.decided}
    result.verdict_reasons = [
        f"{text}; {runs_needed_text(result.runs_needed[shown[text]])}" if text in shown else text
        for text in result.verdict_reasons]



def risk_ceiling(evaluator: Any) -> float:
    """The largest I_max the rulebook can give: its largest index weight (1 without indices)."""
    return max((float(w) for w in evaluator.checked.weights.values()), default=1.0)


def fill_result(result: PathResult, evaluation: Any, stats: Any, verdict: Any,
                ceiling: float = 1.0) -> None:
    """Copy a path's statistics and verdict into ``result`` (mean risk, chances, reasons …)."""
    result.statistics = stats
    result.verdict = verdict
    risk = stats.risk
    result.mean_risk = _float(risk.value)
    result.risk_ci = (float(risk.low), float(risk.high))
    result.chances = {str(k): float(v.value) for k, v in stats.chances.items()}
    result.collision_chance = collision_chances(result.chances)
    energy = _float(stats.energy.value)  # NaN: the FMU provides no 'energy'
    result.energy = energy if energy is not None and energy == energy else None
    result.time = _float(stats.time.value)
    counts = dict(getattr(stats, "dominant_counts", {}) or {})
    result.dominant_index = max(counts, key=lambda k: counts[k]) if any(counts.values()) \
        else dominant_index(evaluation)
    i_max = getattr(evaluation, "i_max", None)
    result.risk_spread = None if i_max is None else risk_spread(
        result.name, np.asarray(i_max), dict(getattr(evaluation, "values", {}) or {}), ceiling)
    result.passed = bool(verdict.passed)
    result.undecided = not bool(verdict.decided)
    # A decided failure is explained by the rules that fail decidedly; otherwise by the rules
    # that fail or are not decided.
    failed_for_sure = [rule for rule in verdict.rules if not rule.passed and rule.decided]
    shown = failed_for_sure or [rule for rule in verdict.rules
                                if not rule.passed or not rule.decided]
    result.verdict_reasons = [_reason_text(rule) for rule in shown]
    # Failed runs are the rulebook's to judge (a verdict that reads `failed`, else the
    # `no_failed_runs` rule it gets: docs/rulebook-language.md); a run neither complete nor
    # failed (nor lost to the infrastructure) is missing from the results, and a path with one
    # never passes: this is the last guard.
    missing = result.missing
    if missing > 0 and result.passed:
        result.passed = False
        result.verdict_reasons.append(f"{missing} of {result.runs} run(s) missing")


def _reason_text(rule: Any) -> str:
    """``name: message``; the rule's message already says when it is not decided."""
    return f"{rule.name}: {rule.message}"


def _float(value: Any) -> float | None:
    if value is None:
        return None
    try:
        return float(value)
    except (TypeError, ValueError):
        return None


def collision_chances(chances: Mapping[str, float]) -> dict[str, float]:
    """Chance of a collision per level, from the rulebook's chances whose name ends in a level.

    ``hit_L2``, ``collision.L2``, ``collision_L2`` all count as the L2 column.
    """
    found = {}
    for name, value in chances.items():
        level = chance_level(name)
        if level is not None:
            found[level] = value
    return found


def dominant_index(evaluation: Any) -> str | None:
    names = list(getattr(evaluation, "index_names", ()))
    dominant = np.asarray(getattr(evaluation, "dominant", []))
    if not names or dominant.size == 0:
        return None
    valid = dominant[(dominant >= 0) & (dominant < len(names))]
    if valid.size == 0:
        return None
    counts = np.bincount(valid.astype(int), minlength=len(names))
    return str(names[int(np.argmax(counts))])

