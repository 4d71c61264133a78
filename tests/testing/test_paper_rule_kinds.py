"""Every kind of movement rule the paper lists (section 2) has a line in the operations rulebook
or in a documented example rulebook, and a case that brings it across its limit."""

from __future__ import annotations

from pathlib import Path

import pytest

from idefix_rules.testing.casefile import load_case_file
from idefix_rules.testing.coverage import coverage_of
from idefix_rules.testing.runner import run_case_file

ROOT = Path(__file__).resolve().parents[2]
OPERATIONS = "rulebooks/tests/idefix-ops.yaml"
SITE = "rulebooks/tests/site-areas.yaml"

# paper rule kind → (case file of the rulebook that says it, rule kind, rule name)
RULE_KINDS = {
    "position": (OPERATIONS, "index", "I_pos"),
    "heading": (OPERATIONS, "index", "I_theta"),
    "roll": (OPERATIONS, "index", "I_psi"),
    "pitch": (OPERATIONS, "index", "I_phi"),
    "sinkage": (OPERATIONS, "index", "I_ds"),
    "sinkage rate": (OPERATIONS, "chance", "sinking_fast"),
    "slip": (OPERATIONS, "index", "I_s"),
    "slip angle": (OPERATIONS, "index", "I_beta"),
    "obstacles by level": (OPERATIONS, "index", "I_obs"),
    "keep-out areas": (SITE, "chance", "entered_keep_out"),
    "highly inclined areas": (OPERATIONS, "chance", "on_steep"),
    "unknown areas": (SITE, "chance", "on_unknown"),
    "velocity": (OPERATIONS, "command", "speed_limit"),
    "acceleration (commanded)": (OPERATIONS, "command", "forward_acceleration_limit"),
    "acceleration (run)": (OPERATIONS, "chance", "too_abrupt"),
    "largest turn": (OPERATIONS, "command", "max_turn_angle"),
    "minimum delta position / heading": (OPERATIONS, "command", "min_motion"),
}


@pytest.fixture(scope="module")
def coverage() -> dict[tuple[str, str, str], str]:
    states = {}
    for case_path in {OPERATIONS, SITE}:
        outcome = run_case_file(load_case_file(ROOT / case_path))
        for item in coverage_of(outcome):
            states[(case_path, item.kind, item.name)] = item.state
    return states


@pytest.mark.parametrize("kind", sorted(RULE_KINDS))
def test_every_paper_rule_kind_has_a_rule_and_a_case_across_its_limit(kind, coverage):
    case_path, rule_kind, name = RULE_KINDS[kind]
    assert (case_path, rule_kind, name) in coverage, f"{kind}: no {rule_kind} {name!r}"
    assert coverage[(case_path, rule_kind, name)] == "across", kind


def test_the_example_rulebook_is_documented():
    text = (ROOT / "docs" / "rulebook-language.md").read_text(encoding="utf-8")
    assert "rulebooks/examples/site-areas.rules" in text
