"""The rule diff on two small inline rulebooks: every kind of change, per section."""

from __future__ import annotations

import json

from idefix_rules.diff import RuleChange, RuleDiff, diff_rules
from idefix_rules.rulebook import check_text
from idefix_rules.rulebook.check import CheckedRulebook

OLD = """\
rulebook "small" version "1.0.0"
purpose "Old rules"

const critical_slip = 70 % because "Slip above 70 % is critical"
const max_tilt      = 20 deg because "Assumption: tilt limit"
const half_tilt     = max_tilt / 2
const gone          = 1 cm because "Removed later"
const f_obs         = {L1: 0.2, L2: 0.5, L3: 1}

settings {
  theoretical_slip = 20 %
  tolerance_growth = 5 cm/rad
}

obstacles {
  level L1 below 3 cm  buffer 2 cm
  level L2 below 10 cm buffer 5 cm
  level L3             buffer 10 cm
}

command max_turn: require abs(delta_heading) <= 90 deg because "Turn limit"
command old_rule: require abs(delta_position) <= 2 m

index I_s "wheel slip ratio" {
  value  = max over time (max over wheels (abs(wheel.slip)))
  limit  = critical_slip
  weight = 1
  because "Slip"
}

index I_phi "pitch" {
  value  = max over time (abs(pitch - ref.pitch))
  limit  = half_tilt
  weight = 0.8
}

index I_obs "obstacles" {
  value  = sum over parts (sum over levels (collision.hits * f_obs))
  limit  = 1
  weight = 1
  map    = max over parts (max over levels (collision.contact * f_obs))
}

chance hit_L3 = any over parts (collision.hits[L3] > 0) because "Table 1"
chance tilted = max over time (abs(pitch)) > max_tilt

combine {
  run        = max_weighted
  path       = mean
  confidence = 95 %
}

prescreen no_clear_collision: require I_obs < 1 because "Exclude clear collisions"

verdict acceptable_risk: require risk <= 75 % because "Risk limit"
verdict rare_l3_hits: require chance(hit_L3) <= 5 %

rank by risk, time, energy
"""

NEW = """\
# Comments and layout never count.
rulebook "small" version "1.1.0"
purpose "New rules"

const critical_slip = 65 % because "Draft: slip above 65 %"
const max_tilt      = 15 deg because "Assumption: tilt limit"
const half_tilt     = max_tilt / 2
const f_obs         = {L1: 0.2, L2: 0.5, L3: 1}
const fresh         = 2 cm because "Added"

settings {
  theoretical_slip = 10 %
  tolerance_growth = 5 cm/rad
}

obstacles {
  level L1 below 3 cm  buffer 2 cm
  level L2 below 10 cm buffer 8 cm
  level L3             buffer 10 cm
}

command max_turn: require abs(delta_heading) <= 90 deg because "Largest turn per command"
command new_rule: require abs(delta_position) <= 3 m

index I_s "wheel slip ratio" {
  value  = percentile 95 over time (max over wheels (abs(wheel.slip)))
  limit  = critical_slip
  weight = 1
  because "Slip"
}

index I_phi "pitch deviation" {
  value  = max over time (abs(pitch - ref.pitch))
  limit  = half_tilt
  weight = 1
}

index I_obs "obstacles" {
  value  = sum over parts (sum over levels (collision.hits * f_obs))
  limit  = 1
  weight = 1
}

chance hit_L3 = any over parts (collision.hits[L3] > 0) because "Table 1, level L3"
chance tilted = max over time (abs(pitch)) > max_tilt

combine {
  run        = max_weighted
  path       = mean
  confidence = 90 %
}

prescreen no_clear_collision: require I_obs < 1 and risk < 1
  because "Exclude clear collisions"

verdict acceptable_risk: require risk <= 70 % because "Risk limit"

rank by risk, energy
"""


def checked(text: str, path: str) -> CheckedRulebook:
    result = check_text(text, path)
    assert result.checked is not None, [d.message for d in result.diagnostics]
    return result.checked


def changes(diff: RuleDiff) -> dict[tuple[str, str], RuleChange]:
    return {(c.section, c.name): c for c in diff.changes}


def fields(change: RuleChange) -> dict[str, tuple[str | None, str | None]]:
    return {f.field: (f.old, f.new) for f in change.fields}


def test_every_section_reports_its_changes() -> None:
    diff = diff_rules(checked(OLD, "old.rules"), checked(NEW, "new.rules"),
                      "old.rules", "new.rules")
    found = changes(diff)
    assert {key: c.kind for key, c in found.items()} == {
        ("header", "header"): "changed",
        ("constant", "critical_slip"): "changed",
        ("constant", "max_tilt"): "changed",
        ("constant", "half_tilt"): "changed",
        ("constant", "gone"): "removed",
        ("constant", "fresh"): "added",
        ("setting", "theoretical_slip"): "changed",
        ("obstacle level", "L2"): "changed",
        ("command", "max_turn"): "changed",
        ("command", "old_rule"): "removed",
        ("command", "new_rule"): "added",
        ("index", "I_s"): "changed",
        ("index", "I_phi"): "changed",
        ("index", "I_obs"): "changed",
        ("chance", "hit_L3"): "changed",
        ("chance", "tilted"): "affected",
        ("combine", "combine"): "changed",
        ("prescreen", "no_clear_collision"): "changed",
        ("verdict", "acceptable_risk"): "changed",
        ("verdict", "rare_l3_hits"): "removed",
        ("ranking", "ranking"): "changed",
    }
    # Canonical section order.
    sections = [c.section for c in diff.changes]
    assert sections.index("header") < sections.index("constant") < sections.index("index") \
        < sections.index("combine") < sections.index("prescreen") < sections.index("ranking")
    assert diff.counts() == {"added": 2, "removed": 3, "changed": 15, "affected": 1}


def test_values_are_shown_as_written_and_in_si() -> None:
    found = changes(diff_rules(checked(OLD, "a"), checked(NEW, "b")))
    header = fields(found[("header", "header")])
    assert header == {"version": ('"1.0.0"', '"1.1.0"'),
                      "purpose": ('"Old rules"', '"New rules"')}
    tilt = found[("constant", "max_tilt")].fields[0]
    assert (tilt.old, tilt.new) == ("20 deg", "15 deg")
    assert (tilt.old_si, tilt.new_si) == ("0.349066 rad", "0.261799 rad")
    # Same text, other SI value: the constant it reads changed.
    half = found[("constant", "half_tilt")].fields[0]
    assert (half.old, half.new) == ("max_tilt / 2", "max_tilt / 2")
    assert (half.old_si, half.new_si) == ("0.174533 rad", "0.1309 rad")
    level = fields(found[("obstacle level", "L2")])
    assert level == {"buffer": ("5 cm", "8 cm")}
    slip = fields(found[("setting", "theoretical_slip")])
    assert slip == {"value": ("20 %", "10 %")}
    confidence = found[("combine", "combine")].fields[0]
    assert (confidence.field, confidence.old_si, confidence.new_si) == ("confidence", "0.95",
                                                                        "0.9")
    assert fields(found[("ranking", "ranking")]) == {"keys": ("risk, time, energy",
                                                              "risk, energy")}


def test_indices_compare_value_limit_weight_map_and_title() -> None:
    found = changes(diff_rules(checked(OLD, "a"), checked(NEW, "b")))
    slip = fields(found[("index", "I_s")])
    assert slip["value"] == ("max over time (max over wheels (abs(wheel.slip)))",
                             "percentile 95 over time (max over wheels (abs(wheel.slip)))")
    assert slip["limit"] == ("critical_slip", "critical_slip")  # SI moved: 0.7 → 0.65
    assert found[("index", "I_s")].reads_changed == ("critical_slip",)
    pitch = fields(found[("index", "I_phi")])
    assert pitch["title"] == ('"pitch"', '"pitch deviation"')
    assert pitch["weight"] == ("0.8", "1")
    assert found[("index", "I_phi")].reads_changed == ("half_tilt",)
    obstacles = fields(found[("index", "I_obs")])
    assert obstacles == {"map": ("max over parts (max over levels (collision.contact * f_obs))",
                                 None)}


def test_rationales_old_and_new_when_they_changed() -> None:
    found = changes(diff_rules(checked(OLD, "a"), checked(NEW, "b")))
    turn = found[("command", "max_turn")]
    assert turn.fields == ()
    assert turn.rationale_changed
    assert (turn.old_rationale, turn.rationale) == ("Turn limit", "Largest turn per command")
    slip = found[("constant", "critical_slip")]
    assert (slip.old_rationale, slip.rationale) == ("Slip above 70 % is critical",
                                                    "Draft: slip above 65 %")
    tilt = found[("constant", "max_tilt")]
    assert not tilt.rationale_changed and tilt.rationale == "Assumption: tilt limit"
    assert found[("constant", "gone")].rationale == "Removed later"
    assert found[("verdict", "acceptable_risk")].rationale == "Risk limit"


def test_added_and_removed_list_their_fields() -> None:
    found = changes(diff_rules(checked(OLD, "a"), checked(NEW, "b")))
    assert fields(found[("constant", "fresh")]) == {"value": (None, "2 cm")}
    assert found[("constant", "fresh")].fields[0].new_si == "0.02 m"
    assert fields(found[("command", "old_rule")]) == {
        "condition": ("abs(delta_position) <= 2 m", None)}
    assert fields(found[("verdict", "rare_l3_hits")]) == {
        "condition": ("chance(hit_L3) <= 5 %", None)}
    assert fields(found[("prescreen", "no_clear_collision")]) == {
        "condition": ("I_obs < 1", "I_obs < 1 and risk < 1")}


def test_comments_layout_and_order_do_not_count() -> None:
    reordered = OLD.replace('rulebook "small" version "1.0.0"',
                            '# a comment\nrulebook "small"   version "1.0.0"  # inline')
    moved = reordered.replace("chance tilted = max over time (abs(pitch)) > max_tilt\n", "")
    moved += "chance tilted = max over time (abs(pitch)) > max_tilt\n"
    diff = diff_rules(checked(OLD, "a"), checked(moved, "b"))
    assert diff.identical
    assert diff.old.sha256 != diff.new.sha256


def test_the_diff_is_json_data() -> None:
    diff = diff_rules(checked(OLD, "a.rules"), checked(NEW, "b.rules"), "a.rules", "b.rules")
    data = json.loads(json.dumps(diff.to_dict()))
    assert data["old"]["version"] == "1.0.0" and data["new"]["version"] == "1.1.0"
    assert data["old"]["label"] == "a.rules"
    assert not data["identical"]
    kinds = {(c["section"], c["name"]): c["kind"] for c in data["changes"]}
    assert kinds[("constant", "fresh")] == "added"
    tilt = next(c for c in data["changes"] if c["name"] == "max_tilt")
    assert tilt["fields"][0]["new_si"] == "0.261799 rad"


def test_the_markdown_effect_names_only_the_reasons_a_change_brought() -> None:
    """A pass that turns into a fail is said with the rule that now fails, not with the rules
    that were open before and still are; names and reasons with `|` stay in their cell."""
    from idefix_rules.diff.changelog import results_markdown
    from idefix_rules.diff.results import PathDiff, ResultsDiff, ResultsFileDiff, SideResult

    old = SideResult("pass", undecided=True, reasons=("speed_kept not decided",),
                     mean_risk=0.2, rank=1, runs=8)
    new = SideResult("fail", reasons=("speed_kept not decided", "acceptable_risk: 20 % > 10 %"),
                     mean_risk=0.2, rank=1, runs=8)
    kept = SideResult("fail", reasons=("a|b",), mean_risk=0.9, rank=2, runs=8)
    file = ResultsFileDiff("out/results.h5", "c", (PathDiff("x|y", old, new, 3),
                                                   PathDiff("z", kept, kept)),
                           ("x|y", "z"), ("x|y", "z"), "stored")
    text = results_markdown(ResultsDiff((file,)), "verdict", 1)
    rows = [line for line in text.splitlines() if line.startswith("| ") and "---" not in line]
    assert rows[1] == ("| x\\|y | **pass (not decided) → fail**: acceptable_risk: 20 % > 10 % | "
                       "20.0 % | 1 | 3 of 8 |")
    assert rows[2] == "| z | fail | 90.0 % | 2 | 0 of 8 |"
    assert text.endswith("Exit code 1: 1 path verdict(s) changed (fail-on verdict).")
