"""Outputs never speak for another run: set aside at the start, written by rename, naming
their seed and results file; runs lost to the cluster exit 3 and are redone by --resume."""

from __future__ import annotations

import json
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import numpy as np
import pytest
from test_campaign_robustness import KILLER, assert_same_datasets_dicts, datasets

from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.runner import run_campaign
from idefix_rules.campaign.simulation.run_stage import SimulationOptions
from idefix_rules.campaign.storage.dataset_layout import encode_reason
from idefix_rules.campaign.storage.store import STATUS_FAILED
from idefix_rules.cli import main
from idefix_rules.files import set_aside, write_atomic


def test_write_atomic_replaces_whole_files_and_leaves_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "summary.json"
    write_atomic(target, "old\n")
    with pytest.raises(TypeError):
        write_atomic(target, 12)  # type: ignore[arg-type]  # fails half-way: old file stays
    assert target.read_text() == "old\n"
    write_atomic(target, b"new\n")
    assert target.read_text() == "new\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.json"]


def test_set_aside_keeps_the_last_output_under_a_previous_name(tmp_path: Path) -> None:
    (tmp_path / "summary.json").write_text("1")
    (tmp_path / "report.html").write_text("2")
    moved = set_aside(tmp_path / "summary.json", tmp_path / "report.html",
                      tmp_path / "junit.xml", None)
    assert moved == [tmp_path / "summary.previous.json", tmp_path / "report.previous.html"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.previous.html",
                                                          "summary.previous.json"]


@pytest.mark.slow
def test_a_rerun_killed_midway_leaves_no_output_of_the_previous_run_in_place(
        campaign_dir: Path, tmp_path: Path) -> None:
    out = campaign_dir / "out"
    junit = tmp_path / "ci" / "junit.xml"
    path = str(campaign_dir / "campaign.yaml")
    assert main([path, "--quiet", "--seed", "4242", "--junit", str(junit)]) == 1
    for name in ("summary.json", "report.html"):
        assert (out / name).is_file()
    script = tmp_path / "rerun.py"
    script.write_text(KILLER)
    killed = subprocess.run([sys.executable, str(script), path, "3", "777", str(junit)],
                            capture_output=True, text=True, timeout=300)
    assert killed.returncode == -9, killed.stderr
    with h5py.File(out / "results.h5") as results:
        assert results.attrs["state"] == "running" and results.attrs["seed"] == 777
    # Nothing in place claims a result for this run; the last run's outputs are kept aside.
    assert not (out / "summary.json").exists()
    assert not (out / "report.html").exists()
    assert not junit.exists()
    previous = json.loads((out / "summary.previous.json").read_text())
    assert previous["seed"] == 4242
    assert (out / "report.previous.html").is_file()
    assert ET.parse(junit.with_name("junit.xml.previous")).getroot() is not None
    assert (out / "results.previous.h5").is_file()

    # Finishing the run writes outputs that name its seed and results file.
    assert main([path, "--quiet", "--resume", "--seed", "777", "--junit", str(junit)]) == 1
    summary = json.loads((out / "summary.json").read_text())
    assert summary["seed"] == 777
    assert summary["results"] == str((out / "results.h5").resolve())
    properties = {p.get("name"): p.get("value") for p in ET.parse(junit).iter("property")}
    assert properties["seed"] == "777"
    assert properties["results"] == str((out / "results.h5").resolve())
    page = (out / "report.html").read_text()
    assert "seed 777" in page and str((out / "results.h5").resolve()) in page
    assert not list(out.glob(".*.tmp"))


LOST = "infrastructure: worker died 4 times while running it"


@pytest.mark.slow
def test_runs_lost_to_the_cluster_exit_3_and_resume_runs_them_again(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    campaign = load_campaign(campaign_dir / "campaign.yaml")
    clean = run_campaign(campaign, report=False)
    results = campaign.output / "results.h5"
    original = datasets(results)
    with h5py.File(results, "r+") as stored:
        runs = stored["paths/arc/runs"]
        for run in (1, 4):
            runs["signals/x"][run] = np.nan
            runs["failure"][run] = encode_reason(LOST)
            runs["status"][run] = STATUS_FAILED
    assert main(["evaluate", str(results)]) == 3
    out = capsys.readouterr().out
    assert "2 run(s) were lost to the infrastructure" in out and "--resume" in out
    summary = json.loads((campaign.output / "summary.json").read_text())
    assert summary["exit_code"] == 3

    resumed = run_campaign(campaign, SimulationOptions(resume=True), report=False)
    assert resumed.exit_code == clean.exit_code
    assert_same_datasets_dicts(original, datasets(results))


@pytest.mark.slow
def test_resuming_a_complete_campaign_keeps_its_finishing_time(campaign_dir: Path) -> None:
    campaign = load_campaign(campaign_dir / "campaign.yaml")
    run_campaign(campaign, report=False)
    results = campaign.output / "results.h5"
    with h5py.File(results) as stored:
        finished = stored.attrs["finished"]
    assert finished
    run_campaign(campaign, SimulationOptions(resume=True), report=False)
    with h5py.File(results) as stored:
        assert stored.attrs["finished"] == finished
        assert stored.attrs["state"] == "complete"
        assert len(json.loads(stored.attrs["resumed"])) == 1
