"""Confidence sequences and the stopping rule: error rates by simulation on synthetic data.

A decision is wrong when the interval excludes the true mean (then the side of the threshold it
settles on can be the wrong one). With the true mean *at* the threshold every decision is
wrong, the hardest case; the fraction of such sequences must stay at most 1 - confidence even
though the interval is looked at after every run.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import event, example, given, settings
from hypothesis import strategies as st

from idefix_rules.campaign.statistics.bernoulli import fixed_upper, sequential_upper
from idefix_rules.campaign.statistics.runs_needed import runs_needed
from idefix_rules.campaign.statistics.sequential import (
    BLOCK_RUNS,
    asymptotic_interval,
    betting_interval,
    candidate_rejected,
    first_rejection,
    plugin_bets,
    threshold_rejected,
)
from idefix_rules.campaign.statistics.stopping import NOT_SENT, PASSES, PASSES_WAIVED, _order, tiers
from idefix_rules.rulebook.results import RuleResult
from idefix_rules.rulebook.statistics import student_interval, wilson_interval

ALPHA = 0.05
RUNS = 400
REPLICATIONS = 600


def ever_wrong_sequential(draw: np.ndarray, truth: float) -> bool:
    """The confidence sequence excluded the true mean at some run count ≤ len(draw)."""
    return threshold_rejected(draw, truth, ALPHA)


def ever_wrong_fixed(draw: np.ndarray, truth: float, bernoulli: bool, every: int) -> bool:
    """A fixed-count 95 % interval, re-checked after every ``every`` runs, excluded it."""
    for n in range(every, draw.size + 1, every):
        head = draw[:n]
        estimate = (wilson_interval(int(head.sum()), n, 1 - ALPHA) if bernoulli
                    else student_interval(head, 1 - ALPHA, (0.0, 1.0)))
        if not estimate.low <= truth <= estimate.high:
            return True
    return False


@pytest.mark.parametrize(("kind", "truth"), [("bernoulli", 0.01), ("bernoulli", 0.05),
                                             ("bernoulli", 0.3), ("beta", 2 / 7)])
def test_wrong_decisions_stay_below_one_minus_confidence(kind: str, truth: float) -> None:
    rng = np.random.default_rng(20261122)
    wrong = 0
    for _ in range(REPLICATIONS):
        draw = ((rng.random(RUNS) < truth).astype(float) if kind == "bernoulli"
                else rng.beta(2.0, 5.0, RUNS))
        wrong += ever_wrong_sequential(draw, truth)
    assert wrong / REPLICATIONS <= ALPHA, (kind, truth, wrong)


def test_a_fixed_count_interval_checked_after_every_batch_is_wrong_too_often() -> None:
    """The same simulation notices a method that is not valid under repeated looks."""
    rng = np.random.default_rng(7)
    truth = 0.3
    wrong = sum(ever_wrong_fixed((rng.random(RUNS) < truth).astype(float), truth, True, 10)
                for _ in range(REPLICATIONS))
    assert wrong / REPLICATIONS > 2 * ALPHA


def test_the_interval_is_what_the_threshold_test_says() -> None:
    rng = np.random.default_rng(3)
    for n, p in ((50, 0.2), (200, 0.02), (400, 0.0), (120, 0.9)):
        draw = (rng.random(n) < p).astype(float)
        low, high = betting_interval(draw, ALPHA)
        assert low <= draw.mean() <= high
        for threshold in np.linspace(0.0, 1.0, 41):
            if min(abs(threshold - low), abs(threshold - high)) < 1e-6:
                continue
            assert threshold_rejected(draw, threshold, ALPHA) == (
                not low <= threshold <= high), (n, p, threshold)


def test_zero_events_decide_a_one_percent_rule_only_after_enough_runs() -> None:
    # the betting sequence (for means that are not chances): at 400 runs without a stuck run
    # the upper bound is still above 1 %, at 600 below; chances use the exact bounds instead
    # (test_campaign_bernoulli.py: 316 runs)
    assert betting_interval(np.zeros(400), ALPHA)[1] > 0.01
    assert betting_interval(np.zeros(600), ALPHA)[1] < 0.01


@settings(max_examples=60, deadline=None)
@given(st.integers(2, 300), st.floats(0.0, 1.0), st.integers(0, 2**31))
# a random seed found it: the sequence misses the mean early (0.24-0.28 after 60 runs of a
# 0.13 stream), its running intersection is empty after 100, and the interval must stay where
# it last was instead of jumping to the mean
@example(n=60, p=0.1328125, seed=136)
def test_intervals_only_shrink_as_runs_are_added(n: int, p: float, seed: int) -> None:
    draw = (np.random.default_rng(seed).random(n + 40) < p).astype(float)
    before = betting_interval(draw[:n], ALPHA)
    after = betting_interval(draw, ALPHA)
    event("decided at 1 %" if after[1] < 0.01 or after[0] > 0.01 else "not decided at 1 %")
    tolerance = 1e-6  # bounds are found by bisection
    assert after[0] >= before[0] - tolerance and after[1] <= before[1] + tolerance


def test_asymptotic_interval_narrows_with_runs_and_covers_the_mean() -> None:
    rng = np.random.default_rng(5)
    values = rng.normal(0.9, 0.05, 2000)
    small, large = asymptotic_interval(values[:100], ALPHA), asymptotic_interval(values, ALPHA)
    assert small[0] < 0.9 < small[1] and large[0] < 0.9 < large[1]
    assert large[1] - large[0] < small[1] - small[0]
    assert asymptotic_interval(values[:1], ALPHA) == (-math.inf, math.inf)


def rule(statistic: str, value: float, threshold: float, margin: float = 0.0) -> RuleResult:
    return RuleResult("r", True, False, statistic, value, (0.0, 1.0), threshold, None, "m",
                      margin=margin)


class Chances:
    """The part of a RunEvaluation that runs_needed reads for a chance."""

    def __init__(self, values: np.ndarray) -> None:
        self.chances = {"stuck": values}
        self.values: dict[str, np.ndarray] = {}


def test_runs_needed_for_a_rare_event_matches_the_bound_it_estimates() -> None:
    none_stuck = Chances(np.zeros(200, dtype=bool))
    levels = (ALPHA, ALPHA)
    # 200 runs, none stuck, rule <= 1 %: the exact bound needs 299 runs at a fixed count
    fixed = runs_needed(rule("chance(stuck)", 0.0, 0.01), none_stuck, levels, sequential=False)
    assert fixed is not None and 299 <= fixed <= 302
    assert fixed_upper(0, fixed, ALPHA) < 0.01
    sequential = runs_needed(rule("chance(stuck)", 0.0, 0.01), none_stuck, levels,
                             sequential=True)
    assert sequential is not None and 316 <= sequential <= 319
    assert sequential_upper(np.zeros(sequential), ALPHA) < 0.01
    # an estimate sitting on the threshold is never decided, unless a margin settles it
    half = Chances(np.arange(200) % 2 == 0)
    assert runs_needed(rule("chance(stuck)", 0.5, 0.5), half, levels, sequential=True) is None
    near = runs_needed(rule("chance(stuck)", 0.5, 0.5, margin=0.1), half, levels,
                       sequential=True)
    assert near is not None and 200 < near < 2000


def test_a_chain_that_passes_only_under_a_waiver_ranks_between_passing_and_failing() -> None:
    def verdict(passed: bool, decided: bool = True) -> SimpleNamespace:
        return SimpleNamespace(passed=passed, decided=decided)

    passing, failing, open_ = verdict(True), verdict(False), verdict(False, decided=False)
    assert tiers(passing, passing) == {PASSES}
    assert tiers(failing, failing) == {NOT_SENT}
    assert tiers(failing, passing) == {PASSES_WAIVED}  # its failures are waived
    assert tiers(open_, open_) == {PASSES, PASSES_WAIVED, NOT_SENT}
    assert tiers(open_, passing) == {PASSES, PASSES_WAIVED}  # its open rule is waived
    waived = {PASSES_WAIVED}
    # a chain that passes is sent before one that passes only under a waiver, whatever
    # their risks; two of them are ordered by risk, like two passing chains
    assert _order(({PASSES}, (0.5, 0.6)), (waived, (0.1, 0.2))) == -1
    assert _order((waived, (0.5, 0.6)), ({NOT_SENT}, (0.1, 0.2))) == -1
    assert _order((waived, (0.1, 0.2)), (waived, (0.3, 0.4))) == -1
    assert _order((waived, (0.1, 0.35)), (waived, (0.3, 0.4))) is None
    assert _order(({PASSES, NOT_SENT}, (0.5, 0.6)), (waived, (0.1, 0.2))) is None


def test_order_is_settled_only_when_every_open_outcome_agrees() -> None:
    passes, fails, open_ = {PASSES}, {NOT_SENT}, {PASSES, NOT_SENT}
    assert _order((passes, (0.1, 0.2)), (fails, (0.0, 0.05))) == -1  # passing first
    assert _order((fails, (0.1, 0.2)), (fails, (0.3, 0.4))) == -1  # apart: lower first
    assert _order((fails, (0.1, 0.35)), (fails, (0.3, 0.4))) is None  # overlapping
    assert _order((open_, (0.1, 0.2)), (fails, (0.3, 0.4))) == -1  # above either way
    assert _order((open_, (0.5, 0.6)), (fails, (0.3, 0.4))) is None  # depends on the verdict


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 400), st.floats(0.0, 1.0, allow_subnormal=False), st.floats(1e-6, 0.5),
       st.sampled_from(["lower", "upper"]), st.booleans(), st.integers(0, 2**31))
@example(runs=1000, candidate=0.0, alpha=0.05, side="lower", binary=True, seed=1)
@example(runs=1000, candidate=1.0, alpha=0.05, side="upper", binary=True, seed=2)
def test_one_candidate_is_rejected_as_among_many(runs: int, candidate: float, alpha: float,
                                                  side: str, binary: bool, seed: int) -> None:
    """The bisection's one-candidate test says what first_rejection says (same arithmetic)."""
    rng = np.random.default_rng(seed)
    x = (rng.random(runs) < rng.random()).astype(float) if binary else rng.beta(0.5, 2.0, runs)
    for fixed in (None, runs):
        bets = plugin_bets(x, alpha, two_sided=False, fixed_runs=fixed)
        for probe in (candidate, float(x.mean()) if runs else 0.5):
            expected = bool(first_rejection(x, bets, np.array([probe]), alpha, side)[0]
                            <= x.size)
            assert candidate_rejected(x, bets, probe, alpha, side) == expected


def test_one_candidate_on_a_long_stream_sums_its_capital_by_blocks() -> None:
    rng = np.random.default_rng(5)
    x = rng.beta(0.5, 2.0, BLOCK_RUNS + 300)
    bets = plugin_bets(x, ALPHA, two_sided=False)
    for side in ("lower", "upper"):
        for probe in np.linspace(0.0, 1.0, 33):
            assert candidate_rejected(x, bets, float(probe), ALPHA, side) == bool(
                first_rejection(x, bets, np.array([probe]), ALPHA, side)[0] <= x.size)
