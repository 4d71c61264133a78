"""Rules affected indirectly: a prescreen, verdict, chance or index whose own text did not
change but which reads a changed index, chance or constant, however indirectly, is listed as
``affected`` with the names it reads, the changes it comes from and, where the rule model
decides it, its direction."""

from __future__ import annotations

import json

import pytest

from idefix_rules.cli import main
from idefix_rules.diff import RuleDiff, diff_rules
from idefix_rules.rulebook import check_text

BASE = """\
rulebook "indirect" version "1.0.0"
purpose "Rules that read other rules"

const critical_slip = 70 % because "Slip above 70 % is critical"
const f_obs         = {L1: 0.2, L2: 0.6, L3: 1} because "Factor per level"
const max_speed     = 1 cm/s because "Speed limit"

obstacles {
  level L1 below 3 cm  buffer 2 cm
  level L2 below 10 cm buffer 5 cm
  level L3             buffer 10 cm
}

index I_s "slip" {
  value  = max over time (max over wheels (abs(wheel.slip)))
  limit  = critical_slip
  weight = 1
  because "Slip"
}

index I_obs "obstacles" {
  value  = sum over parts (sum over levels (collision.hits * f_obs))
  limit  = 1
  weight = 1
  because "Eq. 4"
}

chance too_fast = max over time (speed) > 2 cm/s because "Speed"
chance slipping = max over time (max over wheels (abs(wheel.slip))) > critical_slip
  because "Critical slip at any time"

prescreen no_clear_collision: require I_obs < 1 because "Critical hits"
prescreen calm_slip: require I_s < 1 because "Slip"

verdict acceptable_risk: require risk <= 70 % because "Mean risk"
verdict speed_kept: require chance(too_fast) <= 5 % because "Speed"
verdict slip_kept: require chance(slipping) <= 10 % because "Slip"

rank by risk, time, energy
"""


def diff(old_text: str, new_text: str) -> RuleDiff:
    old = check_text(old_text, "old.rules")
    new = check_text(new_text, "new.rules")
    assert old.checked is not None and new.checked is not None, (old.diagnostics,
                                                                 new.diagnostics)
    return diff_rules(old.checked, new.checked)


def changed(text: str, *replacements: tuple[str, str]) -> str:
    for before, after in replacements:
        assert text.count(before) == 1, before
        text = text.replace(before, after)
    return text.replace('version "1.0.0"', 'version "1.1.0"')


def table(result: RuleDiff) -> dict[tuple[str, str], tuple[str, str, tuple[str, ...],
                                                           tuple[str, ...]]]:
    return {(c.section, c.name): (c.kind, c.direction, c.reads_changed, c.upstream)
            for c in result.changes if c.section != "header"}


def test_a_factor_reaches_the_prescreen_and_the_risk_through_its_index() -> None:
    result = diff(BASE, changed(BASE, ("{L1: 0.2, L2: 0.6, L3: 1}", "{L1: 0.3, L2: 0.8, L3: 1}")))
    assert table(result) == {
        ("constant", "f_obs"): ("changed", "stricter", (), ()),
        ("index", "I_obs"): ("affected", "stricter", ("f_obs",), ("f_obs",)),
        ("prescreen", "no_clear_collision"): ("affected", "stricter", ("I_obs",), ("f_obs",)),
        ("verdict", "acceptable_risk"): ("affected", "stricter", ("risk",), ("f_obs",)),
    }


def test_a_lower_factor_is_looser_all_the_way_down() -> None:
    result = diff(BASE, changed(BASE, ("{L1: 0.2, L2: 0.6, L3: 1}", "{L1: 0.1, L2: 0.6, L3: 1}")))
    directions = {c.name: c.direction for c in result.changes if c.kind == "affected"}
    assert directions == {"I_obs": "looser", "no_clear_collision": "looser",
                          "acceptable_risk": "looser"}


def test_a_threshold_reaches_the_rules_two_steps_away() -> None:
    # critical_slip → I_s (limit) → prescreen calm_slip, and → the risk → acceptable_risk;
    # critical_slip → chance slipping → verdict slip_kept
    result = diff(BASE, changed(BASE, ("critical_slip = 70 %", "critical_slip = 60 %"),
                                ("above 70 %", "above 60 %")))
    assert table(result) == {
        ("constant", "critical_slip"): ("changed", "stricter", (), ()),
        ("index", "I_s"): ("changed", "stricter", ("critical_slip",), ()),
        ("chance", "slipping"): ("affected", "stricter", ("critical_slip",),
                                 ("critical_slip",)),
        ("prescreen", "calm_slip"): ("affected", "stricter", ("I_s",), ("I_s", "critical_slip")),
        ("verdict", "acceptable_risk"): ("affected", "stricter", ("risk",),
                                         ("I_s", "critical_slip")),
        ("verdict", "slip_kept"): ("affected", "stricter", ("slipping",),
                                   ("critical_slip",)),
    }


def test_a_changed_chance_threshold_loosens_the_verdict_that_reads_the_chance() -> None:
    result = diff(BASE, changed(BASE, ("(speed) > 2 cm/s", "(speed) > 3 cm/s")))
    assert table(result) == {
        ("chance", "too_fast"): ("changed", "looser", (), ()),
        ("verdict", "speed_kept"): ("affected", "looser", ("too_fast",), ("too_fast",)),
    }


def test_a_new_index_shape_leaves_the_direction_to_the_cases() -> None:
    result = diff(BASE, changed(BASE, ("value  = max over time (max over wheels",
                                       "value  = final over time (max over wheels")))
    kinds = table(result)
    assert kinds[("index", "I_s")][:2] == ("changed", "unknown")
    assert kinds[("prescreen", "calm_slip")] == ("affected", "unknown", ("I_s",), ("I_s",))
    assert kinds[("verdict", "acceptable_risk")] == ("affected", "unknown", ("risk",), ("I_s",))


def test_a_weight_moves_the_risk_but_not_the_rules_reading_the_index() -> None:
    result = diff(BASE, changed(BASE, ("limit  = 1\n  weight = 1\n  because \"Eq. 4\"",
                                       "limit  = 1\n  weight = 0.5\n  because \"Eq. 4\"")))
    assert table(result) == {
        ("index", "I_obs"): ("changed", "looser", (), ()),
        ("verdict", "acceptable_risk"): ("affected", "looser", ("risk",), ("I_obs",)),
    }


def test_an_added_index_raises_the_risk_only() -> None:
    added = """
index I_v "speed" {
  value  = max over time (speed)
  limit  = max_speed
  weight = 1
  because "Speed"
}
"""
    result = diff(BASE, changed(BASE, ("\nchance too_fast", added + "\nchance too_fast")))
    assert table(result) == {
        ("index", "I_v"): ("added", "stricter", (), ()),
        ("verdict", "acceptable_risk"): ("affected", "stricter", ("risk",), ("I_v",)),
    }


@pytest.mark.parametrize("replacement", [
    ('because "Eq. 4"', 'because "Eq. 4 of the paper"'),  # a rationale
    ('index I_obs "obstacles"', 'index I_obs "obstacle hits"'),  # a title
    ("rank by risk, time, energy", "rank by risk, energy, time"),  # the ranking reads risk
])
def test_wording_and_ranking_affect_no_rule(replacement: tuple[str, str]) -> None:
    result = diff(BASE, changed(BASE, replacement))
    assert [c.kind for c in result.changes if c.section != "header"] == ["changed"]


def test_text_and_json_show_what_it_reads_and_where_that_comes_from(
        tmp_path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "250")
    old, new = tmp_path / "old.rules", tmp_path / "new.rules"
    old.write_text(BASE, encoding="utf-8")
    new.write_text(changed(BASE, ("{L1: 0.2, L2: 0.6, L3: 1}", "{L1: 0.3, L2: 0.8, L3: 1}")),
                   encoding="utf-8")
    assert main(["diff", str(old), str(new)]) == 0
    lines = [" ".join(line.replace("│", " ").split()) for line in capsys.readouterr()
             .out.splitlines()]
    assert ("prescreen no_clear_collision affected stricter reads changed: I_obs (through "
            "f_obs) Critical hits") in lines
    assert "2 changed, 3 affected; 4 stricter, 1 neutral" in lines  # the header is neutral
    assert main(["diff", "--format", "json", str(old), str(new)]) == 0
    changes = {c["name"]: c for c in json.loads(capsys.readouterr().out)["rules"]["changes"]}
    assert {key: changes["no_clear_collision"][key] for key in
            ("section", "kind", "direction", "reads_changed", "upstream")} == {
        "section": "prescreen", "kind": "affected", "direction": "stricter",
        "reads_changed": ["I_obs"], "upstream": ["f_obs"]}
    assert changes["f_obs"]["upstream"] == []
    assert main(["diff", "--format", "md", str(old), str(new)]) == 0
    assert ("- affected prescreen **no_clear_collision**: reads `I_obs`, which changed "
            "(through `f_obs`) — _Critical hits_") in capsys.readouterr().out
