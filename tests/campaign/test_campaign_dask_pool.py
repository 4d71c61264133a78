"""Dask runs each task in a child of its worker: crashes, hangs and errors fail only their own
run, with the local pool's reasons; a run that kills its workers is retried, then failed."""

from __future__ import annotations

import os
import time

import campaign_pool_tasks as tasks
import pytest

from idefix_rules.campaign.simulation.dask_pool import DaskPool, is_infrastructure
from idefix_rules.campaign.simulation.pool import LocalPool
from idefix_rules.campaign.simulation.processes import IsolatedRunner, run_isolated

PAYLOADS = ["a", "segfault", "b", "hang", "raise", "exit", "c", "d", "e", "f"]


def test_an_isolated_runner_survives_its_tasks_crashes_and_hangs() -> None:
    runner = IsolatedRunner(tasks.misbehave)
    try:
        assert runner.run(0, "a", timeout=30.0).value == "a"
        first = runner._child
        assert runner.run(1, "b", timeout=30.0).value == "b"
        assert runner._child is first  # one child serves task after task
        crashed = runner.run(2, "segfault", timeout=30.0)
        assert not crashed.ok and crashed.reason == "the simulation process crashed (SIGSEGV)"
        hung = runner.run(3, "hang", timeout=0.5)
        assert not hung.ok and hung.reason == "exceeded the run timeout of 0.5 s"
        assert runner.run(4, "c", timeout=None).value == "c"
    finally:
        runner.close()


def test_a_child_killed_while_idle_does_not_fail_the_next_run() -> None:
    runner = IsolatedRunner(tasks.misbehave)
    try:
        assert runner.run(0, "a", timeout=30.0).ok
        assert runner._child is not None
        os.kill(runner._child.pid, 9)
        time.sleep(0.1)
        assert runner.run(1, "b", timeout=30.0).value == "b"
    finally:
        runner.close()


def test_run_isolated_keeps_one_runner_per_thread() -> None:
    assert run_isolated(tasks.square, "k", 7, None).value == 49
    assert run_isolated(tasks.square, "k", 8, None).value == 64


@pytest.mark.slow
def test_dask_fails_the_same_runs_for_the_same_reasons_as_the_local_pool() -> None:
    local = dict(LocalPool(tasks.misbehave, workers=2, run_timeout=2.0).map(
        enumerate(PAYLOADS)))
    dask = dict(DaskPool(tasks.misbehave, workers=2, run_timeout=2.0).map(
        enumerate(PAYLOADS)))
    assert dask == local
    assert {i for i, o in dask.items() if o.ok} == {0, 2, 6, 7, 8, 9}
    assert dask[3].reason == "exceeded the run timeout of 2 s"


@pytest.mark.slow
def test_a_run_that_kills_every_dask_worker_it_lands_on_fails_after_bounded_retries() -> None:
    payloads = ["a", "b", "kill-worker", "c", "d", "e", "f", "g"]
    results = dict(DaskPool(tasks.kill_worker, workers=2, run_timeout=30.0).map(
        enumerate(payloads)))
    assert results.keys() == set(range(len(payloads)))
    killer = results[2]
    assert not killer.ok and is_infrastructure(killer.reason)
    assert "worker died 4 times" in killer.reason
    assert all(results[i].ok and results[i].value == p
               for i, p in enumerate(payloads) if p != "kill-worker")
