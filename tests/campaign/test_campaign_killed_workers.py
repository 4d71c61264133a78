"""A worker killed from outside (SIGKILL or SIGTERM, as the out-of-memory killer or an operator
would) while it runs a run: the run is run again, up to 3 attempts, with the datasets of an
undisturbed campaign; killed at every attempt it is recorded as ``infrastructure: killed by
SIGKILL 3 times``, no failure of its path, and ``--resume`` runs it. A crash inside the FMU
(SIGSEGV) stays the run's own failure."""

from __future__ import annotations

import json
import os
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import campaign_pool_tasks as tasks
import h5py
import pytest
from test_campaign_robustness import assert_same_datasets

from idefix_rules.campaign.simulation import monte_carlo, reference_runs
from idefix_rules.campaign.simulation.dask_pool import DaskPool
from idefix_rules.campaign.simulation.pool import LocalPool
from idefix_rules.campaign.storage.store import STATUS_FAILED
from idefix_rules.cli import main

LOST = "infrastructure: killed by SIGKILL 3 times"


class Killer:
    """Kills each process that announces itself in ``folder`` (a marked task, see
    campaign_pool_tasks), at most ``limit`` of them, from a thread of the test."""

    def __init__(self, folder: Path, limit: int | None = None,
                 how: signal.Signals = signal.SIGKILL) -> None:
        self.folder = folder
        self.limit = limit
        self.how = how
        self.announced: list[int] = []
        self.killed: list[int] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, daemon=True)
        self._thread.start()

    def _watch(self) -> None:
        while not self._stop.is_set():
            for entry in sorted(self.folder.iterdir()):
                if entry.name.startswith("."):
                    continue
                pid = int(entry.name)
                entry.unlink()  # each announcement is handled once, while its task waits
                self.announced.append(pid)
                if self.limit is None or len(self.killed) < self.limit:
                    os.kill(pid, self.how)  # a process of this test, running a marked task
                    self.killed.append(pid)
            time.sleep(0.02)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)


@pytest.fixture
def killer(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[type[Killer]]:
    """Marked tasks announce themselves in a fresh folder; ``killer(limit)`` starts a Killer."""
    folder = tmp_path / "announced"
    folder.mkdir()
    monkeypatch.setenv(tasks.MARK, str(folder))
    started: list[Killer] = []

    class Started(Killer):
        def __init__(self, limit: int | None = None,  # type: ignore[override]
                     how: signal.Signals = signal.SIGKILL) -> None:
            super().__init__(folder, limit, how)
            started.append(self)

    yield Started
    for each in started:
        each.stop()


def test_the_local_pool_runs_a_killed_run_again_and_records_one_killed_every_time(
        killer: type[Killer]) -> None:
    once = killer(limit=1)
    results = dict(LocalPool(tasks.marked, workers=2, run_timeout=30.0).map(
        enumerate(["a", "marked", "b"])))
    once.stop()
    assert {key: outcome.value for key, outcome in results.items()} == \
        {0: "a", 1: "marked", 2: "b"}
    assert len(once.killed) == 1 and len(once.announced) == 2

    always = killer()
    results = dict(LocalPool(tasks.marked, workers=2, run_timeout=30.0).map(
        enumerate(["a", "marked", "b", "c"])))
    always.stop()
    assert not results[1].ok and results[1].reason == LOST
    assert len(always.killed) == 3  # the first attempt and 2 more
    assert all(results[key].ok for key in (0, 2, 3))


def test_sigterm_from_outside_is_the_infrastructure_too(killer: type[Killer]) -> None:
    terminator = killer(how=signal.SIGTERM)
    results = dict(LocalPool(tasks.marked, workers=2, run_timeout=30.0).map(
        enumerate(["a", "marked"])))
    terminator.stop()
    assert results[0].ok
    assert results[1].reason == "infrastructure: killed by SIGTERM 3 times"


def test_a_segfault_inside_the_run_is_its_own_failure_and_not_run_again(
        killer: type[Killer]) -> None:
    watcher = killer(limit=0)  # kills nothing, counts the attempts
    results = dict(LocalPool(tasks.marked, workers=2, run_timeout=30.0).map(
        enumerate(["marked-segfault", "b"])))
    watcher.stop()
    assert results[0].reason == "the simulation process crashed (SIGSEGV)"
    assert len(watcher.announced) == 1
    assert results[1].value == "b"


@pytest.mark.slow
def test_dask_runs_a_run_whose_process_was_killed_again_up_to_3_times(
        killer: type[Killer]) -> None:
    always = killer()
    results = dict(DaskPool(tasks.marked, workers=2, run_timeout=30.0).map(
        enumerate(["a", "marked", "b", "segfault"])))
    always.stop()
    assert results[0].value == "a" and results[2].value == "b"
    assert not results[1].ok and results[1].reason == LOST
    assert len(always.killed) == 3
    assert results[3].reason == "the simulation process crashed (SIGSEGV)"


def run(folder: Path, out: str, *options: str) -> int:
    return main([str(folder / "campaign.yaml"), "--out", str(folder / out), "--quiet",
                 "--no-report", "--workers", "2", *options])


def mark_run(folder: Path, out: str, path: str, run_index: int | None,
             monkeypatch: pytest.MonkeyPatch) -> None:
    """Make run ``run_index`` of ``path`` (as stored in ``folder/out``; None: its reference
    run) a marked task."""
    with h5py.File(folder / out / "results.h5") as stored:
        group = stored[f"paths/{path}"]
        commands = len(group["chain"][()])
        value = 0.0 if run_index is None \
            else float(group["runs/parameters/initial.x"][run_index])
    monkeypatch.setenv(tasks.MARKED, f"{commands}:{value!r}")
    # the task function of the reference runs and of the Monte Carlo runs
    monkeypatch.setattr(reference_runs, "simulate", tasks.marked_simulate)
    monkeypatch.setattr(monte_carlo, "simulate", tasks.marked_simulate)


def summary_of(folder: Path, out: str) -> dict[str, dict[str, object]]:
    data = json.loads((folder / out / "summary.json").read_text())
    return {"": data, **{record["name"]: record for record in data["paths"]}}


@pytest.mark.slow
def test_a_run_killed_once_is_run_again_with_the_datasets_of_an_undisturbed_campaign(
        campaign_dir: Path, killer: type[Killer], monkeypatch: pytest.MonkeyPatch) -> None:
    undisturbed = run(campaign_dir, "undisturbed")
    mark_run(campaign_dir, "undisturbed", "arc", 2, monkeypatch)
    once = killer(limit=1)
    assert run(campaign_dir, "killed") == undisturbed
    once.stop()
    assert len(once.killed) == 1 and len(once.announced) == 2
    assert_same_datasets(campaign_dir / "undisturbed" / "results.h5",
                         campaign_dir / "killed" / "results.h5")


@pytest.mark.slow
def test_a_local_dask_cluster_runs_a_killed_run_again_with_the_same_datasets(
        campaign_dir: Path, killer: type[Killer], monkeypatch: pytest.MonkeyPatch) -> None:
    run(campaign_dir, "undisturbed")
    mark_run(campaign_dir, "undisturbed", "straight", 4, monkeypatch)
    once = killer(limit=1)
    run(campaign_dir, "dask", "--dask-local")
    once.stop()
    assert len(once.killed) == 1 and len(once.announced) == 2
    assert_same_datasets(campaign_dir / "undisturbed" / "results.h5",
                         campaign_dir / "dask" / "results.h5")


@pytest.mark.slow
def test_a_run_killed_at_every_attempt_is_lost_not_failed_and_resume_completes_it(
        campaign_dir: Path, killer: type[Killer], monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    assert run(campaign_dir, "undisturbed") == 1  # straight fails on its risk
    mark_run(campaign_dir, "undisturbed", "arc", 2, monkeypatch)
    always = killer()
    capsys.readouterr()
    code = main([str(campaign_dir / "campaign.yaml"), "--out", str(campaign_dir / "killed"),
                 "--no-report", "--workers", "2"])
    always.stop()
    assert code == 3  # a run lost to the infrastructure: no verdict yet, resume it
    assert len(always.killed) == 3
    shown = " ".join(capsys.readouterr().out.split())
    assert f"arc run 2 lost: {LOST}" in shown
    assert "1 run(s) were lost to the infrastructure" in shown
    assert f"--resume --out {campaign_dir / 'killed'} --runs 6 --seed 5" in shown

    results = campaign_dir / "killed" / "results.h5"
    with h5py.File(results) as stored:
        assert stored.attrs["state"] == "interrupted"
        runs = stored["paths/arc/runs"]
        assert runs["status"][2] == STATUS_FAILED
        assert runs["failure"][2].rstrip(b"\0").decode() == LOST
    before, lost = summary_of(campaign_dir, "undisturbed"), summary_of(campaign_dir, "killed")
    assert lost[""]["exit_code"] == 3
    arc = lost["arc"]
    assert arc["failed_runs"] == 0  # not counted against the chain ...
    assert arc["failures"] == [{"run": 2, "reason": LOST}]  # ... but listed as lost
    assert arc["completed_runs"] == 5
    assert arc["verdict"] == before["arc"]["verdict"] == "pass"
    assert not any("failed" in reason for reason in arc["reasons"])  # type: ignore[attr-defined]

    monkeypatch.delenv(tasks.MARK)  # the marked run no longer announces itself
    assert run(campaign_dir, "killed", "--resume") == 1
    assert_same_datasets(campaign_dir / "undisturbed" / "results.h5", results)
    with h5py.File(results) as stored:
        assert stored.attrs["state"] == "complete"
    assert summary_of(campaign_dir, "killed")[""]["exit_code"] == 1


@pytest.mark.slow
def test_a_reference_run_killed_at_every_attempt_leaves_its_path_to_resume(
        campaign_dir: Path, killer: type[Killer], monkeypatch: pytest.MonkeyPatch) -> None:
    undisturbed = run(campaign_dir, "undisturbed")
    mark_run(campaign_dir, "undisturbed", "arc", None, monkeypatch)
    always = killer()
    assert run(campaign_dir, "killed") == 3
    always.stop()
    assert len(always.killed) == 3
    arc = summary_of(campaign_dir, "killed")["arc"]
    assert (arc["status"], arc["reason"]) == ("reference_failed", LOST)
    assert summary_of(campaign_dir, "killed")["straight"]["completed_runs"] == 6

    monkeypatch.delenv(tasks.MARK)
    assert run(campaign_dir, "killed", "--resume") == undisturbed
    assert_same_datasets(campaign_dir / "undisturbed" / "results.h5",
                         campaign_dir / "killed" / "results.h5")
