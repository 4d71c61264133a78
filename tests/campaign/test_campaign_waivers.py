"""Waivers (docs/campaign-format.md, "waivers"): checked at their line before simulating, a
waived failure reported as waived (console, Decision, summary.json, JUnit) and counted as held
by the exit code; a waiver matching nothing is exit 2."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from datetime import date
from pathlib import Path

import pytest
from campaign_texts import CAMPAIGN, RULEBOOK

from idefix_rules.campaign.load import load_campaign
from idefix_rules.campaign.waivers import waiver_problems
from idefix_rules.cli import main
from idefix_rules.rulebook import check_text

pytestmark = pytest.mark.slow

WAIVER = """\
  - rule: {rule}
    path: {path}
    reason: "survey shows the slope is benign"
    approved_by: "J. Doe"
    until: {until}
"""


def with_waivers(folder: Path, *entries: str, campaign: str = CAMPAIGN) -> Path:
    path = folder / "campaign.yaml"
    path.write_text(campaign + "waivers:\n" + "".join(entries))
    return path


def waiver(rule: str, path: str = "all", until: str = "2026-12-01", extra: str = "") -> str:
    return WAIVER.format(rule=rule, path=path, until=until) + extra


def problems(path: Path, today: date) -> list[tuple[str, int, int]]:
    checked = check_text(RULEBOOK, "test.rules").checked
    assert checked is not None
    found = waiver_problems(load_campaign(path), checked.rulebook, today)
    return [(d.code, d.span.line, d.span.column) for d in found if d.span is not None]


def test_a_waiver_is_valid_on_its_expiry_day_and_expired_the_day_after(
        campaign_dir: Path) -> None:
    path = with_waivers(campaign_dir, waiver("acceptable_risk", until="2026-12-01"))
    assert problems(path, date(2026, 12, 1)) == []
    line = CAMPAIGN.count("\n") + 1 + 5  # waivers:, then the entry's fifth line
    assert problems(path, date(2026, 12, 2)) == [("C213", line, 12)]


def test_an_unknown_rule_and_an_unknown_path_are_errors_at_their_line(
        campaign_dir: Path) -> None:
    path = with_waivers(campaign_dir, waiver("acceptable_rsk", path="stright"))
    first = CAMPAIGN.count("\n") + 2
    assert problems(path, date(2026, 1, 1)) == [("C211", first, 11), ("C212", first + 1, 11)]


def test_a_command_rule_needs_command_rules_true(campaign_dir: Path) -> None:
    path = with_waivers(campaign_dir, waiver("wheel_rate_limit", path="too-fast"))
    assert [code for code, _, _ in problems(path, date(2026, 1, 1))] == ["C214"]
    path = with_waivers(campaign_dir, waiver("wheel_rate_limit", path="too-fast",
                                         extra="    command_rules: true\n"))
    assert problems(path, date(2026, 1, 1)) == []


def test_a_bad_waiver_stops_the_campaign_before_simulating(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = with_waivers(campaign_dir, waiver("acceptable_risk", until="2000-01-01"))
    assert main([str(path), "--quiet", "--no-report"]) == 2
    assert "C213" in capsys.readouterr().err
    assert not (campaign_dir / "out" / "results.h5").exists()


def test_a_waiver_of_a_rule_that_holds_matches_nothing_exit_2(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = with_waivers(campaign_dir, waiver("runs_complete", path="straight"))
    assert main([str(path), "--quiet", "--no-report"]) == 2
    captured = capsys.readouterr()
    assert "C215" in captured.err and "matches nothing" in captured.err
    summary = json.loads((campaign_dir / "out" / "summary.json").read_text())
    assert summary["exit_code"] == 2


def test_waived_failures_are_reported_waived_and_count_as_held(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # Without waivers: straight fails acceptable_risk and too-fast is rejected, exit 1.
    assert main([str(campaign_dir / "campaign.yaml"), "--quiet", "--no-report"]) == 1
    capsys.readouterr()
    junit = campaign_dir / "junit.xml"
    path = with_waivers(campaign_dir, waiver("acceptable_risk"),
                        waiver("wheel_rate_limit", path="too-fast",
                               extra="    command_rules: true\n"))
    code = main([str(path), "--quiet", "--no-report", "--junit", str(junit)])
    out = capsys.readouterr().out
    assert code == 0
    summary = json.loads((campaign_dir / "out" / "summary.json").read_text())
    assert summary["exit_code"] == 0
    paths = {p["name"]: p for p in summary["paths"]}
    # six runs do not show arc's risk below 50 % on bounds that hold for any run risks: its
    # acceptable_risk is open, and the waiver for every path covers it too
    assert {name: p["verdict"] for name, p in paths.items()} == {
        "straight": "waived", "arc": "waived", "too-fast": "waived"}
    signed = {"reason": "survey shows the slope is benign", "approved_by": "J. Doe",
              "until": "2026-12-01"}
    assert paths["straight"]["waivers"] == [
        {"rule": "acceptable_risk", "kind": "verdict", **signed}]
    assert paths["too-fast"]["waivers"] == [
        {"rule": "wheel_rate_limit", "kind": "command", **signed},
        {"rule": "acceptable_risk", "kind": "verdict", **signed}]
    assert paths["arc"]["waivers"] == [{"rule": "acceptable_risk", "kind": "verdict", **signed}]
    # three runs cannot tell the chains apart in the same drawn worlds: each could be best
    decision = summary["decision"]
    assert decision["path"] == "arc"
    assert set(decision["candidates"]) == {"arc", "too-fast", "straight"}
    assert decision["text"].startswith("send arc or ")
    assert "too-fast breaks wheel_rate_limit, acceptable_risk under a waiver" in decision["text"]
    assert "not told apart" in decision["text"]
    said = "waived: survey shows the slope is benign (approved by J. Doe until 2026-12-01)"
    assert f"straight: waived · risk 86.0 % · acceptable_risk {said}" in out
    assert "0 of 3 passed, 3 waived (exit 0)" in out
    suite = ET.parse(junit).getroot().find("testsuite")
    assert suite is not None
    assert (suite.get("skipped"), suite.get("failures")) == ("3", "0")
    cases = {c.get("name"): c for c in suite.iter("testcase")}
    skipped = cases["straight"].find("skipped")
    assert skipped is not None and cases["straight"].find("failure") is None
    assert skipped.get("message") == f"{said} [acceptable_risk]"
    assert cases["arc"].find("failure") is None


def test_a_chain_whose_only_failures_are_waived_may_be_sent_and_the_decision_says_so(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    only_straight = CAMPAIGN.split("  arc:")[0] + "simulation:" + CAMPAIGN.split("simulation:")[1]
    path = with_waivers(campaign_dir, waiver("acceptable_risk", path="straight"),
                        campaign=only_straight)
    assert main([str(path), "--quiet", "--no-report"]) == 0
    out = capsys.readouterr().out
    text = ("send straight (waived: breaks acceptable_risk under a waiver, passes every other "
            "verdict, rank 1 of 1)")
    assert f"Decision: {text}" in " ".join(out.split())
    summary = json.loads((campaign_dir / "out" / "summary.json").read_text())
    assert summary["decision"]["text"] == text
    assert summary["decision"]["reasons"] == ["waived acceptable_risk"]


def test_the_report_shows_the_waived_verdict_and_the_waiver(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = with_waivers(campaign_dir, waiver("acceptable_risk", path="straight"))
    assert main([str(path), "--quiet"]) == 1  # too-fast is still rejected
    html = (campaign_dir / "out" / "report.html").read_text()
    assert '<span class="other">waived</span>' in html
    assert ("Waived verdict rule acceptable_risk: survey shows the slope is benign (approved "
            "by J. Doe until 2026-12-01)") in html


def test_a_prescreen_waiver_is_known_and_matches_nothing_when_the_prescreen_holds(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = with_waivers(campaign_dir, waiver("reference_not_critical", path="arc"))
    assert problems(path, date(2026, 1, 1)) == []
    assert main([str(path), "--quiet", "--no-report"]) == 2
    err = " ".join(capsys.readouterr().err.split())
    line = CAMPAIGN.count("\n") + 2
    assert f"campaign.yaml:{line}:5: error[C215]" in err
    assert "rule 'reference_not_critical' did not fail on path 'arc'" in err
