"""Roughly how many runs would settle what is still open: a verdict rule whose limit lies
inside its bounds, or a paired comparison neither ordered nor tied.

The estimate keeps the statistic's present value and spread and finds the smallest run count
whose bounds (of the kind and at the levels the campaign judges with,
:mod:`idefix_rules.campaign.statistics.bounds`) would settle it: a rule passes, fails or lies
within its margin of the limit; a pair is ordered or tied. The count is found to about 1 % (zero
events
pass a 1 % limit after 316 runs exactly):

>>> import numpy as np
>>> from types import SimpleNamespace
>>> rule = SimpleNamespace(statistic="chance(stuck)", threshold=0.01, margin=0.0)
>>> runs = SimpleNamespace(chances={"stuck": np.zeros(200, dtype=bool)}, values={})
>>> runs_needed(rule, runs, (0.05, 0.05), sequential=True)
318
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from idefix_rules.campaign.statistics.bounds import rejects
from idefix_rules.limits import MAX_RUNS


def _rule_values(statistic: str, evaluation: Any, failures: np.ndarray | None
                 ) -> tuple[np.ndarray, str] | None:
    """The per-run values behind a verdict rule's statistic and their kind."""
    if statistic == "risk":
        return np.asarray(evaluation.i_max, dtype=np.float64), "bounded"
    if statistic == "time":
        return np.asarray(evaluation.time, dtype=np.float64), "time"
    if statistic == "energy":
        return np.asarray(evaluation.energy, dtype=np.float64), "unbounded"
    if statistic == "failed":
        return (None if failures is None else
                (np.asarray(failures, dtype=np.float64), "bernoulli"))
    for prefix, source, kind in (("chance(", "chances", "bernoulli"),
                                 ("mean(", "values", "bounded")):
        if statistic.startswith(prefix) and statistic.endswith(")"):
            values = getattr(evaluation, source).get(statistic[len(prefix):-1])
            if values is not None:
                return np.asarray(values, dtype=np.float64), kind
    return None


def smallest(decides: Callable[[int], bool], start: int, limit: int = MAX_RUNS) -> int | None:
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


def typical_runs(kind: str, mean: float, spread: float, n: int) -> np.ndarray:
    """``n`` runs with the observed mean (and spread): events spread evenly for a chance,
    alternating mean ± spread otherwise (clipped to [0, 1] when bounded)."""
    index = np.arange(n, dtype=np.float64)
    if kind == "bernoulli":
        return np.floor((index + 1) * mean) - np.floor(index * mean)
    signs = np.where(index % 2 == 0, 1.0, -1.0)
    runs = mean + spread * signs
    return np.clip(runs, 0.0, 1.0) if kind == "bounded" else runs


def settles(kind: str, runs: np.ndarray, limit: float, margin: float,
            levels: tuple[float, float], sequential: bool,
            tuned: tuple[float, float] | None = None) -> bool:
    """Whether bounds on ``runs`` (lower at ``levels[0]``, upper at ``levels[1]``; bets tuned
    for ``tuned``, by default those levels) exclude ``limit``, or lie within ``margin`` of
    it."""
    alpha_low, alpha_high = levels
    tuned_low, tuned_high = tuned if tuned is not None else levels
    if rejects(kind, runs, limit, alpha_high, "upper", sequential, tuned_high) \
            or rejects(kind, runs, limit, alpha_low, "lower", sequential, tuned_low):
        return True
    return margin > 0 \
        and rejects(kind, runs, limit - margin, alpha_low, "lower", sequential, tuned_low) \
        and rejects(kind, runs, limit + margin, alpha_high, "upper", sequential, tuned_high)


def runs_needed(rule: Any, evaluation: Any, levels: tuple[float, float], sequential: bool,
                stop_time: float = 0.0, failures: np.ndarray | None = None,
                tuned: tuple[float, float] | None = None) -> int | None:
    """Roughly how many runs would settle ``rule`` (a rule result that is not decided) if its
    statistic kept its present value and spread; ``levels`` the α of its lower and upper
    bound (``tuned``: the levels their bets are tuned for, by default the same). None when
    no estimate can be given (a compound condition, a statistic sitting on its limit without
    a margin, or more than 1,000,000 runs)."""
    if rule.statistic is None or rule.threshold is None or evaluation is None:
        return None
    found = _rule_values(rule.statistic, evaluation, failures)
    if found is None or found[0].size < 2:
        return None
    values, kind = found
    threshold = float(rule.threshold)
    margin = float(getattr(rule, "margin", 0.0) or 0.0)
    if kind == "time":
        if stop_time <= 0:
            return None
        values, threshold, margin = values / stop_time, threshold / stop_time, margin / stop_time
        kind = "bounded"
    mean, spread = float(values.mean()), float(values.std(ddof=1))
    gap = abs(mean - threshold)
    if not math.isfinite(gap) or (gap == 0 and margin == 0):
        return None
    return smallest(lambda n: settles(kind, typical_runs(kind, mean, spread, n), threshold,
                                      margin, levels, sequential, tuned), values.size)


def pair_runs_needed(differences: np.ndarray, alpha: float, margin: float,
                     sequential: bool, tuned: float | None = None) -> int | None:
    """Roughly how many paired runs would order or tie two paths whose per-world risk
    differences are ``differences`` (in [−1, 1]), at their present mean and spread; each side
    of the interval at ``alpha`` (bets tuned for ``tuned``, by default ``alpha``)."""
    d = np.asarray(differences, dtype=np.float64)
    if d.size < 2:
        return None
    mean, spread = float(d.mean()), float(d.std(ddof=1))
    if mean == 0 and margin == 0:
        return None

    def decides(n: int) -> bool:
        runs = (typical_runs("unbounded", mean, spread, n).clip(-1.0, 1.0) + 1.0) / 2.0
        return settles("bounded", runs, 0.5, margin / 2.0, (alpha, alpha), sequential,
                       None if tuned is None else (tuned, tuned))

    return smallest(decides, d.size)
