"""Executing runs: a local process pool robust to crashing and hanging runs, or Dask.

Both backends take ``(key, payload)`` tasks, a module-level task function and a timeout per
task (a number, a function of the key, or None), and yield ``(key, Outcome)`` as runs finish
(in completion order; results are stored by key, so order never matters). A run fails only for
its own reason, with the same words on both: an exception of the task function, a crash of the
process running it (``the simulation process crashed (SIGSEGV)``), or its timeout.

The local pool gives each worker process one task at a time over a pipe. That is what makes a
crash attributable: when a worker dies (even by a segfault inside the FMU) the parent knows the
one run it was executing, records it as failed with the signal, and starts a fresh worker. A run
that exceeds the timeout is ended by killing its worker. A worker killed from outside while it
runs a run (SIGKILL or SIGTERM the pool did not send: the out-of-memory killer, an operator)
says nothing about the run: the run is given to a fresh worker again, up to
:data:`~idefix_rules.campaign.simulation.processes.MAX_KILLS` attempts, and then yields
``infrastructure: killed by SIGKILL 3 times``. Workers keep their FMU instance between runs; a
worker whose task answers :class:`~idefix_rules.campaign.simulation.processes.Retire` (its FMU
returned Fatal) is retired once the answer is in and replaced like a crashed one.

On Linux workers are forked: cheap to start again after a crash, and they never re-run the
caller's ``__main__`` (forkserver and spawn do, which breaks scripts without a main guard). The
parent holds no FMU instance and the children never touch the parent's HDF5 file (they leave
through ``os._exit``). Elsewhere the platform's safe default (spawn) is used.

On Dask (:mod:`~idefix_rules.campaign.simulation.dask_pool`) each task runs the same way, in a child
process of its Dask worker, so a crashing FMU never takes a Dask worker (and the runs queued
on it) down.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import sys
import time
from collections import deque
from collections.abc import Hashable, Iterable, Iterator
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Any

from idefix_rules.campaign.simulation.dask_pool import DaskPool
from idefix_rules.campaign.simulation.processes import (
    AGAIN,
    MAX_KILLS,
    Continued,
    Outcome,
    Retire,
    TaskFunction,
    Then,
    Timeouts,
    death_outcome,
    killed_reason,
    receive,
    timeout_of,
    timeout_reason,
    wait_until,
    worker_main,
)

__all__ = ["Continued", "DaskPool", "LocalPool", "Outcome", "TaskFunction", "Then", "Timeouts",
           "timeout_of"]


@dataclass
class _Worker:
    process: multiprocessing.process.BaseProcess
    connection: Connection
    key: Hashable | None = None
    deadline: float | None = None  # monotonic time its task's timeout ends
    timeout: float | None = None
    after: bool = False  # its task's value came: it does the work after it (Continued)


class LocalPool:
    """A pool of worker processes, one task each at a time, with crash and timeout handling."""

    def __init__(self, function: TaskFunction, workers: int | None = None,
                 run_timeout: Timeouts = None, start_method: str | None = None,
                 persistent: bool = False) -> None:
        self.function = function
        self.size = max(1, workers or os.cpu_count() or 1)
        self.run_timeout = run_timeout
        # persistent: the workers (and the FMU each holds) outlive a map that ran to its end,
        # for the next map (an adaptive campaign's looks); the owner closes the pool
        self.persistent = persistent
        if start_method is None:
            start_method = "fork" if sys.platform.startswith("linux") else "spawn"
        self._context = multiprocessing.get_context(start_method)
        self._workers: list[_Worker] = []

    @property
    def forks(self) -> bool:
        """Whether the workers are forked (and so hold the parent's module state)."""
        return self._context.get_start_method() == "fork"

    def _spawn(self) -> _Worker:
        parent_end, child_end = self._context.Pipe()
        inherited = parent_end if self.forks else None
        process = self._context.Process(  # type: ignore[attr-defined]
            target=worker_main, args=(child_end, self.function, os.getpid(), inherited),
            daemon=True)
        process.start()
        child_end.close()
        return _Worker(process, parent_end)

    def _retire(self, worker: _Worker, kill: bool) -> None:
        if kill and worker.process.is_alive():
            worker.process.kill()
        worker.process.join(timeout=5)
        worker.connection.close()
        self._workers.remove(worker)

    def map(self, tasks: Iterable[tuple[Hashable, Any]]) -> Iterator[tuple[Hashable, Outcome]]:
        """Run every task; yields ``(key, Outcome)`` as each finishes. A task is taken from
        ``tasks`` when a worker is free for it: a worker that finished gets its next task
        before the finished runs are yielded (it simulates while the caller stores them), so
        at most two per worker are held at a time, one running and one finished (and those a
        kill from outside sends round again). A task whose value is :class:`Continued` yields
        its ``Outcome`` and later a :class:`Then` for the work after it; its worker takes no
        other task until then."""
        pending = iter(tasks)
        exhausted = False
        again: deque[tuple[Hashable, Any]] = deque()  # runs whose worker was killed from outside
        payloads: dict[Hashable, Any] = {}  # of the runs being executed
        kills: dict[Hashable, list[str]] = {}
        finished = False

        def fill() -> None:
            """Give every idle worker its next task, starting a worker (up to the size) only
            for a task there is: never more processes than runs to simulate."""
            nonlocal exhausted
            while True:
                worker = next((w for w in self._workers if w.key is None), None)
                if worker is None and len(self._workers) >= self.size:
                    return
                if again:
                    key, payload = again.popleft()
                else:
                    try:
                        key, payload = next(pending)
                    except StopIteration:
                        exhausted = True
                        return
                if worker is None:
                    worker = self._spawn()
                    self._workers.append(worker)
                if not self._hand(worker, key, payload):
                    again.appendleft((key, payload))  # the worker died idle: not the run's
                    continue
                payloads[key] = payload

        try:
            while True:
                fill()
                busy = [w for w in self._workers if w.key is not None]
                if not busy:
                    if exhausted and not again:
                        finished = True
                        return
                    continue
                ready: list[tuple[Hashable, Outcome]] = []
                for key, outcome in self._collect(busy):
                    if isinstance(outcome, Then):  # after the task's outcome, given before
                        ready.append((key, outcome))
                        continue
                    payload = payloads.pop(key)
                    if outcome.killed_by:
                        signals = kills.setdefault(key, [])
                        signals.append(outcome.killed_by)
                        if len(signals) < MAX_KILLS:
                            again.append((key, payload))
                            continue
                        outcome = Outcome(False, None, killed_reason(signals))
                    kills.pop(key, None)
                    ready.append((key, outcome))
                # the freed workers start their next runs while the caller stores these
                fill()
                yield from ready
        finally:
            if not (self.persistent and finished):  # stopped early: busy workers end now
                self.close()

    def _hand(self, worker: _Worker, key: Hashable, payload: Any) -> bool:
        """Give a worker its task (False: the worker is gone, and retired)."""
        try:
            worker.connection.send((key, payload))
        except (OSError, ValueError):
            self._retire(worker, kill=True)
            return False
        worker.key = key
        worker.timeout = timeout_of(self.run_timeout, key)
        worker.deadline = None if worker.timeout is None else time.monotonic() + worker.timeout
        return True

    def _collect(self, busy: list[_Worker]) -> Iterator[tuple[Hashable, Outcome]]:
        deadlines = [w.deadline for w in busy if w.deadline is not None]
        handles: dict[Any, _Worker] = {}
        for worker in busy:
            handles[worker.connection] = worker
            handles[worker.process.sentinel] = worker
        ready = wait_until(list(handles), min(deadlines) if deadlines else None)
        done: set[int] = set()
        for handle in ready:
            worker = handles[handle]
            if id(worker) in done:
                continue
            done.add(id(worker))
            key = worker.key
            message = receive(worker.connection)
            if message is not None:
                _, ok, value, reason = message
                if isinstance(value, Continued):  # the task's value; the rest follows
                    worker.after = True
                    worker.deadline = None if worker.timeout is None \
                        else time.monotonic() + worker.timeout
                    yield key, Outcome(ok, value.value, reason)
                    continue
                worker.key = worker.deadline = None
                worker.after = False
                if isinstance(value, Retire):  # it ends: the next task gets a fresh worker
                    self._retire(worker, kill=True)
                    if value.again:  # not its own failure: the run goes to a fresh worker
                        yield key, Outcome(False, None, reason, killed_by=AGAIN)
                        continue
                    value = value.value
                yield key, value if isinstance(value, Then) else Outcome(ok, value, reason)
            else:
                worker.process.join(timeout=5)
                outcome = death_outcome(worker.process.exitcode)
                if worker.after:  # the task's outcome stands; what came after it is lost
                    outcome = Then(False, None, outcome.reason)
                self._retire(worker, kill=True)
                yield key, outcome
        now = time.monotonic()
        for worker in list(busy):
            if id(worker) in done or worker.key is None or worker.deadline is None:
                continue
            if now >= worker.deadline:
                key, seconds, after = worker.key, worker.timeout, worker.after
                self._retire(worker, kill=True)
                reason = timeout_reason(seconds or 0.0)
                yield key, Then(False, None, reason) if after else Outcome(False, None, reason)

    def close(self) -> None:
        for worker in list(self._workers):
            if worker.key is None:
                with contextlib.suppress(OSError, ValueError):
                    worker.connection.send(None)
            self._retire(worker, kill=worker.key is not None)
