"""Expectations, exit codes and JUnit from evaluation results (no simulation)."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from idefix_rules.campaign.evaluation.fill_result import collision_chances, fill_result
from idefix_rules.campaign.evaluation.path_result import CampaignEvaluation, PathResult
from idefix_rules.campaign.input.expectations import (
    CollisionExpectation,
    MeanRiskExpectation,
    PathVerdictExpectation,
    RankFirstExpectation,
)
from idefix_rules.campaign.outcome.expectation_checks import check_expectation, check_expectations
from idefix_rules.campaign.outcome.junit import junit_xml
from idefix_rules.campaign.outcome.outputs import exit_code, summary
from idefix_rules.cli.outcome import ci_line
from idefix_rules.rulebook import RunEvaluation, check_text, compile_rulebook


def evaluation() -> CampaignEvaluation:
    good = PathResult("good", 0, "simulated", runs=10, completed=10, mean_risk=0.3,
                      risk_ci=(0.25, 0.35), collision_chance={"L1": 0.0, "L2": 0.1, "L3": 0.0},
                      passed=True, rank=1)
    close = PathResult("close", 1, "simulated", runs=10, completed=10, mean_risk=0.49,
                       risk_ci=(0.4, 0.6), passed=True, undecided=True, rank=2)
    broken = PathResult("broken", 2, "simulated", runs=10, completed=8,
                        failures={3: "the simulation process crashed (SIGSEGV)", 7: "timeout"},
                        mean_risk=0.1, risk_ci=(0.05, 0.15), passed=False, rank=3,
                        collision_chance={"L2": 0.0})
    rejected = PathResult("rejected", 3, "rejected", reason="command 1 breaks rule 'x'")
    return CampaignEvaluation([good, close, broken, rejected], ["good", "close", "broken"],
                              {"name": "r", "version": "1.0.0"}, {"campaign_name": "c"})


def test_verdict_expectations_need_a_decided_verdict() -> None:
    results = evaluation()
    held = check_expectation(PathVerdictExpectation(path="good", verdict="pass"), results)
    assert held.held
    undecided = check_expectation(PathVerdictExpectation(path="close", verdict="pass"), results)
    assert not undecided.held and "not decided" in undecided.message
    rejected = check_expectation(PathVerdictExpectation(path="rejected", verdict="fail"),
                                 results)
    assert rejected.held


def test_failed_runs_never_satisfy_risk_or_collision_expectations() -> None:
    results = evaluation()
    risk = check_expectation(MeanRiskExpectation(path="broken", max_mean_risk="50 %"), results)
    assert not risk.held and "2 failed run(s)" in risk.message
    hits = check_expectation(
        CollisionExpectation(path="broken", max_collision_chance={"L2": "50 %"}), results)
    assert not hits.held


def test_rank_and_collision_expectations() -> None:
    results = evaluation()
    assert check_expectation(RankFirstExpectation(rank_first="good"), results).held
    assert not check_expectation(RankFirstExpectation(rank_first="close"), results).held
    # 1 hit in 10 runs: 10 % is within 20 %, but its bounds (0.05–52.5 %) do not show it
    within = CollisionExpectation(path="good", max_collision_chance={"L2": "10 %", "any": "20 %"})
    found = check_expectation(within, results)
    assert not found.held and "not decided at this number of runs" in found.message
    over = CollisionExpectation(path="good", max_collision_chance={"L2": "5 %"})
    assert not check_expectation(over, results).held


def test_expectations_hold_only_where_the_bounds_show_them() -> None:
    """3 hits in 300 runs: bounds 0.035–4.0 % (one-sided 5 % each, valid after an adaptive
    stop too: campaign/statistics/bernoulli.py, anytime_bounds); a mean risk of 0.30 with
    bounds 0.25–0.35. A limit above the upper bound holds, one between the bounds is not
    decided, one below the lower bound fails outright."""
    results = evaluation()
    results.paths[0].completed = results.paths[0].runs = 300
    results.paths[0].collision_chance = {"L2": 0.01}

    def chance(limit: str) -> tuple[bool, bool]:
        found = check_expectation(CollisionExpectation(
            path="good", max_collision_chance={"L2": limit}), results)
        return found.held, "not decided" in found.message

    assert chance("4.01 %") == (True, False)   # just above the upper bound, 4.003 %
    assert chance("3.99 %") == (False, True)   # just below it
    assert chance("0.04 %") == (False, True)   # just above the lower bound, 0.035 %
    assert chance("0.03 %") == (False, False)  # below it: shown above the limit

    def risk(limit: str) -> tuple[bool, bool]:
        found = check_expectation(MeanRiskExpectation(path="good", max_mean_risk=limit),
                                  results)
        return found.held, "not decided" in found.message

    assert risk("35.1 %") == (True, False) and risk("34.9 %") == (False, True)
    assert risk("25.1 %") == (False, True) and risk("24.9 %") == (False, False)


def test_rank_first_needs_a_settled_lead() -> None:
    """Unpaired: the lead over a passing chain whose risk bounds overlap is open; over a
    chain shown to fail it is settled whatever the risks (passing chains rank first)."""
    results = evaluation()
    results.paths[1].undecided = False
    results.paths[1].risk_ci = (0.34, 0.6)  # overlaps good's 0.25-0.35
    found = check_expectation(RankFirstExpectation(rank_first="good"), results)
    assert not found.held and "its lead over close is not settled" in found.message
    results.paths[1].risk_ci = (0.36, 0.6)
    assert check_expectation(RankFirstExpectation(rank_first="good"), results).held


def test_exit_code_without_expectations_needs_every_path_to_pass() -> None:
    results = evaluation()
    assert exit_code(results, [], has_expectations=False) == 1
    only_good = CampaignEvaluation(results.paths[:1], ["good"], {}, {})
    assert exit_code(only_good, [], has_expectations=False) == 0
    checks = check_expectations([RankFirstExpectation(rank_first="good")], results)
    assert exit_code(results, checks, has_expectations=True) == 0


def _junit_failures(text: str) -> tuple[ET.Element, dict[str, ET.Element]]:
    root = ET.fromstring(text)
    cases = {c.get("name", ""): c for c in root.iter("testcase")}
    return root, cases


def test_junit_with_expectations_fails_only_on_expectations() -> None:
    results = evaluation()
    checks = check_expectations([RankFirstExpectation(rank_first="close"),
                                 PathVerdictExpectation(path="good", verdict="pass")], results)
    root, cases = _junit_failures(junit_xml(results, checks, "c", {"good": 1.25}))
    suites = {s.get("name"): s for s in root.iter("testsuite")}
    assert list(suites) == ["c.paths", "c.expectations"]
    assert [c.get("name") for c in suites["c.paths"].iter("testcase")] == [
        "good", "close", "broken", "rejected"]
    failing = [name for name, c in cases.items() if c.find("failure") is not None]
    # Exactly what makes the exit code 1: the expectation, not the failing paths.
    assert failing == ["expect[0] close ranks first"]
    assert exit_code(results, checks, has_expectations=True) == 1
    assert root.get("failures") == "1" and root.get("tests") == "6"
    assert suites["c.paths"].get("failures") == "0"
    broken = cases["broken"]
    verdict = suites["c.paths"].find("properties/property[@name='verdict[broken]']")
    assert verdict is not None and verdict.get("value") == "fail"
    assert (broken.findtext("system-out") or "").startswith("path broken: fail · risk 10.0 %\n")
    assert "run 3 failed: the simulation process crashed (SIGSEGV)" in (
        broken.findtext("system-out") or "")
    assert cases["good"].get("time") == "1.250"
    assert all(c.get("time") is not None for c in cases.values())


def test_junit_without_expectations_fails_on_path_verdicts() -> None:
    results = evaluation()
    root, cases = _junit_failures(junit_xml(results, [], "c"))
    assert [s.get("name") for s in root.iter("testsuite")] == ["c.paths"]
    failing = [name for name, c in cases.items() if c.find("failure") is not None]
    # close passes on its point estimate only (not decided): not shown to pass, a failure
    assert failing == ["close", "broken", "rejected"]
    assert root.get("failures") == "3"
    assert exit_code(results, [], has_expectations=False) == 1
    passing = CampaignEvaluation(results.paths[:1], ["good"], {}, {})
    root, _ = _junit_failures(junit_xml(passing, [], "c"))
    assert root.get("failures") == "0" and exit_code(passing, [], False) == 0


@pytest.mark.parametrize(("name", "shown"), [
    ("ba\x02se", "ba\\x02se"), ("tab\tand\x0bvt", "tab\tand\\x0bvt"),
    ("odd\ufffe", "odd\\ufffe"), ("é\x00", "é\\x00"), ("plain é ✓", "plain é ✓")])
def test_junit_stays_xml_when_the_campaign_name_holds_a_control_character(
        name: str, shown: str) -> None:
    """A name a YAML escape can give: XML 1.0 cannot hold it, even as a reference, so it is
    written as its Python escape and a CI publisher still reads the file."""
    root = ET.fromstring(junit_xml(evaluation(), [], name))  # raises on a file that is not XML
    assert root.get("name") == shown
    assert {s.get("name") for s in root.iter("testsuite")} == {f"{shown}.paths"}


def test_summary_lists_failures_and_uses_mAs() -> None:
    results = evaluation()
    results.paths[0].energy = 0.5
    data = summary(results, [], 1)
    good, _, broken, rejected = data["paths"]
    assert good["energy_mAs"] == 500.0
    assert data["decision"]["kind"] == "send" and data["decision"]["path"] == "good"
    assert data["units"]["energy_mAs"].startswith("mAs")
    assert broken["failures"][0] == {"run": 3,
                                     "reason": "the simulation process crashed (SIGSEGV)"}
    assert rejected["verdict"] == "rejected" and rejected["rank"] is None


def test_collision_columns_come_from_level_named_chances() -> None:
    assert collision_chances({"hit_L1": 0.1, "collision_L3": 0.2, "too_fast": 0.5}) == \
        {"L1": 0.1, "L3": 0.2}


def test_an_undecided_verdict_says_not_decided_once() -> None:
    checked = check_text(
        'rulebook "t" version "1.0.0"\npurpose "test"\n'
        "index I_a { value = max over time (abs(pitch)) limit = 1 rad weight = 1 }\n"
        "verdict acceptable: require risk <= 50 %\n", "t.rules").checked
    assert checked is not None
    rules = compile_rulebook(checked)
    i_max = np.array([0.2, 0.7, 0.4, 0.6])  # mean 0.475: 50 % lies inside the interval
    runs = RunEvaluation(
        index_names=("I_a",), values={"I_a": i_max}, raw={"I_a": i_max},
        per_sample={"I_a": i_max[:, None]}, weighted={"I_a": i_max}, i_max=i_max,
        dominant=np.zeros(4, dtype=int), dominant_sample=np.zeros(4, dtype=int),
        chance_names=(), chances={}, time=np.full(4, 10.0), energy=np.full(4, 0.5))
    stats = rules.path_statistics(runs)
    path = PathResult("close", 0, "simulated", runs=4, completed=4)
    fill_result(path, runs, stats, rules.verdict(stats))
    assert path.undecided and path.passed
    assert len(path.verdict_reasons) == 1
    assert path.verdict_reasons[0].count("not decided") == 1
    results = CampaignEvaluation([path], ["close"], {}, {})
    detail = ET.fromstring(junit_xml(results, [], "c")).find(".//system-out")
    assert detail is not None
    # the verdict in one line (as the failure's message), then the details, which say it once
    verdict, details = (detail.text or "").split("\n", 1)
    assert verdict == "path close: pass (not decided) · risk 47.5 % · not decided: acceptable"
    assert details.count("not decided") == 1


def test_without_expectations_a_pass_not_decided_fails_ci() -> None:
    good, close = evaluation().paths[:2]
    assert good.held and close.verdict_text == "pass" and not close.held
    decided = CampaignEvaluation([good], ["good"], {}, {})
    assert exit_code(decided, [], has_expectations=False) == 0
    both = CampaignEvaluation([good, close], ["good", "close"], {}, {})
    assert exit_code(both, [], has_expectations=False) == 1
    root, cases = _junit_failures(junit_xml(both, [], "c"))
    assert root.get("failures") == "1"
    failure = cases["close"].find("failure")
    assert failure is not None and \
        failure.get("message") == "path close: pass (not decided) · risk 49.0 %"
    assert ci_line([], 1, both) == ("CI verdicts (no expectations: every path must pass): 1 of "
                                    "2 passed, 1 passing but not decided (exit 1)")


def test_the_report_prints_the_risks_the_console_prints_not_a_value_rounded_twice() -> None:
    """summary.json keeps a path's figures unrounded: the report prints them again, and a value
    stored rounded (0.067464 as 0.0675) printed 6.8 % where the console and JUnit said 6.7 %."""
    from idefix_rules.campaign.outcome.outputs import path_record
    from idefix_rules.report.html import _number
    from idefix_rules.report.reading import row_from_summary

    for risk, time, energy in ((0.067464, 232.149, 0.70204999), (0.2274999, 10.05, 0.0),
                               (0.5, 0.0, 1.0)):
        path = PathResult("p", 0, "simulated", runs=4, completed=4, mean_risk=risk,
                          risk_ci=(risk - 0.01, risk + 0.01), chances={"c": risk},
                          energy=energy, time=time)
        row = row_from_summary(path_record(path))
        assert _number(row.mean_risk, 1, 100) == f"{100.0 * risk:.1f}"
        assert row.risk_ci95 == path.risk_ci and row.chances == {"c": risk}
        assert row.time_s == time and row.energy_mAs == energy * 1000.0


def test_runs_never_simulated_are_counted_in_the_summary_beside_the_failed_ones() -> None:
    """An interrupted campaign evaluated: 4 of 16 runs complete, one failed, one lost to the
    infrastructure, 10 never simulated. The rulebook's `failed` statistic counts 11; summary.json
    said 1 failed and nothing of the 10 (missing_runs now)."""
    from idefix_rules.campaign.outcome.outputs import path_record

    path = PathResult("p", 0, "simulated", runs=16, completed=4,
                      failures={2: "the simulation process crashed (SIGSEGV)",
                                9: "infrastructure: killed by SIGKILL 3 times"})
    assert (path.failed, path.lost, path.missing) == (1, 1, 10)
    record = path_record(path)
    # the rulebook's failed statistic counts both: 11
    assert (record["failed_runs"], record["missing_runs"]) == (1, 10)
    assert [failure["run"] for failure in record["failures"]] == [2, 9]
    complete = PathResult("q", 1, "simulated", runs=16, completed=15, failures={3: "timeout"})
    assert (path_record(complete)["failed_runs"], path_record(complete)["missing_runs"]) == (1, 0)


def test_rank_first_in_a_paired_campaign_reads_the_paired_comparison() -> None:
    from idefix_rules.campaign.statistics.pairwise import PairComparison

    results = evaluation()
    results.paths[1].undecided = False
    results.paths[1].risk_ci = (0.0, 1.0)  # the separate bounds do not matter when paired

    def pair(outcome: str, first: str = "close", second: str = "good") -> PairComparison:
        return PairComparison(first, second, 10, 1, 9, 0, 0.1, 0.05, 0.15, 0.99, 0.02,
                              outcome)

    for outcome, held in (("second safer", True), ("open", False), ("tied", True),
                          ("first safer", False)):
        results.pairs = [pair(outcome)]
        found = check_expectation(RankFirstExpectation(rank_first="good"), results)
        assert found.held is held, outcome
        assert ("tied with close" in found.message) is (outcome == "tied")


def test_any_collision_without_its_own_chance_is_bounded_by_the_sum_of_the_levels() -> None:
    """Without a chance of a hit of any level, the union of the levels' hits lies between the
    largest level's chance and the sum of theirs: 2 L1 and 2 L2 hits in 128 runs may be 4
    runs with a hit, so `any <= 6 %` is not shown by the largest level's 1.6 % (whose upper
    bound alone is below 6 %): not decided. `any <= 20 %` holds."""
    results = evaluation()
    good = results.paths[0]
    good.completed = good.runs = 128
    good.collision_chance = {"L1": 2 / 128, "L2": 2 / 128, "L3": 0.0}
    found = check_expectation(CollisionExpectation(
        path="good", max_collision_chance={"any": "6 %"}), results)
    assert not found.held and "not decided" in found.message
    found = check_expectation(CollisionExpectation(
        path="good", max_collision_chance={"any": "20 %"}), results)
    assert found.held


def test_rank_first_holds_for_either_chain_of_a_tie_at_the_top() -> None:
    from idefix_rules.campaign.statistics.pairwise import PairComparison

    results = evaluation()
    results.paths[1].undecided = False
    results.paths[1].rank = 1  # tied with good: they share the first rank
    results.pairs = [PairComparison("close", "good", 10, 5, 5, 0, 0.0, -0.01, 0.01, 0.99, 0.02,
                                    "tied")]
    for name, other in (("good", "close"), ("close", "good")):
        found = check_expectation(RankFirstExpectation(rank_first=name), results)
        assert found.held and f"tied with {other}" in found.message, name


def test_raw_index_values_carry_the_si_unit_of_their_expression() -> None:
    """The default rulebook's raw values: angles in rad, sinkage in m, ratios 1."""
    from pathlib import Path

    from idefix_rules.campaign.evaluation.evaluation_datasets import raw_units
    from idefix_rules.campaign.preparation import compile_rulebook_file

    units = raw_units(compile_rulebook_file(Path(__file__).parents[2] / "rulebooks" /
                                            "idefix-ops.rules"))
    assert units["I_ds"] == "m" and units["I_beta"] == "rad" and units["I_s"] == "1"


LOST = "infrastructure: worker died 4 times while running it"
AGAIN = "idefix-verify c.yaml --resume --junit ci.xml"


def lost_evaluation() -> CampaignEvaluation:
    """good passes; arc lost runs 1 and 4 of 8 to the infrastructure and passes on the six
    left; straight's reference run was lost (verdict error, nothing simulated)."""
    good = evaluation().paths[0]
    arc = PathResult("arc", 1, "simulated", runs=8, completed=6,
                     failures={1: LOST, 4: LOST}, mean_risk=0.2, risk_ci=(0.1, 0.3),
                     passed=True, rank=2)
    straight = PathResult("straight", 2, "reference_failed", runs=8, reason=LOST)
    return CampaignEvaluation([good, arc, straight], ["good", "arc"],
                              {"name": "r", "version": "1.0.0"}, {"campaign_name": "c"})


def test_junit_of_runs_lost_to_the_infrastructure_is_in_error_as_the_exit_code_3() -> None:
    """Exit code 3 (runs lost, not a verdict): each path that lost runs is an error case
    naming the runs, their reasons and the command that runs them again; it was a passing
    case (failures="0" errors="0", a green report for a red job) with the loss only in its
    output, and a reference run lost was an error of type "error"."""
    results = lost_evaluation()
    assert exit_code(results, [], has_expectations=False) == 3
    root, cases = _junit_failures(junit_xml(results, [], "c", resume=AGAIN))
    assert (root.get("tests"), root.get("failures"), root.get("errors")) == ("3", "0", "2")
    assert cases["good"].find("error") is None and cases["good"].find("failure") is None
    arc = cases["arc"].find("error")
    assert arc is not None and cases["arc"].find("failure") is None
    assert arc.attrib == {
        "type": "infrastructure",
        "message": "path arc: runs 1, 4 lost to the infrastructure (2 of 8), not a verdict; "
                   f"run them again with `{AGAIN}`"}
    assert arc.text == f"run 1 lost: {LOST}\nrun 4 lost: {LOST}\nrun them again with `{AGAIN}`"
    assert f"run 1 lost: {LOST}" in (cases["arc"].findtext("system-out") or "")
    straight = cases["straight"].find("error")
    assert straight is not None and straight.attrib == {
        "type": "infrastructure",
        "message": "path straight: its reference run was lost to the infrastructure, not a "
                   f"verdict; run them again with `{AGAIN}`"}
    assert straight.text == f"reference run lost: {LOST}\nrun them again with `{AGAIN}`"


def test_an_expectation_on_a_path_that_lost_runs_is_not_judged_but_in_error() -> None:
    """``expect: straight fails`` on a path whose reference run was lost: the expectation
    does not hold (verdict error), which is the loss, not a failure of the chain: an error
    case (it was <failure type="expectation">verdict error, as if the chain had passed). An
    expectation on a path that lost nothing fails as before; the path cases of the lost
    paths are errors too, the exit code being 3 whatever the expectations say."""
    results = lost_evaluation()
    checks = check_expectations([PathVerdictExpectation(path="straight", verdict="fail"),
                                 PathVerdictExpectation(path="good", verdict="fail")], results)
    assert exit_code(results, checks, has_expectations=True) == 3
    root, cases = _junit_failures(junit_xml(results, checks, "c", resume=AGAIN))
    assert (root.get("failures"), root.get("errors")) == ("1", "3")
    unjudged = cases["expect[0] straight fails"].find("error")
    assert unjudged is not None and unjudged.attrib == {
        "type": "infrastructure",
        "message": "not judged: straight lost runs to the infrastructure (verdict error); "
                   f"run them again with `{AGAIN}`"}
    assert cases["expect[0] straight fails"].find("failure") is None
    failed = cases["expect[1] good fails"].find("failure")
    assert failed is not None and failed.get("message") == "verdict pass"
    assert [name for name, case in cases.items() if case.find("error") is not None] == [
        "arc", "straight", "expect[0] straight fails"]


FAILING_RULEBOOK = (
    'rulebook "t" version "1.0.0"\npurpose "test"\n'
    "index I_a { value = max over time (abs(pitch)) limit = 1 rad weight = 1 }\n"
    "verdict acceptable: require risk <= 50 %\n"
    "verdict quick: require time <= 5 s\n"
    "verdict frugal: require energy <= 1 As\n")


def failing_path() -> PathResult:
    """Four runs at risk 0.9 taking 10 s each: acceptable and quick fail, decidedly."""
    checked = check_text(FAILING_RULEBOOK, "t.rules").checked
    assert checked is not None
    rules = compile_rulebook(checked)
    i_max = np.full(4, 0.9)
    runs = RunEvaluation(
        index_names=("I_a",), values={"I_a": i_max}, raw={"I_a": i_max},
        per_sample={"I_a": i_max[:, None]}, weighted={"I_a": i_max}, i_max=i_max,
        dominant=np.zeros(4, dtype=int), dominant_sample=np.zeros(4, dtype=int),
        chance_names=(), chances={}, time=np.full(4, 10.0), energy=np.full(4, 0.5))
    stats = rules.path_statistics(runs)
    path = PathResult("straight", 0, "simulated", runs=4, completed=4, rank=1)
    fill_result(path, runs, stats, rules.verdict(stats))
    assert path.verdict_text == "fail" and not path.undecided
    return path


def test_a_failure_message_names_the_rules_the_path_breaks() -> None:
    """A CI server's summary shows a failure's message only: it names the verdict rules the
    path fails (or the command rule that rejected it), as the console's verdict line does; it
    said only "path straight: fail" / "path too-fast: rejected"."""
    rejected = PathResult("too-fast", 1, "rejected", reason=(
        "command 1 breaks rule 'wheel_rate_limit' (max_wheel_rate = 0.5 rad/s): Fastest; "
        "command 2 breaks rule 'turn_limit' (delta_heading = 200 deg)"))
    excluded = PathResult("detour", 2, "excluded", reason=(
        "the reference run fails prescreen 'reference_not_critical' (risk = 1)"))
    results = CampaignEvaluation([failing_path(), rejected, excluded], ["straight"], {}, {})
    _, cases = _junit_failures(junit_xml(results, [], "c"))
    messages = {name: case.find("failure").get("message")  # type: ignore[union-attr]
                for name, case in cases.items()}
    assert messages == {
        "straight": "path straight: fail · risk 90.0 % · fails acceptable, quick",
        "too-fast": "path too-fast: rejected · breaks wheel_rate_limit, turn_limit",
        "detour": "path detour: excluded · fails prescreen reference_not_critical"}


# What the JUnit schema CI servers validate against allows (the Jenkins xUnit plugin's
# junit-10.xsd, which refuses a file that breaks it): per element, its attributes and children.
JUNIT_10 = {
    "testsuites": ({"name", "time", "tests", "failures", "errors"}, {"testsuite"}),
    "testsuite": ({"name", "tests", "failures", "errors", "group", "time", "skipped",
                   "timestamp", "hostname", "id", "package", "file", "log", "url"},
                  {"testsuite", "properties", "testcase", "system-out", "system-err"}),
    "properties": (set(), {"property"}),
    "property": ({"name", "value"}, set()),
    "testcase": ({"name", "time", "classname", "group"},
                 {"skipped", "error", "failure", "rerunFailure", "rerunError",
                  "flakyFailure", "flakyError", "system-out", "system-err"}),
    "failure": ({"type", "message"}, set()),
    "error": ({"type", "message"}, set()),
    "skipped": ({"type", "message"}, set()),
    "system-out": (set(), set()),
    "system-err": (set(), set()),
}
REQUIRED = {"testsuite": {"name", "tests", "failures", "errors"}, "property": {"name", "value"},
            "testcase": {"name"}}


def assert_junit_10(text: str) -> None:
    root = ET.fromstring(text)
    assert root.tag == "testsuites"
    for element in root.iter():
        attributes, children = JUNIT_10[element.tag]
        assert set(element.attrib) <= attributes, (element.tag, element.attrib)
        assert REQUIRED.get(element.tag, set()) <= set(element.attrib), element.tag
        assert {child.tag for child in element} <= children, (element.tag, list(element))
        if "time" in element.attrib:
            assert re.fullmatch(r"[0-9]*(\.[0-9]*)?", element.get("time", "")), element.attrib


def test_the_junit_file_is_valid_against_the_schema_ci_servers_check() -> None:
    """<properties> inside a <testcase> and a skipped count on <testsuites> broke it: the
    xUnit plugin refuses such a file. The verdict of each path is a property of its suite
    (``verdict[<path>]``) and the first line of the case's output."""
    from idefix_rules.errors import Span, error

    results = evaluation()
    checks = check_expectations([RankFirstExpectation(rank_first="close"),
                                 PathVerdictExpectation(path="good", verdict="pass")], results)
    unused = error("C215", "waiver matches nothing", Span("c.yaml", 3, 5))
    for text in (junit_xml(results, [], "c"), junit_xml(results, checks, "c", {"good": 1.25}),
                 junit_xml(results, checks, "c", problems=[unused]),
                 junit_xml(lost_evaluation(), [], "c", resume=AGAIN)):
        assert_junit_10(text)
    root = ET.fromstring(junit_xml(results, [], "c"))
    assert "skipped" not in root.attrib
    properties = {p.get("name"): p.get("value") for p in root.iter("property")}
    assert {key: value for key, value in properties.items() if key.startswith("verdict[")} == {
        "verdict[good]": "pass", "verdict[close]": "pass (not decided)",
        "verdict[broken]": "fail", "verdict[rejected]": "rejected"}
    assert properties["asserted"] == "yes"
