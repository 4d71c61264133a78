"""A changed nominal in the rule diff: a rule change, and which way it goes."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from idefix_rules.diff.rules import diff_rules
from idefix_rules.rulebook import check, check_text
from idefix_rules.rulebook.compile import compile_rulebook
from idefix_rules.rulebook.strategies import RunRanges, realistic_runs, rulebook_variations
from idefix_rules.testing.properties import check_direction

GRADED = """rulebook "graded" version "1.0.0"
purpose "Slip and sinkage graded through their nominal values"

const nominal_slip  = 20 %
const critical_slip = 70 %

index I_s "wheel slip ratio" {
  value   = max over time (max over wheels (abs(wheel.slip)))
  nominal = nominal_slip
  limit   = critical_slip
  weight  = 1
}

index I_ds "wheel sinkage" {
  value   = max over time (max over wheels (wheel.sinkage))
  nominal = 1 cm
  limit   = 4 cm
  weight  = 1
}

index I_phi "pitch deviation" {
  value  = max over time (abs(pitch - ref.pitch))
  limit  = 10 deg
  weight = 1
}

verdict acceptable_risk: require risk <= 60 %
verdict slip_ok: require mean(I_s) <= 55 %
"""


def changes(old_text: str, new_text: str) -> dict[tuple[str, str], tuple[str, str]]:
    """(section, name) → (kind, direction) of every change but the header."""
    old = check_text(old_text, "old.rules").checked
    new = check_text(new_text, "new.rules").checked
    assert old is not None and new is not None
    return {(c.section, c.name): (c.kind, c.direction)
            for c in diff_rules(old, new).changes if c.section != "header"}


def edited(old: str, new: str) -> str:
    assert GRADED.count(old) == 1, old
    return GRADED.replace(old, new)


@pytest.mark.parametrize(("old", "new", "where", "expected"), [
    # the nominal as written
    ("nominal = 1 cm", "nominal = 2 cm", ("index", "I_ds"), "looser"),
    ("nominal = 1 cm", "nominal = 5 mm", ("index", "I_ds"), "stricter"),
    ("nominal = 1 cm", "nominal = 10 mm", ("index", "I_ds"), "neutral"),
    # through the constant it reads
    ("const nominal_slip  = 20 %", "const nominal_slip  = 30 %", ("constant", "nominal_slip"),
     "looser"),
    ("const nominal_slip  = 20 %", "const nominal_slip  = 10 %", ("constant", "nominal_slip"),
     "stricter"),
    # added: from half the limit (2 cm, 5 deg) to the nominal
    ("  limit  = 10 deg\n", "  nominal = 2 deg\n  limit  = 10 deg\n", ("index", "I_phi"),
     "stricter"),
    ("  limit  = 10 deg\n", "  nominal = 8 deg\n  limit  = 10 deg\n", ("index", "I_phi"),
     "looser"),
    ("  limit  = 10 deg\n", "  nominal = 5 deg\n  limit  = 10 deg\n", ("index", "I_phi"),
     "neutral"),
    # removed: from the nominal back to half the limit
    ("  nominal = 1 cm\n", "", ("index", "I_ds"), "looser"),
    # limit and nominal together
    ("nominal = 1 cm\n  limit   = 4 cm", "nominal = 2 cm\n  limit   = 5 cm", ("index", "I_ds"),
     "looser"),
    ("nominal = 1 cm\n  limit   = 4 cm", "nominal = 5 mm\n  limit   = 5 cm", ("index", "I_ds"),
     "unknown"),
])
def test_labels_of_nominal_changes(old, new, where, expected):
    found = changes(GRADED, edited(old, new))
    assert found[where][1] == expected
    assert found[where][0] == "changed"


def test_the_change_lists_the_nominal_as_written_and_in_si():
    old = check_text(GRADED, "old.rules").checked
    new = check_text(edited("nominal = 1 cm", "nominal = 15 mm"), "new.rules").checked
    [change] = [c for c in diff_rules(old, new).changes if c.section == "index"]
    [field] = change.fields
    assert (field.field, field.old, field.new) == ("nominal", "1 cm", "15 mm")
    assert (field.old_si, field.new_si) == ("0.01 m", "0.015 m")


def test_an_added_nominal_is_a_field_from_nothing():
    old = check_text(GRADED, "old.rules").checked
    new = check_text(edited("  limit  = 10 deg\n", "  nominal = 2 deg\n  limit  = 10 deg\n"),
                     "new.rules").checked
    [change] = [c for c in diff_rules(old, new).changes if c.section == "index"]
    assert [(f.field, f.old, f.new) for f in change.fields] == [("nominal", None, "2 deg")]


def test_a_constant_read_by_a_nominal_changes_its_index_in_si():
    old = check_text(GRADED, "old.rules").checked
    new = check_text(edited("const nominal_slip  = 20 %", "const nominal_slip  = 25 %"),
                     "new.rules").checked
    [change] = [c for c in diff_rules(old, new).changes if c.section == "index"]
    assert (change.name, change.kind, change.direction) == ("I_s", "changed", "looser")
    [field] = change.fields
    assert (field.old, field.new, field.old_si, field.new_si) == (
        "nominal_slip", "nominal_slip", "0.2", "0.25")
    assert change.reads_changed == ("nominal_slip",)


VARIATIONS = check_text(GRADED, "graded.rules").checked
# Runs around the rulebook's nominals and limits, so paths both pass and fail.
AROUND = RunRanges(slip=(0.0, 0.3), slip_angle=0.3, sinkage=0.015, tilt=0.09, hits=0, stuck=False,
                   runs=(2, 6), samples=(12, 30), step=(2.0, 4.0))


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(st.data())
def test_a_labelled_nominal_change_never_moves_a_path_the_other_way(data):
    assert VARIATIONS is not None
    description, variant = data.draw(rulebook_variations(VARIATIONS.rulebook))
    checked = check(variant).checked
    assert checked is not None
    found = [c for c in diff_rules(VARIATIONS, checked).changes if c.section != "header"]
    directions = {c.direction for c in found} - {"neutral"}
    direction = directions.pop() if len(directions) == 1 else \
        ("neutral" if not directions else "unknown")
    moved = next((word for word in ("nominal", "limit", "weight", "constant", "threshold")
                  if word in description), "other")
    event(f"{moved}: {direction}")
    signals, context = data.draw(realistic_runs(AROUND))
    before, after = check_direction(compile_rulebook(VARIATIONS), compile_rulebook(checked),
                                    direction, signals, context)
    event(f"{direction}: {'pass' if before else 'fail'} → {'pass' if after else 'fail'}")
