"""Ranks on paired differences: the confidence sequence of per-world risk differences, ties
within the indifference margin, and its error rate on synthetic streams of known means."""

from __future__ import annotations

import numpy as np
import pytest

from idefix_rules.campaign.statistics import pairwise

ALPHA = 0.05
MARGIN = 0.02
LOOKS = range(32, 401, 32)  # an adaptive campaign's looks up to a 400-run cap
REPLICATIONS = 300
# Binomial spread of an error rate of α over the replications, three times.
TOLERANCE = 3.0 * (ALPHA * (1 - ALPHA) / REPLICATIONS) ** 0.5


def worlds(rng: np.random.Generator, gap: float, runs: int = 400) -> tuple[np.ndarray, ...]:
    """Run risks of two paths in the same worlds: a shared world term and each path's own
    noise, the second path's mean ``gap`` above the first's (no clipping: the means are exact)."""
    world = 0.3 * rng.uniform(-1, 1, runs)
    first = 0.5 + world + 0.1 * rng.uniform(-1, 1, runs)
    second = 0.5 + gap + world + 0.1 * rng.uniform(-1, 1, runs)
    return first, second


def first_decision(first: np.ndarray, second: np.ndarray, margin: float) -> str:
    """The first decided outcome over the looks (open at the cap): what a campaign stops on."""
    rows = np.arange(first.size)
    for look in LOOKS:
        pair = pairwise.compare("a", "b", (rows[:look], first[:look]),
                                (rows[:look], second[:look]), ALPHA, margin)
        if pair.settled:
            return pair.outcome
    return pairwise.OPEN


@pytest.mark.parametrize(("gap", "wrong"), [
    # equal means: ordering either way is wrong, a tie (or open) is right
    (0.0, {pairwise.FIRST_SAFER, pairwise.SECOND_SAFER}),
    # the second path riskier by just more than the margin: a tie or the reverse order is wrong
    (MARGIN * 1.25, {pairwise.TIED, pairwise.SECOND_SAFER}),
])
def test_wrong_decisions_are_at_most_alpha(gap: float, wrong: set[str]) -> None:
    rng = np.random.default_rng(19)
    outcomes = [first_decision(*worlds(rng, gap), MARGIN) for _ in range(REPLICATIONS)]
    errors = sum(outcome in wrong for outcome in outcomes) / REPLICATIONS
    assert errors <= ALPHA + TOLERANCE
    # and the sequence decides: most campaigns end on the right answer before the cap
    right = pairwise.TIED if gap == 0 else pairwise.FIRST_SAFER
    assert sum(outcome == right for outcome in outcomes) / REPLICATIONS >= 0.5


def test_an_interval_inside_the_margin_is_a_tie_and_outside_an_order() -> None:
    assert pairwise.outcome(-0.019, 0.019, 0.02) == pairwise.TIED
    assert pairwise.outcome(-0.02, 0.019, 0.02) == pairwise.OPEN  # on the margin: not inside
    assert pairwise.outcome(-0.05, -0.001, 0.02) == pairwise.FIRST_SAFER
    assert pairwise.outcome(0.001, 0.05, 0.02) == pairwise.SECOND_SAFER
    assert pairwise.outcome(-0.001, 0.001, 0.0) == pairwise.OPEN  # no margin: never a tie
    assert pairwise.outcome(0.005, 0.015, 0.02) == pairwise.TIED  # inside the margin wins


def test_the_difference_is_taken_over_the_worlds_both_paths_completed() -> None:
    first = (np.array([0, 1, 2, 4]), np.array([0.2, 0.9, 0.3, 0.1]))
    second = (np.array([1, 2, 3, 4]), np.array([0.5, 0.5, 0.5, 0.1]))
    pair = pairwise.compare("a", "b", first, second, ALPHA, MARGIN)
    assert (pair.shared, pair.first_safer, pair.second_safer, pair.equal) == (3, 1, 1, 1)
    assert pair.difference == pytest.approx((0.4 - 0.2 + 0.0) / 3)
    assert pair.low <= pair.difference <= pair.high


def test_every_pair_is_compared_and_only_the_first_contender_against_the_others_is_needed(
        ) -> None:
    rows = np.arange(64)
    risks = {name: (rows, np.full(64, 0.5)) for name in "abc"}
    pairs = pairwise.compare_pairs(risks, ["a", "b", "c"], alpha=0.05 / 3, margin=0.0)
    assert [(p.first, p.second) for p in pairs] == [("a", "b"), ("a", "c"), ("b", "c")]
    assert all(p.confidence == pytest.approx(1 - 0.05 / 3) for p in pairs)
    assert pairwise.compare_pairs({"a": risks["a"]}, ["a"], 0.05, 0.0) == []
    # the decision depends on the chain to send against each other contender only
    marked = pairwise.mark_needed(pairs, ["b", "a"])
    assert [(p.first, p.second, p.needed) for p in marked] == [
        ("a", "b", True), ("a", "c", False), ("b", "c", False)]


def test_tied_neighbours_share_a_rank_within_the_same_verdict() -> None:
    rows = np.arange(400)
    same = {name: (rows, np.full(400, 0.7)) for name in ("a", "b", "c")}
    pairs = pairwise.compare_pairs(same, ["a", "b", "c"], ALPHA / 3, MARGIN)
    ranks, ties = pairwise.shared_ranks(["a", "b", "c"], {"a": True, "b": True, "c": True},
                                        pairs)
    assert ranks == {"a": 1, "b": 1, "c": 1} and ties == [("a", "b"), ("b", "c")]
    ranks, ties = pairwise.shared_ranks(["a", "b", "c"], {"a": True, "b": False, "c": False},
                                        pairs)
    assert ranks == {"a": 1, "b": 2, "c": 2} and ties == [("b", "c")]


def test_the_pairs_shown_are_the_neighbours_and_then_every_pair_the_decision_waits_on() -> None:
    from idefix_rules.campaign.statistics.pairwise import PairComparison, shown

    def pair(first: str, second: str, outcome: str, needed: bool) -> PairComparison:
        return PairComparison(first, second, 32, 20, 12, 0, -0.01, -0.05, 0.03, 0.99, 0.0,
                              outcome, needed)

    ranking = ["approach", "smooth", "wide", "straight"]
    pairs = [pair("approach", "smooth", "first safer", True),
             pair("smooth", "wide", "open", False),
             pair("wide", "straight", "first safer", False),
             pair("wide", "approach", "open", True),      # the decision waits on it
             pair("smooth", "straight", "open", False)]   # no decision depends on it
    found = [(above, p.first, p.second) for above, p in shown(ranking, pairs)]
    assert found == [("approach", "approach", "smooth"), ("smooth", "smooth", "wide"),
                     ("wide", "wide", "straight"), ("approach", "wide", "approach")]
