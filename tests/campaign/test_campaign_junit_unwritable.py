"""A JUnit file that cannot go where --junit puts it (here a folder the campaign made there
since the arguments were read) is C207, exit 2, once the results are stored; summary.json,
written last, is not written then (it said exit code 1 for a command that exited 2), and the
command the hint gives writes both, --junit included."""

from __future__ import annotations

import errno
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


@pytest.mark.slow
def test_a_summary_that_cannot_be_written_takes_the_junit_file_with_it(
        campaign_dir: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """The disk fills between the JUnit file and summary.json: exit 3, and no JUnit file is
    left to show the campaign's outcome for a command that exited 3."""
    from idefix_rules.campaign.outcome import outputs

    out = campaign_dir / "out"
    junit = campaign_dir / "ci.xml"
    assert main([str(campaign_dir / "campaign.yaml"), "--quiet", "--no-report", "--junit",
                 str(junit)]) == 1
    earlier = junit.read_text()

    def full(path: Path, data: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(outputs, "write_summary", full)
    capsys.readouterr()
    assert main(["evaluate", str(out / "results.h5"), "--junit", str(junit)]) == 3
    assert "needed to write summary.json" in capsys.readouterr().err
    assert not junit.exists() and not (out / "summary.json").exists()
    # the copy set aside is the earlier run's, not the one this command wrote and took back
    assert (campaign_dir / "ci.xml.previous").read_text() == earlier
