"""One path's worst-case search as a sequence of batches: ask for worlds, tell their risks.

:class:`PathSearch` knows nothing of FMUs or files: it proposes points in quantile space
(:mod:`.space`) and learns from the run risks it is told, so the same code is driven by the
campaign's simulations (:mod:`.stage`) and, in the tests, by a risk known in closed form.
Two phases share the path's run budget:

1. **search**: a cross-entropy search (:mod:`.cross_entropy`) for the highest run risk, with
   the budget left after the boundary's share;
2. **boundary**: when the worst world found is critical and the nominal world is not, rays from
   the nominal world towards the worst world and along the most sensitive parameters, each
   bracketing where the risk first reaches the threshold (:mod:`.boundary`).

>>> from idefix_rules.campaign.input.distributions import Normal
>>> space = QuantileSpace.of({"a": Normal(distribution="normal", mean=0.0, std=1.0),
...                          "b": Normal(distribution="normal", mean=0.0, std=1.0)})
>>> search = PathSearch(space, SearchSettings(runs=120), np.random.default_rng(3),
...                     nominal_risk=0.0)
>>> while len(points := search.ask()):
...     search.tell(np.clip(points[:, 0] / 1.5, 0, 1), ["I_a"] * len(points))
>>> search.worst.risk, bool(1.5 <= search.worst.z[0] < 1.8)   # critical from z = 1.5 on
(1.0, True)
>>> low, high = search.rays[0].bracket
>>> low <= 1.5 <= high and high - low < 0.1
True
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from idefix_rules.campaign.worst.boundary import (
    DEFAULT_AXES,
    DEFAULT_ROUNDS,
    Axis,
    Ray,
    runs_per_ray,
    sensitive_axes,
)
from idefix_rules.campaign.worst.cross_entropy import CrossEntropy, ranking
from idefix_rules.campaign.worst.space import DEFAULT_TAIL, QuantileSpace

SEARCH, BOUNDARY, DONE = "search", "boundary", "done"
TOWARD_WORST = "toward the worst world"


@dataclass(frozen=True)
class SearchSettings:
    """A search's budget and shape (the same for every path)."""

    runs: int  # per path, search and boundary together
    threshold: float = 1.0  # a run is critical when its I_max reaches this
    tail: float = DEFAULT_TAIL
    rounds: int = DEFAULT_ROUNDS
    axes: int = DEFAULT_AXES

    @staticmethod
    def population(dimensions: int) -> int:
        """Worlds per generation: 4 per parameter, at least 12, at most 32."""
        return min(32, max(12, 4 * dimensions))

    def first_generation(self, dimensions: int) -> int:
        return 2 * self.population(dimensions)

    def boundary_runs(self, dimensions: int) -> int:
        return (1 + min(self.axes, dimensions)) * runs_per_ray(self.rounds)

    def minimum_runs(self, dimensions: int) -> int:
        """The first generation, one more, and the boundary's share."""
        return (self.first_generation(dimensions) + self.population(dimensions)
                + self.boundary_runs(dimensions))


@dataclass(frozen=True)
class Point:
    """A simulated world of the search: its row among the path's runs (the order asked)."""

    row: int
    z: np.ndarray
    risk: float  # NaN: the run failed
    dominant: str | None
    phase: str
    generation: int | None = None
    ray: int | None = None


@dataclass
class PathSearch:
    """The search of one path; ``ask`` the next batch of points, ``tell`` their risks."""

    space: QuantileSpace
    settings: SearchSettings
    rng: np.random.Generator
    nominal_risk: float
    nominal_dominant: str | None = None
    phase: str = SEARCH
    points: list[Point] = field(default_factory=list)
    axes: list[Axis] = field(default_factory=list)
    rays: list[Ray] = field(default_factory=list)
    _asked: np.ndarray | None = None
    _asked_steps: list[tuple[int, float]] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.origin = self.space.nominal()
        self.cross_entropy = CrossEntropy(self.space.dimensions, self.space.bound,
                                          self.origin, self.rng)
        dimensions = self.space.dimensions
        self.search_budget = self.settings.runs - self.settings.boundary_runs(dimensions)

    @property
    def used(self) -> int:
        return len(self.points)

    def ask(self) -> np.ndarray:
        """The next batch (points, dimensions); empty once the search is done."""
        if self.phase == SEARCH:
            remaining = self.search_budget - self.used
            dimensions = self.space.dimensions
            size = self.settings.first_generation(dimensions) if not self.points \
                else self.settings.population(dimensions)
            count = min(size, remaining)
            if count > 0:
                self._asked = self.cross_entropy.propose(count)
                return self._asked
            self._start_boundary()
        if self.phase == BOUNDARY:
            self._asked_steps = [(number, step) for number, ray in enumerate(self.rays)
                                 for step in ray.ask()]
            if self._asked_steps:
                self._asked = np.array([self.rays[number].point(step)
                                        for number, step in self._asked_steps])
                return self._asked
            self.phase = DONE
        return np.empty((0, self.space.dimensions))

    def tell(self, risks: Sequence[float] | np.ndarray, dominants: Sequence[str | None]
             ) -> None:
        """The run risks (NaN: failed) and dominant indices of the batch just asked."""
        asked = self._asked
        if asked is None:
            raise RuntimeError("tell without ask")
        values = np.asarray(risks, dtype=float)
        if self.phase == SEARCH:
            generation = self.cross_entropy.generation
            self._record(asked, values, dominants, SEARCH, generation=generation)
            if generation == 0:
                self.axes = sensitive_axes(self.space.names, asked, values, self.settings.axes)
            self.cross_entropy.update(asked, values)
        else:
            self._record(asked, values, dominants, BOUNDARY,
                         rays=[number for number, _ in self._asked_steps])
            for number, ray in enumerate(self.rays):
                mine = [i for i, (owner, _) in enumerate(self._asked_steps) if owner == number]
                if mine:
                    ray.tell([self._asked_steps[i][1] for i in mine], values[mine].tolist())
        self._asked = None

    def _record(self, points: np.ndarray, risks: np.ndarray,
                dominants: Sequence[str | None], phase: str, generation: int | None = None,
                rays: Sequence[int] | None = None) -> None:
        for i, z in enumerate(points):
            self.points.append(Point(self.used, np.asarray(z, dtype=float), float(risks[i]),
                                     dominants[i], phase, generation,
                                     None if rays is None else rays[i]))

    @property
    def worst(self) -> Point:
        """The riskiest world the search phase simulated (ties: the nearest to the nominal
        world); the nominal world itself (row -1) when no search run completed or none is
        riskier. The boundary's worlds are the boundary's answer, not candidates: the ray
        "toward the worst world" keeps pointing at this one."""
        nominal = Point(-1, self.origin, self.nominal_risk, self.nominal_dominant, "nominal")
        candidates = [nominal, *(p for p in self.points if p.phase == SEARCH)]
        order = ranking(np.array([p.risk for p in candidates]),
                        np.array([p.z for p in candidates]), self.origin, resolution=0.0)
        return candidates[int(order[0])]

    def critical(self, risk: float) -> bool:
        return bool(np.isfinite(risk) and risk >= self.settings.threshold)

    def _start_boundary(self) -> None:
        """Rays from the nominal world, when a boundary lies between it and the worst world."""
        self.phase = BOUNDARY
        worst = self.worst
        if self.critical(self.nominal_risk) or not self.critical(worst.risk):
            return
        threshold, rounds = self.settings.threshold, self.settings.rounds
        offset = worst.z - self.origin
        length = float(np.linalg.norm(offset))
        if length > 0:
            self.rays.append(Ray(TOWARD_WORST, self.origin, offset / length, length, threshold,
                                 end_risk=worst.risk, rounds=rounds))
        for axis in self.axes:
            direction = np.zeros(self.space.dimensions)
            direction[axis.column] = 1.0 if axis.rho > 0 else -1.0
            end = self.space.exit_distance(self.origin, direction)
            way = "up" if axis.rho > 0 else "down"
            self.rays.append(Ray(f"{axis.parameter} {way}", self.origin, direction, end,
                                 threshold, rounds=rounds, axis=axis.parameter))
