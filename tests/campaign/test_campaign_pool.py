"""The local pool: results by key whatever the order; crashes and hangs become failed runs."""

from __future__ import annotations

import campaign_pool_tasks as tasks

from idefix_rules.campaign.simulation.pool import LocalPool


def test_every_task_comes_back_once_with_its_result() -> None:
    pool = LocalPool(tasks.square, workers=2)
    results = dict(pool.map((i, i) for i in range(20)))
    assert results.keys() == set(range(20))
    assert all(outcome.ok and outcome.value == i * i for i, outcome in results.items())


def test_a_segfault_an_exit_an_exception_and_a_hang_fail_only_their_own_run() -> None:
    payloads = ["a", "segfault", "b", "hang", "raise", "exit", "c", "d"]
    pool = LocalPool(tasks.misbehave, workers=2, run_timeout=1.0)
    results = dict(pool.map(enumerate(payloads)))
    assert {i for i, o in results.items() if o.ok} == {0, 2, 6, 7}
    assert results[6].value == "c"
    assert "SIGSEGV" in results[1].reason
    assert "run timeout of 1 s" in results[3].reason
    assert results[4].reason == "RuntimeError: model error"
    assert "exit code 7" in results[5].reason


def test_with_one_worker_a_crash_does_not_stop_the_rest() -> None:
    pool = LocalPool(tasks.misbehave, workers=1)
    results = dict(pool.map(enumerate(["segfault", "x", "segfault", "y"])))
    assert [results[i].ok for i in range(4)] == [False, True, False, True]


def test_closing_the_iteration_early_ends_the_busy_worker_processes() -> None:
    pool = LocalPool(tasks.misbehave, workers=2, run_timeout=30.0)
    iterator = pool.map(enumerate(["a", "hang", "b"]))
    first_key, first = next(iterator)
    assert first.ok and first_key in (0, 2)
    processes = [w.process for w in pool._workers]
    iterator.close()
    assert pool._workers == []
    assert all(not process.is_alive() for process in processes)


def test_a_persistent_pool_keeps_its_workers_from_map_to_map_until_closed() -> None:
    # An adaptive campaign's looks run on one pool: the second batch goes to the workers (and
    # the FMU each has loaded) of the first; a pool made for one map closes after it.
    pool = LocalPool(tasks.pid, workers=2, persistent=True)
    first = {outcome.value for _, outcome in pool.map((i, i) for i in range(8))}
    processes = [w.process for w in pool._workers]
    assert len(processes) == 2 and all(process.is_alive() for process in processes)
    second = {outcome.value for _, outcome in pool.map((i, i) for i in range(8))}
    assert second <= first and second == {process.pid for process in processes}
    pool.close()
    assert pool._workers == [] and not any(process.is_alive() for process in processes)

    once = LocalPool(tasks.pid, workers=2)
    dict(once.map((i, i) for i in range(4)))
    assert once._workers == []


def test_a_persistent_pool_stopped_early_still_ends_its_busy_workers() -> None:
    pool = LocalPool(tasks.misbehave, workers=2, run_timeout=30.0, persistent=True)
    iterator = pool.map(enumerate(["a", "hang", "b"]))
    next(iterator)
    processes = [w.process for w in pool._workers]
    iterator.close()
    assert pool._workers == [] and not any(process.is_alive() for process in processes)
