"""A path's statistics with the one-sided bounds its verdict is judged on.

The rulebook's own statistics (:func:`idefix_rules.rulebook.statistics.path_statistics`) carry
two-sided Student-t and Wilson intervals at the rulebook's confidence, a quick summary. A
campaign replaces every interval with two one-sided bounds at the levels of its
:class:`~idefix_rules.campaign.statistics.budget.AlphaBudget`, of the kind the data call for:

============================  =====================================  ==========================
statistic                     fixed run count                        adaptive (``runs: auto``)
============================  =====================================  ==========================
``chance(NAME)``, ``failed``  Clopper–Pearson                        mixture martingale
risk, ``mean(INDEX)``, time   betting bound, bets tuned for ``n``    betting confidence sequence
energy (no bound)             Student-t                              asymptotic sequence
============================  =====================================  ==========================

(:mod:`~idefix_rules.campaign.statistics.bernoulli`,
:mod:`~idefix_rules.campaign.statistics.sequential`). Time is a bounded mean on [0, stop time].
``failed`` is the share of failed runs among the runs, with bounds, never the bare fraction. None
of these bounds collapses when every run saturates.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from idefix_rules.campaign.statistics import bernoulli
from idefix_rules.campaign.statistics.budget import AlphaBudget
from idefix_rules.campaign.statistics.sequential import (
    asymptotic_half_width,
    first_rejection,
    one_sided_bound,
    plugin_bets,
)
from idefix_rules.rulebook.results import Estimate, PathStatistics, RunEvaluation
from idefix_rules.rulebook.statistics import sample_mean, sample_std

Levels = Callable[[str], tuple[float, float]]


def bounded_estimate(values: np.ndarray, alpha_low: float, alpha_high: float,
                     sequential: bool, scale: float = 1.0,
                     tuned: tuple[float, float] | None = None) -> Estimate:
    """Mean of ``values`` in [0, ``scale``] with a lower bound at ``alpha_low`` and an upper
    bound at ``alpha_high``; (nan, 0, scale) without values. ``tuned``: the levels (lower,
    upper) the bets are tuned for, by default the bounds' own."""
    x = np.asarray(values, dtype=np.float64).ravel()
    if x.size == 0:
        return Estimate(math.nan, 0.0, scale)
    unit = x / scale
    fixed = None if sequential else int(x.size)
    bet_low, bet_high = tuned if tuned is not None else (alpha_low, alpha_high)
    return Estimate(sample_mean(x),
                    one_sided_bound(unit, alpha_low, "lower", fixed, bet_low) * scale,
                    one_sided_bound(unit, alpha_high, "upper", fixed, bet_high) * scale)


def chance_estimate(events: np.ndarray, alpha_low: float, alpha_high: float,
                    sequential: bool) -> Estimate:
    """Share of runs with the event (0/1 in run order) with exact one-sided bounds."""
    x = np.asarray(events, dtype=np.float64).ravel()
    if x.size == 0:
        return Estimate(math.nan, 0.0, 1.0)
    low, high = bernoulli.bounds(x, alpha_low, alpha_high, sequential)
    return Estimate(float(x.mean()), low, high)


def unbounded_estimate(values: np.ndarray, alpha_low: float, alpha_high: float,
                       sequential: bool, tuned: tuple[float, float] | None = None) -> Estimate:
    """Mean without a known range: the asymptotic confidence sequence (adaptive) or
    Student-t (fixed count), each side at its α; (-inf, inf) with fewer than two values.
    ``tuned``: the levels (lower, upper) the sequence's boundary is tuned for, by default
    the bounds' own."""
    x = np.asarray(values, dtype=np.float64).ravel()
    mean = sample_mean(x)
    if x.size < 2:
        return Estimate(mean, -math.inf, math.inf)
    variance = sample_std(x, mean) ** 2

    def half(alpha: float, tuned_alpha: float) -> float:
        if sequential:  # the sequence's half width at 2α puts α on each side
            return asymptotic_half_width(x.size, variance, min(2.0 * alpha, 0.999),
                                         tuned_alpha=min(2.0 * tuned_alpha, 0.999))
        from scipy.special import stdtrit  # Student's t quantile (scipy.stats.t.ppf)

        return float(stdtrit(x.size - 1, 1.0 - alpha)) * math.sqrt(variance / x.size)

    tuned_low, tuned_high = tuned if tuned is not None else (alpha_low, alpha_high)
    return Estimate(mean, mean - half(alpha_low, tuned_low), mean + half(alpha_high, tuned_high))


def failure_sequence(complete_rows: np.ndarray, failed_rows: np.ndarray,
                     missing: int = 0) -> np.ndarray:
    """1 per failed run, 0 per complete one, in run order; ``missing`` runs (neither) count
    as failed, after the others.

    >>> failure_sequence(np.array([0, 1, 3]), np.array([2]), missing=1).tolist()
    [0.0, 0.0, 1.0, 0.0, 1.0]
    """
    rows = np.concatenate((np.asarray(complete_rows, dtype=np.int64),
                           np.asarray(failed_rows, dtype=np.int64)))
    flags = np.concatenate((np.zeros(len(complete_rows)), np.ones(len(failed_rows))))
    ordered = flags[np.argsort(rows, kind="stable")]
    return np.concatenate((ordered, np.ones(max(0, missing))))


def judged_statistics(evaluation: RunEvaluation, stats: PathStatistics, stop_time: float,
                      budget: AlphaBudget, sequential: bool,
                      failures: np.ndarray | None = None) -> PathStatistics:
    """``stats`` with every interval replaced by the bounds the verdict is judged on (see the
    module docstring): each statistic's lower and upper bound at ``budget.levels``.
    ``failures``: the runs' failure flags in run order (:func:`failure_sequence`); without
    them, ``stats``' counts with the failures last."""
    levels = budget.levels

    def bounded(values: np.ndarray, statistic: str, scale: float = 1.0) -> Estimate:
        return bounded_estimate(values, *levels(statistic), sequential, scale,
                                budget.tuned_levels(statistic))

    time = np.asarray(evaluation.time, dtype=np.float64)
    if stop_time > 0 and time.size and np.all((time >= 0) & (time <= stop_time)):
        time_estimate = bounded(time, "time", stop_time)
    else:
        time_estimate = unbounded_estimate(time, *levels("time"), sequential,
                                           budget.tuned_levels("time"))
    if failures is None:
        failures = np.concatenate((np.zeros(stats.runs), np.ones(stats.failed_runs)))
    return dataclasses.replace(
        stats,
        risk=bounded(evaluation.i_max, "risk"),
        index_mean={name: bounded(evaluation.values[name], f"mean({name})")
                    for name in evaluation.index_names},
        chances={name: chance_estimate(evaluation.chances[name], *levels(f"chance({name})"),
                                       sequential)
                 for name in evaluation.chance_names},
        time=time_estimate,
        energy=unbounded_estimate(evaluation.energy, *levels("energy"), sequential,
                                  budget.tuned_levels("energy")),
        failed=chance_estimate(failures, *levels("failed"), sequential),
    )


# --- tests of one value, for estimates of the runs a decision needs ---------------------------

def rejects(kind: str, values: np.ndarray, candidate: float, alpha: float, side: str,
            sequential: bool, tuned: float | None = None) -> bool:
    """Whether the ``side`` bound (``lower``/``upper``) at ``alpha`` of the mean of ``values``
    excludes ``candidate``: ``kind`` ``bernoulli`` (0/1), ``bounded`` (in [0, 1]) or
    ``unbounded``; ``tuned``: the level its bets (boundary) are tuned for, by default
    ``alpha``. One test, no bisection: cheap on long streams."""
    tuned = alpha if tuned is None else tuned
    x = np.asarray(values, dtype=np.float64).ravel()
    if x.size == 0:
        return False
    if kind == "bernoulli":
        if not sequential:
            count = round(float(x.sum()))
            bound = (bernoulli.fixed_lower(count, x.size, alpha) if side == "lower"
                     else bernoulli.fixed_upper(count, x.size, alpha))
            return bound > candidate if side == "lower" else bound < candidate
        return (bernoulli.sequential_lower_above(x, candidate, alpha) if side == "lower"
                else bernoulli.sequential_upper_below(x, candidate, alpha))
    if kind == "bounded":
        if not 0.0 <= candidate <= 1.0:  # outside the range: the side facing it excludes it
            return (candidate > 1.0) == (side == "upper")
        bets = plugin_bets(x, tuned, two_sided=False,
                           fixed_runs=None if sequential else int(x.size))
        return bool(first_rejection(x, bets, np.array([candidate]), alpha, side)[0] <= x.size)
    estimate = unbounded_estimate(x, alpha, alpha, sequential, (tuned, tuned))
    return estimate.low > candidate if side == "lower" else estimate.high < candidate
