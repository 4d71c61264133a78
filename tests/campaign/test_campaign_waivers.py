"""Waivers (docs/campaign-format.md, "waivers"): checked at their line before simulating and
before a stored campaign is evaluated again (exit 2), a waived failure reported as waived
(console, Decision, summary.json, JUnit, the report) and counted as held by the exit code and
the expectations; a waiver matching nothing is exit 2."""

from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ET
from collections.abc import Callable
from datetime import date
from pathlib import Path

import h5py
import pytest
from campaign_texts import CAMPAIGN, RULEBOOK

from idefix_rules.campaign.input import waivers
from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.input.waivers import waiver_problems
from idefix_rules.cli import main
from idefix_rules.rulebook import check_text

pytestmark = pytest.mark.slow

# The day the campaigns below are run on: their waivers hold until 2026-12-01, so the tests
# do not start failing when the calendar passes that date.
TODAY = date(2026, 6, 1)

WAIVER = """\
  - rule: {rule}
    path: {path}
    reason: "survey shows the slope is benign"
    approved_by: "J. Doe"
    until: {until}
"""


@pytest.fixture(autouse=True)
def set_today(monkeypatch: pytest.MonkeyPatch) -> Callable[[date], None]:
    """The expiry check's today is :data:`TODAY`; the fixture's value sets another day."""
    days = [TODAY]

    class Calendar(date):
        @classmethod
        def today(cls) -> Calendar:
            return cls.fromordinal(days[-1].toordinal())

    monkeypatch.setattr(waivers, "date", Calendar)
    return days.append


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


@pytest.mark.parametrize(("entry", "code", "line", "column"), [
    (waiver("acceptable_rsk"), "C211", 1, 11),  # unknown rule: at its `rule`
    (waiver("acceptable_risk", path="stright"), "C212", 2, 11),  # unknown path
    (waiver("acceptable_risk", until="2000-01-01"), "C213", 5, 12),  # expired
    (waiver("wheel_rate_limit", path="too-fast"), "C214", 1, 11),  # no command_rules: true
])
def test_a_bad_waiver_stops_the_campaign_before_simulating(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str], entry: str, code: str,
        line: int, column: int) -> None:
    path = with_waivers(campaign_dir, entry)
    assert main([str(path), "--quiet", "--no-report"]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert f"campaign.yaml:{CAMPAIGN.count(chr(10)) + 1 + line}:{column}: error[{code}]" in err
    assert not (campaign_dir / "out" / "results.h5").exists()


def held_by_waivers(folder: Path, until: str) -> Path:
    """The test campaign with both of its failures waived until ``until`` (exit 0)."""
    return with_waivers(folder, waiver("acceptable_risk", until=until),
                        waiver("wheel_rate_limit", path="too-fast", until=until,
                               extra="    command_rules: true\n"))


def test_a_campaign_runs_on_its_waivers_last_day_and_is_refused_the_day_after(
        campaign_dir: Path, set_today: Callable[[date], None],
        capsys: pytest.CaptureFixture[str]) -> None:
    path = held_by_waivers(campaign_dir, "2026-12-01")
    set_today(date(2026, 12, 1))
    assert main([str(path), "--quiet", "--no-report"]) == 0
    capsys.readouterr()
    results = campaign_dir / "out" / "results.h5"
    last_good = results.read_bytes()
    set_today(date(2026, 12, 2))
    assert main([str(path), "--quiet", "--no-report"]) == 2
    err = " ".join(capsys.readouterr().err.split())
    line = CAMPAIGN.count("\n") + 1 + 5  # waivers:, then the first entry's fifth line
    assert f"campaign.yaml:{line}:12: error[C213]" in err
    assert f"campaign.yaml:{line + 5}:12: error[C213]" in err
    assert "expired on 2026-12-01 (today is 2026-12-02)" in err
    # refused before simulating: the last day's results are put back, unchanged
    assert results.read_bytes() == last_good
    assert not (campaign_dir / "out" / "results.previous.h5").exists()


def test_evaluate_checks_the_waivers_expiry_against_today(
        campaign_dir: Path, set_today: Callable[[date], None],
        capsys: pytest.CaptureFixture[str]) -> None:
    path = held_by_waivers(campaign_dir, "2026-12-01")
    results = campaign_dir / "out" / "results.h5"
    assert main([str(path), "--quiet", "--no-report"]) == 0
    set_today(date(2026, 12, 1))  # the last day: the stored campaign's waivers still hold
    assert main(["evaluate", str(results)]) == 0
    summary = json.loads((campaign_dir / "out" / "summary.json").read_text())
    assert [p["verdict"] for p in summary["paths"]] == ["waived", "waived", "waived"]
    capsys.readouterr()
    set_today(date(2026, 12, 2))  # the day after: expired, as a run would find it
    assert main(["evaluate", str(results)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    line = CAMPAIGN.count("\n") + 1 + 5
    stored = f"{results.resolve()}:/provenance/campaign"  # the campaign as it ran
    assert f"{stored}:{line}:12: error[C213]" in err
    assert f"{stored}:{line + 5}:12: error[C213]" in err
    assert "expired on 2026-12-01 (today is 2026-12-02)" in err
    assert "renew it in the campaign file (a new date, approved again) and run the campaign " \
        "again" in err
    assert not (campaign_dir / "out" / "summary.json").exists()  # no summary says waived


def test_evaluate_names_a_waiver_in_the_campaign_text_stored_with_the_results(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The campaign file may have changed since it ran, or be gone: a stored waiver's
    mistake is said at its line in the stored text, which is quoted."""
    path = with_waivers(campaign_dir, waiver("acceptable_risk", path="straight"))
    assert main([str(path), "--quiet", "--no-report"]) == 1  # too-fast is still rejected
    path.write_text("# rewritten since\n" + path.read_text())
    renamed = campaign_dir / "renamed.rules"
    renamed.write_text(RULEBOOK.replace("acceptable_risk", "risk_kept"))
    capsys.readouterr()
    results = campaign_dir / "out" / "results.h5"
    assert main(["evaluate", str(results), "--rulebook", str(renamed)]) == 2
    err = capsys.readouterr().err
    line = CAMPAIGN.count("\n") + 2
    assert f"{results.resolve()}:/provenance/campaign:{line}:11: error[C211]" in err, err
    assert "  - rule: acceptable_risk\n" in err and str(path) not in err


def test_a_waiver_of_a_rule_that_holds_matches_nothing_exit_2(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = with_waivers(campaign_dir, waiver("runs_complete", path="straight"))
    assert main([str(path), "--quiet", "--no-report"]) == 2
    captured = capsys.readouterr()
    assert "C215" in captured.err and "matches nothing" in captured.err
    summary = json.loads((campaign_dir / "out" / "summary.json").read_text())
    assert summary["exit_code"] == 2


def test_the_report_says_why_the_exit_code_is_2(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The report's CI line says the exit code 2 as the console, summary.json and JUnit do:
    with the waiver that matches nothing, at its line."""
    from html import unescape

    path = with_waivers(campaign_dir, waiver("runs_complete", path="straight"))
    assert main([str(path), "--quiet"]) == 2
    capsys.readouterr()
    page = (campaign_dir / "out" / "report.html").read_text()
    banner = unescape(page[page.index('id="decision"'):].split("</div></div>")[0])
    assert "(exit 2)" in banner
    line = CAMPAIGN.count("\n") + 2
    assert (f"{path}:{line}:5: error[C215]: waivers[0]: the waiver matches nothing: rule "
            "'runs_complete' did not fail on path 'straight'") in banner, banner


def test_a_waiver_of_a_rule_the_named_path_passes_matches_nothing_and_waives_nothing(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # acceptable_risk fails on straight, passes on arc (decided with 40 runs: six cannot show
    # arc's risk below 50 % on exact bounds): a waiver naming arc covers nothing.
    path = with_waivers(campaign_dir, waiver("acceptable_risk", path="arc"),
                        campaign=CAMPAIGN.replace("runs: 6", "runs: 40"))
    assert main([str(path), "--quiet", "--no-report"]) == 2  # not 1: the waiver is a mistake
    err = " ".join(capsys.readouterr().err.split())
    assert f"campaign.yaml:{CAMPAIGN.count(chr(10)) + 2}:5: error[C215]" in err
    assert "rule 'acceptable_risk' did not fail on path 'arc'" in err
    summary = json.loads((campaign_dir / "out" / "summary.json").read_text())
    assert summary["exit_code"] == 2
    assert {p["name"]: (p["verdict"], p["waivers"]) for p in summary["paths"]} == {
        "straight": ("fail", []), "arc": ("pass", []), "too-fast": ("rejected", [])}


def test_evaluate_with_a_rulebook_the_path_passes_finds_the_waiver_matches_nothing(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = with_waivers(campaign_dir, waiver("acceptable_risk", path="straight"))
    assert main([str(path), "--quiet", "--no-report"]) == 1  # too-fast is still rejected
    lenient = campaign_dir / "lenient.rules"
    lenient.write_text(RULEBOOK.replace("require risk <= 50 %", "require risk <= 100 %"))
    capsys.readouterr()
    results = campaign_dir / "out" / "results.h5"
    assert main(["evaluate", str(results), "--rulebook", str(lenient)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "error[C215]" in err and "did not fail on path 'straight'" in err
    summary = json.loads((campaign_dir / "out" / "summary.json").read_text())
    assert summary["exit_code"] == 2
    assert [p["verdict"] for p in summary["paths"]] == ["pass", "pass", "rejected"]


@pytest.mark.parametrize(("expected", "code", "held"), [("pass", 0, True), ("fail", 1, False)])
def test_with_expectations_a_waived_path_counts_as_passing(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str], expected: str, code: int,
        held: bool) -> None:
    expecting = CAMPAIGN + f"expect:\n  - {{path: straight, verdict: {expected}}}\n"
    path = with_waivers(campaign_dir, waiver("acceptable_risk", path="straight"),
                        campaign=expecting)
    junit = campaign_dir / "junit.xml"
    assert main([str(path), "--quiet", "--no-report", "--junit", str(junit)]) == code
    summary = json.loads((campaign_dir / "out" / "summary.json").read_text())
    assert summary["exit_code"] == code
    assert [(e["held"], e["message"]) for e in summary["expectations"]] == [
        (held, "verdict waived")]
    suites = {s.get("name"): s for s in ET.parse(junit).getroot().iter("testsuite")}
    paths, expectations = suites["toy.paths"], suites["toy.expectations"]
    assert (paths.get("skipped"), paths.get("failures")) == ("1", "0")  # the path: reported
    assert expectations.get("failures") == ("0" if code == 0 else "1")


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
    assert main([str(path)]) == 1  # too-fast is still rejected
    console = " ".join(capsys.readouterr().out.split())
    html = (campaign_dir / "out" / "report.html").read_text()
    assert '<span class="other">waived</span>' in html
    # CI's outcome in the banner in the console's words, counts included
    ci = re.search(r'<div class="ci">([^<]+)</div>', html)
    assert ci is not None and ci[1].startswith("CI verdicts (no expectations: every path must "
                                                "pass): ") and ", 1 waived" in ci[1], html
    assert ci[1] in console
    assert ("Waived verdict rule acceptable_risk: survey shows the slope is benign (approved "
            "by J. Doe until 2026-12-01)") in html


def test_a_report_from_results_without_their_summary_still_says_waived(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # Files written before the summary was stored with the evaluation: Table 1 and the
    # decision come from each path's stored verdict and waivers.
    path = with_waivers(campaign_dir, waiver("acceptable_risk", path="straight"))
    assert main([str(path), "--quiet", "--no-report"]) == 1  # too-fast is still rejected
    results = campaign_dir / "out" / "results.h5"
    with h5py.File(results, "r+") as file:
        del file["evaluation"].attrs["summary"]
    assert main(["report", str(results), "-o", str(campaign_dir / "again")]) == 0
    html = (campaign_dir / "again" / "report.html").read_text()
    rows = dict(re.findall(r'<td data-label="Path"><b>([^<]+)</b></td>.*?'
                           r'<td data-label="Verdict"><span class="\w+">(\w+)', html))
    assert rows == {"straight": "waived", "arc": "pass", "too-fast": "rejected"}
    assert ("Waived verdict rule acceptable_risk: survey shows the slope is benign (approved "
            "by J. Doe until 2026-12-01)") in html
    banner = re.search(r'id="decision"><b>Decision:</b> ([^<]+)', html)
    assert banner is not None
    assert "send straight (waived: breaks acceptable_risk under a waiver" in banner[1]


def test_a_prescreen_waiver_lets_an_excluded_chain_go_on_to_monte_carlo(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # A strict pre-screen: both chains' reference runs (risk 0.214) are critical for it.
    (campaign_dir / "test.rules").write_text(
        RULEBOOK.replace("require risk < 1", "require risk < 5 %"))
    assert main([str(campaign_dir / "campaign.yaml"), "--quiet", "--no-report"]) == 1
    capsys.readouterr()
    summary = json.loads((campaign_dir / "out" / "summary.json").read_text())
    excluded = {p["name"]: (p["status"], p["verdict"], p["completed_runs"])
                for p in summary["paths"]}
    assert excluded == {"straight": ("excluded", "excluded", 0),
                        "arc": ("excluded", "excluded", 0),
                        "too-fast": ("rejected", "rejected", 0)}
    junit = campaign_dir / "junit.xml"
    # 40 runs: six cannot show arc's risk below 50 % on exact bounds (its verdict undecided)
    path = with_waivers(campaign_dir, waiver("reference_not_critical", path="arc"),
                        campaign=CAMPAIGN.replace("runs: 6", "runs: 40"))
    assert main([str(path), "--quiet", "--no-report", "--junit", str(junit)]) == 1
    out = " ".join(capsys.readouterr().out.split())
    summary = json.loads((campaign_dir / "out" / "summary.json").read_text())
    paths = {p["name"]: p for p in summary["paths"]}
    assert (paths["arc"]["status"], paths["arc"]["verdict"]) == ("simulated", "waived")
    assert paths["arc"]["completed_runs"] == 40  # simulated in Monte Carlo
    assert paths["arc"]["waivers"] == [
        {"rule": "reference_not_critical", "kind": "prescreen",
         "reason": "survey shows the slope is benign", "approved_by": "J. Doe",
         "until": "2026-12-01"}]
    assert (paths["straight"]["status"], paths["straight"]["waivers"]) == ("excluded", [])
    assert "fails prescreen 'reference_not_critical'" in paths["straight"]["reason"]
    said = "waived: survey shows the slope is benign (approved by J. Doe until 2026-12-01)"
    assert f"arc: waived · risk 37.2 % · reference_not_critical {said}" in out
    with h5py.File(campaign_dir / "out" / "results.h5") as file:
        assert file["paths/arc/runs/status"].shape == (40,)
        assert "runs" not in file["paths/straight"]
    suite = ET.parse(junit).getroot().find("testsuite")
    assert suite is not None and (suite.get("skipped"), suite.get("failures")) == ("1", "2")
    skipped = next(c for c in suite.iter("testcase") if c.get("name") == "arc").find("skipped")
    assert skipped is not None and skipped.get("message") == f"{said} [reference_not_critical]"


def test_a_prescreen_waiver_is_known_and_matches_nothing_when_the_prescreen_holds(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = with_waivers(campaign_dir, waiver("reference_not_critical", path="arc"))
    assert problems(path, date(2026, 1, 1)) == []
    assert main([str(path), "--quiet", "--no-report"]) == 2
    err = " ".join(capsys.readouterr().err.split())
    line = CAMPAIGN.count("\n") + 2
    assert f"campaign.yaml:{line}:5: error[C215]" in err
    assert "rule 'reference_not_critical' did not fail on path 'arc'" in err


def test_an_adaptive_campaign_s_looks_know_the_chains_simulated_under_a_waived_command_rule(
        campaign_dir: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """too-fast breaks a waived command rule: it is `waived` whatever its verdict, so every
    look ranks it below the chains that may pass clean (statistics/stopping.py)."""
    from idefix_rules.campaign import adaptive

    seen: list[frozenset[str]] = []
    real = adaptive.settle

    def spy(*args, **kwargs):  # type: ignore[no-untyped-def]
        seen.append(frozenset(kwargs["waived_before"]))
        return real(*args, **kwargs)

    monkeypatch.setattr(adaptive, "settle", spy)
    auto = CAMPAIGN.replace("runs: 6", "runs: auto\nmax_runs: 32\nmin_runs: 8\nbatch_runs: 8")
    assert auto != CAMPAIGN
    path = with_waivers(campaign_dir, waiver("wheel_rate_limit", path="too-fast",
                                             extra="    command_rules: true\n"),
                        campaign=auto)
    main([str(path), "--quiet", "--no-report"])
    capsys.readouterr()
    assert seen and all(names == {"too-fast"} for names in seen)
    summary = json.loads((campaign_dir / "out" / "summary.json").read_text())
    too_fast = next(p for p in summary["paths"] if p["name"] == "too-fast")
    assert [w["kind"] for w in too_fast["waivers"]] == ["command"]
