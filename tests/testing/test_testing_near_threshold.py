"""Near-the-threshold draws: both sides of a level are hit, and a property about a stricter
limit is not vacuous on them (where it is on plain realistic runs)."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings

from idefix_rules.rulebook import check_text
from idefix_rules.rulebook.compile import compile_rulebook
from idefix_rules.rulebook.strategies import RunRanges, realistic_runs
from idefix_rules.testing.near_threshold import near_threshold_runs
from idefix_rules.testing.properties import check_direction

RULEBOOK = """rulebook "tilt" version "1.0.0"
purpose "A roll index"

const critical_tilt = 10 deg

index I_psi "roll deviation" {
  value  = max over time (abs(roll - ref.roll))
  limit  = critical_tilt
  weight = 1
}

verdict acceptable_risk: require risk <= 70 %
"""
OLD = compile_rulebook(check_text(RULEBOOK, "tilt.rules").checked)
# stricter by 11 %, a little more than the near draws' 10 % margin: a draw at the margin's
# very edge (d = 0.1, a bound hypothesis likes to draw) sits exactly on a 10 % stricter limit
# and still passes it
NEW = compile_rulebook(check_text(RULEBOOK.replace("= 10 deg", "= 8.9 deg"),
                                  "tilt.rules").checked)
RANGES = RunRanges(runs=(1, 1), stuck=False, hits=0)
SETTINGS = settings(max_examples=40, derandomize=True, deadline=None, database=None,
                    suppress_health_check=list(HealthCheck))


def _flips(strategy) -> dict[str, int]:
    """Draws where the path passed under OLD and fails under NEW (and all draws)."""
    counts = {"draws": 0, "pass_to_fail": 0, "passed": 0}

    @SETTINGS
    @given(strategy)
    def run(batch):
        before, after = check_direction(OLD, NEW, "stricter", *batch)
        counts["draws"] += 1
        counts["passed"] += before
        counts["pass_to_fail"] += before and not after

    run()
    return counts


def test_a_stricter_limit_turns_passing_paths_into_failing_ones_near_the_threshold():
    # risk just inside or outside the verdict's 70 %: an 11 % stricter limit flips about a
    # third of the draws; plain realistic runs (the same seed and count) almost never
    near = _flips(near_threshold_runs(OLD, "I_psi", level=0.7, ranges=RANGES))
    plain = _flips(realistic_runs(RANGES))
    assert near["draws"] == plain["draws"] == 40
    # every passing near draw sits within 10 % below the limit, so an 11 % stricter limit fails
    # each of them (how many of the 40 land inside is the seed's choice); plain draws mostly
    # pass farther from it and many of them stay passing (26 of 26 against 6 of 24 here)
    assert near["passed"] >= 3
    assert near["pass_to_fail"] == near["passed"]
    assert plain["passed"] >= 3 and plain["pass_to_fail"] < plain["passed"]


@SETTINGS
@given(near_threshold_runs(OLD, "I_psi", margin=0.05, ranges=RANGES))
def test_draws_land_within_the_margin_of_the_limit(batch):
    signals, context = batch
    ratio = float(OLD.evaluate(signals, context).raw["I_psi"].max()) / np.radians(10)
    assert 0.95 - 1e-9 <= ratio <= 1.05 + 1e-9 and ratio != 1.0  # margin inclusive, in floats


def test_events_count_each_side(pytester):
    pytester.makepyfile(test_sides=f'''
from hypothesis import given, settings
from idefix_rules.rulebook import check_text
from idefix_rules.rulebook.compile import compile_rulebook
from idefix_rules.rulebook.strategies import RunRanges
from idefix_rules.testing.near_threshold import near_threshold_runs

COMPILED = compile_rulebook(check_text({RULEBOOK!r}, "tilt.rules").checked)

@settings(max_examples=20, derandomize=True, deadline=None, database=None)
@given(near_threshold_runs(COMPILED, "I_psi", ranges=RunRanges(runs=(1, 1))))
def test_sides(batch):
    pass
''')
    result = pytester.runpytest("-p", "no:cacheprovider", "--hypothesis-show-statistics")
    result.assert_outcomes(passed=1)
    events = [line for line in result.stdout.lines if "% , I_psi:" in line.replace("%,", "% ,")]
    seen = sorted(line.split(", ", 1)[1] for line in events)
    # both sides are drawn; a draw the strategy could not land says so as its own event
    assert {"I_psi: just inside 1", "I_psi: just outside 1"} <= set(seen), seen
    assert set(seen) <= {"I_psi: just inside 1", "I_psi: just outside 1",
                         "I_psi: cannot be moved to 1"}, seen
