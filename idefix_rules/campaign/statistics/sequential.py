"""Anytime-valid confidence sequences: intervals that may be looked at after every batch of runs.

A fixed-count interval (Student-t, Wilson) covers the mean with probability ``confidence`` at
one number of runs chosen in advance. Checked again after every batch and used to stop, it
misses far more often (``tests/campaign/test_campaign_sequential.py`` shows it). A *confidence
sequence* covers the mean at every number of runs at once: P(some look misses) ≤ α.

* Means of values in [0, 1] (run risk, index values, chances, time / stop time): the hedged
  capital confidence sequence of Waudby-Smith & Ramdas, "Estimating means of bounded random
  variables by betting" (JRSS B, 2024), with their predictable plug-in bets. For a candidate
  mean ``m`` two bettors stake on the runs in order, ``K⁺ₜ(m) = ∏(1 + λ⁺ᵢ(m)(xᵢ − m))`` and
  ``K⁻ₜ(m) = ∏(1 − λ⁻ᵢ(m)(xᵢ − m))``; under mean ``m`` both are non-negative martingales, so by
  Ville's inequality ``max(½K⁺, ½K⁻)`` ever reaches ``1/α`` with probability ≤ α. The interval
  after ``n`` runs is every ``m`` not rejected at any ``t ≤ n`` (the running intersection, so
  intervals only shrink). Bets: ``λₜ = √(2 log(2/α) / (σ̂²ₜ₋₁ · t · log(1 + t)))`` truncated to
  ``c/m`` and ``c/(1 − m)`` with ``c = 3/4``.
* Means without bounds (energy): the asymptotic confidence sequence of Waudby-Smith, Arnold,
  Wu, Howard & Ramdas, "Time-uniform central limit theory and asymptotic confidence sequences"
  (Ann. Statist., 2024) — valid as the run count grows, documented as asymptotic.

The runs enter in run-index order, so the interval is a function of the stored runs only, never
of the order in which workers finished them.

>>> import numpy as np
>>> low, high = betting_interval(np.zeros(400), alpha=0.05)
>>> low, round(high, 4)
(0.0, 0.0122)
"""

from __future__ import annotations

import math

import numpy as np

BET_TRUNCATION = 0.75  # c: the largest fraction of capital one run may stake
GRID_POINTS = 129  # coarse candidate means before the bounds are refined by bisection
BISECTION_STEPS = 30  # bounds to 2⁻³⁰ of a grid cell
ZOOMS = 4  # finer grids tried when the interval is narrower than a cell
BLOCK_RUNS = 8192  # runs processed at once (memory stays flat in the run count)


def plugin_bets(values: np.ndarray, alpha: float, two_sided: bool = True,
                fixed_runs: int | None = None) -> np.ndarray:
    """Predictable bets λₜ (t = 1 … n): each uses only the runs before it. ``two_sided``: both
    bettors share α (log(2/α)), else one bettor has it all (log(1/α)). ``fixed_runs``: bets
    tuned for an interval after that many runs only (a fixed-count campaign), still valid at
    every run count."""
    n = values.shape[-1]
    t = np.arange(1, n + 1, dtype=np.float64)
    # mean and variance estimates after t runs (t = 0 … n-1 used for run t+1), along the last
    # axis (one stream per row when given several)
    running_mean = (0.5 + np.cumsum(values, axis=-1)) / (t + 1.0)
    squares = np.cumsum((values - running_mean) ** 2, axis=-1)
    variance = (0.25 + squares) / (t + 1.0)
    previous_variance = np.concatenate((np.full((*values.shape[:-1], 1), 0.25),
                                        variance[..., :-1]), axis=-1)
    level = math.log((2.0 if two_sided else 1.0) / alpha)
    horizon = t * np.log1p(t) if fixed_runs is None else float(max(fixed_runs, 1))
    return np.sqrt(2.0 * level / (previous_variance * horizon))


def rejected(values: np.ndarray, bets: np.ndarray, candidates: np.ndarray,
             alpha: float) -> np.ndarray:
    """Whether each candidate mean is outside the confidence sequence after all ``values``
    (rejected at some run count ≤ n)."""
    return first_rejection(values, bets, candidates, alpha) <= values.size


def first_rejection(values: np.ndarray, bets: np.ndarray, candidates: np.ndarray,
                    alpha: float, side: str = "both") -> np.ndarray:
    """The number of runs after which each candidate mean is first rejected (``values.size``
    + 1 when never): the running intersection after ``t`` runs holds the candidates with a
    first rejection above ``t``. ``side``: ``both`` (the hedged pair of bettors, α shared),
    ``lower`` (only the bettor on runs above the candidate: rejects candidates below the mean,
    a lower bound at α) or ``upper`` (the mirror)."""
    threshold = math.log(1.0 / alpha)
    hedge = math.log(0.5) if side == "both" else 0.0
    candidates = np.asarray(candidates, dtype=np.float64)
    with np.errstate(divide="ignore"):
        up_cap = np.where(candidates > 0, BET_TRUNCATION / candidates, np.inf)
        down_cap = np.where(candidates < 1, BET_TRUNCATION / (1.0 - candidates), np.inf)
    log_up = np.zeros(candidates.shape)
    log_down = np.zeros(candidates.shape)
    first = np.full(candidates.shape, values.size + 1, dtype=np.int64)
    for start in range(0, values.size, BLOCK_RUNS):
        x = values[start:start + BLOCK_RUNS, None]
        bet = bets[start:start + BLOCK_RUNS, None]
        up = log_up + (np.cumsum(np.log1p(np.minimum(bet, up_cap) * (x - candidates)), axis=0)
                       if side != "upper" else 0.0)
        down = log_down + (np.cumsum(np.log1p(-np.minimum(bet, down_cap) * (x - candidates)),
                                     axis=0) if side != "lower" else 0.0)
        capital = up if side == "lower" else down if side == "upper" else np.maximum(up, down)
        hit = np.broadcast_to(capital, (x.shape[0], candidates.size)) + hedge >= threshold
        found = hit.any(axis=0) & (first > values.size)
        first[found] = start + 1 + np.argmax(hit[:, found], axis=0)
        log_up = np.broadcast_to(up, (x.shape[0], candidates.size))[-1]
        log_down = np.broadcast_to(down, (x.shape[0], candidates.size))[-1]
    return first


def rejections(values: np.ndarray, candidate: float, alpha: float, side: str,
               fixed_runs: int | None = None, bet_alpha: float | None = None) -> np.ndarray:
    """For many streams at once (one per row, runs along the last axis): after each run count,
    whether the ``side`` bettor (``lower``/``upper``, as in :func:`first_rejection`) has
    rejected ``candidate`` at level ``alpha`` by then (bets tuned for ``bet_alpha``, by
    default ``alpha``: see :func:`one_sided_bound`). The simulations of
    :mod:`idefix_rules.campaign.statistics.error_rates` read it.

    >>> rows = np.vstack([np.ones(64), np.zeros(64)])
    >>> rejections(rows, 0.5, 0.05, "lower")[:, -1].tolist()
    [True, False]
    """
    capital = running_log_capital(values, candidate, side,
                                  alpha if bet_alpha is None else bet_alpha, fixed_runs)
    return np.asarray(capital >= math.log(1.0 / alpha))


def running_log_capital(values: np.ndarray, candidate: float, side: str, bet_alpha: float,
                        fixed_runs: int | None = None) -> np.ndarray:
    """For many streams at once (one per row): the running maximum of the ``side`` bettor's
    log capital against ``candidate`` after each run count, bets tuned for ``bet_alpha``. It
    rejects ``candidate`` at any level β once it reaches ``log(1/β)``."""
    x = np.clip(np.asarray(values, dtype=np.float64), 0.0, 1.0)
    bets = plugin_bets(x, bet_alpha, two_sided=False, fixed_runs=fixed_runs)
    capital = np.cumsum(_log_steps(x, bets, candidate, side), axis=-1)
    return np.asarray(np.maximum.accumulate(capital, axis=-1))


def one_sided_bound(values: np.ndarray, alpha: float, side: str,
                    fixed_runs: int | None = None, bet_alpha: float | None = None) -> float:
    """A one-sided bound at level ``alpha`` for the mean of ``values`` (in [0, 1], run order):
    ``lower`` or ``upper``; the running intersection over every run count, with bets tuned
    for ``fixed_runs`` when given. 0 (lower) or 1 (upper) without values.

    ``bet_alpha``: the level the bets are tuned for (by default ``alpha``). Ville's inequality
    holds for any predictable bets, so the bound is valid at ``alpha`` whatever they are
    tuned for; with the bets fixed, the bounds at two levels are nested (the capital is the
    same, only the threshold ``log(1/alpha)`` moves), which a campaign that raises its levels
    as chains are shown to fail relies on (:mod:`idefix_rules.campaign.statistics.budget`).

    Each bettor's capital falls as the candidate moves towards the far side of the mean, so
    the rejected candidates form one interval from the near end ([0, L) for ``lower``) and
    bisection finds its edge.

    >>> round(one_sided_bound(np.ones(128), 0.05, "lower", fixed_runs=128), 3)
    0.969
    """
    x = np.clip(np.asarray(values, dtype=np.float64).ravel(), 0.0, 1.0)
    if x.size == 0:
        return 0.0 if side == "lower" else 1.0
    bets = plugin_bets(x, alpha if bet_alpha is None else bet_alpha, two_sided=False,
                       fixed_runs=fixed_runs)
    inside, outside = (1.0, 0.0) if side == "lower" else (0.0, 1.0)
    if not candidate_rejected(x, bets, outside, alpha, side):
        return outside  # not even the far end is rejected
    for _ in range(BISECTION_STEPS + 10):
        middle = 0.5 * (inside + outside)
        if candidate_rejected(x, bets, middle, alpha, side):
            outside = middle
        else:
            inside = middle
    return float(outside)


def candidate_rejected(values: np.ndarray, bets: np.ndarray, candidate: float, alpha: float,
                       side: str) -> bool:
    """Whether the ``side`` bettor (``lower`` or ``upper``) rejects one candidate mean by the
    last of ``values``: ``first_rejection(…)[0] <= values.size``, with the same arithmetic
    but without the bookkeeping of many candidates, which a bisection asks for forty times
    (a tenth of the time on a thousand runs)."""
    if values.size > BLOCK_RUNS:  # capital summed a block at a time: that sum's rounding
        return bool(first_rejection(values, bets, np.array([candidate]), alpha, side)[0]
                    <= values.size)
    steps = _log_steps(values, bets, candidate, side)
    return bool(np.any(np.cumsum(steps) >= math.log(1.0 / alpha)))


def _log_steps(x: np.ndarray, bets: np.ndarray, candidate: float, side: str) -> np.ndarray:
    """The ``side`` bettor's log-capital steps against one candidate mean (bets truncated so
    that the capital stays positive)."""
    if side == "lower":
        cap = BET_TRUNCATION / candidate if candidate > 0 else math.inf
        return np.asarray(np.log1p(np.minimum(bets, cap) * (x - candidate)))
    cap = BET_TRUNCATION / (1.0 - candidate) if candidate < 1 else math.inf
    return np.asarray(np.log1p(-np.minimum(bets, cap) * (x - candidate)))


def _last_survivors(x: np.ndarray, bets: np.ndarray, alpha: float) -> tuple[float, float]:
    """Where the running intersection was when it became empty (a miss, probability ≤ α):
    the candidates rejected last, found on ever finer grids around them. Returned for every
    later run count, so the intervals stay nested even after a miss."""
    span = (0.0, 1.0)
    last = np.array([0.0])
    for _ in range(ZOOMS + 1):
        grid = np.linspace(span[0], span[1], GRID_POINTS)
        first = first_rejection(x, bets, grid, alpha)
        chosen = np.flatnonzero(first == first.max())
        last = grid[chosen]
        low = grid[max(int(chosen[0]) - 1, 0)]
        high = grid[min(int(chosen[-1]) + 1, GRID_POINTS - 1)]
        span = (float(low), float(high))
    return float(last[0]), float(last[-1])


def betting_interval(values: np.ndarray, alpha: float) -> tuple[float, float]:
    """The confidence sequence's interval for the mean of ``values`` (in [0, 1], run order)
    after all of them; (0, 1) without values. Bounds are rounded outwards."""
    x = np.clip(np.asarray(values, dtype=np.float64).ravel(), 0.0, 1.0)
    if x.size == 0:
        return 0.0, 1.0
    bets = plugin_bets(x, alpha)
    span = (0.0, 1.0)
    for _ in range(ZOOMS):
        grid = np.linspace(span[0], span[1], GRID_POINTS)
        inside = np.flatnonzero(~rejected(x, bets, grid, alpha))
        if inside.size:
            break
        # Narrower than a grid cell (or empty, a miss of probability ≤ α): look again inside
        # the cell around the mean, which holds every value not rejected.
        centre = int(np.clip(np.searchsorted(grid, x.mean()), 1, GRID_POINTS - 1))
        span = (float(grid[centre - 1]), float(grid[centre]))
    else:
        # Nothing accepted even on the finest grid: the running intersection is empty (the
        # sequence missed the mean) unless it is narrower still; either way the interval is
        # where it was last, which keeps the intervals nested.
        return _last_survivors(x, bets, alpha)
    first, last = int(inside[0]), int(inside[-1])
    # The set of candidates not rejected is an interval (the hedged capital is quasiconvex in
    # m): refine each end between a rejected and an accepted grid point.
    low_out, low_in = (grid[first - 1], grid[first]) if grid[first] > 0 else (None, 0.0)
    high_in, high_out = (grid[last], grid[last + 1]) if grid[last] < 1 else (1.0, None)
    for _ in range(BISECTION_STEPS if low_out is not None or high_out is not None else 0):
        probes = []
        if low_out is not None:
            probes.append(0.5 * (low_out + low_in))
        if high_out is not None:
            probes.append(0.5 * (high_in + high_out))
        result = list(rejected(x, bets, np.array(probes), alpha))
        if low_out is not None:
            middle, out = probes.pop(0), result.pop(0)
            low_out, low_in = (middle, low_in) if out else (low_out, middle)
        if high_out is not None:
            middle, out = probes.pop(0), result.pop(0)
            high_in, high_out = (high_in, middle) if out else (middle, high_out)
    low = 0.0 if low_out is None else float(low_out)
    high = 1.0 if high_out is None else float(high_out)
    return low, high


def threshold_rejected(values: np.ndarray, threshold: float, alpha: float) -> bool:
    """Whether ``threshold`` (in [0, 1]) is outside the confidence sequence after ``values``:
    the sequential test behind "decided"."""
    x = np.clip(np.asarray(values, dtype=np.float64).ravel(), 0.0, 1.0)
    if x.size == 0:
        return False
    return bool(rejected(x, plugin_bets(x, alpha), np.array([threshold]), alpha)[0])


def asymptotic_half_width(n: int, variance: float, alpha: float,
                          planned_runs: int = 500, tuned_alpha: float | None = None) -> float:
    """Half width of the asymptotic confidence sequence after ``n`` runs of this variance
    (each side at α/2; tightest near ``planned_runs``). ``tuned_alpha``: the level the
    boundary's mixture is tuned for (by default ``alpha``); with it fixed, the half widths
    at two levels are nested."""
    side = alpha / 2.0
    tuned = (alpha if tuned_alpha is None else tuned_alpha) / 2.0
    rho2 = (-2.0 * math.log(tuned) + math.log(-2.0 * math.log(tuned) + 1.0)) / planned_runs
    spread = n * variance * rho2 + 1.0
    return math.sqrt(2.0 * spread / (n * n * rho2) * math.log(math.sqrt(spread) / side))


def asymptotic_interval(values: np.ndarray, alpha: float,
                        planned_runs: int = 500) -> tuple[float, float]:
    """Asymptotic confidence sequence (Gaussian mixture boundary) for an unbounded mean;
    (-inf, inf) with fewer than two values."""
    x = np.asarray(values, dtype=np.float64).ravel()
    if x.size < 2:
        return -math.inf, math.inf
    half = asymptotic_half_width(x.size, float(x.var(ddof=1)), alpha, planned_runs)
    mean = float(x.mean())
    return mean - half, mean + half
