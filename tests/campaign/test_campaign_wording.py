"""Values in the author's units, verdicts in words, and the decision."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest
from hypothesis import event, given
from hypothesis import strategies as st

from idefix_rules.campaign.input.wording import (
    DisplayUnits,
    number,
    parameter_text,
    rule_text,
    verdict_reasons,
    violation_text,
)
from idefix_rules.campaign.outcome.decision import decide
from idefix_rules.rulebook.results import CommandViolation

CAMPAIGN = """\
uncertainty:
  parameters:
    initial.x: {distribution: normal, mean: "0 m", std: "1 cm"}
    soil.cohesion: {distribution: log_normal, median: "250 Pa", sigma: 0.4}
    soil.friction_angle: {distribution: uniform, low: "30 deg", high: "45 deg"}
    soil.shear_modulus_K: {distribution: truncated_normal, mean: "1.4 cm", std: "0.2 cm"}
paths:
  turn:
    - {max_wheel_rate: "0.05 rad/s", delta_position: "0 m", delta_heading: "120 deg"}
    - {max_wheel_rate: "3 deg/s", delta_position: "50 cm", delta_heading: "0 deg"}
"""


def test_a_rejected_point_turn_speaks_degrees() -> None:
    units = DisplayUnits.from_campaign_text(CAMPAIGN)
    violation = CommandViolation("max_turn_angle", 1, {"delta_heading": 2 * math.pi / 3},
                                 "Largest allowed turn angle per command", "…")
    text = violation_text(violation, units)
    assert text == ("command 1 breaks rule 'max_turn_angle' (delta_heading = 120 deg): "
                    "Largest allowed turn angle per command")
    # A unit the campaign wrote only with a zero value still counts; a non-zero one wins.
    assert units.unit_of("delta_position") == "cm"
    assert units.unit_of("max_wheel_rate") == "rad/s"
    # Derived quantities the campaign never wrote fall back to the unit people use.
    assert units.show("speed", 0.0125) == "12.5 mm/s"


def test_sampled_parameters_in_the_campaign_units() -> None:
    units = DisplayUnits.from_campaign_text(CAMPAIGN)
    assert parameter_text("soil.cohesion", 312.34, "kg/(m·s^2)", units) == "312 Pa"
    assert parameter_text("soil.friction_angle", math.radians(37.5), "rad", units) == "37.5 deg"
    assert parameter_text("soil.shear_modulus_K", 0.0142, "m", units) == "1.42 cm"
    assert parameter_text("initial.yaw", math.radians(-1.5), "rad", units) == "-1.5 deg"
    # "mean: 0 m, std: 1 cm": the non-zero value's unit.
    assert parameter_text("initial.x", -0.0212, "m", units) == "-2.12 cm"
    # An unknown stored unit is shown as stored, never converted wrongly.
    assert parameter_text("toy.slip", 0.15, "1", units) == "0.15"


@pytest.mark.parametrize(("value", "text"), [(0.0, "0"), (120.00000001, "120"),
                                              (0.000123456, "0.000123"), (747.04, "747"),
                                              (50.0, "50"), (-2.25, "-2.25")])
def test_numbers_keep_three_significant_digits(value: float, text: str) -> None:
    assert number(value) == text


def _rule(passed: bool, decided: bool, value: float, threshold: float,
          statistic: str = "risk") -> dict[str, object]:
    return {"name": "r", "passed": passed, "decided": decided, "statistic": statistic,
            "value": value, "interval": [value - 0.02, value + 0.02], "threshold": threshold,
            "message": "rulebook message"}


def test_verdict_rules_in_percent_just_inside_and_outside() -> None:
    assert rule_text(_rule(False, True, 0.7001, 0.7)) == \
        "r: risk 70 % (95 % family-wise bounds 68–72 %) is above the limit 70 %"
    assert rule_text(_rule(True, True, 0.6999, 0.7)).endswith("within the limit 70 %")
    assert "not decided: the limit 70 % lies inside the interval" in rule_text(
        _rule(True, False, 0.69, 0.7))
    assert rule_text(_rule(False, True, 0.2344, 0.05, "chance(too_abrupt)")).startswith(
        "r: chance(too_abrupt) 23.4 %")
    # A compound condition has no single statistic: the rulebook's own message is kept.
    assert rule_text({"name": "c", "statistic": None, "message": "both"}) == "c: both"
    # Decided failures explain a verdict; undecided rules only when nothing failed for sure.
    verdict = {"rules": [_rule(False, True, 0.9, 0.7), _rule(True, False, 0.69, 0.7)]}
    assert len(verdict_reasons(verdict)) == 1


def _path(name: str, verdict: str, rank: int | None, undecided: bool = False,
          reasons: tuple[str, ...] = ()) -> SimpleNamespace:
    return SimpleNamespace(name=name, verdict=verdict, rank=rank, undecided=undecided,
                           reasons=list(reasons))


def test_decision_send_none_unsettled() -> None:
    sent = decide([_path("a", "fail", 2, reasons=("x",)), _path("b", "pass", 1)])
    assert (sent.kind, sent.path) == ("send", "b")
    none = decide([_path("straight", "fail", 3, reasons=("acceptable_risk: …",)),
                   _path("smooth", "fail", 1, reasons=("acceleration_kept: …",)),
                   _path("sharp", "rejected", None)])
    assert (none.kind, none.path) == ("none", "smooth")
    assert none.text.startswith("no chain is acceptable; least bad is smooth (rank 1 of 2)")
    assert "acceleration_kept" in none.text
    unsettled = decide([_path("a", "pass", 1, undecided=True), _path("b", "fail", 2)])
    assert (unsettled.kind, unsettled.path) == ("unsettled", "a")
    nothing = decide([_path("sharp", "rejected", None)])
    assert nothing.kind == "none" and nothing.path is None
    # A decided pass is sent even when a better-ranked path is undecided, and it says so.
    both = decide([_path("a", "pass", 1, undecided=True), _path("b", "pass", 2)])
    assert both.path == "b" and "a ranks better but is not decided yet" in both.text


VERDICTS = ("pass", "fail", "rejected", "excluded", "error")


@st.composite
def campaigns(draw: st.DrawFn) -> list[SimpleNamespace]:
    verdicts = draw(st.lists(st.sampled_from(VERDICTS), min_size=1, max_size=6))
    ranked = [i for i, v in enumerate(verdicts) if v in ("pass", "fail")]
    order = draw(st.permutations(ranked))
    paths = []
    for index, verdict in enumerate(verdicts):
        rank = order.index(index) + 1 if index in ranked else None
        undecided = verdict in ("pass", "fail") and draw(st.booleans())
        paths.append(_path(f"p{index}", verdict, rank, undecided, (f"r{index}",)))
    return paths


@given(campaigns())
def test_the_decision_follows_the_verdicts(paths: list[SimpleNamespace]) -> None:
    decision = decide(paths)
    event(decision.kind)
    decided_pass = [p for p in paths if p.verdict == "pass" and not p.undecided]
    if decided_pass:
        best = min(decided_pass, key=lambda p: p.rank)
        assert (decision.kind, decision.path) == ("send", best.name)
    elif any(p.undecided for p in paths):
        assert decision.kind == "unsettled"
        assert decision.path in {p.name for p in paths if p.undecided}
    else:
        assert decision.kind == "none"
        ranked = [p for p in paths if p.rank is not None]
        if ranked:
            least = min(ranked, key=lambda p: p.rank)
            assert decision.path == least.name and f"r{least.name[1:]}" in decision.text
        else:
            assert decision.path is None
    # Never "send" a chain that does not pass decidedly.
    if decision.kind == "send":
        sent = next(p for p in paths if p.name == decision.path)
        assert sent.verdict == "pass" and not sent.undecided
