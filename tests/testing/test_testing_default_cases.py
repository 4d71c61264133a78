"""The default rulebook's own cases: they pass, cover every rule, and catch every mutant.

These are the rule engineers' checks of the files they edit (``rulebooks/idefix-ops.rules`` and
``rulebooks/tests/idefix-ops.yaml``): a rule change that their cases no longer describe fails
here, and only here. What the runner and the mutator do is tested on frozen copies in
``test_testing_frozen_cases.py``."""

from __future__ import annotations

from pathlib import Path

import pytest

from idefix_rules.cli import main
from idefix_rules.testing import load_case_file, run_case_file
from idefix_rules.testing.coverage import coverage_of
from idefix_rules.testing.mutation_score import score_mutants

ROOT = Path(__file__).parents[2]
CASES = ROOT / "rulebooks" / "tests" / "idefix-ops.yaml"


@pytest.fixture(scope="module")
def case_file():
    return load_case_file(CASES)


def test_every_default_case_passes(case_file):
    outcome = run_case_file(case_file)
    failed = {o.case.name: [m.render() for m in o.mismatches]
              for o in outcome.outcomes if not o.passed}
    assert failed == {}
    assert len(outcome.outcomes) == len(case_file.cases)


def test_every_rule_is_brought_across_its_limit_by_some_case(case_file):
    items = coverage_of(run_case_file(case_file))
    model = case_file.checked.rulebook
    declared = {r.name for group in (model.command_rules, model.indices, model.chances,
                                     model.prescreens, model.verdicts) for r in group}
    assert {item.name for item in items} == declared
    assert {item.name: item.state for item in items if item.state != "across"} == {}


def test_the_cli_runs_the_default_cases_with_a_summary_line(capsys, monkeypatch):
    monkeypatch.chdir(ROOT)
    code = main(["test"])
    out = capsys.readouterr().out
    assert code == 0
    every_case = sum(len(load_case_file(path).cases)
                     for path in sorted((ROOT / "rulebooks" / "tests").glob("*.yaml")))
    assert out.strip().splitlines()[-1].startswith(f"{every_case} passed")


# The survivors of `idefix-verify test --mutate` (nudge 10 %) on the default cases, each with
# its reason in docs/testing-rulebooks.md ("Survivors of the default rulebook"): a new survivor
# fails here until a case kills it or it is documented.
DOCUMENTED_SURVIVORS = {
    'chance average_off_course: dropped - ref.y',
    'chance average_off_course: dropped mean over runs (x - ref.x) from hypot(…)',
    'chance average_off_course: final over time → max over time',
    'chance average_off_course: threshold 1 → 0.9',
    'chance average_off_course: threshold 1 → 1.1',
    'chance too_abrupt: threshold max_acceleration → max_acceleration * 0.9',
    'chance too_abrupt: threshold max_acceleration → max_acceleration * 1.1',
    'chance too_fast: threshold max_speed → max_speed * 0.9',
    'chance too_fast: threshold max_speed → max_speed * 1.1',
    'command lateral_acceleration_limit: threshold max_lateral_acceleration → '
    'max_lateral_acceleration * 0.9',
    'command lateral_acceleration_limit: threshold max_lateral_acceleration → '
    'max_lateral_acceleration * 1.1',
    'command max_turn_angle: threshold max_turn → max_turn * 0.9',
    'command max_turn_angle: threshold max_turn → max_turn * 1.1',
    'command min_motion: threshold min_delta_heading → min_delta_heading * 0.9',
    'command min_motion: threshold min_delta_heading → min_delta_heading * 1.1',
    'command min_motion: threshold min_delta_position → min_delta_position * 0.9',
    'command min_motion: threshold min_delta_position → min_delta_position * 1.1',
    'command speed_limit: threshold max_speed → max_speed * 0.9',
    'command speed_limit: threshold max_speed → max_speed * 1.1',
    'command wheel_rate_limit: threshold max_wheel_rate_limit → max_wheel_rate_limit * 0.9',
    'command wheel_rate_limit: threshold max_wheel_rate_limit → max_wheel_rate_limit * 1.1',
    'constant f_obs: factor f_obs[L3] 1 → 1.1',
    'index I_beta: max over wheels → sum over wheels',
    'index I_ds: max over wheels → sum over wheels',
    'index I_phi: dropped - ref.pitch',
    'index I_pos: final over time → max over time',
    'index I_psi: dropped - ref.roll',
    'index I_s: max over wheels → sum over wheels',
    'index I_s: percentile 95 over time → percentile 90 over time',
    'prescreen no_clear_collision: threshold 1 → 0.9',
    'verdict acceleration_kept: threshold 5 % → 4.5 %',
    'verdict acceleration_kept: threshold 5 % → 5.5 %',
    'verdict acceptable_risk: threshold 70 % → 63 %',
    'verdict acceptable_risk: threshold 70 % → 77 %',
    'verdict average_position_kept: threshold 50 % → 45 %',
    'verdict average_position_kept: threshold 50 % → 55 %',
    'verdict chains_finish: threshold 5 % → 4.5 %',
    'verdict chains_finish: threshold 5 % → 5.5 %',
    'verdict rare_l3_hits: threshold 5 % → 4.5 %',
    'verdict rare_l3_hits: threshold 5 % → 5.5 %',
    'verdict rarely_stuck: threshold 1 % → 0.9 %',
    'verdict rarely_stuck: threshold 1 % → 1.1 %',
    'verdict runs_complete: threshold 1 % → 0.9 %',
    'verdict runs_complete: threshold 1 % → 1.1 %',
    'verdict speed_kept: threshold 5 % → 4.5 %',
    'verdict speed_kept: threshold 5 % → 5.5 %',
}


def test_every_mutant_is_killed_or_a_documented_survivor(case_file):
    report = score_mutants([case_file])
    assert [r.skipped for r in report.results if r.skipped] == []
    model = case_file.checked.rulebook
    rules = sum(len(group) for group in (model.command_rules, model.indices, model.chances,
                                         model.prescreens, model.verdicts))
    assert len(report.scored) >= rules  # every rule of the default rulebook yields mutants
    survivors = {str(r.mutant) for r in report.survivors}
    assert survivors <= DOCUMENTED_SURVIVORS, sorted(survivors - DOCUMENTED_SURVIVORS)
