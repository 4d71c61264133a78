"""Exact bounds for chances: Clopper–Pearson at a fixed run count, the mixture martingale in
adaptive campaigns, and the one-sided betting bounds of bounded means."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st
from scipy import stats

from idefix_rules.campaign.statistics import bernoulli
from idefix_rules.campaign.statistics.sequential import betting_interval, one_sided_bound

ALPHA = 0.05


def test_zero_events_pass_a_one_percent_rule_after_316_runs_sequentially_299_fixed():
    assert bernoulli.runs_to_pass(0.01, ALPHA) == 316
    assert bernoulli.sequential_upper(np.zeros(316), ALPHA) < 0.01
    assert bernoulli.sequential_upper(np.zeros(315), ALPHA) > 0.01
    # the exact fixed-count bound: 0.99^299 <= 0.05 < 0.99^298
    assert bernoulli.runs_to_pass(0.01, ALPHA, sequential=False) == 299
    assert bernoulli.fixed_upper(0, 299, ALPHA) < 0.01 < bernoulli.fixed_upper(0, 298, ALPHA)
    # the betting sequence these replace needed 489
    assert betting_interval(np.zeros(488), ALPHA)[1] > 0.01


def test_clopper_pearson_is_the_binomial_tail():
    for events, runs in ((0, 50), (3, 50), (49, 50), (50, 50)):
        high = bernoulli.fixed_upper(events, runs, ALPHA)
        low = bernoulli.fixed_lower(events, runs, ALPHA)
        if events < runs:
            assert stats.binom.cdf(events, runs, high) == pytest.approx(ALPHA)
        else:
            assert high == 1.0
        if events > 0:
            assert stats.binom.sf(events - 1, runs, low) == pytest.approx(ALPHA)
        else:
            assert low == 0.0


@pytest.mark.parametrize("sequential", [True, False])
def test_a_path_where_every_run_has_the_event_keeps_an_interval_of_some_width(sequential):
    low, high = bernoulli.bounds(np.ones(128), ALPHA, ALPHA, sequential)
    assert high == 1.0 and 0.95 < low < 0.99
    low, high = bernoulli.bounds(np.zeros(128), ALPHA, ALPHA, sequential)
    assert low == 0.0 and 0.01 < high < 0.05


@pytest.mark.parametrize("side", ["lower", "upper"])
def test_bounded_means_keep_an_interval_when_every_run_saturates(side):
    value = 1.0 if side == "lower" else 0.0
    bound = one_sided_bound(np.full(128, value), ALPHA, side, fixed_runs=128)
    assert 0.01 < abs(bound - value) < 0.05


def test_a_one_sided_bound_is_tighter_than_the_two_sided_interval_at_the_same_alpha():
    rng = np.random.default_rng(4)
    values = rng.beta(2.0, 5.0, 300)
    low, high = betting_interval(values, ALPHA)
    assert low < one_sided_bound(values, ALPHA, "lower") < values.mean()
    assert values.mean() < one_sided_bound(values, ALPHA, "upper") < high


@pytest.mark.parametrize("truth", [0.01, 0.05, 0.3])
def test_the_mixture_martingale_rejects_the_true_proportion_at_most_alpha_of_the_time(truth):
    """Ever rejected within 400 runs, looked at after every run, each side at α: vectorised
    over 2000 streams."""
    rng = np.random.default_rng(20261127)
    draws = rng.random((2000, 400)) < truth
    runs = np.arange(1, 401)
    events = np.cumsum(draws, axis=1)
    target = math.log(1 / ALPHA)
    below = (bernoulli.log_evidence_below(events, runs, truth) >= target).any(axis=1)
    above = (bernoulli.log_evidence_above(events, runs, truth) >= target).any(axis=1)
    tolerance = 3 * math.sqrt(ALPHA * (1 - ALPHA) / 2000)
    assert below.mean() <= ALPHA + tolerance and above.mean() <= ALPHA + tolerance


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 600), st.floats(0.0, 1.0), st.integers(0, 2**31))
def test_the_evidence_grows_with_the_limit_above_the_observed_share(runs, share, seed):
    """The rejected limits form one interval above the observed share, so bisection finds
    the bound."""
    events = int(np.random.default_rng(seed).binomial(runs, share))
    limits = np.linspace(events / runs, 1.0, 400)[1:-1]
    evidence = bernoulli.log_evidence_below(events, runs, limits)
    assert np.all(np.diff(evidence) >= -1e-9)


def test_the_sequential_bounds_only_tighten():
    rng = np.random.default_rng(8)
    draw = (rng.random(500) < 0.04).astype(float)
    uppers = [bernoulli.sequential_upper(draw[:n], ALPHA) for n in (50, 100, 200, 500)]
    lowers = [bernoulli.sequential_lower(draw[:n], ALPHA) for n in (50, 100, 200, 500)]
    assert uppers == sorted(uppers, reverse=True) and lowers == sorted(lowers)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 700), st.sampled_from([0.0, 0.002, 0.01, 0.05, 0.4, 0.97, 1.0]),
       st.integers(0, 2**31), st.sampled_from([0.05, 0.0125, 0.003]),
       st.sampled_from([0.999, 1.001]))
def test_testing_a_limit_directly_agrees_with_the_bound_either_side_of_it(
        runs, truth, seed, alpha, factor):
    """The direct test at a limit (the runs-needed estimate's) says what comparing the
    bisected bound with that limit says, with the limit just inside and just outside the
    bound, on both sides."""
    draw = (np.random.default_rng(seed).random(runs) < truth).astype(float)
    upper = bernoulli.sequential_upper(draw, alpha)
    lower = bernoulli.sequential_lower(draw, alpha)
    high_limit, low_limit = upper * factor, lower * factor
    event("the limit is above the upper bound" if high_limit > upper
          else "the limit is below the upper bound")
    assert bernoulli.sequential_upper_below(draw, high_limit, alpha) == (upper < high_limit)
    assert bernoulli.sequential_lower_above(draw, low_limit, alpha) == (lower > low_limit)


def test_a_boundary_looked_up_is_the_boundary_computed():
    """The boundaries kept from one look to the next are the ones bisection gives, whatever
    else was asked for with them."""
    events = np.array([0.0, 0.0, 3.0, 7.0, 0.0])
    runs = np.array([32.0, 544.0, 64.0, 100.0, 32.0])
    bernoulli._BOUNDARIES.clear()
    first = bernoulli._boundary(events, runs, ALPHA)
    again = bernoulli._boundary(events[::-1], runs[::-1], ALPHA)
    alone = [bernoulli._bisect(events[i:i + 1], runs[i:i + 1], ALPHA)[0] for i in range(5)]
    assert first.tolist() == alone and again.tolist() == alone[::-1]
    assert bernoulli._boundary(events, runs, 0.01)[0] > first[0]  # alpha is part of the key
