"""The default rulebook's own cases: they pass, cover every rule, and catch every mutant.

These are the rule engineers' checks of the files they edit (``rulebooks/idefix-ops.rules`` and
``rulebooks/tests/idefix-ops.yaml``): a rule change that their cases no longer describe fails
here, and only here. What the runner and the mutator do is tested on frozen copies in
``test_testing_frozen_cases.py``."""

from __future__ import annotations

from pathlib import Path

import pytest

from idefix_rules.cli import main
from idefix_rules.rulebook.check import check
from idefix_rules.rulebook.compile import compile_rulebook
from idefix_rules.testing import load_case_file, run_case, run_case_file
from idefix_rules.testing.coverage import coverage_of
from idefix_rules.testing.mutations import mutants

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
    assert out.strip().splitlines()[-1].startswith(f"{len(load_case_file(CASES).cases)} passed")


def _first_failure(compiled, cases):
    for case in cases:
        outcome = run_case(compiled, case)
        if not outcome.passed:
            return outcome
    return None


# Mutants that cannot change any outcome, with the reason. The average-position chance holds in
# every run of a path or in none (it reads the runs' average position: one value per path), so
# its verdict's threshold says the same anywhere strictly between 0 % and 100 %.
EQUIVALENT = {
    "verdict average_position_kept: threshold 50 % × 2",
    "verdict average_position_kept: threshold 50 % × 0.5",
}


def test_every_single_rule_mutant_makes_a_case_fail(case_file):
    survivors = []
    count = 0
    for mutant in mutants(case_file.checked.rulebook):
        count += 1
        result = check(mutant.rulebook)
        assert result.checked is not None, f"{mutant} is not a valid rulebook"
        if _first_failure(compile_rulebook(result.checked), case_file.cases) is None:
            survivors.append(str(mutant))
    model = case_file.checked.rulebook
    rules = sum(len(group) for group in (model.command_rules, model.indices, model.chances,
                                         model.prescreens, model.verdicts))
    assert count >= rules  # every rule of the default rulebook yields mutants
    assert set(survivors) <= EQUIVALENT, sorted(set(survivors) - EQUIVALENT)
