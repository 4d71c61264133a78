"""Sampling: distributions have the right shape, designs depend on seeds only."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from idefix_rules.campaign.input import sampling
from idefix_rules.campaign.input.distributions import (
    Fixed,
    LogNormal,
    Normal,
    TruncatedNormal,
    Uniform,
)

PARAMETERS = {
    "initial.x": Normal(distribution="normal", mean="0 m", std="1 cm"),
    "initial.yaw": TruncatedNormal(distribution="truncated_normal", mean="0 deg", std="2 deg",
                                   low="-3 deg", high="3 deg"),
    "soil.cohesion": LogNormal(distribution="log_normal", median="250 Pa", sigma=0.4),
    "soil.friction_angle": Uniform(distribution="uniform", low="30 deg", high="50 deg"),
    "soil.n": Fixed(distribution="fixed", value=1.0),
}


@pytest.mark.parametrize("method", ["monte_carlo", "latin_hypercube", "sobol"])
def test_the_same_seed_gives_the_same_values_and_another_seed_others(method: str) -> None:
    stream = sampling.path_stream("a", paired=False)
    first = sampling.sample_path(PARAMETERS, method, seed=7, stream=stream, runs=64)
    again = sampling.sample_path(PARAMETERS, method, seed=7, stream=stream, runs=64)
    other = sampling.sample_path(PARAMETERS, method, seed=8, stream=stream, runs=64)
    other_path = sampling.sample_path(PARAMETERS, method, seed=7,
                                      stream=sampling.path_stream("b", paired=False), runs=64)
    for name in PARAMETERS:
        assert np.array_equal(first[name], again[name])
    assert not np.array_equal(first["initial.x"], other["initial.x"])
    assert not np.array_equal(first["initial.x"], other_path["initial.x"])


def test_monte_carlo_run_values_do_not_depend_on_the_number_of_runs() -> None:
    few = sampling.sample_path(PARAMETERS, "monte_carlo", seed=1, stream=(), runs=5)
    many = sampling.sample_path(PARAMETERS, "monte_carlo", seed=1, stream=(), runs=50)
    for name in PARAMETERS:
        assert np.array_equal(few[name], many[name][:5])


def test_run_seed_is_the_seed_sequence_keyed_by_stream_and_run() -> None:
    seq = sampling.run_seed(5, (2,), 9)
    assert seq.entropy == 5 and seq.spawn_key == (2, 9)
    assert sampling.run_seed(5, (), 9).spawn_key == (9,)


@pytest.mark.parametrize("method", ["monte_carlo", "latin_hypercube", "sobol"])
def test_paired_paths_draw_the_same_values_and_unpaired_paths_their_own(method: str) -> None:
    paired = [sampling.sample_path(PARAMETERS, method, seed=7,
                                   stream=sampling.path_stream(name, paired=True), runs=16)
              for name in ("straight", "detour")]
    unpaired = [sampling.sample_path(PARAMETERS, method, seed=7,
                                     stream=sampling.path_stream(name, paired=False), runs=16)
                for name in ("straight", "detour")]
    for name in PARAMETERS:
        assert np.array_equal(paired[0][name], paired[1][name])
    for name in ("initial.x", "initial.yaw", "soil.cohesion", "soil.friction_angle"):
        assert not np.any(unpaired[0][name] == unpaired[1][name])


def test_an_unpaired_path_stream_is_made_from_its_name_alone() -> None:
    # 32 bits of sha256("straight"): no other path's name or position enters it
    assert sampling.path_stream("straight", paired=False) == (0x2A424875,)
    assert sampling.path_stream("straight", paired=True) == ()


@pytest.mark.parametrize("method", ["monte_carlo", "latin_hypercube", "sobol"])
def test_sampled_distributions_have_their_moments_and_bounds(method: str) -> None:
    values = sampling.sample_path(PARAMETERS, method, seed=3, stream=(), runs=4096)
    assert abs(np.mean(values["initial.x"])) < 0.001
    assert math.isclose(np.std(values["initial.x"]), 0.01, rel_tol=0.05)
    yaw = values["initial.yaw"]
    assert yaw.min() >= -math.radians(3) and yaw.max() <= math.radians(3)
    assert math.isclose(np.median(values["soil.cohesion"]), 250.0, rel_tol=0.05)
    friction = values["soil.friction_angle"]
    assert friction.min() >= math.radians(30) and friction.max() <= math.radians(50)
    assert np.all(values["soil.n"] == 1.0)


def test_latin_hypercube_puts_one_sample_in_each_stratum() -> None:
    design = sampling.unit_design("latin_hypercube", 3, seed=0, stream=(), runs=20)
    for column in design.T:
        assert sorted(np.floor(column * 20).astype(int)) == list(range(20))


def test_sobol_with_a_power_of_two_is_silent_and_otherwise_warns() -> None:
    assert sampling.sobol_warning("sobol", 64) is None
    assert "not a power of two" in (sampling.sobol_warning("sobol", 100) or "")
    assert sampling.sobol_warning("monte_carlo", 100) is None
    prefix = sampling.unit_design("sobol", 2, seed=0, stream=(), runs=100)
    full = sampling.unit_design("sobol", 2, seed=0, stream=(), runs=128)
    assert np.array_equal(prefix, full[:100])


def test_nominal_values_are_mean_midpoint_median_or_fixed() -> None:
    nominal = sampling.nominal_values(PARAMETERS)
    assert nominal["initial.x"] == 0.0
    assert nominal["soil.cohesion"] == 250.0
    assert math.isclose(nominal["soil.friction_angle"], math.radians(40))
    assert nominal["soil.n"] == 1.0


@settings(max_examples=50, deadline=None)
@given(u=st.floats(0.0, 1.0), low=st.floats(-10, 10), width=st.floats(0.01, 10))
def test_inverse_cdfs_stay_finite_and_inside_bounds(u: float, low: float, width: float) -> None:
    spec = TruncatedNormal(distribution="truncated_normal", mean=low, std=width,
                           low=low - width, high=low + width / 2)
    value = float(sampling.inverse_cdf(spec, np.array([u]))[0])
    assert low - width <= value <= low + width / 2
    normal = float(sampling.inverse_cdf(Normal(distribution="normal", mean=low, std=width),
                                        np.array([u]))[0])
    assert math.isfinite(normal)


def truncated(mean: float, std: float, low: float, high: float) -> TruncatedNormal:
    return TruncatedNormal(distribution="truncated_normal", mean=mean, std=std, low=low,
                           high=high)


@pytest.mark.parametrize(("low", "high", "expected"), [
    # half-normal: sqrt(1 − 2/π)
    (0.0, 1e9, math.sqrt(1.0 - 2.0 / math.pi)),
    (-1e9, 0.0, math.sqrt(1.0 - 2.0 / math.pi)),
    # an interval 1e-5 σ wide: the density is flat across it, width / sqrt(12)
    (0.5, 0.50001, 1e-5 / math.sqrt(12.0)),
    # far in a tail the truncated normal is exponential with rate a: σ = (1 − 3/a² + …) / a
    (1000.0, 1001.0, (1.0 - 3e-6) / 1000.0),
    (-1001.0, -1000.0, (1.0 - 3e-6) / 1000.0),
])
def test_a_truncated_normal_on_one_side_of_its_mean_has_its_analytic_sigma(
        low: float, high: float, expected: float) -> None:
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # scipy's moments warn and give NaN here
        found = sampling.standard_deviation(truncated(0.0, 2.0, 2.0 * low, 2.0 * high))
    assert found == pytest.approx(2.0 * expected, rel=1e-9)


def test_a_truncated_normal_near_its_mean_has_scipy_s_sigma() -> None:
    from scipy import stats

    for low, high in ((3.0, 4.0), (0.1, 2.5), (-4.0, -3.0), (-1.0, 2.0)):
        assert sampling.standard_deviation(truncated(1.0, 0.5, 1.0 + 0.5 * low,
                                                     1.0 + 0.5 * high)) == pytest.approx(
            0.5 * float(stats.truncnorm.std(low, high)), rel=1e-10)


@pytest.mark.parametrize(("sigma", "finite"), [(90.0, True), (1000.0, False)])
def test_a_log_normal_too_wide_for_a_double_draws_inf_without_a_runtime_warning(
        sigma: float, finite: bool) -> None:
    """Its largest draws (and σ) are beyond a double: inf, which the parameter's range check
    refuses at the campaign's line (F110); scipy's "overflow encountered in exp" reached the
    console before."""
    import warnings

    spec = LogNormal(distribution="log_normal", median=250.0, sigma=sigma)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        top = sampling.inverse_cdf(spec, np.array([0.5, 1.0]))
        spread = sampling.standard_deviation(spec)
    assert top[0] == pytest.approx(250.0)
    assert math.isfinite(top[1]) is finite
    assert spread == math.inf
