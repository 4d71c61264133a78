"""Named areas in the rule diff: listed with their fields, and which way a change goes."""

from __future__ import annotations

from test_diff_rules import changes, checked, fields

from idefix_rules.diff import diff_rules

BASE = """\
rulebook "areas" version "1.0.0"
purpose "Named areas in the diff"

obstacles {
  level L1 below 3 cm  buffer 2 cm
  level L2 below 10 cm buffer 5 cm
  level L3             buffer 10 cm
  area crater keep_out level L3 buffer 10 cm
  area scarp steep above 20 deg level L3 buffer 5 cm
}

index I { value = max over time (abs(pitch)) limit = 1 rad weight = 1 }

chance near_crater = any over time (area.crater.buffer > 0)
chance on_scarp = any over time (area.scarp.inside > 0)

verdict crater_kept: require chance(near_crater) <= 5 %
verdict scarp_kept: require chance(on_scarp) <= 5 %
"""


def diff(new_text: str):
    return changes(diff_rules(checked(BASE, "old.rules"), checked(new_text, "new.rules")))


def test_a_wider_buffer_is_stricter_and_a_narrower_looser():
    wider = diff(BASE.replace("keep_out level L3 buffer 10 cm", "keep_out level L3 buffer 12 cm"))
    change = wider[("area", "crater")]
    assert fields(change) == {"buffer": ("10 cm", "12 cm")}
    assert change.direction == "stricter"
    narrower = diff(BASE.replace("keep_out level L3 buffer 10 cm", "keep_out level L3 buffer 8 cm"))
    assert narrower[("area", "crater")].direction == "looser"


def test_a_lower_steep_threshold_is_stricter():
    assert diff(BASE.replace("above 20 deg", "above 18 deg"))[("area", "scarp")].direction == \
        "stricter"
    assert diff(BASE.replace("above 20 deg", "above 22 deg"))[("area", "scarp")].direction == \
        "looser"


def test_another_level_or_an_added_area_is_listed():
    found = diff(BASE.replace("crater keep_out level L3", "crater keep_out level L2"))
    assert found[("area", "crater")].direction == "unknown"
    added = diff(BASE.replace("  area scarp", "  area dark unknown level L2 buffer 5 cm\n"
                              "  area scarp"))
    assert added[("area", "dark")].kind == "added"


def test_rules_reading_a_changed_area_are_listed_as_affected():
    found = diff(BASE.replace("keep_out level L3 buffer 10 cm", "keep_out level L3 buffer 12 cm"))
    chance, verdict = found[("chance", "near_crater")], found[("verdict", "crater_kept")]
    assert (chance.kind, chance.direction, chance.upstream) == ("affected", "stricter",
                                                                ("crater",))
    assert (verdict.kind, verdict.direction) == ("affected", "stricter")
    # only the buffer moved: a rule reading the inside of the area is not affected
    assert ("chance", "on_scarp") not in found
    steeper = diff(BASE.replace("above 20 deg", "above 22 deg"))
    assert steeper[("chance", "on_scarp")].direction == "looser"
    assert steeper[("verdict", "scarp_kept")].kind == "affected"
