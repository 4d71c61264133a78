"""`report` on a campaign whose runs were never evaluated (interrupted, still running, or cut
before its evaluation) says so in its decision instead of deciding on verdicts no path has
("none was simulated: every chain was rejected or excluded", which was false)."""

from __future__ import annotations

import html
import re
import shutil
from pathlib import Path

import h5py
import pytest
from test_cli_damaged_results import stored  # noqa: F401 - the fixture

from idefix_rules.cli import main


def _decision(page: Path) -> str:
    text = page.read_text()
    found = re.search(r'id="decision"><b>Decision:</b> (.*?)(<div|</div>)', text, re.S)
    assert found is not None
    return html.unescape(found.group(1))


@pytest.mark.parametrize("state", ["interrupted", "complete"])
def test_a_report_of_runs_never_evaluated_says_so(
        state: str, stored: Path, tmp_path: Path,  # noqa: F811 - the fixture
        capsys: pytest.CaptureFixture[str]) -> None:
    results = tmp_path / "results.h5"
    shutil.copy(stored, results)
    with h5py.File(results, "a") as file:
        del file["evaluation"]
        for name in file["paths"]:
            if "evaluation" in file["paths"][name]:
                del file["paths"][name]["evaluation"]
        file.attrs["state"] = state
    assert main(["report", str(results), "-o", str(tmp_path / "report")]) == 0
    decision = _decision(tmp_path / "report" / "report.html")
    assert "rejected or excluded" not in decision
    if state == "interrupted":
        assert decision.startswith("none yet: the campaign is interrupted and its runs so far "
                                   "were never evaluated; continue it with `--resume`")
    else:
        assert decision == ("none yet: the campaign's runs were never evaluated; score them "
                            "with `idefix-verify evaluate`")


def test_the_banner_of_a_campaign_without_expectations_says_what_ci_checked(
        stored: Path, tmp_path: Path) -> None:  # noqa: F811 - the fixture
    assert main(["report", str(stored), "-o", str(tmp_path)]) == 0
    page = (tmp_path / "report.html").read_text()
    assert re.search(r'<div class="ci">CI verdicts \(no expectations: every path must pass\): '
                     r'[0-9]+ of [0-9]+ passed[^<]* \(exit [0-9]\)</div>', page), \
        page[page.find('id="decision"'):][:400]


def test_a_file_whose_chains_were_all_rejected_is_not_called_unevaluated(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """No path simulated: nothing to evaluate, so "never evaluated" would be false; an older
    file without a stored decision gets it worked out from the verdicts (every chain
    rejected)."""
    from test_cli_evaluate_gate import SHORT_ONLY
    from test_cli_user_errors import RULEBOOK, campaign, materialise

    files = campaign()
    files["test.rules"] = RULEBOOK + SHORT_ONLY
    materialise(tmp_path, files, cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    assert main(["campaign.yaml", "--runs", "2", "--quiet", "--no-report"]) == 1
    results = tmp_path / "out" / "results.h5"
    with h5py.File(results, "a") as file:  # as an older file: no stored summary
        if "summary" in file["evaluation"].attrs:
            del file["evaluation"].attrs["summary"]
    assert main(["report", str(results), "-o", str(tmp_path / "report")]) == 0
    capsys.readouterr()
    decision = _decision(tmp_path / "report" / "report.html")
    assert decision.startswith("no chain is acceptable (none was scored: every chain was "
                               "rejected or excluded before Monte Carlo)"), decision


def test_a_report_of_a_missing_results_file_is_h001(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["report", str(tmp_path / "nowhere" / "results.h5")]) == 2
    assert "error[H001]" in capsys.readouterr().err
