"""Whether a path's run risk discriminates: its share of runs at the limit and the spread of
I_max (idefix_rules/campaign/evaluation/spread.py), and the warning a campaign prints."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from campaign_texts import RULEBOOK

from idefix_rules.campaign.evaluation.spread import CRITICAL, MIN_RUNS, SAME, risk_spread
from idefix_rules.cli import main


def _runs(critical: int, total: int) -> np.ndarray:
    """``critical`` runs at the limit, the rest spread below it."""
    return np.concatenate([np.full(critical, 1.0), np.linspace(0.3, 0.8, total - critical)])


def test_a_run_at_0_99_is_at_the_limit_and_one_just_below_is_not() -> None:
    spread = risk_spread("a", np.array([CRITICAL, np.nextafter(CRITICAL, 0.0)] * 4), {})
    assert spread.critical == 0.5


@pytest.mark.parametrize(("critical", "saturated"), [(8, True), (7, False)])
def test_half_the_runs_at_the_limit_saturate_the_path(critical: int, saturated: bool) -> None:
    spread = risk_spread("straight", _runs(critical, 16), {"I_pos": _runs(critical, 16)})
    assert spread.saturated is saturated
    assert (spread.warning is not None) is saturated
    if saturated:
        assert spread.warning == ("straight: 50.0 % of its 16 runs are at I_max >= 0.99 (at "
                                  "its limit: I_pos in 50.0 %); its risk says these runs are "
                                  "critical, not how critical, so it does not tell them apart")


@pytest.mark.parametrize(("ceiling", "at", "critical"), [
    (0.5, 0.495, 0.5), (0.5, float(np.nextafter(0.495, 0.0)), 0.0), (1.0, 0.495, 0.0),
    (0.0, 0.0, 0.0)])
def test_the_limit_is_that_of_the_largest_weight(ceiling: float, at: float,
                                                 critical: float) -> None:
    """With every index weighted 0.5, I_max cannot pass 0.5: a run at 0.495 is at the limit
    (with weight 1 it is not); with every weight 0, no run is critical."""
    risks = np.array([at] * 4 + [0.1] * 4)
    spread = risk_spread("a", risks, {"I_pos": risks / max(ceiling, 1e-9)}, ceiling)
    assert spread.critical == critical
    assert spread.saturated is (critical >= 0.5)
    assert spread.to_dict()["critical_at"] == round(0.99 * ceiling, 6)
    if spread.saturated:
        assert "runs are at I_max >= 0.495 (at its limit: I_pos in 50.0 %)" in str(
            spread.warning)


@pytest.mark.parametrize(("runs", "warned"), [(MIN_RUNS, True), (MIN_RUNS - 1, False)])
def test_too_few_runs_say_nothing_about_a_spread(runs: int, warned: bool) -> None:
    assert (risk_spread("a", np.ones(runs), {}).warning is not None) is warned


@pytest.mark.parametrize(("apart", "uniform"), [(0.0, True), (0.5 * SAME, True),
                                               (0.99 * SAME, True), (1.01 * SAME, False)])
def test_runs_that_all_score_the_same_are_named_down_to_rounding(apart: float,
                                                                 uniform: bool) -> None:
    # the flat control's straight chain: every run the same physics shifted, 4.7e-9 apart
    risks = np.full(10, 0.04)
    risks[3] += apart
    spread = risk_spread("flat", risks, {})
    assert spread.uniform is uniform and not spread.saturated
    if uniform:
        assert spread.warning == ("flat: every one of its 10 runs scores I_max 4.0 %; the "
                                  "uncertainty moves nothing the rulebook reads")
    else:
        assert spread.warning is None


def test_a_path_without_a_complete_run_has_a_strict_json_record() -> None:
    # summary.json is written with allow_nan=False: NaN quartiles would fail the whole write
    record = risk_spread("a", np.full(4, np.nan), {}).to_dict()
    assert record["runs"] == 0 and record["warning"] is None
    assert record["quartiles"] == [None, None, None] and record["iqr"] is None
    json.dumps(record, allow_nan=False)


def test_runs_that_did_not_complete_are_left_out() -> None:
    i_max = np.array([1.0, 1.0, np.nan, 0.2, np.nan, 0.3, 0.4, 0.5, 0.6, 0.7])
    index = np.array([1.0, 0.2, 1.0, 0.2, 1.0, 0.2, 0.2, 0.2, 0.2, 0.2])
    spread = risk_spread("a", i_max, {"I_s": index})
    assert spread.runs == 8 and spread.critical == 0.25
    assert spread.at_limit == {"I_s": 0.125}
    assert spread.quartiles == tuple(np.percentile(i_max[np.isfinite(i_max)], [25, 50, 75]))


@pytest.mark.slow
def test_a_campaign_whose_runs_all_saturate_says_so(campaign_dir: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    # the toy campaign's slip limit a millionth of a ratio, and no prescreen (which would
    # exclude the paths whose reference run is critical): every run of every path is at it
    rulebook = campaign_dir / "test.rules"
    changed = RULEBOOK.replace("limit  = critical_slip", "limit  = 0.000001").replace(
        "prescreen reference_not_critical: require risk < 1\n"
        "  because \"Nominal run must not be critical\"\n", "")
    assert changed.count("0.000001") == 1 and "prescreen" not in changed
    rulebook.write_text(changed)
    junit = campaign_dir / "junit.xml"
    code = main([str(campaign_dir / "campaign.yaml"), "--runs", "8", "--junit", str(junit)])
    out = " ".join(capsys.readouterr().out.split())
    assert code == 1
    # said in every output a reader may open, not on the console alone
    page = " ".join((campaign_dir / "out" / "report.html").read_text().split())
    assert page.count("Warning: straight: 100.0 % of its 8 runs are at I_max &gt;= 0.99") == 1
    import xml.etree.ElementTree as ET

    case = next(c for c in ET.parse(junit).getroot().iter("testcase")
                if c.get("name") == "straight")
    assert "warning: straight: 100.0 % of its 8 runs are at I_max >= 0.99" in (
        case.findtext("system-out") or "")
    for name in ("straight", "arc"):
        assert (f"warning: {name}: 100.0 % of its 8 runs are at I_max >= 0.99 (at its limit: "
                "I_s in 100.0 %") in out
    summary = json.loads((campaign_dir / "out" / "summary.json").read_text())
    straight = next(p for p in summary["paths"] if p["name"] == "straight")
    assert straight["risk_spread"]["critical"] == 1.0
    assert straight["risk_spread"]["saturated"] is True
    assert straight["risk_spread"]["at_limit"]["I_s"] == 1.0
    assert straight["risk_spread"]["iqr"] == 0.0
    # every index weighted 0.5: I_max is 0.5 at most, and the same runs are at its limit
    rulebook.write_text(changed.replace("weight = 1", "weight = 0.5"))
    code = main([str(campaign_dir / "campaign.yaml"), "--runs", "8", "--no-report"])
    out = " ".join(capsys.readouterr().out.split())
    assert code == 1
    assert ("warning: straight: 100.0 % of its 8 runs are at I_max >= 0.495 (at its limit: "
            "I_s in 100.0 %") in out
