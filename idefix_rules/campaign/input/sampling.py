"""Sampling uncertain parameters: distributions, designs and deterministic seeds.

A path draws from a *stream*, a spawn-key prefix: run ``j`` draws from
``SeedSequence(seed, spawn_key=(*stream, j))`` (plain Monte Carlo), or takes row ``j`` of a design
generated from ``SeedSequence(seed, spawn_key=stream)`` (Latin hypercube, Sobol). A paired
campaign (the default) gives every path the empty stream ``()``: run ``j`` of every path is the
same simulated world (common random numbers), so differences between paths are measured in the
same worlds. An unpaired campaign gives each path its own stream, a number made from the path's
name (:func:`path_stream`), so adding or removing a path never changes another path's draws.
Nothing depends on the worker that simulates the run, so results are identical for any worker
count and order.

>>> from idefix_rules.campaign.input.distributions import Normal
>>> values = sample_path({"x0": Normal(distribution="normal", mean=0.0, std=0.01)},
...                      "monte_carlo", seed=1, stream=(), runs=3)
>>> values["x0"].shape
(3,)
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from idefix_rules.campaign.input.distributions import (
    Fixed,
    LogNormal,
    Normal,
    SamplingMethod,
    TruncatedNormal,
    Uniform,
)

if TYPE_CHECKING:
    from idefix_rules.campaign.input.load import Campaign

AnyDistribution = Fixed | Normal | TruncatedNormal | Uniform | LogNormal

# scipy.stats takes about a second to import: it is imported by the functions that draw or
# transform values, not by those that only read a distribution's nominal value (re-scoring a
# stored campaign needs only those).

# Keeps inverse CDFs finite at the ends of the unit interval.
_EDGE = 1e-12
_TAIL_NODES = 128  # Gauss–Legendre nodes of a one-sided truncated normal's variance


def nominal(spec: AnyDistribution) -> float:
    """The value the reference run uses: mean, midpoint, median or the fixed value."""
    if isinstance(spec, Fixed):
        return spec.value
    if isinstance(spec, Normal | TruncatedNormal):
        if isinstance(spec, TruncatedNormal):
            return float(min(max(spec.mean, spec.low), spec.high))
        return spec.mean
    if isinstance(spec, Uniform):
        return 0.5 * (spec.low + spec.high)
    return spec.median


def standard_deviation(spec: AnyDistribution) -> float:
    """Standard deviation of a distribution, SI."""
    if isinstance(spec, Fixed):
        return 0.0
    if isinstance(spec, Normal):
        return spec.std
    if isinstance(spec, Uniform):
        return (spec.high - spec.low) / math.sqrt(12.0)
    from scipy import stats

    if isinstance(spec, TruncatedNormal):
        low, high = (spec.low - spec.mean) / spec.std, (spec.high - spec.mean) / spec.std
        if low < 0.0 < high:
            return float(stats.truncnorm.std(low, high, loc=spec.mean, scale=spec.std))
        return spec.std * _one_sided_truncated_std(low, high)
    # a wide log-normal (sigma: 1000): a σ beyond a double, which scipy gives as nan or inf
    # with RuntimeWarnings
    with np.errstate(over="ignore", invalid="ignore"):
        std = float(stats.lognorm.std(spec.sigma, scale=spec.median))
    return math.inf if math.isnan(std) else std


def _one_sided_truncated_std(low: float, high: float) -> float:
    """σ of a standard normal truncated to ``[low, high]`` on one side of its mean.

    scipy's moments lose their digits there: ``truncnorm.std(500, 501)`` is 0.00071 against
    0.0020, and from about 600 σ on, or for an interval of 1e-5 σ, they are NaN with
    RuntimeWarnings. With ``y = x − low`` (``low ≥ 0``; the other side mirrored) the density is
    proportional to ``exp(−low·y − y²/2)``, smooth and without the vanishing factor
    ``exp(−low²/2)``; Gauss–Legendre quadrature over ``[0, min(high − low, 60 / low, 12)]``
    (beyond, the weight is below ``e^-60``) gives its variance.

    >>> round(_one_sided_truncated_std(500.0, 501.0), 8)  # about 1 / 500
    0.00199998
    """
    if high <= 0.0:
        low, high = -high, -low
    width = min(high - low, 12.0, 60.0 / low if low > 0.0 else math.inf)
    nodes, weights = np.polynomial.legendre.leggauss(_TAIL_NODES)
    y = 0.5 * width * (nodes + 1.0)
    density = 0.5 * width * weights * np.exp(-low * y - 0.5 * y * y)
    total = float(np.sum(density))
    mean = float(np.sum(density * y)) / total
    return math.sqrt(float(np.sum(density * (y - mean) ** 2)) / total)


def inverse_cdf(spec: AnyDistribution, u: np.ndarray) -> np.ndarray:
    """Map uniform numbers in (0, 1) to the distribution."""
    from scipy import stats

    u = np.clip(u, _EDGE, 1.0 - _EDGE)
    if isinstance(spec, Fixed):
        return np.full(u.shape, spec.value)
    if isinstance(spec, Normal):
        return np.asarray(stats.norm.ppf(u, loc=spec.mean, scale=spec.std), dtype=float)
    if isinstance(spec, TruncatedNormal):
        low, high = (spec.low - spec.mean) / spec.std, (spec.high - spec.mean) / spec.std
        values = stats.truncnorm.ppf(u, low, high, loc=spec.mean, scale=spec.std)
        clipped: np.ndarray = np.clip(np.asarray(values, dtype=float), spec.low, spec.high)
        return clipped
    if isinstance(spec, Uniform):
        return np.asarray(spec.low + u * (spec.high - spec.low), dtype=float)
    # A wide log-normal (sigma: 1000) draws values beyond a double: they are inf, which the
    # parameter's range check refuses at the campaign's line (F110), not a RuntimeWarning.
    with np.errstate(over="ignore"):
        return np.asarray(stats.lognorm.ppf(u, spec.sigma, scale=spec.median), dtype=float)


def cumulative(spec: AnyDistribution, values: np.ndarray) -> np.ndarray:
    """The quantile of each value: the inverse of :func:`inverse_cdf` (a fixed parameter is
    always at its median, 0.5).

    >>> round(float(cumulative(Uniform(distribution="uniform", low=0.0, high=4.0),
    ...                        np.array(3.0))), 3)
    0.75
    """
    from scipy import stats

    values = np.asarray(values, dtype=float)
    if isinstance(spec, Fixed):
        return np.full(values.shape, 0.5)
    if isinstance(spec, Normal):
        return np.asarray(stats.norm.cdf(values, loc=spec.mean, scale=spec.std), dtype=float)
    if isinstance(spec, TruncatedNormal):
        low, high = (spec.low - spec.mean) / spec.std, (spec.high - spec.mean) / spec.std
        return np.asarray(stats.truncnorm.cdf(values, low, high, loc=spec.mean,
                                              scale=spec.std), dtype=float)
    if isinstance(spec, Uniform):
        return np.asarray(np.clip((values - spec.low) / (spec.high - spec.low), 0.0, 1.0),
                          dtype=float)
    return np.asarray(stats.lognorm.cdf(values, spec.sigma, scale=spec.median), dtype=float)


Stream = tuple[int, ...]
PAIRED_STREAM: Stream = ()


def path_stream(name: str, paired: bool) -> Stream:
    """The spawn-key prefix a path draws from: ``()`` when paired (every path draws the same
    worlds), else the first 32 bits of the sha256 of the path's name.

    >>> path_stream("straight", paired=True)
    ()
    >>> path_stream("straight", paired=False) == path_stream("straight", paired=False)
    True
    """
    if paired:
        return PAIRED_STREAM
    return (int.from_bytes(hashlib.sha256(name.encode("utf-8")).digest()[:4], "big"),)


def seed_derivation(paired: bool) -> str:
    """How run seeds are derived, in words (stored in results.h5)."""
    stream = "()" if paired else "(h,) with h the first 32 bits of sha256(path name)"
    return (f"stream s = {stream}; monte_carlo: run j uses SeedSequence(seed, "
            "spawn_key=(*s, j)); latin_hypercube/sobol: the design uses SeedSequence(seed, "
            "spawn_key=s) and run j takes row j")


def run_seed(seed: int, stream: Stream, run_index: int) -> np.random.SeedSequence:
    """The seed of run ``run_index`` of a path drawing from ``stream``."""
    return np.random.SeedSequence(seed, spawn_key=(*stream, run_index))


def path_seed(seed: int, stream: Stream) -> np.random.SeedSequence:
    """The seed of a path's whole design (Latin hypercube, Sobol)."""
    return np.random.SeedSequence(seed, spawn_key=stream)


def unit_design(method: SamplingMethod, dimensions: int, seed: int, stream: Stream,
                runs: int) -> np.ndarray:
    """Uniform design of shape (runs, dimensions) in (0, 1).

    Sobol designs are balanced only for a power-of-two number of points: other run counts take
    the first ``runs`` points of the next power-of-two design (still low-discrepancy, but the
    balance guarantee is lost; :func:`sobol_warning` says so).
    """
    if dimensions == 0:
        return np.empty((runs, 0))
    if method == "monte_carlo":
        design = np.empty((runs, dimensions))
        for run_index in range(runs):
            rng = np.random.default_rng(run_seed(seed, stream, run_index))
            design[run_index] = rng.random(dimensions)
        return design
    rng = np.random.default_rng(path_seed(seed, stream))
    from scipy.stats import qmc

    if method == "latin_hypercube":
        return np.asarray(qmc.LatinHypercube(d=dimensions, rng=rng).random(runs))
    exponent = max(0, math.ceil(math.log2(runs)))
    sobol = qmc.Sobol(d=dimensions, scramble=True, rng=rng)
    return np.asarray(sobol.random_base2(exponent)[:runs])


def sobol_warning(method: SamplingMethod, runs: int) -> str | None:
    if method == "sobol" and runs & (runs - 1):
        return (f"Sobol sampling with {runs} runs (not a power of two): using the first "
                f"{runs} points of a {1 << math.ceil(math.log2(runs))}-point design; "
                "its balance properties hold only for powers of two")
    return None


def sample_path(parameters: Mapping[str, AnyDistribution], method: SamplingMethod, seed: int,
                stream: Stream, runs: int) -> dict[str, np.ndarray]:
    """Sampled values (runs,) per parameter, in SI, for one path drawing from ``stream``."""
    uncertain = [name for name, spec in parameters.items() if not isinstance(spec, Fixed)]
    design = unit_design(method, len(uncertain), seed, stream, runs)
    values = {}
    for name, spec in parameters.items():
        if isinstance(spec, Fixed):
            values[name] = np.full(runs, spec.value)
        else:
            values[name] = inverse_cdf(spec, design[:, uncertain.index(name)])
    return values


def nominal_values(parameters: Mapping[str, AnyDistribution]) -> dict[str, float]:
    return {name: nominal(spec) for name, spec in parameters.items()}


# An adaptive campaign (runs: auto) draws every run independently: its stopping bounds need
# independent runs, so a design (Latin hypercube, Sobol) is not used.
ADAPTIVE_SAMPLING: SamplingMethod = "monte_carlo"


def adaptive_sampling_note(method: str) -> str | None:
    """Said once when the campaign asks for a design an adaptive campaign cannot use."""
    if method == ADAPTIVE_SAMPLING:
        return None
    return (f"runs: auto draws every run independently (monte_carlo); the campaign's {method} "
            "design is not used, because the confidence sequences that decide when to stop "
            "need independent runs")


def planned_draws(campaign: Campaign, names: Sequence[str]
                  ) -> tuple[int, dict[str, dict[str, np.ndarray]]]:
    """The runs planned per path (an adaptive campaign's cap) and every uncertain parameter's
    draws for them, per path of ``names``: the values the Monte Carlo stage draws (the same
    method, seed and stream), known before any run is simulated."""
    if campaign.adaptive is not None:
        planned, method = campaign.adaptive.max_runs, ADAPTIVE_SAMPLING
    else:
        planned, method = campaign.runs, campaign.model.uncertainty.method
    parameters = campaign.model.uncertainty.parameters
    if not parameters:
        return planned, {name: {} for name in names}
    paired = campaign.model.uncertainty.paired
    if paired:  # every path draws the same worlds: drawn once, shared
        shared = sample_path(parameters, method, campaign.seed, path_stream("", True), planned)
        return planned, {name: shared for name in names}
    return planned, {name: sample_path(parameters, method, campaign.seed,
                                       path_stream(name, False), planned)
                     for name in names}
