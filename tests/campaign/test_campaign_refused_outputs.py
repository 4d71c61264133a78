"""A refused command leaves no earlier run's JUnit file or ``summary.json`` to speak for it
(docs/operations.md, "Outputs never speak for another run"): a CI job that uploads them with
``if: always()`` uploads none rather than the last green run's, and a JUnit file set aside is
named ``ci.xml.previous``, which a CI server's ``reports/*.xml`` glob does not take for a
second report. A folder another live campaign owns (C208) is left to it, and so is the JUnit
file that campaign writes; a ``--junit`` mistake (C703) moves nothing."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from campaign_texts import RULEBOOK

from idefix_rules.campaign.storage.ownership import LOCK_FILE, Owner, process_start
from idefix_rules.cli import main
from idefix_rules.files import set_aside_report

GREEN = "expect:\n  - {path: too-fast, verdict: fail}\n"  # holds: exit 0


@pytest.fixture
def green_run(campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> Path:
    """``campaign.yaml`` run once, green: ``out/summary.json`` and ``rep/ci.xml`` say exit 0."""
    campaign = campaign_dir / "campaign.yaml"
    campaign.write_text(campaign.read_text() + GREEN)
    assert main([str(campaign), "--quiet", "--no-report", "--junit",
                 str(campaign_dir / "rep" / "ci.xml")]) == 0
    capsys.readouterr()
    assert 'failures="0" errors="0"' in (campaign_dir / "rep" / "ci.xml").read_text()
    assert json.loads((campaign_dir / "out" / "summary.json").read_text())["exit_code"] == 0
    return campaign_dir


@pytest.fixture
def sleeper() -> Iterator[subprocess.Popen[bytes]]:
    """A live process of this host that is not this one."""
    process = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"])
    try:
        yield process
    finally:
        process.kill()
        process.wait()


def names(folder: Path) -> list[str]:
    return sorted(path.name for path in folder.iterdir())


def run_again(folder: Path, *more: str) -> int:
    return main([str(folder / "campaign.yaml"), "--quiet", "--no-report", "--junit",
                 str(folder / "rep" / "ci.xml"), *more])


@pytest.mark.slow
def test_a_campaign_refused_for_its_own_mistake_sets_the_last_summary_and_junit_aside(
        green_run: Path, capsys: pytest.CaptureFixture[str]) -> None:
    campaign = green_run / "campaign.yaml"
    green = (green_run / "rep" / "ci.xml").read_text()
    campaign.write_text(campaign.read_text().replace("runs: 6", "runs: eight"))
    assert run_again(green_run) == 2
    assert "error[C100]: runs: expected a whole number of runs" in capsys.readouterr().err
    assert names(green_run / "rep") == ["ci.xml.previous"]  # no *.xml for a CI's glob
    assert (green_run / "rep" / "ci.xml.previous").read_text() == green
    out = green_run / "out"
    assert names(out) == ["results.h5", "summary.previous.json", "terrain.dem"]
    assert json.loads((out / "summary.previous.json").read_text())["exit_code"] == 0


@pytest.mark.slow
def test_a_campaign_refused_after_it_owns_the_folder_leaves_no_xml_for_a_ci_glob(
        green_run: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (green_run / "test.rules").write_text(RULEBOOK.replace("limit  = 1\n", "limit  = \n", 1))
    assert run_again(green_run) == 2
    assert "test.rules:" in capsys.readouterr().err
    assert names(green_run / "rep") == ["ci.xml.previous"]
    assert not (green_run / "out" / "summary.json").exists()


@pytest.mark.slow
def test_a_junit_destination_refused_moves_nothing(green_run: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    notes = green_run / "rep" / "notes.txt"
    notes.write_text("not a report\n")
    assert main([str(green_run / "campaign.yaml"), "--quiet", "--junit", str(notes)]) == 2
    assert "error[C703]" in capsys.readouterr().err
    assert notes.read_text() == "not a report\n"
    assert names(green_run / "rep") == ["ci.xml", "notes.txt"]
    assert "summary.json" in names(green_run / "out")


def live_lock(folder: Path, pid: int, junit: Path | None) -> None:
    owner = Owner(pid, socket.gethostname(), "2025-05-01T12:00:03+02:00",
                  "idefix-verify run campaign.yaml", process_start(pid),
                  None if junit is None else str(junit.resolve()))
    (folder / LOCK_FILE).write_text(owner.to_json())


@pytest.mark.slow
def test_a_folder_in_use_is_left_to_its_owner_and_so_is_the_junit_file_it_writes(
        green_run: Path, sleeper: subprocess.Popen[bytes],
        capsys: pytest.CaptureFixture[str]) -> None:
    out, junit = green_run / "out", green_run / "rep" / "ci.xml"
    live_lock(out, sleeper.pid, junit)  # the same command, still running
    assert run_again(green_run) == 2
    assert "error[C208]" in capsys.readouterr().err
    assert names(green_run / "rep") == ["ci.xml"]
    assert names(out) == [LOCK_FILE, "results.h5", "summary.json", "terrain.dem"]


@pytest.mark.slow
def test_a_folder_in_use_is_left_to_its_owner_but_this_commands_junit_is_set_aside(
        green_run: Path, sleeper: subprocess.Popen[bytes],
        capsys: pytest.CaptureFixture[str]) -> None:
    out = green_run / "out"
    live_lock(out, sleeper.pid, None)  # a campaign that writes no JUnit file
    assert run_again(green_run) == 2
    assert "error[C208]" in capsys.readouterr().err
    assert names(green_run / "rep") == ["ci.xml.previous"]
    assert names(out) == [LOCK_FILE, "results.h5", "summary.json", "terrain.dem"]


@pytest.mark.slow
def test_an_evaluate_refused_sets_its_junit_aside_and_keeps_the_summary_of_the_results(
        green_run: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = green_run / "out"
    assert main(["evaluate", str(out / "results.h5"), "--rulebook",
                 str(green_run / "missing.rules"), "--junit",
                 str(green_run / "rep" / "ci.xml")]) == 2
    assert "missing.rules" in capsys.readouterr().err
    assert names(green_run / "rep") == ["ci.xml.previous"]
    assert json.loads((out / "summary.json").read_text())["exit_code"] == 0


REPORT = '<?xml version="1.0" encoding="utf-8"?>\n<testsuites name="{}" />\n'


def test_a_copy_kept_under_the_earlier_name_goes_when_the_report_is_set_aside(
        tmp_path: Path) -> None:
    """``ci.previous.xml``, the name earlier versions kept a report under, matched
    ``reports/*.xml``: a report set aside now replaces it (or, alone, it becomes the kept
    copy), so a workspace that keeps its files between jobs stops showing it."""
    junit = tmp_path / "ci.xml"
    junit.write_text(REPORT.format("newer"))
    (tmp_path / "ci.previous.xml").write_text(REPORT.format("older"))
    assert set_aside_report(junit) == [tmp_path / "ci.xml.previous"]
    assert names(tmp_path) == ["ci.xml.previous"]
    assert "newer" in (tmp_path / "ci.xml.previous").read_text()
    (tmp_path / "ci.xml.previous").unlink()
    (tmp_path / "ci.previous.xml").write_text(REPORT.format("older"))
    assert set_aside_report(junit) == []
    assert names(tmp_path) == ["ci.xml.previous"]
    assert "older" in (tmp_path / "ci.xml.previous").read_text()
    (tmp_path / "ci.previous.xml").write_text("a file of the user's, not a report\n")
    set_aside_report(junit)
    assert names(tmp_path) == ["ci.previous.xml", "ci.xml.previous"]
