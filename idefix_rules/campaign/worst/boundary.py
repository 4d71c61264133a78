"""The failure boundary: how far from the nominal world a chain becomes critical.

Along a few rays from the nominal world in quantile space (:mod:`.space`) — towards the worst
world found, and along the parameters the risk is most sensitive to — the first world where the
run risk reaches the threshold is bracketed by a grid search:

- round 1 simulates 4 points evenly along the ray up to its end (3 when the end is the worst
  world, already simulated); the first critical point and the last point before it that is not
  critical bracket the boundary (the nominal world is the start, known not critical);
- every later round simulates 3 points evenly inside the bracket, which shrinks it to a quarter.

After ``rounds`` rounds the boundary lies in a bracket of ``end / 4^rounds`` (1/64 of the ray
with the default 3 rounds) when the risk grows along the ray past it. With a risk that goes up
and down along a ray, the bracket holds the first crossing the grid resolves (a critical stretch
nearer than the first grid step can be missed: docs/worst-case.md says so). Every point of a
round of every ray of every path is simulated in one batch, so the rounds cost wall time, not
the points.

>>> ray = Ray("toward x", np.zeros(1), np.ones(1), end=2.0, threshold=1.0)
>>> for _ in range(3):
...     steps = ray.ask()
...     ray.tell(steps, [min(1.0, 0.8 * t) for t in steps])   # critical from t = 1.25
>>> ray.bracket
(1.21875, 1.25)
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from idefix_rules.campaign.evaluation.sensitivity import correlations

FIRST_ROUND = 4  # points along a ray whose end is not simulated yet
LATER_ROUNDS = 3  # points inside the bracket
DEFAULT_ROUNDS = 3
DEFAULT_AXES = 2


def runs_per_ray(rounds: int) -> int:
    """The most runs one ray takes: 4, then 3 a round."""
    return FIRST_ROUND + LATER_ROUNDS * max(0, rounds - 1)


@dataclass
class Ray:
    """One ray ``origin + t · direction`` (``direction`` a unit vector in z), searched for the
    first ``t`` whose run risk reaches ``threshold``."""

    label: str
    origin: np.ndarray
    direction: np.ndarray
    end: float
    threshold: float
    end_risk: float | None = None  # known at the end (the worst world), else simulated
    rounds: int = DEFAULT_ROUNDS
    axis: str | None = None  # the parameter of an axis ray
    points: list[tuple[float, float]] = field(default_factory=list)  # (t, risk), NaN: failed
    done_rounds: int = 0

    def __post_init__(self) -> None:
        if self.end_risk is not None:
            self.points.append((self.end, self.end_risk))

    def ask(self) -> list[float]:
        """The distances along the ray to simulate next (empty: done)."""
        if self.done_rounds >= self.rounds or self.end <= 0.0:
            return []
        if self.done_rounds == 0:
            count = FIRST_ROUND - (1 if self.end_risk is not None else 0)
            return [self.end * (i + 1) / FIRST_ROUND for i in range(count)]
        bracket = self.bracket
        if bracket is None:
            return []
        low, high = bracket
        return [low + (high - low) * (i + 1) / (LATER_ROUNDS + 1) for i in range(LATER_ROUNDS)]

    def tell(self, steps: Sequence[float], risks: Sequence[float]) -> None:
        self.points.extend((float(t), float(r)) for t, r in zip(steps, risks, strict=True))
        self.done_rounds += 1

    def point(self, step: float) -> np.ndarray:
        return np.asarray(self.origin + step * self.direction, dtype=float)

    @property
    def crossing(self) -> float | None:
        """The nearest ``t`` found critical (None: no point of the ray is)."""
        critical = [t for t, risk in self.points if math.isfinite(risk) and risk >= self.threshold]
        return min(critical) if critical else None

    @property
    def bracket(self) -> tuple[float, float] | None:
        """(last t known not critical, first t found critical): the boundary lies between."""
        high = self.crossing
        if high is None:
            return None
        below = [t for t, risk in self.points
                 if t < high and math.isfinite(risk) and risk < self.threshold]
        return max([0.0, *below]), high


@dataclass(frozen=True)
class Axis:
    """A parameter the run risk is sensitive to, from the first (unbiased) generation."""

    parameter: str
    column: int
    rho: float
    significant: bool


def sensitive_axes(names: Sequence[str], points: np.ndarray, risks: np.ndarray,
                   count: int = DEFAULT_AXES) -> list[Axis]:
    """The ``count`` parameters whose quantile coordinate correlates most with the run risk
    (Spearman's ρ over ``points``, strongest first; the sign says which way risk grows).

    >>> z = np.random.default_rng(2).standard_normal((40, 3))
    >>> [(a.parameter, a.rho > 0) for a in sensitive_axes("abc", z, z[:, 2] - 0.3 * z[:, 0])]
    [('c', True), ('a', False)]
    """
    columns: Mapping[str, np.ndarray] = {name: points[:, i] for i, name in enumerate(names)}
    found = correlations(dict(columns), np.asarray(risks, dtype=float))
    position = {name: i for i, name in enumerate(names)}
    return [Axis(c.parameter, position[c.parameter], c.rho, c.significant)
            for c in found[:count] if c.rho != 0.0]
