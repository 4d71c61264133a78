"""`evaluate --rulebook R` gates the stored paths as a campaign would under R before it scores
them: R's command rules on each stored chain (`rejected`), its prescreen on the stored
reference run (`excluded`), with the campaign's waivers. A chain R would never send is not
passed on runs R would never have simulated; a path the stored campaign rejected that R would
simulate has no runs to score (`error`, said why)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import h5py
import pytest
from test_cli_user_errors import RULEBOOK, campaign, materialise

from idefix_rules.cli import main

SHORT_ONLY = ('command short_only: require abs(delta_position) <= 5 cm\n'
              '  because "Short steps only"\n')
TINY_RISK = 'prescreen tiny_risk: require risk < 0.1 %\n  because "Nothing risky"\n'
WAIVER = ("waivers:\n  - {rule: short_only, path: straight, reason: \"requalified\", "
          "approved_by: \"J. Doe\", until: 2099-12-31, command_rules: true}\n")


def _stored(folder: Path, toy: Path, rulebook: str, append: str = "") -> Path:
    files = campaign(append=append)
    files["test.rules"] = rulebook
    folder.mkdir(exist_ok=True)
    materialise(folder, files, toy)
    here = Path.cwd()
    try:
        os.chdir(folder)
        code = main(["campaign.yaml", "--runs", "4", "--quiet", "--no-report"])
    finally:
        os.chdir(here)
    assert code in (0, 1), code  # the stored verdicts are read back below
    return folder / "out" / "results.h5"


def _evaluate(results: Path, rulebook: Path, capsys: pytest.CaptureFixture[str]
              ) -> tuple[int, dict[str, dict[str, object]], str]:
    code = main(["evaluate", str(results), "--rulebook", str(rulebook)])
    captured = capsys.readouterr()
    summary = json.loads((results.parent / "summary.json").read_text())
    return code, {path["name"]: path for path in summary["paths"]}, \
        " ".join((captured.out + captured.err).split())


def test_a_chain_the_new_rulebook_rejects_or_excludes_is_not_passed(
        tmp_path: Path, cli_toy_fmu: Path, capsys: pytest.CaptureFixture[str]) -> None:
    results = _stored(tmp_path / "stored", cli_toy_fmu, RULEBOOK)
    before = json.loads((results.parent / "summary.json").read_text())
    assert {p["verdict"] for p in before["paths"]} <= {"pass", "fail"}
    rejecting = tmp_path / "rejecting.rules"
    rejecting.write_text(RULEBOOK + SHORT_ONLY)
    code, paths, output = _evaluate(results, rejecting, capsys)
    assert code == 1, output
    assert paths["straight"]["verdict"] == paths["arc"]["verdict"] == "rejected", output
    assert "straight rejected: command 1 breaks rule 'short_only' (delta_position = 0.1 m)" \
        in output
    # no evaluation of the old rulebook left in the results file for the report to show as
    # current; the status stays the campaign's, so the next evaluate gates from there
    with h5py.File(results, "r") as file:
        for name in ("straight", "arc"):
            group = file["paths"][name]
            assert group.attrs["status"] == "simulated" and "evaluation" not in group
    # the report of the re-scored file says why each chain was rejected
    assert main(["report", str(results)]) == 0
    page = " ".join((results.parent / "report.html").read_text().split())
    assert page.count("command 1 breaks rule &#x27;short_only&#x27; (delta_position = 0.1 m)") \
        == 2, page
    excluding = tmp_path / "excluding.rules"
    excluding.write_text(RULEBOOK + TINY_RISK)
    code, paths, output = _evaluate(results, excluding, capsys)
    assert code == 1, output
    assert paths["straight"]["verdict"] == paths["arc"]["verdict"] == "excluded", output
    assert "the reference run fails prescreen 'tiny_risk'" in output
    # and under the campaign's own rulebook again: scored as before
    code, paths, output = _evaluate(results, tmp_path / "stored" / "test.rules", capsys)
    assert [paths[name]["verdict"] for name in ("straight", "arc")] == \
        [path["verdict"] for path in before["paths"]], output


def test_the_campaigns_waivers_let_a_waived_command_rule_through(
        tmp_path: Path, cli_toy_fmu: Path, capsys: pytest.CaptureFixture[str]) -> None:
    results = _stored(tmp_path, cli_toy_fmu, RULEBOOK + SHORT_ONLY, append=WAIVER)
    stored = {p["name"]: p for p in json.loads(
        (results.parent / "summary.json").read_text())["paths"]}
    assert stored["arc"]["verdict"] == "rejected"
    assert stored["straight"]["verdict"] == "waived", stored["straight"]["verdict"]
    code, paths, output = _evaluate(results, tmp_path / "test.rules", capsys)
    assert code == 1, output  # arc stays rejected
    assert paths["arc"]["verdict"] == "rejected", output
    assert paths["straight"]["verdict"] == stored["straight"]["verdict"], output
    assert [w["rule"] for w in paths["straight"]["waivers"]] == ["short_only"], output


def test_a_path_the_stored_campaign_rejected_that_the_new_rulebook_would_run_has_no_score(
        tmp_path: Path, cli_toy_fmu: Path, capsys: pytest.CaptureFixture[str]) -> None:
    results = _stored(tmp_path, cli_toy_fmu, RULEBOOK + SHORT_ONLY)
    accepting = tmp_path / "accepting.rules"
    accepting.write_text(RULEBOOK)
    code, paths, output = _evaluate(results, accepting, capsys)
    assert code == 1, output
    for name in ("straight", "arc"):
        assert paths[name]["verdict"] == "error", output
    assert "straight not simulated: the stored campaign did not simulate this path (rejected: " \
        "command 1 breaks rule 'short_only'" in output
    assert "this rulebook would: run the campaign to score it" in output
    assert "Decision: no chain is acceptable (none was scored: every chain was rejected or " \
        "excluded before Monte Carlo, or needs a run under this rulebook)" in output
    with h5py.File(results, "r") as file:
        assert file["paths"]["straight"].attrs["status"] == "rejected"  # the campaign's


def test_an_adaptive_paths_stop_reason_adds_the_verdict_this_rulebook_gives(
        tmp_path: Path, cli_toy_fmu: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The looks stopped each path on their verdict; excluded by the new rulebook's prescreen,
    its stop reason says so too (results-format.md), in summary.json and on the console."""
    folder = tmp_path / "stored"
    folder.mkdir()
    materialise(folder, campaign(), cli_toy_fmu)
    here = Path.cwd()
    try:
        os.chdir(folder)
        assert main(["campaign.yaml", "--runs", "auto", "--max-runs", "16", "--min-runs", "8",
                     "--quiet", "--no-report"]) in (0, 1)
    finally:
        os.chdir(here)
    results = folder / "out" / "results.h5"
    before = {p["name"]: p["stop_reason"] for p in json.loads(
        (results.parent / "summary.json").read_text())["paths"]}
    assert all(reason.startswith(("decided after", "stopped after", "cap of"))
               for reason in before.values()), before
    excluding = tmp_path / "excluding.rules"
    excluding.write_text(RULEBOOK + TINY_RISK)
    code, paths, output = _evaluate(results, excluding, capsys)
    assert code == 1, output
    for name, reason in before.items():
        assert paths[name]["verdict"] == "excluded", output
        said = f"{reason}; verdict excluded under this rulebook"
        assert paths[name]["stop_reason"] == said
        assert f"{name}: runs: {said}" in output
