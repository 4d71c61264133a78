"""A faulty FMU (crash, hang, FMI error, NaN on chosen runs) on the local pool, a local Dask
cluster and a real ``dask scheduler`` / ``dask worker`` pair: the same runs fail for the same
reasons, every healthy run completes, and the datasets equal the process pool's."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import h5py
import numpy as np
import pytest
from campaign_texts import CAMPAIGN
from test_campaign_robustness import assert_same_datasets

from idefix_rules.campaign import timeouts
from idefix_rules.campaign.store import STATUS_COMPLETE, STATUS_FAILED
from idefix_rules.cli import main

pytestmark = pytest.mark.slow

KINDS = ("crash", "hang", "error", "nan")
FRAGMENTS = {"crash": "the simulation process crashed (SIGSEGV)",
             "hang": "exceeded the run timeout of 3 s",
             "error": "fmi2DoStep failed",
             "nan": "signal 'x' is not finite from sample"}

# Each fault strikes a run at a time drawn in 1 s .. LATEST: the runs whose time falls before
# their path's end (15 s and 45.5 s) are the faulty ones (seed 32: 2 crashes, 1 hang, 3 errors,
# 5 NaN of 24 runs). The nominal times (the middle) are past the end: reference runs are sound.
LATEST = {"crash": 200, "hang": 200, "error": 200, "nan": 100}
FAULTY = CAMPAIGN.replace("runs: 6", "runs: 12").replace("seed: 5", "seed: 32") \
    .replace("  too-fast:\n    - {max_wheel_rate: \"0.5 rad/s\", delta_position: \"0.1 m\", "
             "delta_heading: \"0 deg\"}\n", "") \
    .replace("    toy.slip:", "".join(
        f'    toy.{kind}_at: {{distribution: uniform, low: "1 s", high: "{LATEST[kind]} s"}}\n'
        for kind in KINDS) + "    toy.slip:")


def expected_failures(results: Path) -> dict[tuple[str, int], str]:
    """``(path, run) → fault kind`` from the stored fault times (the first fault ends a run;
    a NaN output only fails a run no other fault ended)."""
    expected = {}
    with h5py.File(results) as stored:
        for name in ("straight", "arc"):
            group = stored[f"paths/{name}"]
            stop = float(group.attrs["stop_time"])
            times = {kind: group[f"runs/parameters/toy.{kind}_at"][()] for kind in KINDS}
            for run in range(int(group["runs"].attrs["count"])):
                ending = {k: float(times[k][run]) for k in ("crash", "hang", "error")}
                first = min(ending, key=lambda kind: ending[kind])
                if ending[first] <= stop:
                    expected[(name, run)] = first
                elif float(times["nan"][run]) <= stop:
                    expected[(name, run)] = "nan"
    return expected


def check_faults(results: Path) -> set[str]:
    """Every faulty run failed with its fault's reason, every other run completed."""
    expected = expected_failures(results)
    with h5py.File(results) as stored:
        for name in ("straight", "arc"):
            runs = stored[f"paths/{name}/runs"]
            status = runs["status"][()]
            reasons = [r.rstrip(b"\0").decode() for r in runs["failure"][()]]
            for run, state in enumerate(status):
                kind = expected.get((name, run))
                if kind is None:
                    assert state == STATUS_COMPLETE, (name, run, reasons[run])
                    assert np.all(np.isfinite(runs["signals/x"][run]))
                else:
                    assert state == STATUS_FAILED, (name, run, kind)
                    assert FRAGMENTS[kind] in reasons[run], (name, run, reasons[run])
    return set(expected.values())


def run(folder: Path, out: str, *options: str) -> int:
    return main([str(folder / "campaign.yaml"), "--out", str(folder / out), "--quiet",
                 "--no-report", "--workers", "2", "--run-timeout", "3", *options])


@pytest.fixture
def faulty_dir(campaign_dir: Path) -> Path:
    (campaign_dir / "campaign.yaml").write_text(FAULTY)
    return campaign_dir


@pytest.fixture
def pool_results(faulty_dir: Path) -> Path:
    assert run(faulty_dir, "pool") == 1  # paths with failed runs cannot pass
    results = faulty_dir / "pool" / "results.h5"
    assert check_faults(results) == set(KINDS)  # the seed chose every kind of fault
    return results


def test_the_process_pool_records_each_fault_and_completes_every_healthy_run(
        pool_results: Path) -> None:
    summary = json.loads((pool_results.parent / "summary.json").read_text())
    assert summary["exit_code"] == 1
    assert all(record["verdict"] == "fail" for record in summary["paths"])


def test_a_local_dask_cluster_records_the_same_faults_and_datasets(
        faulty_dir: Path, pool_results: Path) -> None:
    assert run(faulty_dir, "dask", "--dask-local") == 1
    check_faults(faulty_dir / "dask" / "results.h5")
    assert_same_datasets(pool_results, faulty_dir / "dask" / "results.h5")


@pytest.fixture
def dask_cluster(tmp_path: Path) -> Iterator[str]:
    """A ``dask scheduler`` and a ``dask worker`` (2 processes) on 127.0.0.1, ended after."""
    from dask.distributed import Client

    scheduler_file = tmp_path / "scheduler.json"
    environment = {**os.environ, "DASK_DISTRIBUTED__SCHEDULER__WORKER_SATURATION": "1.0"}
    started = []
    try:
        started.append(subprocess.Popen(
            [sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", "0",
             "--no-dashboard", "--scheduler-file", str(scheduler_file)],
            env=environment, start_new_session=True,
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        deadline = time.monotonic() + 60
        while not scheduler_file.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        assert scheduler_file.exists(), "the Dask scheduler did not start"
        started.append(subprocess.Popen(
            [sys.executable, "-m", "dask", "worker", "--scheduler-file", str(scheduler_file),
             "--nworkers", "2", "--nthreads", "1", "--host", "127.0.0.1", "--no-dashboard"],
            env=environment, start_new_session=True,
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        address = json.loads(scheduler_file.read_text())["address"]
        with Client(address) as client:
            client.wait_for_workers(2, timeout=90)
        yield address
    finally:
        for process in started:
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGTERM)
        for process in started:
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait(timeout=20)


def test_a_dask_scheduler_and_workers_record_the_same_faults_and_datasets(
        faulty_dir: Path, pool_results: Path, dask_cluster: str) -> None:
    assert run(faulty_dir, "cluster", "--scheduler", dask_cluster) == 1
    check_faults(faulty_dir / "cluster" / "results.h5")
    assert_same_datasets(pool_results, faulty_dir / "cluster" / "results.h5")


def test_without_run_timeout_a_hanging_run_ends_at_the_default_timeout(
        faulty_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # The default's floor (20 s) lowered so the test is short; the rest of the default is real:
    # no --run-timeout given, reference runs measured, the timeout derived and enforced.
    monkeypatch.setattr(timeouts, "FLOOR", 2.0)
    code = main([str(faulty_dir / "campaign.yaml"), "--quiet", "--no-report", "--workers", "2"])
    assert code == 1
    results = faulty_dir / "out" / "results.h5"
    hangs = [key for key, kind in expected_failures(results).items() if kind == "hang"]
    assert hangs
    with h5py.File(results) as stored:
        for name, run_index in hangs:
            reason = stored[f"paths/{name}/runs/failure"][run_index].rstrip(b"\0").decode()
            assert reason == "exceeded the run timeout of 2 s"
