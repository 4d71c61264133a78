"""The local pool: results by key whatever the order; crashes and hangs become failed runs;
the work a task does after handing back its value (a run's collision check) is not the run's; a
task whose process must run no other (its FMU returned Fatal) ends it after answering."""

from __future__ import annotations

import campaign_pool_tasks as tasks

from idefix_rules.campaign.simulation.pool import LocalPool, Outcome, Then
from idefix_rules.campaign.simulation.processes import IsolatedRunner


def test_every_task_comes_back_once_with_its_result() -> None:
    pool = LocalPool(tasks.square, workers=2)
    results = dict(pool.map((i, i) for i in range(20)))
    assert results.keys() == set(range(20))
    assert all(outcome.ok and outcome.value == i * i for i, outcome in results.items())


def test_a_pool_starts_no_more_processes_than_it_has_tasks() -> None:
    # A pool larger than the runs it is given (the --workers of a big machine on a short
    # campaign) starts a process per task, not one per slot; a persistent pool given more
    # tasks at the next map grows up to its size.
    pool = LocalPool(tasks.pid, workers=64, persistent=True)
    first = {outcome.value for _, outcome in pool.map((i, i) for i in range(3))}
    assert 1 <= len(first) <= 3 and len(pool._workers) == 3
    second = {outcome.value for _, outcome in pool.map((i, i) for i in range(5))}
    assert len(pool._workers) == 5 and len(second) <= 5
    pool.close()
    assert pool._workers == []


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


def test_the_work_after_a_value_comes_second_and_is_not_the_runs() -> None:
    # A worker's collision check of its run comes after the run (Continued): the run's outcome
    # first, then the check's (Then). Each has the timeout on its own; a check that raises,
    # crashes the worker or hangs fails only itself, and the pool goes on with a fresh worker.
    payloads = {"both-slow": (1.2, 1.2), "raise": (0.0, "raise"), "segfault": (0.0, "segfault"),
                "hang": (0.0, "hang"), "quick": (0.0, 0.0)}
    pool = LocalPool(tasks.continued, workers=2, run_timeout=2.0)
    seen = list(pool.map((key, (key, *value)) for key, value in payloads.items()))
    assert sorted(key for key, _ in seen) == sorted(list(payloads) * 2)
    for key in payloads:
        run, after = [outcome for k, outcome in seen if k == key]
        assert not isinstance(run, Then) and isinstance(after, Then), key
        assert run.ok and run.value == ("ran", key), key
    after = {key: outcome for key, outcome in seen if isinstance(outcome, Then)}
    # 1.2 s + 1.2 s: past the 2 s timeout together, within it each
    assert after["both-slow"].ok and after["both-slow"].value == ("checked", "both-slow")
    assert after["quick"].ok
    assert after["raise"].reason == "RuntimeError: model error"
    assert "SIGSEGV" in after["segfault"].reason
    assert "run timeout of 2 s" in after["hang"].reason


def test_an_isolated_runner_leaves_the_work_after_a_value_for_the_next_task() -> None:
    # Dask's children run the work after a Continued value too (no campaign asks them to);
    # its answer is left, not taken for the next task's.
    runner = IsolatedRunner(tasks.continued)
    try:
        first = runner.run("a", ("a", 0.0, 0.2), timeout=10.0)
        second = runner.run("b", ("b", 0.0, 0.0), timeout=10.0)
    finally:
        runner.close()
    assert (first.ok, first.value) == (True, ("ran", "a"))
    assert (second.ok, second.value) == (True, ("ran", "b"))


def test_a_retiring_task_is_answered_and_its_process_takes_no_other_task() -> None:
    # one worker: every task after a retiring one runs in a fresh process, the one before it
    # in the same; neither answer is a crash
    payloads = ["stay", "retire", "stay", "retire-failed", "stay"]
    pool = LocalPool(tasks.retiring, workers=1, run_timeout=30.0)
    results = dict(pool.map(enumerate(payloads)))
    assert [results[i].ok for i in range(5)] == [True, True, True, False, True]
    assert results[3].reason == "RuntimeError: corrupted for good"
    assert results[0].value == results[1].value
    assert len({results[0].value, results[2].value, results[4].value}) == 3

    runner = IsolatedRunner(tasks.retiring)  # a Dask worker's child, the same way
    try:
        seen = [runner.run(i, payload, timeout=30.0) for i, payload in enumerate(payloads)]
    finally:
        runner.close()
    assert [(o.ok, o.reason) for o in seen] == [(True, "")] * 3 + \
        [(False, "RuntimeError: corrupted for good"), (True, "")]
    assert seen[0].value == seen[1].value
    assert len({seen[0].value, seen[2].value, seen[4].value}) == 3


def test_a_continued_value_without_work_after_it_is_one_answer() -> None:
    pool = LocalPool(tasks.continued_alone, workers=1, run_timeout=30.0)
    seen = list(pool.map((i, i) for i in range(3)))
    assert [(key, type(outcome), outcome.value) for key, outcome in seen] == \
        [(i, Outcome, i) for i in range(3)]


def test_a_timeout_longer_than_the_system_can_wait_for_is_kept() -> None:
    # poll() takes milliseconds in a C int (about 24.8 days): a longer timeout (--run-timeout
    # 3000000, or 1e10) is waited for in parts, and the runs come back as with none.
    for timeout in (3e6, 1e10):
        pool = LocalPool(tasks.square, workers=2, run_timeout=timeout)
        results = dict(pool.map((i, i) for i in range(4)))
        assert {i: o.value for i, o in results.items()} == {0: 0, 1: 1, 2: 4, 3: 9}
        runner = IsolatedRunner(tasks.square)
        try:
            outcome = runner.run("k", 3, timeout)
            assert outcome.ok and outcome.value == 9, outcome
        finally:
            runner.close()
