"""The worst-case search without an FMU: the same search code driven by run risks known in
closed form, so where it must end up is known exactly (idefix_rules/campaign/worst)."""

from __future__ import annotations

import doctest
from collections.abc import Callable
from types import ModuleType

import numpy as np
import pytest
from scipy import stats

import idefix_rules.campaign.worst.boundary
import idefix_rules.campaign.worst.cross_entropy
import idefix_rules.campaign.worst.outcome
import idefix_rules.campaign.worst.search
import idefix_rules.campaign.worst.space
from idefix_rules.campaign.input.distributions import (
    Fixed,
    LogNormal,
    Normal,
    TruncatedNormal,
    Uniform,
)
from idefix_rules.campaign.input.sampling import cumulative, inverse_cdf
from idefix_rules.campaign.worst.boundary import Ray, runs_per_ray
from idefix_rules.campaign.worst.cross_entropy import ranking
from idefix_rules.campaign.worst.outcome import path_record
from idefix_rules.campaign.worst.search import TOWARD_WORST, PathSearch, SearchSettings
from idefix_rules.campaign.worst.space import QuantileSpace

# Two parameters like a slip and a lateral start offset: slip uniform in [0.05, 0.25], offset
# normal(0, 1 cm), and a third that does not matter.
SLIP = Uniform(distribution="uniform", low=0.05, high=0.25)
OFFSET = Normal(distribution="normal", mean=0.0, std=0.01)
NOISE = LogNormal(distribution="log_normal", median=250.0, sigma=0.4)
SPACE = QuantileSpace.of({"slip": SLIP, "offset": OFFSET, "noise": NOISE,
                          "fixed": Fixed(distribution="fixed", value=3.0)})

# Run risk: the larger of slip / 22 % and offset / 1.5 cm, capped at 1 (two indices with
# weight 1). Critical where slip >= 0.22 (quantile 0.85, z = 1.036) or offset >= 1.5 cm
# (z = 1.5).
SLIP_LIMIT, OFFSET_LIMIT = 0.22, 0.015
Z_SLIP = float(stats.norm.ppf((SLIP_LIMIT - 0.05) / 0.2))
Z_OFFSET = OFFSET_LIMIT / 0.01


def closed_form_risk(points: np.ndarray) -> tuple[np.ndarray, list[str | None]]:
    values = SPACE.values(points)
    slip = values["slip"] / SLIP_LIMIT
    offset = np.clip(values["offset"] / OFFSET_LIMIT, 0.0, None)
    risk = np.minimum(np.maximum(slip, offset), 1.0)
    return risk, ["I_s" if s >= o else "I_y" for s, o in zip(slip, offset, strict=True)]


def drive(search: PathSearch,
          risk: Callable[[np.ndarray], tuple[np.ndarray, list[str | None]]]) -> int:
    batches = 0
    while len(points := search.ask()):
        search.tell(*risk(points))
        batches += 1
    return batches


def new_search(runs: int = 150, seed: int = 7, **settings: float) -> PathSearch:
    nominal_risk, dominant = closed_form_risk(SPACE.nominal()[None, :])
    return PathSearch(SPACE, SearchSettings(runs=runs, **settings),  # type: ignore[arg-type]
                      np.random.default_rng(seed), float(nominal_risk[0]), dominant[0])


@pytest.mark.parametrize("module", [idefix_rules.campaign.worst.space,
                                    idefix_rules.campaign.worst.cross_entropy,
                                    idefix_rules.campaign.worst.boundary,
                                    idefix_rules.campaign.worst.search,
                                    idefix_rules.campaign.worst.outcome])
def test_docstring_examples(module: ModuleType) -> None:
    failures, tried = doctest.testmod(module)
    assert tried > 0 and failures == 0


def test_the_space_leaves_out_fixed_parameters_and_maps_back_into_each_support() -> None:
    assert SPACE.names == ("slip", "offset", "noise")
    far = SPACE.values(np.array([[-40.0, 40.0, -40.0]]))
    assert 0.05 <= far["slip"][0] <= 0.25 and np.isfinite(far["offset"][0])
    assert far["noise"][0] > 0
    assert SPACE.nominal() == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)
    assert SPACE.bound == pytest.approx(3.719, abs=1e-3)


@pytest.mark.parametrize("spec", [
    Normal(distribution="normal", mean=1.0, std=0.5),
    TruncatedNormal(distribution="truncated_normal", mean=1.0, std=0.5, low=0.2, high=1.3),
    Uniform(distribution="uniform", low=-2.0, high=4.0),
    LogNormal(distribution="log_normal", median=250.0, sigma=0.4),
])
def test_cumulative_inverts_the_inverse_cdf(spec: object) -> None:
    quantiles = np.array([1e-4, 0.1, 0.5, 0.85, 0.9999])
    assert cumulative(spec, inverse_cdf(spec, quantiles)) == pytest.approx(  # type: ignore
        quantiles, abs=1e-9)


def test_an_asymmetric_truncated_normal_has_its_nominal_off_the_median() -> None:
    spec = TruncatedNormal(distribution="truncated_normal", mean=1.0, std=0.5, low=0.2,
                           high=1.3)
    space = QuantileSpace.of({"k": spec})
    nominal = space.values(space.nominal()[None, :])["k"][0]
    assert nominal == pytest.approx(1.0) and space.nominal()[0] > 0.3


def test_the_tail_probability_is_the_share_of_campaign_worlds_as_far_out() -> None:
    rng = np.random.default_rng(4)
    worlds = rng.standard_normal((200_000, 3))
    point = np.array([1.2, -0.8, 1.9])
    share = float(np.mean(np.sum(worlds ** 2, axis=1) >= np.sum(point ** 2)))
    assert SPACE.tail_probability(point) == pytest.approx(share, abs=0.003)


def test_ties_go_to_the_world_nearest_the_nominal_one_and_failed_runs_come_last() -> None:
    points = np.array([[3.0, 0.0], [1.0, 0.0], [2.0, 0.0], [0.5, 0.0]])
    scores = np.array([1.0, 1.0, np.nan, 0.9995])  # within 0.1 percentage point of 1
    assert ranking(scores, points, np.zeros(2)).tolist() == [3, 1, 0, 2]


def test_the_search_finds_the_most_likely_critical_world_and_brackets_the_boundary() -> None:
    search = new_search()
    drive(search, closed_form_risk)
    assert search.used <= 150
    worst = search.worst
    assert worst.risk == 1.0
    # the critical world nearest the nominal one is on the slip axis at z = 1.036: the search
    # ends near it, on the slip's side (the boundary's rays find it exactly)
    assert Z_SLIP <= worst.z[0] < Z_SLIP + 0.6
    assert abs(worst.z[1]) < 1.0 and abs(worst.z[2]) < 1.0
    rays = {ray.label: ray for ray in search.rays}
    assert set(rays) == {TOWARD_WORST, "slip up", "offset up"}
    # along each ray the true crossing is inside the bracket, which is 1/64 of the ray
    truth = {"slip up": Z_SLIP, "offset up": Z_OFFSET}
    direction = rays[TOWARD_WORST].direction
    truth[TOWARD_WORST] = min(Z_SLIP / direction[0] if direction[0] > 0 else np.inf,
                              Z_OFFSET / direction[1] if direction[1] > 0 else np.inf)
    for label, ray in rays.items():
        low, high = ray.bracket or (np.nan, np.nan)
        assert low <= truth[label] <= high, label
        assert high - low <= ray.end / 64 + 1e-9, label


def test_the_record_names_the_boundary_and_the_smallest_change() -> None:
    search = new_search()
    drive(search, closed_form_risk)
    record = path_record("p", search)
    change = record["smallest_change"]
    assert change["distance"] == pytest.approx(Z_SLIP, abs=0.05)
    slip = change["world"]["parameters"]["slip"]
    assert slip["value"] == pytest.approx(SLIP_LIMIT, abs=0.005)
    assert slip["quantile"] == pytest.approx(0.85, abs=0.01)
    assert record["worst"]["risk"] == 1.0 and record["critical"]
    assert record["runs_used"] == record["search_runs"] + record["boundary_runs"]
    offset = next(b for b in record["boundaries"] if b["direction"] == "offset up")
    assert offset["critical_world"]["parameters"]["offset"]["value"] == pytest.approx(
        OFFSET_LIMIT, abs=0.0005)
    assert offset["last_safe_world"]["parameters"]["offset"]["value"] < OFFSET_LIMIT


def test_the_same_seed_asks_for_the_same_worlds_and_another_for_others() -> None:
    first, again, other = new_search(seed=3), new_search(seed=3), new_search(seed=4)
    for search in (first, again, other):
        drive(search, closed_form_risk)
    assert np.array_equal(np.array([p.z for p in first.points]),
                          np.array([p.z for p in again.points]))
    assert not np.array_equal(np.array([p.z for p in first.points])[:10],
                              np.array([p.z for p in other.points])[:10])


def test_the_search_climbs_a_smooth_risk_higher_than_four_times_its_runs_of_monte_carlo(
        ) -> None:
    # risk grows with slip and falls with the offset, never critical (highest 0.872 at the
    # corner of the box): no boundary is searched
    def smooth(points: np.ndarray) -> tuple[np.ndarray, list[str | None]]:
        return 0.5 + 0.05 * points[:, 0] - 0.05 * points[:, 1], ["I"] * len(points)

    search = new_search(runs=150)
    drive(search, smooth)
    searched = search.used
    assert search.rays == [] and searched == 150 - search.settings.boundary_runs(3)
    campaign = np.random.default_rng(0).standard_normal((4 * searched, 3))
    assert search.worst.risk > smooth(campaign)[0].max() + 0.03
    record = path_record("p", search)
    assert record["smallest_change"] is None and not record["critical"]


def test_a_nominal_world_already_critical_needs_no_change() -> None:
    search = PathSearch(SPACE, SearchSettings(runs=150), np.random.default_rng(1), 1.0, "I_s")
    drive(search, lambda points: (np.ones(len(points)), ["I_s"] * len(points)))
    assert search.rays == []
    assert search.worst.row == -1  # the nominal world itself: nearest of the equally risky
    assert path_record("p", search)["smallest_change"] == {"direction": None, "distance": 0.0,
                                                            "world": None}


def test_failed_runs_are_neither_worst_nor_critical() -> None:
    def failing(points: np.ndarray) -> tuple[np.ndarray, list[str | None]]:
        risk, dominant = closed_form_risk(points)
        risk[points[:, 1] > 1.0] = np.nan  # runs far out on the offset fail
        return risk, dominant

    search = new_search()
    drive(search, failing)
    assert np.isfinite(search.worst.risk)
    assert path_record("p", search)["failed_runs"] > 0


def test_the_budget_is_kept_and_the_minimum_explained() -> None:
    settings = SearchSettings(runs=100)
    assert settings.population(3) == 12 and settings.first_generation(3) == 24
    assert settings.boundary_runs(3) == 3 * runs_per_ray(3) == 30
    assert settings.minimum_runs(3) == 66
    assert settings.minimum_runs(6) == 48 + 24 + 30


def test_a_ray_with_a_critical_stretch_nearer_than_its_first_step_keeps_the_first_seen() -> None:
    ray = Ray("r", np.zeros(1), np.ones(1), end=4.0, threshold=1.0)
    while steps := ray.ask():
        ray.tell(steps, [1.0 if 0.2 < t < 0.5 or t >= 3.0 else 0.0 for t in steps])
    low, high = ray.bracket or (0.0, 0.0)
    assert 2.9 < low <= 3.0 <= high < 3.1
