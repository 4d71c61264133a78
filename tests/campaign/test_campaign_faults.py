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
from test_campaign_robustness import assert_same_datasets, simulated_until

from idefix_rules.campaign.simulation import dask_pool, timeouts
from idefix_rules.campaign.storage.store import STATUS_COMPLETE, STATUS_FAILED
from idefix_rules.cli import main

pytestmark = pytest.mark.slow

KINDS = ("crash", "hang", "error", "nan")
FRAGMENTS = {"crash": "the simulation process crashed (SIGSEGV)",
             "hang": "exceeded the run timeout of 3 s",
             "error": "fmi2DoStep failed",
             "nan": "signal 'x' is not finite from sample"}

# Each fault strikes a run at a time drawn in 1 s .. LATEST: the runs whose time falls within
# what is simulated of their path — up to one step past the chain's end (11 s and 34 s), the
# FMU is not stepped after it — are the faulty ones (seed 32: 1 crash, 1 hang, 2 errors,
# 4 NaN of 24 runs). The nominal times (the middle) are past the end: reference runs are sound.
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
            stop = simulated_until(group)
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


class DaskProcesses:
    """A ``dask scheduler`` on 127.0.0.1 and the ``dask worker`` processes started for it."""

    def __init__(self, folder: Path) -> None:
        self.scheduler_file = folder / "scheduler.json"
        # the processes' own temporary folder, to see what they leave in it
        self.temporary = folder / "cluster-tmp"
        self.temporary.mkdir()
        self.environment = {**os.environ, "TMPDIR": str(self.temporary),
                            "DASK_DISTRIBUTED__SCHEDULER__WORKER_SATURATION": "1.0"}
        self.started: list[subprocess.Popen[bytes]] = []
        self._start("scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                    "--scheduler-file", str(self.scheduler_file))
        deadline = time.monotonic() + 60
        while not self.scheduler_file.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        assert self.scheduler_file.exists(), "the Dask scheduler did not start"
        self.address = str(json.loads(self.scheduler_file.read_text())["address"])

    def _start(self, *args: str) -> None:
        self.started.append(subprocess.Popen(
            [sys.executable, "-m", "dask", *args], env=self.environment,
            start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))

    def start_workers(self, count: int) -> None:
        from dask.distributed import Client

        self._start("worker", "--scheduler-file", str(self.scheduler_file), "--nworkers",
                    str(count), "--nthreads", "1", "--host", "127.0.0.1", "--no-dashboard")
        with Client(self.address) as client:
            client.wait_for_workers(count, timeout=90)

    def end(self) -> None:
        for process in self.started:
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGTERM)
        for process in self.started:
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait(timeout=20)


@pytest.fixture
def dask_processes(tmp_path: Path) -> Iterator[DaskProcesses]:
    processes = DaskProcesses(tmp_path)
    try:
        yield processes
    finally:
        processes.end()


@pytest.fixture
def dask_cluster(dask_processes: DaskProcesses) -> str:
    """A scheduler with a ``dask worker`` of 2 processes, on 127.0.0.1."""
    dask_processes.start_workers(2)
    return dask_processes.address


def test_a_dask_scheduler_and_workers_record_the_same_faults_and_datasets(
        faulty_dir: Path, pool_results: Path, dask_cluster: str) -> None:
    assert run(faulty_dir, "cluster", "--scheduler", dask_cluster) == 1
    check_faults(faulty_dir / "cluster" / "results.h5")
    assert_same_datasets(pool_results, faulty_dir / "cluster" / "results.h5")


def test_the_workers_of_a_dask_cluster_leave_no_extracted_fmu_behind(
        faulty_dir: Path, dask_processes: DaskProcesses) -> None:
    """On a cluster every worker extracts the FMU itself (it cannot see the campaign's folder):
    once, into the Dask worker's own scratch folder, which its run processes share (they are
    started again after each crash or hang, and killed with their worker) and Dask removes
    when the worker ends. Before, each run process extracted it into the temporary folder and
    left it there."""
    dask_processes.start_workers(2)
    assert run(faulty_dir, "cluster", "--scheduler", dask_processes.address) == 1
    check_faults(faulty_dir / "cluster" / "results.h5")  # crashes and hangs: processes anew
    during = sorted(path.name for path in dask_processes.temporary.rglob("*")
                    if path.name.startswith("idefix-fmu-"))
    assert len(during) == 2, during  # one per Dask worker, whatever its processes' count
    assert not any(dask_processes.temporary.glob("tmp*"))  # no process extracted its own
    dask_processes.end()
    left = [str(path.relative_to(dask_processes.temporary))
            for path in dask_processes.temporary.rglob("*") if not path.is_dir()]
    # Dask's own lock files stay (its next start purges them); nothing else does
    assert [name for name in left if not (name.startswith("dask-scratch-space/")
                                          and name.endswith((".lock", ".dirlock")))] == [], left


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


def test_a_cluster_without_workers_stops_with_exit_3_and_resumes_once_workers_come(
        faulty_dir: Path, pool_results: Path, dask_processes: DaskProcesses,
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(dask_pool, "NO_WORKER_GRACE", 2.0)  # 60 s in production
    monkeypatch.setattr(dask_pool, "HEALTH_CHECK", 0.5)
    capsys.readouterr()
    assert run(faulty_dir, "cluster", "--scheduler", dask_processes.address) == 3
    err = capsys.readouterr().err
    assert "the Dask cluster has had no worker for 2 s" in err
    assert f"--resume --out {faulty_dir / 'cluster'} --runs 12 --seed 32" in err
    results = faulty_dir / "cluster" / "results.h5"
    with h5py.File(results) as stored:
        assert stored.attrs["state"] == "interrupted"
    dask_processes.start_workers(2)
    assert run(faulty_dir, "cluster", "--scheduler", dask_processes.address, "--resume") == 1
    assert_same_datasets(pool_results, results)
