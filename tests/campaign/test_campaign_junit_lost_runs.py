"""A campaign that lost runs to the infrastructure exits 3, and its JUnit file says so: an
error case for the path that lost them, naming the runs, their reasons and the command that
runs them again (with the run's --junit), never a green suite for a red job."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import pytest
from test_campaign_outputs import assert_junit_10

from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.cli import main

LOST = "infrastructure: killed by SIGKILL 3 times"


@pytest.mark.slow
def test_a_campaign_that_lost_runs_writes_an_error_case_with_the_resume_command(
        campaign_dir: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    original = ResultStore.write_run

    def losing(store: ResultStore, name: str, run: int, *rest: Any) -> None:
        if name == "arc" and run in (1, 4):  # its worker killed from outside at each attempt
            store.write_failure(name, run, LOST)
            return
        original(store, name, run, *rest)

    monkeypatch.setattr(ResultStore, "write_run", losing)
    junit = campaign_dir / "rep" / "ci.xml"
    campaign = campaign_dir / "campaign.yaml"
    assert main([str(campaign), "--quiet", "--no-report", "--workers", "1", "--junit",
                 str(junit)]) == 3
    out = capsys.readouterr().out
    assert "CI: runs were lost to the infrastructure, not a verdict (exit 3)" in out
    again = (f"idefix-verify {campaign} --resume --out {campaign_dir / 'out'} --runs 6 "
             f"--seed 5 --workers 1 --junit {junit} --no-report")
    root = ET.parse(junit).getroot()
    assert root.get("errors") == "1"
    cases = {case.get("name"): case for case in root.iter("testcase")}
    error = cases["arc"].find("error")
    assert error is not None and error.attrib == {
        "type": "infrastructure",
        "message": "path arc: runs 1, 4 lost to the infrastructure (2 of 6), not a verdict; "
                   f"run them again with `{again}`"}
    assert error.text == f"run 1 lost: {LOST}\nrun 4 lost: {LOST}\nrun them again with `{again}`"
    # the other cases are what they would be: too-fast's command rule fails it
    rejected = cases["too-fast"].find("failure")
    assert rejected is not None and \
        rejected.get("message") == "path too-fast: rejected · breaks wheel_rate_limit"
    assert_junit_10(junit.read_text())
    assert json.loads((campaign_dir / "out" / "summary.json").read_text())["exit_code"] == 3
