"""The case runner and the mutator on the frozen operations rulebook 1.1.0 and its cases
(``tests/fixtures/rulebooks``): realistic input that no edit of ``rulebooks/`` changes, so the
expected texts below can name what that version says."""

from __future__ import annotations

from pathlib import Path

import pytest

from idefix_rules.rulebook.check import check
from idefix_rules.rulebook.compile import compile_rulebook
from idefix_rules.testing import load_case_file, run_case, run_case_file
from idefix_rules.testing.mutations import mutants

ROOT = Path(__file__).parents[2]
CASES = ROOT / "tests" / "fixtures" / "rulebooks" / "idefix-ops-1.1.0.yaml"


@pytest.fixture(scope="module")
def case_file():
    return load_case_file(CASES)


def test_the_frozen_cases_pass(case_file):
    assert case_file.checked.rulebook.header.version == "1.1.0"
    outcome = run_case_file(case_file)
    failed = {o.case.name: [m.render() for m in o.mismatches]
              for o in outcome.outcomes if not o.passed}
    assert failed == {}
    assert len(outcome.outcomes) == 34


def test_a_mutant_fails_with_expected_actual_and_the_rule_text(case_file):
    mutant = next(m for m in mutants(case_file.checked.rulebook)
                  if m.rule == "I_s" and m.change == "max over wheels → min over wheels")
    compiled = compile_rulebook(check(mutant.rulebook).checked)
    failed = next((o for o in (run_case(compiled, case) for case in case_file.cases)
                   if not o.passed), None)
    assert failed is not None
    text = failed.mismatches[0].render()
    assert "index I_s: expected 0.5 ± 0.005, got 0" in text
    assert "rule: index I_s: value = percentile 95 over time (min over wheels" in text
    assert "from: run 1: raw value 0" in text
    assert f"{CASES.relative_to(ROOT)}" in text or str(CASES) in text


def test_every_rule_of_the_frozen_rulebook_is_mutated(case_file):
    found = list(mutants(case_file.checked.rulebook))
    mutated = {m.rule for m in found if m.kind != "constant"}
    # of the constants only the table of obstacle factors is mutated (entries nudged both ways)
    assert sorted(m.change for m in found if m.kind == "constant") == [
        "factor f_obs[L1] 0.2 → 0.18", "factor f_obs[L1] 0.2 → 0.22",
        "factor f_obs[L2] 0.6 → 0.54", "factor f_obs[L2] 0.6 → 0.66",
        "factor f_obs[L3] 1 → 0.9", "factor f_obs[L3] 1 → 1.1"]
    model = case_file.checked.rulebook
    declared = {r.name for group in (model.command_rules, model.indices, model.chances,
                                     model.prescreens, model.verdicts) for r in group}
    assert mutated == declared
    assert len(declared) == 5 + 8 + 6 + 2 + 6
