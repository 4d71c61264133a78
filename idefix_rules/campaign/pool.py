"""Executing runs: a local process pool robust to crashing and hanging runs, or Dask.

Both backends take ``(key, payload)`` tasks and a module-level task function, and yield
``(key, Outcome)`` as runs finish (in completion order; results are stored by key, so order
never matters).

The local pool gives each worker process one task at a time over a pipe. That is what makes a
crash attributable: when a worker dies (even by a segfault inside the FMU) the parent knows the
one run it was executing, records it as failed with the signal, and starts a fresh worker. A run
that exceeds the timeout is ended by killing its worker. Workers keep their FMU instance between
runs.

On Linux workers are forked: cheap to start again after a crash, and they never re-run the
caller's ``__main__`` (forkserver and spawn do, which breaks scripts without a main guard). The
parent holds no FMU instance and the children never touch the parent's HDF5 file (they leave
through ``os._exit``). Elsewhere the platform's safe default (spawn) is used.
"""

from __future__ import annotations

import contextlib
import faulthandler
import multiprocessing
import os
import signal
import sys
import time
import traceback
from collections.abc import Callable, Hashable, Iterable, Iterator
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from typing import Any

TaskFunction = Callable[[Any], Any]


@dataclass(frozen=True)
class Outcome:
    """What became of one task: ``value`` when ``ok``, else the reason it failed."""

    ok: bool
    value: Any = None
    reason: str = ""


def _worker_main(connection: Connection, function: TaskFunction, parent: int,
                 inherited: Connection | None = None) -> None:
    # Ctrl-C goes to the parent, which decides; workers are ended by it.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # A crash is recorded by the parent with its signal; no stack dump in the logs.
    faulthandler.disable()
    if inherited is not None:
        inherited.close()  # the parent's end, copied by fork
    while True:
        try:
            # Other workers forked later hold copies of this pipe, so a dead parent does not
            # always show as EOF: look at the parent itself while idle.
            while not connection.poll(1.0):
                if os.getppid() != parent:
                    return
            message = connection.recv()
        except (EOFError, OSError):
            return
        if message is None:
            return
        key, payload = message
        try:
            result = (key, True, function(payload), "")
        except Exception as failure:
            reason = f"{type(failure).__name__}: {failure}"
            result = (key, False, None, reason or traceback.format_exc(limit=2))
        try:
            connection.send(result)
        except (OSError, ValueError):
            return


@dataclass
class _Worker:
    process: multiprocessing.process.BaseProcess
    connection: Connection
    key: Hashable | None = None
    started: float = 0.0


def _describe_death(exitcode: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        try:
            name = signal.Signals(-exitcode).name
        except ValueError:
            name = f"signal {-exitcode}"
        return f"the simulation process crashed ({name})"
    return f"the simulation process exited unexpectedly (exit code {exitcode})"


class LocalPool:
    """A pool of worker processes, one task each at a time, with crash and timeout handling."""

    def __init__(self, function: TaskFunction, workers: int | None = None,
                 run_timeout: float | None = None, start_method: str | None = None) -> None:
        self.function = function
        self.size = max(1, workers or os.cpu_count() or 1)
        self.run_timeout = run_timeout
        if start_method is None:
            start_method = "fork" if sys.platform.startswith("linux") else "spawn"
        self._context = multiprocessing.get_context(start_method)
        self._workers: list[_Worker] = []

    def _spawn(self) -> _Worker:
        parent_end, child_end = self._context.Pipe()
        inherited = parent_end if self._context.get_start_method() == "fork" else None
        process = self._context.Process(  # type: ignore[attr-defined]
            target=_worker_main, args=(child_end, self.function, os.getpid(), inherited),
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
        """Run every task; yields ``(key, Outcome)`` as each finishes."""
        pending = iter(tasks)
        exhausted = False
        try:
            while True:
                while not exhausted and len(self._workers) < self.size:
                    self._workers.append(self._spawn())
                idle = [w for w in self._workers if w.key is None]
                for worker in idle:
                    try:
                        key, payload = next(pending)
                    except StopIteration:
                        exhausted = True
                        break
                    worker.connection.send((key, payload))
                    worker.key, worker.started = key, time.monotonic()
                busy = [w for w in self._workers if w.key is not None]
                if not busy:
                    if exhausted:
                        return
                    continue
                yield from self._collect(busy)
        finally:
            self.close()

    def _collect(self, busy: list[_Worker]) -> Iterator[tuple[Hashable, Outcome]]:
        timeout = None
        if self.run_timeout is not None:
            now = time.monotonic()
            timeout = max(0.0, min(w.started + self.run_timeout - now for w in busy))
        handles: dict[Any, _Worker] = {}
        for worker in busy:
            handles[worker.connection] = worker
            handles[worker.process.sentinel] = worker
        ready = wait(list(handles), timeout=timeout)
        done: set[int] = set()
        for handle in ready:
            worker = handles[handle]
            if id(worker) in done:
                continue
            done.add(id(worker))
            key = worker.key
            message = None
            if worker.connection.poll():
                try:
                    message = worker.connection.recv()
                except (EOFError, OSError):
                    message = None
            if message is not None:
                worker.key = None
                _, ok, value, reason = message
                yield key, Outcome(ok, value, reason)
            else:
                worker.process.join(timeout=5)
                reason = _describe_death(worker.process.exitcode)
                self._retire(worker, kill=True)
                yield key, Outcome(False, None, reason)
        if self.run_timeout is not None:
            now = time.monotonic()
            for worker in list(busy):
                if id(worker) in done or worker.key is None:
                    continue
                if now - worker.started >= self.run_timeout:
                    key = worker.key
                    self._retire(worker, kill=True)
                    yield key, Outcome(False, None,
                                       f"exceeded the run timeout of {self.run_timeout:g} s")

    def close(self) -> None:
        for worker in list(self._workers):
            if worker.key is None:
                with contextlib.suppress(OSError, ValueError):
                    worker.connection.send(None)
            self._retire(worker, kill=worker.key is not None)


class DaskPool:
    """The same interface on a Dask distributed cluster (``address``) or a LocalCluster.

    A run's timeout is not enforced on Dask (workers cannot be killed per task from here); a
    crashing run makes Dask retire the worker and report the task as failed, which is recorded.
    """

    def __init__(self, function: TaskFunction, address: str | None = None,
                 workers: int | None = None) -> None:
        from dask.distributed import Client, LocalCluster

        self.function = function
        self._cluster = None
        if address is None:
            self._cluster = LocalCluster(  # type: ignore[no-untyped-call]
                n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True)
            self._client = Client(self._cluster)  # type: ignore[no-untyped-call]
        else:
            from idefix_rules.errors import InfrastructureError, UserInputError

            try:
                self._client = Client(address)  # type: ignore[no-untyped-call]
            except ValueError as failure:  # not an address at all: a usage mistake
                raise UserInputError(f"--scheduler {address!r}: {failure}") from None
            except OSError as failure:  # no scheduler answers there
                raise InfrastructureError(f"cannot reach the Dask scheduler {address}: "
                                          f"{failure}") from None
        self.size = max(1, sum(self._client.nthreads().values()))  # type: ignore[no-untyped-call]

    def map(self, tasks: Iterable[tuple[Hashable, Any]]) -> Iterator[tuple[Hashable, Outcome]]:
        from dask.distributed import as_completed

        futures = {}
        for key, payload in tasks:
            future = self._client.submit(self.function, payload, pure=False, retries=0)
            futures[future] = key
        try:
            for future in as_completed(list(futures)):  # type: ignore[no-untyped-call]
                key = futures.pop(future)  # the cluster may drop the result once read
                if future.status == "finished":
                    yield key, Outcome(True, future.result())
                else:
                    failure = future.exception()
                    yield key, Outcome(False, None, f"{type(failure).__name__}: {failure}")
        finally:
            self.close()

    def close(self) -> None:
        self._client.close()  # type: ignore[no-untyped-call]
        if self._cluster is not None:
            self._cluster.close()
