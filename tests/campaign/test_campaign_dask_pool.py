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


@pytest.mark.slow
@pytest.mark.parametrize("after", [0.05, 0.3, 0.8])
def test_ctrl_c_while_the_local_cluster_starts_leaves_no_cluster_open(after: float) -> None:
    """Ctrl-C lands while the LocalCluster's workers start (they take about a second): the
    pool stops with KeyboardInterrupt and closes what it started; nothing is left for
    Dask's exit hook, whose close of a half-started cluster fails with a traceback
    (``AssertionError: Status.init``)."""
    import signal
    import threading

    from distributed.core import Status
    from distributed.deploy.spec import SpecCluster

    before = set(SpecCluster._instances)
    timer = threading.Timer(after, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    started = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        pool = DaskPool(tasks.square, workers=2)
        try:  # a start faster than the timer: the Ctrl-C lands in the map's wait
            list(pool.map((i, i) for i in range(10_000)))
        finally:
            pool.close()
    timer.join()
    assert time.monotonic() - started < 60
    left = [cluster for cluster in set(SpecCluster._instances) - before
            if cluster.status != Status.closed]
    assert left == []


@pytest.mark.slow
def test_ctrl_c_while_connecting_to_a_scheduler_stops_at_once() -> None:
    """Nothing is started there to close whole: Ctrl-C is not deferred (a scheduler that
    never answers kept it waiting for the connect timeout, then said exit 3)."""
    import signal
    import socket
    import threading

    with socket.socket() as silent:  # listens, never answers
        silent.bind(("127.0.0.1", 0))
        silent.listen()
        address = f"tcp://127.0.0.1:{silent.getsockname()[1]}"
        timer = threading.Timer(1.0, os.kill, (os.getpid(), signal.SIGINT))
        timer.start()
        started = time.monotonic()
        with pytest.raises(KeyboardInterrupt):
            DaskPool(tasks.square, address=address).close()
        timer.join()
    assert time.monotonic() - started < 10


def test_ctrl_c_is_not_taken_over_where_it_is_ignored() -> None:
    """A campaign started with Ctrl-C ignored (a background job of a script) keeps it
    ignored while the cluster starts."""
    import signal

    from idefix_rules.campaign.simulation.dask_pool import ctrl_c_deferred

    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with ctrl_c_deferred() as pressed:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)
            assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
        assert pressed == []
    finally:
        signal.signal(signal.SIGINT, previous)


IGNORED_FROM_THE_START = """\
import logging, signal, sys
from dask.distributed import Client, LocalCluster
from idefix_rules.campaign.simulation.dask_pool import workers_ignore_ctrl_c

def ignores():
    return signal.getsignal(signal.SIGINT) == signal.SIG_IGN

if __name__ == "__main__":
    # as at a terminal, whatever the test runner's parent did with Ctrl-C (nohup, `cmd &`)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    if sys.argv[1] == "fork server":
        workers_ignore_ctrl_c()
    # no preload: what the workers do with Ctrl-C is what they were started with
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=":0", silence_logs=logging.ERROR) as cluster, \\
            Client(cluster) as client:
        print(sorted(set(client.run(ignores).values())))
    print(signal.getsignal(signal.SIGINT) is signal.default_int_handler)
"""


@pytest.mark.parametrize("start", ["fork server", "as Dask starts them"])
def test_local_cluster_workers_ignore_ctrl_c_from_their_first_instant(
        start: str, tmp_path) -> None:
    """A terminal's Ctrl-C reaches the workers too; one that comes while a worker still
    imports Dask (before the preload that ignores it) killed that worker with its traceback.
    Forked from a fork server started ignoring it, a worker ignores it before its first
    instruction; Dask's own start (spawn) gives Python's handler. This process keeps its own."""
    import subprocess
    import sys

    script = tmp_path / "ignored.py"
    script.write_text(IGNORED_FROM_THE_START)
    done = subprocess.run([sys.executable, str(script), start], capture_output=True, text=True,
                          timeout=120, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.split("\n")
    assert lines[0] == ("[True]" if start == "fork server" else "[False]"), done.stdout
    assert lines[1] == "True"


def test_the_fork_server_start_method_is_the_campaigns_alone() -> None:
    """While the campaign's local cluster lives its nannies start workers from the fork
    server (restarts too); afterwards the process's other Dask clusters start theirs as
    before."""
    import dask

    key = "distributed.worker.multiprocessing-method"
    before = dask.config.get(key)
    assert before != "forkserver"
    pool = DaskPool(tasks.misbehave, workers=1)
    try:
        assert dask.config.get(key) == "forkserver"
        assert dict(pool.map([(0, "a")]))[0].value == "a"
    finally:
        pool.close()
    assert dask.config.get(key) == before


def test_runs_on_a_later_local_cluster_see_the_campaigns_environment_and_folder(
        tmp_path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The fork server is started once per process, with the environment and the folder of
    that moment; a later campaign's runs work in its own (TMPDIR, a variable set since, the
    folder it was started from), as spawned workers did."""
    first = DaskPool(tasks.misbehave, workers=1)
    try:
        assert dict(first.map([(0, "a")]))[0].value == "a"  # the fork server is running now
    finally:
        first.close()
    monkeypatch.setenv("IDEFIX_TEST_LATER", "set since")
    monkeypatch.chdir(tmp_path)
    later = DaskPool(tasks.surroundings, workers=1)
    try:
        outcome = dict(later.map([(0, "IDEFIX_TEST_LATER")]))[0]
    finally:
        later.close()
    assert outcome.ok, outcome.reason
    assert outcome.value == (str(tmp_path), "set since")
