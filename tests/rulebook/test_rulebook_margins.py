"""Verdict indifference margins (syntax, checks, the fourth outcome) and the direction each
verdict judges its statistics in."""

import dataclasses

import pytest

from idefix_rules.rulebook.check import check
from idefix_rules.rulebook.compile import compile_rulebook
from idefix_rules.rulebook.format import format_rulebook
from idefix_rules.rulebook.judging import judging
from idefix_rules.rulebook.parser import parse_rulebook
from idefix_rules.rulebook.results import Estimate, PathStatistics

HEADER = 'rulebook "t" version "1.0.0"\npurpose "test"\n'
INDEX = """
index I_a { value = max over time (abs(pitch)) limit = 1 rad weight = 1 }
chance hit = any over parts (collision.hits[L3] > 0)
"""


def checked(rules: str):
    result = check(parse_rulebook(HEADER + INDEX + rules, "t.rules"))
    return result


def statistics(risk=(0.5, 0.5, 0.5), hit=(0.0, 0.0, 0.0), time=(100.0, 100.0, 100.0)
               ) -> PathStatistics:
    return PathStatistics(
        runs=100, failed_runs=0, confidence=0.95, risk=Estimate(*risk), risk_std=0.1,
        index_mean={"I_a": Estimate(*risk)}, index_max={"I_a": 1.0},
        chances={"hit": Estimate(*hit)}, time=Estimate(*time), energy=Estimate(1.0, 1.0, 1.0),
        dominant_counts={"I_a": 100})


def test_a_verdict_margin_parses_formats_and_round_trips():
    text = (HEADER + INDEX + "combine { verdict_indifference = 0.5 % }\n"
            'verdict rare: require chance(hit) <= 5 % indifference 1 % because "rarely"\n'
            "verdict plain: require risk <= 0.7 indifference 0.02\n")
    book = parse_rulebook(text, "t.rules")
    assert str(book.verdicts[0].indifference.value) == "1.0"
    assert book.verdicts[1].indifference.unit is None  # `0.7 indifference` is not a unit
    printed = format_rulebook(book)
    assert "verdict rare: require chance(hit) <= 5 % indifference 1 % because" in printed
    assert "verdict_indifference = 0.5 %" in printed
    assert parse_rulebook(printed, "t.rules") == book


def test_margins_resolve_per_verdict_with_the_default_for_ratios_only():
    result = checked("combine { verdict_indifference = 0.5 % }\n"
                     "verdict rare: require chance(hit) <= 5 %\n"
                     "verdict own: require risk <= 70 % indifference 2 %\n"
                     "verdict quick: require time <= 10 min\n"
                     "verdict slow_ok: require time <= 10 min indifference 30 s\n"
                     "verdict none: require risk <= 70 % indifference 0 %\n")
    assert result.ok, result.diagnostics
    assert result.checked.verdict_margins == pytest.approx(
        {"rare": 0.005, "own": 0.02, "quick": 0.0, "slow_ok": 30.0, "none": 0.0})


@pytest.mark.parametrize(("rule", "code"), [
    ("verdict v: require time <= 10 min indifference 2 %", "E411"),
    ("verdict v: require time <= 10 min and risk <= 70 % indifference 1 %", "E411"),
    ("verdict v: require risk <= 70 % indifference -1 %", "E412"),
    ("combine { verdict_indifference = 60 % }\nverdict v: require risk <= 70 %", "E412"),
    ("combine { verdict_indifference = 1 s }\nverdict v: require risk <= 70 %", "E204"),
])
def test_a_margin_of_the_wrong_dimension_or_range_is_an_error(rule, code):
    assert [d.code for d in checked(rule).diagnostics] == [code]


def test_within_the_margin_is_its_own_outcome_and_the_path_does_not_pass():
    rules = compile_rulebook(checked("verdict rare: require chance(hit) <= 5 % "
                                     "indifference 1 %\n").checked)
    near = rules.verdict(statistics(hit=(0.05, 0.042, 0.058)))
    [rule, _] = near.rules
    assert (rule.passed, rule.decided, rule.near, rule.margin) == (False, True, True, 0.01)
    assert "within the margin" in rule.message
    assert not near.passed and near.decided and near.marginal
    # an interval that also clears the limit passes: a pass is never turned into "near"
    cleared = rules.verdict(statistics(hit=(0.045, 0.041, 0.049)))
    assert cleared.passed and cleared.decided and not cleared.marginal
    # reaching past the margin on either side: not decided
    wide = rules.verdict(statistics(hit=(0.05, 0.03, 0.058)))
    assert not wide.decided and not wide.rules[0].near
    # a decided failure elsewhere makes the path fail, not marginal
    failing = compile_rulebook(checked(
        "verdict rare: require chance(hit) <= 5 % indifference 1 %\n"
        "verdict low: require risk <= 20 %\n").checked)
    verdict = failing.verdict(statistics(hit=(0.05, 0.042, 0.058)))
    assert not verdict.passed and verdict.decided and not verdict.marginal


def test_near_goes_through_not_and_or():
    rules = compile_rulebook(checked(
        "verdict v: require not (chance(hit) > 5 %) and risk <= 70 % indifference 1 %\n"
    ).checked)
    assert rules.verdict(statistics(hit=(0.05, 0.045, 0.055))).marginal
    # `and` with a decided failure: fails
    verdict = rules.verdict(statistics(risk=(0.9, 0.85, 0.95), hit=(0.05, 0.045, 0.055)))
    assert verdict.decided and not verdict.passed and not verdict.marginal


def test_the_ranking_puts_a_marginal_path_with_the_ones_that_do_not_pass():
    rules = compile_rulebook(checked("verdict rare: require chance(hit) <= 5 % "
                                     "indifference 1 %\n").checked)
    near = statistics(risk=(0.1, 0.1, 0.1), hit=(0.05, 0.042, 0.058))
    passing = statistics(risk=(0.6, 0.6, 0.6))
    assert rules.rank({"near": near, "passing": passing}) == ["passing", "near"]


def test_each_statistic_is_judged_in_the_direction_its_rules_compare_it():
    book = parse_rulebook(HEADER + INDEX + """
verdict a: require risk <= 70 % and chance(hit) < 5 %
verdict b: require not (time > 10 min)
verdict c: require 1 % <= mean(I_a)
verdict d: require runs >= 100 and max(I_a) < 1 and failed <= 1 %
verdict e: require abs(energy - 1 As) < 0.1 As or risk >= 10 %
""", "t.rules")
    found = judging(book)
    assert found.directions == {"risk": "both", "chance(hit)": "upper", "time": "upper",
                                "mean(I_a)": "lower", "failed": "upper", "energy": "both"}
    # one unit per comparison of a statistic with a limit, two per statistic judged both ways
    assert found.units == 2 + 1 + 1 + 1 + 2 + 1
    assert found.levels("risk", 0.05, 0.01) == (0.01, 0.01)
    assert found.levels("chance(hit)", 0.05, 0.01) == (0.01, 0.05)
    assert found.levels("mean(I_a)", 0.05, 0.01) == (0.05, 0.01)
    assert found.levels("chance(other)", 0.05, 0.01) == (0.05, 0.05)


def test_a_rulebook_without_margins_judges_as_before():
    rules = compile_rulebook(checked("verdict rare: require chance(hit) <= 5 %\n").checked)
    verdict = rules.verdict(statistics(hit=(0.05, 0.042, 0.058)))
    assert not verdict.decided and not verdict.marginal
    assert dataclasses.asdict(verdict.rules[0])["near"] is False


def test_a_chance_compared_with_zero_is_read_on_the_runs_themselves():
    rules = compile_rulebook(checked("verdict none_failed: require failed <= 0 %\n"
                                     "verdict no_hit: require chance(hit) == 0 %\n").checked)
    bounded = dataclasses.replace(statistics(hit=(0.0, 0.0, 0.03)),
                                  failed=Estimate(0.0, 0.0, 0.02))
    verdict = rules.verdict(bounded)
    assert verdict.passed and verdict.decided
    hit = dataclasses.replace(bounded, chances={"hit": Estimate(0.01, 0.001, 0.05)})
    assert not rules.verdict(hit).passed and rules.verdict(hit).decided
    assert judging(parse_rulebook(HEADER + INDEX + "verdict v: require failed <= 0 %",
                                  "t.rules")).units == 0
