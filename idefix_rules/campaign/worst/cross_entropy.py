"""The cross-entropy method: a search for the worlds of highest run risk, in quantile space.

A Gaussian with independent coordinates (``mean``, ``spread``) over the standard-normal
quantile coordinates (:mod:`.space`) proposes each generation; the best of the generation (the
*elites*) pull it towards themselves, smoothed, and the next generation is drawn from it
(:meth:`CrossEntropy.update` says how). The first generation is a Latin hypercube of the
campaign's own distributions (``z`` standard normal): an unbiased sample, which also gives the
sensitivity axes of the failure boundary (:mod:`.boundary`).

The elites are the worlds of highest run risk. Risks within :data:`RISK_RESOLUTION` of each
other count as equal there and the world closer to the nominal one comes first: I_max is
capped at 1, so every critical world scores the same, and among about equally risky worlds the
more likely one is the more useful answer (parameters that do not matter are pulled back to
their nominal values instead of wandering). Runs that failed (no risk) come last. The worst
world reported is the exact highest risk, ties to the nearest world (``resolution=0``).

Reproducible: every draw comes from the generator given (seeded from the campaign seed and the
path), and the update reads only the risks, which do not depend on how many workers simulated
them or in which order.

>>> rng = np.random.default_rng(1)
>>> search = CrossEntropy(2, bound=3.7, origin=np.zeros(2), rng=rng)
>>> for _ in range(12):
...     z = search.propose(16)
...     search.update(z, -np.sum(np.square(z - [1.0, -2.0]), axis=1))
>>> [round(float(v), 1) for v in search.best_point]
[1.0, -2.0]
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats
from scipy.stats import qmc

from idefix_rules.campaign.worst.space import distance

ELITE_SHARE = 0.25  # of a generation
SMOOTHING = 0.7  # weight of the elites in the update of the mean and spread
MIN_SPREAD = 0.05  # in z: keeps a generation from collapsing onto one world
MAX_SPREAD = 2.0  # in z: twice the campaign's own spread
RISK_RESOLUTION = 1e-3  # risks closer than this count as equal (0.1 percentage point)


def ranking(scores: np.ndarray, points: np.ndarray, origin: np.ndarray,
            resolution: float = RISK_RESOLUTION) -> np.ndarray:
    """Row order of ``points``: highest score first (scores rounded to ``resolution``; 0:
    exact), then nearest to ``origin``, then the earlier row; NaN scores last.

    >>> ranking(np.array([0.5, 1.0, np.nan, 1.0]),
    ...         np.array([[0.0], [2.0], [0.0], [1.0]]), np.zeros(1)).tolist()
    [3, 1, 0, 2]
    """
    scores = np.asarray(scores, dtype=float)
    rounded = np.round(scores / resolution) if resolution > 0 else scores
    levels = np.where(np.isfinite(scores), -rounded, np.inf)
    return np.lexsort((np.arange(scores.size), distance(points, origin), levels))


@dataclass
class CrossEntropy:
    """Proposes generations of points in the box ``|z| ≤ bound`` and learns from their risks."""

    dimensions: int
    bound: float
    origin: np.ndarray  # the nominal world: ties go to the nearer world
    rng: np.random.Generator
    mean: np.ndarray = field(init=False)
    spread: np.ndarray = field(init=False)
    generation: int = 0
    elites: np.ndarray = field(init=False)  # points
    elite_scores: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.mean = np.zeros(self.dimensions)
        self.spread = np.ones(self.dimensions)
        self.elites = np.empty((0, self.dimensions))
        self.elite_scores = np.empty(0)

    def propose(self, count: int) -> np.ndarray:
        """The next generation, (count, dimensions)."""
        if self.generation == 0:
            unit = qmc.LatinHypercube(d=self.dimensions, rng=self.rng).random(count)
            points = np.asarray(stats.norm.ppf(unit), dtype=float)
        else:
            points = self.mean + self.spread * self.rng.standard_normal((count,
                                                                         self.dimensions))
        return np.asarray(np.clip(points, -self.bound, self.bound), dtype=float)

    def update(self, points: np.ndarray, scores: np.ndarray) -> None:
        """Learn from a generation's points and their scores (NaN: the run failed).

        The elites are the generation's best quarter. The mean moves towards theirs; the
        spread becomes their spread around the *old* mean, so it grows while the elites keep
        pointing the same way (a slope the search climbs) and shrinks once they surround the
        mean (an optimum), instead of collapsing after a few generations as the elites' own
        spread does. Both are smoothed; the best world seen is kept apart."""
        self.generation += 1
        scores = np.asarray(scores, dtype=float)
        keep = max(3, int(np.ceil(ELITE_SHARE * len(points))))
        order = ranking(scores, points, self.origin)
        order = order[np.isfinite(scores[order])][:keep]
        if order.size == 0:
            return  # nothing to learn from: the same distribution again
        elites = points[order]
        steps = np.sqrt(np.mean(np.square(elites - self.mean), axis=0))
        self.mean = SMOOTHING * elites.mean(axis=0) + (1 - SMOOTHING) * self.mean
        self.spread = np.clip(SMOOTHING * steps + (1 - SMOOTHING) * self.spread,
                              MIN_SPREAD, MAX_SPREAD)
        pool = np.vstack([self.elites, elites])
        pool_scores = np.concatenate([self.elite_scores, scores[order]])
        best = ranking(pool_scores, pool, self.origin)[:keep]
        self.elites, self.elite_scores = pool[best], pool_scores[best]

    @property
    def best_point(self) -> np.ndarray:
        """The best point seen (the nominal world before any update)."""
        return self.elites[0] if len(self.elites) else self.origin
