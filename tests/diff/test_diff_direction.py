"""Direction labels of the rule diff: stricter, looser, neutral, unknown — by example, and as
a property: a change labelled stricter never turns a failing path into a passing one."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from idefix_rules.cli import main
from idefix_rules.diff import diff_rules
from idefix_rules.rulebook import check_text
from idefix_rules.rulebook.check import check
from idefix_rules.rulebook.compile import compile_rulebook
from idefix_rules.rulebook.strategies import (
    RunRanges,
    realistic_runs,
    rulebook_variations,
)
from idefix_rules.testing.properties import check_direction

# Frozen copies (tests/fixtures/rulebooks): the edits below name their exact text.
FIXTURES = Path(__file__).parents[1] / "fixtures" / "rulebooks"
FROZEN = FIXTURES / "idefix-ops-1.1.0.rules"
DEFAULT = FROZEN.read_text(encoding="utf-8")
HISTORY = FIXTURES / "idefix-ops-0.9.0.rules"


SLIP = "const critical_slip            = "


def labels(old_text: str, new_text: str) -> dict[tuple[str, str], str]:
    old = check_text(old_text, "old.rules").checked
    new = check_text(new_text, "new.rules").checked
    assert old is not None and new is not None
    return {(c.section, c.name): c.direction for c in diff_rules(old, new).changes}


def edited(old: str, new: str, count: int = 1) -> str:
    assert DEFAULT.count(old) >= 1, old
    return DEFAULT.replace(old, new, count)


@pytest.mark.parametrize(("old", "new", "where", "expected"), [
    # a lower critical slip makes I_s larger: stricter; higher: looser
    (SLIP + "70 %", SLIP + "50 %", ("constant", "critical_slip"), "stricter"),
    (SLIP + "70 %", SLIP + "80 %", ("constant", "critical_slip"), "looser"),
    (SLIP + "70 %", SLIP + "0.7", ("constant", "critical_slip"), "neutral"),
    # verdict threshold on the path risk
    ("require risk <= 70 %", "require risk <= 80 %", ("verdict", "acceptable_risk"), "looser"),
    ("require risk <= 70 %", "require risk <= 60 %", ("verdict", "acceptable_risk"), "stricter"),
    # a comparison that gains or loses its boundary: `<=` → `<` holds less often
    ("require risk <= 70 %", "require risk < 70 %", ("verdict", "acceptable_risk"), "stricter"),
    ("require I_obs < 1", "require I_obs <= 1", ("prescreen", "no_clear_collision"), "looser"),
    ("abs(delta_position) >= min_delta_position", "abs(delta_position) > min_delta_position",
     ("command", "min_motion"), "stricter"),
    # a chance that counts more runs, read by a verdict with an upper bound
    ("(collision.hits[L3] > 0)", "(collision.hits[L3] >= 0)", ("chance", "hit_L3"), "stricter"),
    # the side swapped, not only the boundary: monotonicity cannot say
    ("require risk <= 70 %", "require risk >= 70 %", ("verdict", "acceptable_risk"), "unknown"),
    ("require risk <= 70 %", "require risk == 70 %", ("verdict", "acceptable_risk"), "unknown"),
    # command rule threshold
    ("<= max_turn\n", "<= 60 deg\n", ("command", "max_turn_angle"), "unknown"),
    ("const max_turn                 = 90 deg", "const max_turn                 = 120 deg",
     ("constant", "max_turn"), "looser"),
    ("const min_delta_position       = 5 cm", "const min_delta_position       = 8 cm",
     ("constant", "min_delta_position"), "stricter"),
    # weights and factors raise the risk
    ("limit  = critical_sinkage\n  weight = 1", "limit  = critical_sinkage\n  weight = 0.5",
     ("index", "I_ds"), "looser"),
    ("{L1: 0.2, L2: 0.6, L3: 1}", "{L1: 0.3, L2: 0.6, L3: 1}", ("constant", "f_obs"), "stricter"),
    ("{L1: 0.2, L2: 0.6, L3: 1}", "{L1: 0.3, L2: 0.5, L3: 1}", ("constant", "f_obs"), "unknown"),
    # a chance threshold read by a verdict with an upper bound
    ("const max_acceleration         = 3 mm/s^2", "const max_acceleration         = 2 mm/s^2",
     ("chance", "too_abrupt"), "stricter"),
    # a reducer swap changes the shape: monotonicity cannot say
    ("max over time (abs(roll - ref.roll))", "min over time (abs(roll - ref.roll))",
     ("index", "I_psi"), "unknown"),
    # the percentile parameter: a higher percentile is a larger value
    ("percentile 95 over time", "percentile 99 over time", ("index", "I_s"), "stricter"),
    # settings and obstacle levels
    ("tolerance_growth = 5 cm/rad", "tolerance_growth = 8 cm/rad", ("setting", "tolerance_growth"),
     "looser"),
    ("level L3             buffer 10 cm", "level L3             buffer 20 cm",
     ("obstacle level", "L3"), "neutral"),
    ("confidence = 95 %", "confidence = 99 %", ("combine", "combine"), "neutral"),
    ("confidence = 95 %", "confidence = 95 %\n  indifference = 2 %", ("combine", "combine"),
     "neutral"),
    ("rank by risk, time, energy", "rank by risk, energy, time", ("ranking", "ranking"),
     "neutral"),
])
def test_labels_of_single_changes(old, new, where, expected):
    found = labels(DEFAULT, edited(old, new))
    assert found[where] == expected


def test_added_and_removed_requirements():
    extra = DEFAULT + '\nverdict quick: require time <= 10 min\n'
    assert labels(DEFAULT, extra)[("verdict", "quick")] == "stricter"
    assert labels(extra, DEFAULT)[("verdict", "quick")] == "looser"
    assert labels(DEFAULT, DEFAULT + "\nchance tilted = max over time (abs(roll)) > 5 deg\n")[
        ("chance", "tilted")] == "neutral"


def test_version_warnings():
    changed = edited("require risk <= 70 %", "require risk <= 60 %")
    old = check_text(DEFAULT, "old.rules").checked
    same_version = check_text(changed, "new.rules").checked
    assert diff_rules(old, same_version).warnings == (
        "the rules changed but the version did not (still 1.1.0): raise it before uplink",)
    backwards = check_text(changed.replace('version "1.1.0"', 'version "0.9.1"'), "n.rules")
    assert diff_rules(old, backwards.checked).warnings == (
        "the version went backwards: 1.1.0 → 0.9.1",)
    forwards = check_text(changed.replace('version "1.1.0"', 'version "1.2.0"'), "n.rules")
    assert diff_rules(old, forwards.checked).warnings == ()
    assert diff_rules(old, old).warnings == ()


@pytest.mark.parametrize(("before", "after", "backwards"), [
    ("1.3.0-rc.2", "1.3.0-rc.10", False),  # numeric identifiers compare as numbers
    ("1.3.0-rc.10", "1.3.0-rc.2", True),
    ("1.3.0-rc.9", "1.3.0", False),  # a release after its pre-releases
    ("1.3.0", "1.3.0-rc.9", True),
    ("1.3.0-alpha", "1.3.0-alpha.1", False),  # more identifiers, the ones before equal
    ("1.3.0-9", "1.3.0-alpha", False),  # numeric below alphanumeric
    ("1.3.0-beta", "1.3.0-alpha.9", True),
])
def test_pre_release_versions_go_up_in_semver_precedence(
        before: str, after: str, backwards: bool) -> None:
    changed = edited("require risk <= 70 %", "require risk <= 60 %")
    old = check_text(DEFAULT.replace('version "1.1.0"', f'version "{before}"'), "o.rules")
    new = check_text(changed.replace('version "1.1.0"', f'version "{after}"'), "n.rules")
    assert diff_rules(old.checked, new.checked).warnings == (
        (f"the version went backwards: {before} → {after}",) if backwards else ())


def test_cli_table_json_and_markdown_carry_the_labels(capsys):
    assert main(["diff", str(HISTORY), str(FROZEN), "--format", "json"]) == 0
    rules = json.loads(capsys.readouterr().out)["rules"]
    by_name = {(c["section"], c["name"]): c["direction"] for c in rules["changes"]}
    assert by_name[("constant", "critical_tilt")] == "stricter"     # 20 deg → 15 deg
    assert by_name[("constant", "critical_slip")] == "looser"       # 65 % → 70 %
    assert by_name[("verdict", "acceptable_risk")] == "stricter"    # 75 % → 70 %
    assert by_name[("prescreen", "reference_not_critical")] == "looser"  # removed
    assert by_name[("index", "I_s")] == "unknown"                   # max → percentile 95
    assert rules["directions"]["stricter"] >= 5
    assert main(["diff", str(HISTORY), str(FROZEN)]) == 0
    table = capsys.readouterr().out
    assert "direction" in table and "stricter" in table and "looser" in table
    assert main(["diff", str(HISTORY), str(FROZEN), "--format", "md"]) == 0
    md = capsys.readouterr().out
    assert md.startswith("## idefix-ops 1.1.0 (from idefix-ops 0.9.0)")
    assert "### Stricter" in md and "### Looser" in md
    assert "- changed constant **critical_tilt**: value `20 deg` → `15 deg`" in md


def test_cli_warns_when_the_version_did_not_move(tmp_path, capsys):
    new = tmp_path / "new.rules"
    new.write_text(edited("require risk <= 70 %", "require risk <= 60 %"), encoding="utf-8")
    assert main(["diff", str(FROZEN), str(new)]) == 0
    assert "warning: the rules changed but the version did not" in capsys.readouterr().out


MODEL = check_text(DEFAULT, "idefix-ops.rules").checked
# Runs that sit around the frozen rulebook's limits, so paths both pass and fail.
NARROW = RunRanges(slip=(0.0, 0.5), slip_angle=0.8, sinkage=0.035, tilt=0.16, drift=0.008,
                   heading_drift=0.16, hits=0, stuck=False, max_wheel_rate=0.05, runs=(2, 6),
                   samples=(12, 30), step=(2.0, 4.0))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_a_stricter_change_never_turns_a_fail_into_a_pass(data):
    assert MODEL is not None
    description, variant = data.draw(rulebook_variations(MODEL.rulebook))
    checked = check(variant).checked
    assert checked is not None
    changes = [c for c in diff_rules(MODEL, checked).changes if c.section != "header"]
    direction = changes[0].direction if len(changes) == 1 else \
        ("neutral" if not changes else "unknown")
    if len(changes) > 1:  # a constant and the rules that read it: all must agree
        found = {c.direction for c in changes} - {"neutral"}
        direction = found.pop() if len(found) == 1 else "unknown"
    event(f"direction: {direction}")
    event(f"changed: {description.split(' ')[0]}")
    signals, context = data.draw(realistic_runs(NARROW))
    before, after = check_direction(compile_rulebook(MODEL), compile_rulebook(checked),
                                    direction, signals, context)
    event(f"{direction}: {'pass' if before else 'fail'} → {'pass' if after else 'fail'}")


STEEP = """
const critical_inclination = 20 deg
  because "Terrain inclined more than 20 deg is highly inclined"
chance on_steep = any over time (area.highly_inclined.inside > 0)
verdict steep_avoided: require chance(on_steep) <= 1 %
"""
L3 = "  level L3             buffer 10 cm\n"


def test_a_constant_read_by_an_area_moves_the_area_and_the_rules_that_read_it() -> None:
    """A lower steep threshold makes the area larger: more samples on it, stricter. The area
    is also an obstacle of L3, and the number of its patches hit can fall as well as rise (two
    that grow into one are hit once): the rules counting L3 hits, and the change with them,
    are unknown, not neutral."""
    old = edited(L3, L3 + "  area highly_inclined steep above critical_inclination level L3 "
                 "buffer 5 cm\n") + STEEP
    new = old.replace("critical_inclination = 20 deg", "critical_inclination = 15 deg")
    found = labels(old, new)
    assert found[("chance", "on_steep")] == found[("verdict", "steep_avoided")] == "stricter"
    assert found[("index", "I_obs")] == found[("chance", "hit_L3")] == "unknown"
    assert found[("prescreen", "no_clear_collision")] == "unknown"
    assert found[("verdict", "acceptable_risk")] == found[("verdict", "rare_l3_hits")] == \
        "unknown"
    assert found[("constant", "critical_inclination")] == "unknown"
    assert found[("area", "highly_inclined")] == "unknown"
    looser = labels(old, old.replace("critical_inclination = 20 deg",
                                     "critical_inclination = 25 deg"))
    assert looser[("chance", "on_steep")] == looser[("verdict", "steep_avoided")] == "looser"
    assert looser[("constant", "critical_inclination")] == "unknown"


NEAR_L3 = """
chance near_l3 = any over parts (collision.buffer[L3] > 0)
verdict l3_kept_at_a_distance: require chance(near_l3) <= 5 %
index I_far "off course" {
  value  = final over time (drift / tolerance_radius)
  limit  = 1
  weight = 0.5
}
"""


@pytest.mark.parametrize(("old", "new", "setting", "affected", "expected"), [
    # a wider L3 buffer flags more samples in collision.buffer[L3]: stricter
    ("level L3             buffer 10 cm", "level L3             buffer 20 cm",
     ("obstacle level", "L3"), [("chance", "near_l3"), ("verdict", "l3_kept_at_a_distance")],
     "stricter"),
    ("level L3             buffer 10 cm", "level L3             buffer 5 cm",
     ("obstacle level", "L3"), [("chance", "near_l3")], "looser"),
    # a faster-growing tolerance radius lowers drift / tolerance_radius: looser
    ("tolerance_growth = 5 cm/rad", "tolerance_growth = 10 cm/rad",
     ("setting", "tolerance_growth"), [("index", "I_far"), ("verdict", "acceptable_risk")],
     "looser"),
    # which rocks are of a level moves every signal per level: unknown, and said
    ("level L1 below 3 cm", "level L1 below 5 cm", ("obstacle level", "L1"),
     [("chance", "near_l3"), ("index", "I_obs")], "unknown"),
])
def test_a_setting_or_obstacle_level_lists_the_rules_it_moves_with_their_direction(
        old: str, new: str, setting: tuple[str, str], affected: list[tuple[str, str]],
        expected: str) -> None:
    before = DEFAULT + NEAR_L3
    assert before.count(old) == 1, old
    found = labels(before, before.replace(old, new))
    assert found[setting] == expected
    for where in affected:
        assert found.get(where) == expected, (where, found)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_a_comparison_that_gains_its_boundary_turns_passes_into_fails_only_when_stricter(data):
    """Runs without L3 hits sit on the boundary of `hits[L3] > 0`: with `>= 0` every run
    counts as a hit and `rare_l3_hits` fails. The label must allow that (stricter), and the
    opposite label must not."""
    base = compile_rulebook(MODEL)
    changed_text = edited("(collision.hits[L3] > 0)", "(collision.hits[L3] >= 0)")
    assert labels(DEFAULT, changed_text)[("chance", "hit_L3")] == "stricter"
    changed = check_text(changed_text, "new.rules").checked
    assert changed is not None
    signals, context = data.draw(realistic_runs(NARROW))
    before, after = check_direction(base, compile_rulebook(changed), "stricter", signals, context)
    assert not after  # every run now hits L3
    event(f"{'pass' if before else 'fail'} → fail")
    if before:
        with pytest.raises(AssertionError, match="looser change turned a pass into a fail"):
            check_direction(base, compile_rulebook(changed), "looser", signals, context)


# A named area is an obstacle of its level: a change of one moves what the collision check
# gives, not how the rules read it. Its footprint in a run: hit (contact at one sample, the
# clearance 0 there), its buffer entered (clearance within 5 cm) or kept far from.
CLEAR = """
chance close = min over time (min over parts (collision.clearance)) < 5 cm
verdict kept_clear: require chance(close) <= 5 %
"""
# Rules that read the hits of one level each: moving an area from L1 to L3 is stricter here.
HITS = """\
rulebook "hits" version "1.0.0"
purpose "Hits of one level each"

obstacles {
  level L1 below 3 cm  buffer 2 cm
  level L2 below 10 cm buffer 5 cm
  level L3             buffer 10 cm
}

index I_phi { value = max over time (abs(pitch)) limit = 1 rad weight = 1 }

chance hit_L1 = any over parts (collision.hits[L1] > 0)
chance hit_L3 = any over parts (collision.hits[L3] > 0)

verdict rare_l3_hits: require chance(hit_L3) <= 5 %
"""
LEVEL_INDEX = {"L1": 0, "L2": 1, "L3": 2}


def with_area(text: str, level: str | None) -> str:
    if level is None:
        return text
    line = "  level L3             buffer 10 cm\n"
    assert text.count(line) == 1
    return text.replace(line, line + f"  area blocker keep_out level {level} buffer 1 cm\n")


def with_footprint(signals: dict, level: str | None, states: list[str], sample: int) -> dict:
    """The runs as the collision check gives them with the area at ``level`` (None: no area);
    ``states[run]``: hit, near or far. Areas are checked against the wheels (part 0)."""
    if level is None:
        return signals
    out = {name: np.array(value, dtype=float, copy=True) for name, value in signals.items()}
    k = LEVEL_INDEX[level]
    for run, state in enumerate(states):
        if state == "hit":
            out["collision.hits"][run, 0, k] += 1
            out["collision.contact"][run, sample, 0, k] = 1.0
            out["collision.clearance"][run, sample, 0] = 0.0
        elif state == "near":
            out["collision.buffer"][run, 0, k] += 1
            out["collision.clearance"][run, sample, 0] = min(
                out["collision.clearance"][run, sample, 0], 0.03)
    return out


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_an_area_change_never_moves_a_path_against_its_label(data):
    """An area added, removed or moved to another level, on rulebooks reading the hits of every
    level (I_obs), of one level each and the clearance: the label of the change (with the
    rules it affects: all must agree) holds on the runs with the area's footprint counted at
    its old level for the old rulebook and at its new one for the new rulebook."""
    bases = {"operations and clearance": DEFAULT + CLEAR, "hits of one level each": HITS}
    base = bases[data.draw(st.sampled_from(sorted(bases)), label="rulebook")]
    levels = data.draw(st.lists(st.sampled_from([None, "L1", "L2", "L3"]), min_size=2,
                                max_size=2, unique=True), label="levels old, new")
    old_checked = check_text(with_area(base, levels[0]), "old.rules").checked
    new_checked = check_text(with_area(base, levels[1]), "new.rules").checked
    assert old_checked is not None and new_checked is not None
    found = {c.direction for c in diff_rules(old_checked, new_checked).changes
             if c.section != "header"} - {"neutral"}
    direction = found.pop() if len(found) == 1 else ("neutral" if not found else "unknown")
    event(f"{levels[0]} → {levels[1]}: {direction}")
    signals, context = data.draw(realistic_runs(NARROW))
    runs, samples = signals["t"].shape
    states = data.draw(st.lists(st.sampled_from(["hit", "near", "far"]), min_size=runs,
                                max_size=runs), label="footprint")
    sample = data.draw(st.integers(0, samples - 1), label="sample")
    before, after = check_direction(
        compile_rulebook(old_checked), compile_rulebook(new_checked), direction,
        with_footprint(signals, levels[0], states, sample), context,
        new_signals=with_footprint(signals, levels[1], states, sample))
    event(f"{direction}: {'pass' if before else 'fail'} → {'pass' if after else 'fail'}")


def test_an_area_moved_from_l1_to_l3_is_stricter_where_only_l3_counts():
    """The labels the property above meets on the rulebook reading one level each."""
    found = labels(with_area(HITS, "L1"), with_area(HITS, "L3"))
    assert found[("area", "blocker")] == found[("verdict", "rare_l3_hits")] == "stricter"
    assert found[("chance", "hit_L1")] == "neutral"  # no verdict reads it
    assert labels(with_area(HITS, "L3"), with_area(HITS, "L1"))[("area", "blocker")] == "looser"
    assert labels(HITS, with_area(HITS, "L1"))[("area", "blocker")] == "neutral"
    assert labels(DEFAULT + CLEAR, with_area(DEFAULT + CLEAR, "L2"))[("area", "blocker")] == \
        "stricter"
