"""A JUnit file that cannot go where --junit puts it (here a folder the campaign made there
since the arguments were read) is C207, exit 2, once the results are stored; summary.json,
written last, is not written then (it said exit code 1 for a command that exited 2), and the
command the hint gives writes both, --junit included."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from idefix_rules.cli import main


@pytest.mark.slow
def test_a_junit_file_that_cannot_be_written_is_c207_and_no_summary_disagrees(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = campaign_dir / "out"
    assert main([str(campaign_dir / "campaign.yaml"), "--quiet", "--no-report", "--junit",
                 str(out)]) == 2
    results = (out / "results.h5").resolve()
    err = " ".join(capsys.readouterr().err.split())
    assert err == (f"{out}: error[C207]: cannot write the JUnit file {out}: Is a directory "
                   f"hint: the results are in {results}; once {out} can be written, write the "
                   f"outputs again with `idefix-verify evaluate {results} --junit {out}`")
    assert sorted(path.name for path in out.iterdir()) == ["results.h5", "terrain.dem"]
    junit = campaign_dir / "ci.xml"
    assert main(["evaluate", str(results), "--junit", str(junit)]) == 1
    assert json.loads((out / "summary.json").read_text())["exit_code"] == 1
    assert junit.read_text().startswith("<?xml")
