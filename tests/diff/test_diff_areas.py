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
    # no rule here reads the collision signals, and an area's own signals do not depend on its
    # level: another level changes no pass or fail
    found = diff(BASE.replace("crater keep_out level L3", "crater keep_out level L2"))
    assert (found[("area", "crater")].kind, found[("area", "crater")].direction) == \
        ("changed", "neutral")
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


# Rules that read the collision signals, which count every area as an obstacle of its level.
COLLIDING = BASE + """
const f_obs = {L1: 0.2, L2: 0.6, L3: 1}

index I_obs {
  value = sum over parts (sum over levels (collision.hits * f_obs))
  limit = 1
  weight = 1
}

chance hit_L1 = any over parts (collision.hits[L1] > 0)
chance hit_L3 = any over parts (collision.hits[L3] > 0)
chance touched_L3 = any over time (max over parts (collision.contact[L3]) > 0)
chance close = min over time (min over parts (collision.clearance)) < 5 cm

prescreen no_clear_collision: require I_obs < 1

verdict acceptable_risk: require risk <= 70 %
verdict rare_l1_hits: require chance(hit_L1) <= 5 %
verdict rare_l3_hits: require chance(hit_L3) <= 5 %
verdict rare_l3_contact: require chance(touched_L3) <= 5 %
verdict kept_clear: require chance(close) <= 5 %
"""
BLOCKER = "  area blocker keep_out level L1 buffer 1 cm\n"
WITH_BLOCKER = COLLIDING.replace("  area crater", BLOCKER + "  area crater")
# what an area of L1 moves: the rules reading L1's hits (or every level's) and the clearance
READ_BY_L1 = {("index", "I_obs"), ("chance", "hit_L1"), ("chance", "close"),
              ("prescreen", "no_clear_collision"), ("verdict", "acceptable_risk"),
              ("verdict", "rare_l1_hits"), ("verdict", "kept_clear")}


def colliding_diff(old_text: str, new_text: str):
    return changes(diff_rules(checked(old_text, "old.rules"), checked(new_text, "new.rules")))


def test_an_added_area_is_stricter_for_every_rule_reading_the_collisions_of_its_level():
    found = colliding_diff(COLLIDING, WITH_BLOCKER)
    assert (found[("area", "blocker")].kind, found[("area", "blocker")].direction) == \
        ("added", "stricter")
    affected = {key for key, change in found.items() if change.kind == "affected"}
    assert affected == READ_BY_L1  # not hit_L3, rare_l3_hits nor the contact at L3
    assert {found[key].direction for key in READ_BY_L1} == {"stricter"}
    index = found[("index", "I_obs")]
    assert (index.reads_changed, index.upstream) == (("collision.hits[L1]",), ("blocker",))
    assert found[("chance", "close")].reads_changed == ("collision.clearance",)
    assert found[("prescreen", "no_clear_collision")].reads_changed == ("I_obs",)


def test_a_removed_area_is_looser_for_the_same_rules():
    found = colliding_diff(WITH_BLOCKER, COLLIDING)
    assert (found[("area", "blocker")].kind, found[("area", "blocker")].direction) == \
        ("removed", "looser")
    assert {key for key, change in found.items() if change.kind == "affected"} == READ_BY_L1
    assert {found[key].direction for key in READ_BY_L1} == {"looser"}


def test_another_level_counts_the_area_there_instead():
    found = colliding_diff(COLLIDING, COLLIDING.replace("crater keep_out level L3",
                                                        "crater keep_out level L1"))
    # fewer L3 hits and contacts, more L1 hits; I_obs reads both: the direction is unknown
    assert found[("chance", "hit_L3")].direction == "looser"
    assert found[("verdict", "rare_l3_hits")].direction == "looser"
    assert found[("verdict", "rare_l3_contact")].direction == "looser"
    assert found[("verdict", "rare_l1_hits")].direction == "stricter"
    assert found[("index", "I_obs")].direction == "unknown"
    assert found[("verdict", "acceptable_risk")].direction == "unknown"
    assert found[("area", "crater")].direction == "unknown"
    assert ("chance", "close") not in found  # the clearance is to any obstacle, of any level


def test_a_lower_steep_threshold_moves_the_collisions_of_its_level():
    found = colliding_diff(COLLIDING, COLLIDING.replace("above 20 deg", "above 18 deg"))
    # a larger area: more contact, less clearance, more samples inside
    for key in (("chance", "on_scarp"), ("verdict", "scarp_kept"), ("chance", "touched_L3"),
                ("verdict", "rare_l3_contact"), ("chance", "close"), ("verdict", "kept_clear")):
        assert (found[key].kind, found[key].direction) == ("affected", "stricter"), key
    # but two steep patches that grow into one are one obstacle, hit once: its hits can fall
    for key in (("index", "I_obs"), ("chance", "hit_L3"), ("verdict", "rare_l3_hits"),
                ("prescreen", "no_clear_collision"), ("verdict", "acceptable_risk")):
        assert (found[key].kind, found[key].direction) == ("affected", "unknown"), key
    assert found[("area", "scarp")].direction == "unknown"
    assert ("chance", "hit_L1") not in found


def test_an_area_buffer_moves_its_own_signal_only():
    """The collision check gives an area the buffer of its level; its own buffer is the
    margin of ``area.NAME.buffer``."""
    found = colliding_diff(COLLIDING, COLLIDING.replace("keep_out level L3 buffer 10 cm",
                                                        "keep_out level L3 buffer 20 cm"))
    assert {key for key, change in found.items() if change.kind == "affected"} == {
        ("chance", "near_crater"), ("verdict", "crater_kept")}
    assert found[("area", "crater")].direction == "stricter"


def test_another_kind_is_unknown_for_the_rules_reading_its_level():
    found = colliding_diff(COLLIDING, COLLIDING.replace("area crater keep_out level L3",
                                                        "area crater unknown level L3"))
    assert found[("area", "crater")].direction == "unknown"
    assert found[("chance", "hit_L3")].direction == "unknown"
    assert ("chance", "hit_L1") not in found
