"""Wrong decisions of adaptive campaigns on synthetic streams of known means, 2000 simulated
campaigns per setting (idefix_rules/campaign/statistics/error_rates.py; the table is printed by
benchmarks/bench_error_rates.py and copied into docs/campaign-format.md)."""

from __future__ import annotations

import numpy as np
import pytest

from idefix_rules.campaign.statistics import bernoulli, error_rates, pairwise
from idefix_rules.campaign.statistics.sequential import first_rejection, plugin_bets, rejections

REPLICATIONS = 2000
# A wrong rate of at most α, measured on 2000 campaigns, lies below α + 3 standard errors.
TOLERANCE = error_rates.tolerance(REPLICATIONS)
SETTINGS = list(error_rates.settings())


@pytest.mark.parametrize("position", range(len(SETTINGS)),
                         ids=[f"{s[0]}: {s[1]}" for s in SETTINGS])
def test_wrong_decisions_are_at_most_alpha(position: int) -> None:
    setting, truth, wrong, simulate = SETTINGS[position]
    row = error_rates._row(setting, truth, wrong, simulate, REPLICATIONS, 20261127 + position)
    assert row.wrong <= error_rates.ALPHA + TOLERANCE, row


def test_zero_events_pass_at_the_first_look_after_316_runs() -> None:
    setting, truth, wrong, simulate = SETTINGS[0]
    row = error_rates._row(setting, truth, wrong, simulate, 200, 1)
    assert row.decided == 1.0 and row.mean_runs == 320  # looks every 32 runs: 320 >= 316


def test_without_the_budget_the_same_family_is_wrong_too_often() -> None:
    """Every bound at α, 15 statistics at their limits: the simulation sees the excess the
    budget removes."""
    assert error_rates.unspent(REPLICATIONS).wrong > 2 * error_rates.ALPHA


def test_the_simulated_bounds_are_the_campaign_bounds() -> None:
    rng = np.random.default_rng(3)
    values = rng.beta(4.0, 6.0, (6, 200))
    for side, candidate in (("lower", 0.33), ("upper", 0.47)):
        batch = rejections(values, candidate, 0.05, side)[:, -1]
        for row, expected in zip(values, batch, strict=True):
            bets = plugin_bets(row, 0.05, two_sided=False)
            assert (first_rejection(row, bets, np.array([candidate]), 0.05, side)[0]
                    <= row.size) == expected
    draws = (rng.random((6, 200)) < 0.06).astype(float)
    outcome = error_rates.chance_rule(draws, 0.03, 0.0, (0.05, 0.05), [200]).outcome
    for row, found in zip(draws, outcome, strict=True):
        low, high = bernoulli.bounds(row, 0.05, 0.05, sequential=True)
        expected = "pass" if high < 0.03 else "fail" if low > 0.03 else "open"
        assert found == expected
    first, second = error_rates.worlds(rng, (6, 200), 0.03)
    outcome = error_rates.pair(first, second, 0.05, 0.02, [200]).outcome
    rows = np.arange(200)
    for a, b, found in zip(first, second, outcome, strict=True):
        assert pairwise.compare("a", "b", (rows, a), (rows, b), 0.05, 0.02).outcome == found

