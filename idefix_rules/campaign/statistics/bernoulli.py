"""Exact one-sided bounds for a proportion: chances, and the share of failed runs.

A chance (``chance(hit_L3)``, ``failed``) is the probability that a run has an event; each run
is a Bernoulli draw. Its bounds come from the binomial law itself, never from a normal
approximation, so they stay honest with zero events and when every run has one:

* **Fixed run count**: the Clopper–Pearson bounds. With ``S`` events in ``n`` runs the upper
  bound at level α is the ``p`` with ``P(Bin(n, p) ≤ S) = α`` (1 when ``S = n``), the lower
  bound the ``p`` with ``P(Bin(n, p) ≥ S) = α`` (0 when ``S = 0``). Zero events in 299 runs
  put the upper bound at 0.997 % (``0.99²⁹⁹ ≤ 0.05``).
* **Adaptive campaigns**: a likelihood-ratio mixture martingale, valid at every run count at
  once. To reject ``p ≥ p₀`` (and so bound ``p`` from above) the runs are scored by
  ``M(p₀) = ∫ Π f_q(xᵢ) / f_{p₀}(xᵢ) dπ(q)`` over alternatives ``q = u·p₀ < p₀``, ``u`` drawn
  from ``(1 − p₀)·Beta(a, 1) + p₀·Beta(1, 1)`` with ``a = LEAN_SHAPE``: the mixture leans
  towards ``q = 0`` (no events at all) as far as ``p₀`` is small, which is where zero events
  are the common case. Every term is a non-negative supermartingale under any ``p ≥ p₀``, so
  by Ville's inequality ``M(p₀)`` ever reaches ``1/α`` with probability ≤ α. The lower bound is
  the same on the runs without the event (``1 − p``). The bounds are the running intersection
  over every run count (they only tighten).

Both directions are separate one-sided bounds, each at its own α: a rule is judged in one
direction at a time (:mod:`idefix_rules.campaign.statistics.budget`).

>>> round(fixed_upper(0, 299, 0.05), 5), fixed_lower(0, 299, 0.05)
(0.00997, 0.0)
>>> import numpy as np
>>> runs_to_pass(0.01, 0.05)
316
"""

from __future__ import annotations

import math

import numpy as np

LEAN_SHAPE = 0.1  # a of the Beta(a, 1) part of the alternatives: mass near no events at all
BISECTION_STEPS = 48
# Run counts the running intersection looks at, at most: any subset of run counts gives a valid
# bound (it only leaves out some of the intersection), so long streams keep a spread of them.
INTERSECTION_COUNTS = 256


def fixed_upper(events: int, runs: int, alpha: float) -> float:
    """Clopper–Pearson upper bound at level ``alpha`` (one-sided); 1 without runs."""
    if runs <= 0 or events >= runs:
        return 1.0
    return _beta_quantile(1.0 - alpha, events + 1, runs - events)


def fixed_lower(events: int, runs: int, alpha: float) -> float:
    """Clopper–Pearson lower bound at level ``alpha`` (one-sided); 0 without runs."""
    if runs <= 0 or events <= 0:
        return 0.0
    return _beta_quantile(alpha, events, runs - events + 1)


def _beta_quantile(level: float, a: float, b: float) -> float:
    """The Beta(a, b) quantile: scipy.stats.beta.ppf's value (both wrap Boost's ibeta_inv),
    through scipy.special, a third of the second that importing scipy.stats takes."""
    from scipy.special import betaincinv

    return float(betaincinv(a, b, level))


def log_evidence_below(events: np.ndarray | float, runs: np.ndarray | float,
                       limit: np.ndarray | float) -> np.ndarray:
    """log M(p₀): the evidence after ``runs`` runs with ``events`` events that the proportion
    lies below ``limit`` = p₀ (the null ``p ≥ p₀`` is rejected at level α once this reaches
    ``log(1/α)``). Vectorised over its arguments."""
    from scipy import special

    s = np.asarray(events, dtype=np.float64)
    n = np.asarray(runs, dtype=np.float64)
    p0 = np.asarray(limit, dtype=np.float64)
    s, n, p0 = np.broadcast_arrays(s, n, p0)
    out = np.zeros(s.shape)
    inner = (p0 > 0.0) & (p0 < 1.0)
    # p₀ = 1: any run without the event rejects p ≥ 1; p₀ = 0: p ≥ 0 is never rejected
    out[(p0 >= 1.0) & (n > s)] = np.inf
    out[p0 <= 0.0] = -np.inf
    if not inner.any():
        return out
    s, n, p0 = s[inner], n[inner], p0[inner]
    lean = 1.0 - p0
    parts = []
    for shape, weight in ((LEAN_SHAPE, lean), (1.0, 1.0 - lean)):
        with np.errstate(divide="ignore"):
            log_weight = np.log(weight)
        # ∫₀¹ a u^(a−1) (u p₀)^S (1 − u p₀)^(n−S) du / (p₀^S (1 − p₀)^(n−S)), through the
        # incomplete beta function of q = u p₀
        parts.append(log_weight + math.log(shape) - (shape + s) * np.log(p0)
                     + special.betaln(shape + s, n - s + 1.0)
                     + np.log(special.betainc(shape + s, n - s + 1.0, p0))
                     - (n - s) * np.log1p(-p0))
    out[inner] = np.logaddexp(parts[0], parts[1])
    return out


def log_evidence_above(events: np.ndarray | float, runs: np.ndarray | float,
                       limit: np.ndarray | float) -> np.ndarray:
    """log of the evidence that the proportion lies above ``limit`` (the mirror image)."""
    n = np.asarray(runs, dtype=np.float64)
    return log_evidence_below(n - np.asarray(events, dtype=np.float64), n,
                              1.0 - np.asarray(limit, dtype=np.float64))


# (events, runs, alpha) -> _bisect's boundary: an adaptive campaign asks again at every look for
# the boundaries before each event it asked for at the look before, and its chances with no
# event share one (0, n, alpha). Cleared when full; a value is the same computed or looked up.
_BOUNDARIES: dict[tuple[float, float, float], float] = {}
_BOUNDARIES_KEPT = 1 << 16


def _boundary(events: np.ndarray, runs: np.ndarray, alpha: float) -> np.ndarray:
    """Per (events, runs): the smallest p₀ above the observed share whose null ``p ≥ p₀`` is
    rejected (the upper bound after those runs), by bisection; each pair bisected once."""
    keys = [(float(s), float(n), float(alpha)) for s, n in zip(events, runs, strict=True)]
    known = {key: _BOUNDARIES[key] for key in keys if key in _BOUNDARIES}
    missing = sorted(set(keys) - known.keys())
    if missing:
        found = dict(zip(missing, _bisect(np.array([key[0] for key in missing]),
                                          np.array([key[1] for key in missing]),
                                          alpha).tolist(), strict=True))
        known.update(found)
        if len(_BOUNDARIES) + len(found) > _BOUNDARIES_KEPT:
            _BOUNDARIES.clear()
        _BOUNDARIES.update(found)
    return np.array([known[key] for key in keys], dtype=np.float64)


def _bisect(events: np.ndarray, runs: np.ndarray, alpha: float) -> np.ndarray:
    """:func:`_boundary`'s values, computed."""
    target = math.log(1.0 / alpha)
    low = events / np.maximum(runs, 1.0)
    high = np.ones_like(low)
    for _ in range(BISECTION_STEPS):
        middle = 0.5 * (low + high)
        rejected = log_evidence_below(events, runs, middle) >= target
        high = np.where(rejected, middle, high)
        low = np.where(rejected, low, middle)
    return np.asarray(high)


def _intersection_points(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(events, runs) at the run counts the running intersection of the 0/1 stream ``x``
    (run order, not empty) looks at."""
    count = np.cumsum(x)
    runs = np.arange(1, x.size + 1, dtype=np.float64)
    # The bound falls with every run without the event and rises with each event: its
    # smallest values are just before an event and at the end.
    at = np.flatnonzero(np.concatenate((x[1:] > 0.5, [True])))
    if at.size > INTERSECTION_COUNTS:
        wanted = np.geomspace(1.0, float(x.size), INTERSECTION_COUNTS)
        picked = np.searchsorted(at + 1, wanted)
        at = np.unique(np.concatenate((at[np.minimum(picked, at.size - 1)], at[-1:])))
    return count[at], runs[at]


def anytime_bounds(events: int, runs: int, alpha: float) -> tuple[float, float]:
    """One-sided lower and upper bounds, at ``alpha`` each, of a proportion after ``events``
    in ``runs``: the mixture martingale's at that run count alone, valid however the count was
    reached (a fixed count, or a stop chosen from the data). (0, 1) without runs.

    >>> low, high = anytime_bounds(0, 128, 0.05)
    >>> low, round(high, 4)
    (0.0, 0.0245)
    """
    if runs <= 0:
        return 0.0, 1.0
    high = float(_boundary(np.array([float(events)]), np.array([float(runs)]), alpha)[0])
    low = 1.0 - float(_boundary(np.array([float(runs - events)]), np.array([float(runs)]),
                                alpha)[0])
    return max(0.0, low), min(1.0, high)


def sequential_upper(events: np.ndarray, alpha: float) -> float:
    """Anytime-valid upper bound of the proportion after the 0/1 ``events`` (run order):
    the running intersection over every run count. 1 without runs."""
    x = np.asarray(events, dtype=np.float64).ravel()
    if x.size == 0:
        return 1.0
    return float(np.min(_boundary(*_intersection_points(x), alpha)))


def sequential_upper_below(events: np.ndarray, limit: float, alpha: float) -> bool:
    """Whether :func:`sequential_upper` lies below ``limit`` (to its bisection's 2⁻⁴⁸), tested
    at ``limit`` directly: the evidence grows with p₀ above the observed share, so the
    bound is below ``limit`` where the evidence at ``limit`` reaches ``log(1/α)`` after one
    of the run counts the intersection looks at. One evaluation instead of a bisection."""
    x = np.asarray(events, dtype=np.float64).ravel()
    if x.size == 0 or limit > 1.0:
        return limit > 1.0  # the bound is at most 1
    count, runs = _intersection_points(x)
    with np.errstate(divide="ignore", invalid="ignore"):
        evidence = log_evidence_below(count, runs, limit)
    return bool(np.any(evidence >= math.log(1.0 / alpha)))


def sequential_lower_above(events: np.ndarray, limit: float, alpha: float) -> bool:
    """Whether :func:`sequential_lower` lies above ``limit`` (the mirror image)."""
    if limit < 0.0:  # the bound is at least 0 (and 1 − limit may round to 1)
        return True
    x = np.asarray(events, dtype=np.float64).ravel()
    return sequential_upper_below(1.0 - x, 1.0 - limit, alpha)


def sequential_lower(events: np.ndarray, alpha: float) -> float:
    """Anytime-valid lower bound (the upper bound of the runs without the event, mirrored)."""
    x = np.asarray(events, dtype=np.float64).ravel()
    return 1.0 - sequential_upper(1.0 - x, alpha)


def bounds(events: np.ndarray, alpha_low: float, alpha_high: float,
           sequential: bool) -> tuple[float, float]:
    """(lower bound at ``alpha_low``, upper bound at ``alpha_high``) of the proportion of the
    0/1 ``events``: anytime-valid when ``sequential``, else Clopper–Pearson."""
    x = np.asarray(events, dtype=np.float64).ravel()
    if sequential:
        return sequential_lower(x, alpha_low), sequential_upper(x, alpha_high)
    count, runs = round(float(x.sum())), int(x.size)
    return fixed_lower(count, runs, alpha_low), fixed_upper(count, runs, alpha_high)


def runs_to_pass(limit: float, alpha: float, sequential: bool = True) -> int:
    """Runs without an event after which the upper bound is below ``limit``: how soon a rule
    ``chance(x) <= limit`` can pass at best."""
    if sequential:
        target = math.log(1.0 / alpha)
        runs = 1
        while log_evidence_below(0.0, float(runs), limit) < target:
            runs *= 2
        low = runs // 2
        while runs - low > 1:
            middle = (low + runs) // 2
            if log_evidence_below(0.0, float(middle), limit) >= target:
                runs = middle
            else:
                low = middle
        return runs
    return math.floor(math.log(alpha) / math.log1p(-limit)) + 1
