"""When an adaptive campaign (``runs: auto``) stops a path, and how many runs would decide a
verdict that is not decided.

At each look every ranked path's statistics are put on anytime-valid confidence sequences
(:mod:`idefix_rules.campaign.sequential`) at the rulebook's confidence, and the rulebook's own
verdict logic runs on them. A path stops when

1. its verdict is decided: every verdict rule is decided, or one fails decidedly (then no number
   of runs can make the path pass), and
2. its place relative to every other ranked path is settled: for every pass/fail outcome the
   two verdicts can still take, the order is the same — passing paths rank first, and within a
   group the first rank key's intervals do not overlap; in a paired campaign ranking first by
   risk, the confidence sequence of the two paths' per-world risk differences decides instead
   (:mod:`idefix_rules.campaign.pairwise`): one is safer, or they are tied within the
   rulebook's indifference margin (a tie is a decision too),

or when it reaches ``max_runs``. Because the intervals hold at every run count at once, looking
after every batch and stopping on what they say keeps the confidence of each statistic; a
fixed-count interval re-checked after every batch would not.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from idefix_rules.campaign.sequential import (
    asymptotic_half_width,
    asymptotic_interval,
    betting_interval,
    threshold_rejected,
)
from idefix_rules.limits import MAX_RUNS

STOP_FIXED = "fixed run count"


@dataclass(frozen=True)
class Settlement:
    """What one look says about a path."""

    verdict_decided: bool
    passed: bool
    unsettled_against: tuple[str, ...]  # ranked paths whose order against this one is open

    @property
    def rank_settled(self) -> bool:
        return not self.unsettled_against

    @property
    def done(self) -> bool:
        return self.verdict_decided and self.rank_settled


# --- statistics on confidence sequences ------------------------------------------------------

def _estimate(values: np.ndarray, alpha: float, scale: float = 1.0) -> Any:
    from idefix_rules.rulebook.results import Estimate

    values = np.asarray(values, dtype=np.float64)
    if values.size == 0:
        return Estimate(math.nan, 0.0, scale)
    low, high = betting_interval(values / scale, alpha)
    return Estimate(float(values.mean()), low * scale, high * scale)


def sequential_statistics(evaluation: Any, stats: Any, stop_time: float) -> Any:
    """``stats`` (the rulebook's fixed-count statistics of ``evaluation``) with every interval
    replaced by a confidence sequence at the same confidence: risk, index means and chances
    (values in [0, 1]), time (in [0, stop time]); energy on the asymptotic sequence."""
    from idefix_rules.rulebook.results import Estimate

    alpha = 1.0 - float(stats.confidence)
    time = np.asarray(evaluation.time, dtype=np.float64)
    if stop_time > 0 and time.size and np.all((time >= 0) & (time <= stop_time)):
        time_estimate = _estimate(time, alpha, stop_time)
    else:
        time_estimate = Estimate(float(stats.time.value), -math.inf, math.inf)
    energy = np.asarray(evaluation.energy, dtype=np.float64)
    energy_low, energy_high = asymptotic_interval(energy, alpha)
    return dataclasses.replace(
        stats,
        risk=_estimate(evaluation.i_max, alpha),
        index_mean={name: _estimate(evaluation.values[name], alpha)
                    for name in evaluation.index_names},
        chances={name: _estimate(np.asarray(evaluation.chances[name], dtype=np.float64), alpha)
                 for name in evaluation.chance_names},
        time=time_estimate,
        energy=Estimate(float(stats.energy.value), energy_low, energy_high),
    )


# --- the look ----------------------------------------------------------------------------------

_UNPAIRED = 2  # no paired comparison: the two intervals decide


def _order(first: tuple[set[bool], tuple[float, float]],
           second: tuple[set[bool], tuple[float, float]],
           paired: int | None = _UNPAIRED) -> int | None:
    """-1 when the first path ranks above the second whatever the open verdicts turn out to
    be, 1 when below, 0 when tied, None when it is not settled. ``paired`` is the paired
    comparison's order (-1, 1, 0 tied, None open) when there is one."""
    outcomes: set[int | None] = set()
    (groups_a, (a_low, a_high)), (groups_b, (b_low, b_high)) = first, second
    for passes_a in groups_a:
        for passes_b in groups_b:
            if passes_a != passes_b:
                outcomes.add(-1 if passes_a else 1)
            elif paired != _UNPAIRED:
                outcomes.add(paired)
            elif a_high < b_low:
                outcomes.add(-1)
            elif b_high < a_low:
                outcomes.add(1)
            else:
                outcomes.add(None)
    return outcomes.pop() if len(outcomes) == 1 else None


def settle(evaluator: Any, stats_by_path: Mapping[str, Any],
           pairs: Sequence[Any] = ()) -> dict[str, Settlement]:
    """Each ranked path's settlement from its statistics on confidence sequences and, in a
    paired campaign, the paired comparisons (:class:`~idefix_rules.campaign.pairwise.
    PairComparison`) that decide the first rank key."""
    from idefix_rules.campaign.pairwise import find
    from idefix_rules.rulebook.statistics import rank_key_intervals

    def paired_order(name: str, other: str) -> int | None:
        pair = find(pairs, name, other)
        if pair is None:
            return _UNPAIRED
        order = pair.order()
        return order if order is None or pair.first == name else -order

    facts = {}
    for name, stats in stats_by_path.items():
        verdict = evaluator.verdict(stats)
        groups = {bool(verdict.passed)} if verdict.decided else {True, False}
        keys = rank_key_intervals(evaluator.rulebook, evaluator.checked.constants, stats)
        first_key = keys[0] if keys else (math.nan, math.nan)
        facts[name] = (bool(verdict.decided), bool(verdict.passed), groups, first_key)
    settlements = {}
    for name, (decided, passed, groups, key) in facts.items():
        open_against = tuple(
            other for other, (_, _, other_groups, other_key) in facts.items()
            if other != name and _order((groups, key), (other_groups, other_key),
                                        paired_order(name, other)) is None)
        settlements[name] = Settlement(decided, passed, open_against)
    return settlements


def stop_reason(settlement: Settlement, runs: int, cap: int) -> str | None:
    """Why a path stops after ``runs`` runs, or None when it goes on."""
    if settlement.done:
        outcome = "pass" if settlement.passed else "fail"
        return (f"decided after {runs} runs: verdict {outcome} and rank settled against every "
                "other path")
    if runs < cap:
        return None
    missing = []
    if not settlement.verdict_decided:
        missing.append("verdict not decided")
    if settlement.unsettled_against:
        missing.append("rank against " + ", ".join(settlement.unsettled_against)
                       + " not settled")
    return f"cap of {cap} runs reached: " + "; ".join(missing)


# --- runs that would decide a rule -------------------------------------------------------------

def _rule_values(statistic: str, evaluation: Any) -> tuple[np.ndarray, str] | None:
    """The per-run values behind a verdict rule's statistic and their kind."""
    if statistic == "risk":
        return np.asarray(evaluation.i_max, dtype=np.float64), "bounded"
    if statistic == "time":
        return np.asarray(evaluation.time, dtype=np.float64), "time"
    if statistic == "energy":
        return np.asarray(evaluation.energy, dtype=np.float64), "unbounded"
    for prefix, source, kind in (("chance(", "chances", "bernoulli"),
                                 ("mean(", "values", "bounded")):
        if statistic.startswith(prefix) and statistic.endswith(")"):
            values = getattr(evaluation, source).get(statistic[len(prefix):-1])
            if values is not None:
                return np.asarray(values, dtype=np.float64), kind
    return None


def _smallest(decides: Callable[[int], bool], start: int, limit: int = MAX_RUNS) -> int | None:
    """The smallest run count (to about 1 %) at which ``decides`` holds, searched from
    ``start`` by doubling then bisection; None when even ``limit`` runs do not decide."""
    high = max(2, start)
    while not decides(high):
        if high >= limit:
            return None
        high = min(2 * high, limit)
    low = max(1, high // 2)
    while high - low > max(1, high // 100):
        middle = (low + high) // 2
        if decides(middle):
            high = middle
        else:
            low = middle
    return high


def runs_needed(rule: Any, evaluation: Any, confidence: float, sequential: bool,
                stop_time: float = 0.0) -> int | None:
    """Roughly how many runs would decide ``rule`` (a rule result that is not decided) if its
    statistic kept its present value and spread: the smallest count whose interval (confidence
    sequence when ``sequential``, else the fixed-count interval) no longer holds the threshold.
    None when no estimate can be given (a compound condition, or more than 1,000,000 runs)."""
    if rule.statistic is None or rule.threshold is None or evaluation is None:
        return None
    found = _rule_values(rule.statistic, evaluation)
    if found is None or found[0].size < 2:
        return None
    values, kind = found
    threshold = float(rule.threshold)
    if kind == "time":
        if stop_time <= 0:
            return None
        values, threshold, kind = values / stop_time, threshold / stop_time, "bounded"
    mean, spread = float(values.mean()), float(values.std(ddof=1))
    alpha = 1.0 - confidence
    gap = abs(mean - threshold)
    if gap == 0 or not math.isfinite(gap):
        return None
    if kind == "unbounded" or not sequential:
        return _smallest(lambda n: _fixed_decides(kind, mean, spread, threshold, n, confidence,
                                                  sequential), values.size)
    if not 0.0 <= threshold <= 1.0:
        return None

    def decides(n: int) -> bool:
        return threshold_rejected(_typical_runs(kind, mean, spread, n), threshold, alpha)

    return _smallest(decides, values.size)


def _typical_runs(kind: str, mean: float, spread: float, n: int) -> np.ndarray:
    """``n`` runs with the observed mean (and spread): ones spread evenly for a chance,
    alternating mean ± spread otherwise."""
    index = np.arange(n, dtype=np.float64)
    if kind == "bernoulli":
        return np.floor((index + 1) * mean) - np.floor(index * mean)
    signs = np.where(index % 2 == 0, 1.0, -1.0)
    return np.clip(mean + spread * signs, 0.0, 1.0)


def _fixed_decides(kind: str, mean: float, spread: float, threshold: float, n: int,
                   confidence: float, sequential: bool) -> bool:
    """Whether the fixed-count interval (Wilson for a chance, Student-t otherwise; the
    asymptotic sequence for an unbounded mean of an adaptive campaign) excludes the threshold."""
    from idefix_rules.rulebook.statistics import wilson_interval

    if kind == "bernoulli":
        estimate = wilson_interval(round(mean * n), n, confidence)
        return not estimate.low <= threshold <= estimate.high
    if sequential:
        half = asymptotic_half_width(n, spread * spread, 1.0 - confidence)
    else:
        from scipy import stats as scipy_stats

        half = float(scipy_stats.t.ppf(0.5 + confidence / 2, n - 1)) * spread / math.sqrt(n)
    return abs(mean - threshold) > half
