"""``idefix-verify explain``: besides the rules, the constants (as written, in SI, rationale),
the settings and the obstacle levels (size limit, buffer, factor per level), as text and JSON."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from idefix_rules.cli import main

RULEBOOK = """\
rulebook "explained" version "1.0.0"
purpose "Constants, settings and levels for explain"

const critical_slip = 60 %
  because "Slip above 60 % is critical on the softer regolith"
const critical_sinkage = 4 cm
  because "Assumption: under half the wheel radius"
const f_obs = {L1: 0.3, L2: 0.8, L3: 1}
  because "Risk factor per obstacle level"

settings {
  tolerance_growth = 5 cm/rad
}

obstacles {
  level L1 below 3 cm  buffer 2 cm
  level L2 below 10 cm buffer 5 cm
  level L3             buffer 10 cm
}

index I_s "wheel slip ratio" {
  value  = max over time (max over wheels (abs(wheel.slip)))
  limit  = critical_slip
  weight = 1
  because "Slip"
}

index I_obs "obstacle collisions" {
  value  = sum over parts (sum over levels (collision.hits * f_obs))
  limit  = 1
  weight = 1
  because "Eq. 4"
}

verdict acceptable_risk: require risk <= 70 %
  because "Mean risk limit"
"""


@pytest.fixture
def rulebook(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("COLUMNS", "250")  # one table row per line
    path = tmp_path / "explained.rules"
    path.write_text(RULEBOOK, encoding="utf-8")
    return path


def test_text_lists_constants_settings_and_levels(rulebook: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["explain", str(rulebook)]) == 0
    out = capsys.readouterr().out
    lines = [" ".join(line.replace("│", " ").split()) for line in out.splitlines()]
    # not a terminal here: a record per rule, a line per constant (cli/explain.py)
    assert ("critical_slip = 60 % (= 0.6) # Slip above 60 % is critical on the softer regolith"
            in lines)
    assert "critical_sinkage = 4 cm (= 0.04 m) # Assumption: under half the wheel radius" in lines
    assert "f_obs = {L1: 0.3, L2: 0.8, L3: 1} # Risk factor per obstacle level" in lines
    assert "setting tolerance_growth = 5 cm/rad (= 0.05 m/rad)" in lines
    assert "setting theoretical_slip = (default) (= 0)" in lines
    assert "obstacle level L1: below 3 cm (0.03 m), buffer 2 cm (0.02 m), f_obs 0.3" in lines
    assert "obstacle level L2: below 10 cm (0.1 m), buffer 5 cm (0.05 m), f_obs 0.8" in lines
    assert "obstacle level L3: no size limit, buffer 10 cm (0.1 m), f_obs 1" in lines


def test_json_gives_the_same_as_data(rulebook: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["explain", "--format", "json", str(rulebook)]) == 0
    data = json.loads(capsys.readouterr().out)
    assert (data["name"], data["version"]) == ("explained", "1.0.0")
    assert [(r["kind"], r["name"], r["title"]) for r in data["rules"]] == [
        ("index", "I_s", "wheel slip ratio"), ("index", "I_obs", "obstacle collisions"),
        ("verdict", "acceptable_risk", None)]
    constants = {c["name"]: c for c in data["constants"]}
    assert list(constants) == ["critical_slip", "critical_sinkage", "f_obs"]
    assert constants["critical_slip"] == {
        "name": "critical_slip", "written": "60 %", "si": "0.6", "unit": "", "axes": [],
        "rationale": "Slip above 60 % is critical on the softer regolith", "value": 0.6}
    assert constants["critical_sinkage"]["value"] == pytest.approx(0.04)
    assert constants["critical_sinkage"]["unit"] == "m"
    assert constants["f_obs"]["axes"] == ["level"]
    assert constants["f_obs"]["value"] == {"L1": 0.3, "L2": 0.8, "L3": 1.0}
    assert data["settings"] == [
        {"name": "theoretical_slip", "written": None, "si": "0", "unit": "", "value": 0.0},
        {"name": "tolerance_growth", "written": "5 cm/rad", "si": "0.05 m/rad",
         "unit": "m/rad", "value": pytest.approx(0.05)}]
    assert data["obstacle_levels"] == [
        {"level": "L1", "below": "3 cm", "below_m": pytest.approx(0.03), "buffer": "2 cm",
         "buffer_m": pytest.approx(0.02), "factors": {"f_obs": 0.3}},
        {"level": "L2", "below": "10 cm", "below_m": pytest.approx(0.1), "buffer": "5 cm",
         "buffer_m": pytest.approx(0.05), "factors": {"f_obs": 0.8}},
        {"level": "L3", "below": None, "below_m": None, "buffer": "10 cm",
         "buffer_m": pytest.approx(0.1), "factors": {"f_obs": 1.0}}]
    assert data["combine"]["confidence"] == pytest.approx(0.95)


def test_a_rulebook_without_obstacles_lists_no_level(
        rulebook: Path, capsys: pytest.CaptureFixture[str]) -> None:
    start, end = RULEBOOK.index("const f_obs"), RULEBOOK.index("index I_s")
    rulebook.write_text(RULEBOOK[:start] + RULEBOOK[end:].split("index I_obs")[0]
                        + RULEBOOK.split("index I_obs")[1].split("}\n", 1)[1], encoding="utf-8")
    assert main(["explain", "--format", "json", str(rulebook)]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["obstacle_levels"] == [] and data["settings"][0]["value"] == 0.0
    assert main(["explain", str(rulebook)]) == 0
    assert "obstacle level" not in capsys.readouterr().out


def test_an_invalid_rulebook_exits_2_with_its_place_in_both_formats(
        rulebook: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rulebook.write_text(RULEBOOK.replace("= 4 cm", "= 4 furlongs"), encoding="utf-8")
    for form in ("text", "json"):
        assert main(["explain", "--format", form, str(rulebook)]) == 2
        captured = capsys.readouterr()
        assert captured.out == ""
        assert f"{rulebook}:6:" in captured.err
        assert "Traceback" not in captured.err


def test_named_areas_are_listed_with_their_signals(tmp_path: Path, capsys,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "250")
    path = tmp_path / "areas.rules"
    path.write_text(RULEBOOK.replace("  level L3             buffer 10 cm\n",
                                     "  level L3             buffer 10 cm\n"
                                     "  area rim keep_out level L3 buffer 10 cm\n"
                                     "  area scarp steep above 20 deg level L2 buffer 5 cm\n"),
                    encoding="utf-8")
    assert main(["explain", str(path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert ("area rim: keep-out, level L3, buffer 10 cm (0.1 m); runs read area.rim.inside, "
            "area.rim.buffer") in lines
    assert any(line.startswith("area scarp: steep above 20 deg (0.349066 rad), level L2")
               for line in lines)
    assert main(["explain", "--format", "json", str(path)]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [(a["name"], a["kind"], a["buffer_m"]) for a in data["areas"]] == [
        ("rim", "keep_out", 0.1), ("scarp", "steep", 0.05)]


@pytest.mark.parametrize(("written", "threshold"), [
    ("verdict acceptable_risk: require risk <= 70 %", "<= 70 % (= 0.7)"),
    ("verdict acceptable_risk: require 70 % >= risk", "<= 70 % (= 0.7)"),
    ("verdict acceptable_risk: require 70 % > risk", "< 70 % (= 0.7)"),
    ("verdict acceptable_risk: require 0 != risk", "!= 0"),
    ("command turn: require 90 deg >= abs(delta_heading)", "<= 90 deg (= 1.5708 rad)"),
    ("command turn: require 5 cm <= abs(delta_position)", ">= 5 cm (= 0.05 m)"),
    ("prescreen clear: require 1 > I_obs", "< 1"),
])
def test_a_threshold_is_seen_from_the_value_compared_whichever_side_it_is_on(
        rulebook: Path, capsys: pytest.CaptureFixture[str], written: str,
        threshold: str) -> None:
    verdict = "verdict acceptable_risk: require risk <= 70 %"
    text = RULEBOOK.replace(verdict, written) if written.startswith("verdict") else \
        RULEBOOK + written + "\n"
    rulebook.write_text(text, encoding="utf-8")
    name = written.split()[1].rstrip(":")
    assert main(["explain", "--format", "json", str(rulebook)]) == 0
    [row] = [r for r in json.loads(capsys.readouterr().out)["rules"] if r["name"] == name]
    assert row["threshold"] == threshold
    assert main(["explain", str(rulebook)]) == 0
    assert f"threshold: {threshold}" in capsys.readouterr().out


def test_into_a_pipe_every_record_is_one_line_however_long(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "80")  # what a pipe gets
    path = tmp_path / "areas.rules"
    path.write_text(RULEBOOK.replace("  level L3             buffer 10 cm\n",
                                     "  level L3             buffer 10 cm\n"
                                     "  area keep_out_zone keep_out level L3 buffer 10 cm\n"),
                    encoding="utf-8")
    assert main(["explain", str(path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert ("area keep_out_zone: keep-out, level L3, buffer 10 cm (0.1 m); runs read "
            "area.keep_out_zone.inside, area.keep_out_zone.buffer") in lines
    assert [line for line in lines if line != line.rstrip()] == []
