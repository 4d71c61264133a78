"""A campaign's uncertainty as a search space: standard-normal quantile coordinates.

Each uncertain parameter ``x_i`` with distribution ``F_i`` gets the coordinate
``z_i = Φ⁻¹(F_i(x_i))``: its quantile seen through the standard normal distribution. A point
``z`` of any size maps back to a value inside the parameter's support
(``x_i = F_i⁻¹(Φ(z_i))``), and under the campaign's own distributions (independent parameters)
``z`` is a standard normal vector. That makes two things simple:

- the search moves freely and never leaves a distribution's support; it is kept to the box
  ``|z_i| ≤ Φ⁻¹(1 - tail)``, worlds whose every parameter lies within its ``tail`` …
  ``1 - tail`` quantiles;
- how unusual a world is has an exact answer: ``|z|²`` is chi-square distributed with ``d``
  degrees of freedom, so the share of the campaign's worlds at least as far from the median
  world (every parameter at its median, ``z = 0``) as ``z`` is ``P(χ²_d ≥ |z|²)``
  (:meth:`QuantileSpace.tail_probability`).

>>> from idefix_rules.campaign.input.distributions import Normal, Uniform
>>> space = QuantileSpace.of({"a": Normal(distribution="normal", mean=0.0, std=2.0),
...                          "b": Uniform(distribution="uniform", low=0.0, high=1.0)})
>>> [round(float(v[0]), 3) for v in space.values(np.array([[1.0, 0.0]])).values()]
[2.0, 0.5]
>>> round(space.tail_probability(np.array([0.0, 0.0])), 3)
1.0
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy import stats

from idefix_rules.campaign.input.distributions import Fixed
from idefix_rules.campaign.input.sampling import (
    AnyDistribution,
    cumulative,
    inverse_cdf,
    nominal,
)

DEFAULT_TAIL = 1e-4  # the box: every parameter within its 0.01 % … 99.99 % quantiles


@dataclass(frozen=True)
class QuantileSpace:
    """The uncertain (not fixed) parameters of a campaign, in its order, and the box searched."""

    names: tuple[str, ...]
    distributions: tuple[AnyDistribution, ...]
    tail: float = DEFAULT_TAIL

    @classmethod
    def of(cls, parameters: Mapping[str, AnyDistribution],
           tail: float = DEFAULT_TAIL) -> QuantileSpace:
        uncertain = [(name, spec) for name, spec in parameters.items()
                     if not isinstance(spec, Fixed)]
        return cls(tuple(name for name, _ in uncertain), tuple(spec for _, spec in uncertain),
                   tail)

    @property
    def dimensions(self) -> int:
        return len(self.names)

    @property
    def bound(self) -> float:
        """The box's half width in z: ``Φ⁻¹(1 - tail)`` (3.72 for the default tail)."""
        return float(stats.norm.isf(self.tail))

    def clip(self, z: np.ndarray) -> np.ndarray:
        return np.asarray(np.clip(z, -self.bound, self.bound), dtype=float)

    def nominal(self) -> np.ndarray:
        """z of the nominal world (the reference run's values: mean, median, midpoint), in
        the box."""
        quantiles = [float(cumulative(spec, np.array(nominal(spec))))
                     for spec in self.distributions]
        return self.clip(np.asarray(stats.norm.ppf(quantiles), dtype=float))

    def quantiles(self, z: np.ndarray) -> np.ndarray:
        return np.asarray(stats.norm.cdf(z), dtype=float)

    def values(self, z: np.ndarray) -> dict[str, np.ndarray]:
        """The parameter values (SI) of the points ``z`` (points, dimensions)."""
        z = np.atleast_2d(np.asarray(z, dtype=float))
        u = self.quantiles(z)
        return {name: inverse_cdf(spec, u[:, column])
                for column, (name, spec) in enumerate(zip(self.names, self.distributions,
                                                          strict=True))}

    def exit_distance(self, origin: np.ndarray, direction: np.ndarray) -> float:
        """How far along ``direction`` (a unit vector) a ray from ``origin`` stays in the box."""
        limits = []
        for start, step in zip(origin, direction, strict=True):
            if step > 1e-12:
                limits.append((self.bound - start) / step)
            elif step < -1e-12:
                limits.append((-self.bound - start) / step)
        return max(0.0, min(limits)) if limits else 0.0

    def tail_probability(self, z: np.ndarray) -> float:
        """The share of the campaign's worlds at least as far from the median world as ``z``:
        ``P(χ²_d ≥ |z|²)``."""
        if self.dimensions == 0:
            return 1.0
        return float(stats.chi2.sf(float(np.sum(np.square(z))), self.dimensions))


def distance(z: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """Euclidean distance of each point of ``z`` (points, dimensions) from ``origin``, in
    standard deviations of the standard-normal coordinates."""
    return np.asarray(np.sqrt(np.sum(np.square(np.atleast_2d(z) - origin), axis=1)))


def one_in(probability: float) -> str:
    """``1 in 2,300`` for a probability, as people read a rarity.

    >>> one_in(0.00043), one_in(0.0712), one_in(0.784), one_in(1.0)
    ('1 in 2,300', '1 in 14', '1 in 1.3', '1 in 1')
    """
    if probability <= 0.0 or not math.isfinite(probability):
        return "fewer than 1 in 10^15"
    ratio = 1.0 / probability
    if ratio >= 1e15:
        return "fewer than 1 in 10^15"
    if ratio < 10:
        shown = f"{ratio:.1f}"
        return f"1 in {shown.removesuffix('.0')}"
    digits = max(0, math.floor(math.log10(ratio)) - 1)
    rounded = round(ratio / 10 ** digits) * 10 ** digits
    return f"1 in {rounded:,.0f}"
