"""Running a campaign's tasks on a Dask distributed cluster with the local pool's semantics.

Each task runs in a child process of its Dask worker
(:func:`~idefix_rules.campaign.simulation.processes. run_isolated`): a run that crashes, hangs past
its timeout or raises fails with the same reason as on the local pool, and the Dask worker lives
on. What remains is the infrastructure's own
trouble:

* a run whose child process was killed from outside (SIGKILL, SIGTERM: the out-of-memory killer,
  an operator; :func:`~idefix_rules.campaign.simulation.processes.death_outcome`) is submitted
  again, as on the local pool;
* a run whose Dask worker died under it (killed from outside, out of memory, machine lost) is
  run again: Dask reschedules it itself, and when Dask gives up (``KilledWorker``) or a result is
  lost, it is submitted again, until its processes died :data:`MAX_WORKER_DEATHS` times, the
  two kinds of death counted together (or its result was lost :data:`MAX_LOST_RESULTS` times);
  then it is recorded as failed with a reason starting with :data:`INFRASTRUCTURE`
  ("infrastructure: killed by SIGKILL 3 times", "infrastructure: worker died 4 times …"), which
  ``--resume`` runs again;
* a cluster without workers for :data:`NO_WORKER_GRACE` seconds, a lost scheduler, or no run
  finishing for longer than the largest run timeout plus :data:`STALL_MARGIN` stops the campaign
  with :class:`ClusterError` (exit 3); every run stored so far is
  kept and ``--resume`` continues. A campaign on Dask never waits forever.
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import os
import signal
import threading
import time
from collections import Counter
from collections.abc import Hashable, Iterable, Iterator
from typing import Any

from idefix_rules.campaign.simulation.dask_worker_setup import WORKING_FOLDER
from idefix_rules.campaign.simulation.processes import (
    INFRASTRUCTURE,
    MAX_KILLS,
    Outcome,
    TaskFunction,
    Timeouts,
    is_infrastructure,
    killed_reason,
    run_isolated,
    timeout_of,
)
from idefix_rules.errors import InfrastructureError, UserInputError

__all__ = ["INFRASTRUCTURE", "ClusterError", "DaskPool", "is_infrastructure"]

MAX_WORKER_DEATHS = MAX_KILLS  # the local pool's bound on a run killed from outside
MAX_LOST_RESULTS = 3
NO_WORKER_GRACE = 60.0  # s
STALL_MARGIN = 120.0  # s
POLL = 0.05  # s between looks at the cluster while no run finishes
HEALTH_CHECK = 5.0  # s between asking the scheduler about its workers
RESULT_WAIT = 60.0  # s to fetch a finished run's result before it counts as lost
# Runs submitted at once per worker thread: enough that a thread finds its next run queued,
# few enough that the runs not yet started are not all held (the parent's memory does not
# grow with the number of runs).
IN_FLIGHT_PER_THREAD = 2


class ClusterError(InfrastructureError):
    """The Dask cluster cannot go on (no workers, scheduler lost, no progress): exit 3; the
    runs stored so far stay and ``--resume`` continues."""


@contextlib.contextmanager
def ctrl_c_deferred() -> Iterator[list[bool]]:
    """Within the block, Ctrl-C is noted (the list yielded gets ``True``) instead of raising;
    a second Ctrl-C raises at once. Nothing is deferred off the main thread (where signals
    cannot be handled) or where Ctrl-C does not raise KeyboardInterrupt (ignored, or the
    caller's own handler)."""
    pressed: list[bool] = []
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield pressed  # off the main thread, or Ctrl-C ignored or handled by the caller
        return

    def note(signum: int, frame: Any) -> None:
        if pressed:
            raise KeyboardInterrupt
        pressed.append(True)

    previous = signal.signal(signal.SIGINT, note)
    try:
        yield pressed
    finally:
        signal.signal(signal.SIGINT, previous)


MP_METHOD = "distributed.worker.multiprocessing-method"


def workers_ignore_ctrl_c() -> str | None:
    """Start the local cluster's worker processes ignoring Ctrl-C from their first instant.

    A terminal's Ctrl-C reaches the whole process group. A worker spawned afresh (Dask's
    default) installs Python's handler as it starts and, interrupted while it still imports
    Dask (before its preload, :mod:`dask_worker_setup`, runs), dies with its traceback on the
    campaign's terminal. Here the workers are forked from a fork server that was started with
    Ctrl-C ignored: a process started with SIGINT ignored keeps it ignored (Python installs its
    handler only where SIGINT has its default action), and the fork server hands that on to
    every worker it forks, the ones the nannies start again later too. The fork server has Dask
    imported already, so a worker starts in a fraction of the time. Ctrl-C is ignored by this
    process only while the fork server is started (milliseconds), once per process; off the
    main thread, or without fork servers (Windows), the workers are started as before.

    Returns Dask's start method before (None: unchanged), for :meth:`DaskPool.close` to put
    back: the process's other clusters are not this campaign's."""
    import multiprocessing

    import dask

    if "forkserver" not in multiprocessing.get_all_start_methods() or \
            threading.current_thread() is not threading.main_thread():
        return None
    from multiprocessing import forkserver

    from distributed.utils import get_mp_context

    before = str(dask.config.get(MP_METHOD))
    dask.config.set({MP_METHOD: "forkserver"})  # for the nannies' restarts too, until close
    get_mp_context()  # type: ignore[no-untyped-call]  # the fork server preloads Dask, once
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        forkserver.ensure_running()
    finally:
        signal.signal(signal.SIGINT, previous)
    return before


class DaskPool:
    """The local pool's interface on a Dask cluster (``address``) or a LocalCluster."""

    def __init__(self, function: TaskFunction, address: str | None = None,
                 workers: int | None = None, run_timeout: Timeouts = None,
                 persistent: bool = False) -> None:
        from dask.distributed import Client

        self.function = function
        self.run_timeout = run_timeout
        self.persistent = persistent  # as LocalPool's: kept for the next map, closed by its owner
        self._cluster: Any = None
        self._client: Any = None
        self._method: str | None = None  # Dask's start method to put back at close
        if address is None:
            self._start_local(workers)
        else:
            try:
                self._client = Client(address)  # type: ignore[no-untyped-call]
            except ValueError as failure:  # not an address at all: a usage mistake
                raise UserInputError(f"--scheduler {address!r}: {failure}") from None
            except OSError as failure:  # no scheduler answers there
                raise ClusterError(f"cannot reach the Dask scheduler {address}: "
                                   f"{failure}") from None
        self.size = max(1, sum(self._client.nthreads().values()))

    def _start_local(self, workers: int | None) -> None:
        """A LocalCluster of ``workers`` processes and its client. Ctrl-C while it starts is
        taken once it has started (or failed to), and the cluster closed: interrupted halfway,
        its workers still starting, it could not be closed at all (Dask's exit hook then fails
        on it with a traceback). The workers ignore it (:func:`workers_ignore_ctrl_c`); where they
        cannot (no fork server) a terminal's Ctrl-C reaches them too and the start fails with
        them: that is the interrupt, not the cluster's failure."""
        import dask
        from dask.distributed import Client, LocalCluster

        self._method = workers_ignore_ctrl_c()
        try:
            with ctrl_c_deferred() as pressed:
                try:
                    # One task per worker thread at a time: a worker that dies then takes only
                    # the run it was executing, not runs merely queued on it (which Dask would
                    # count as suspects of its death too).
                    with dask.config.set({"distributed.scheduler.worker-saturation": 1.0}):
                        # Its HTTP server (dashboard, health) on a free port: two local
                        # clusters would otherwise contend for 8787 and Dask warn about it.
                        # Only its errors logged: the campaign says itself what became of each
                        # run, and Ctrl-C would otherwise end in the workers' warnings about
                        # the runs cancelled under them and the nanny's about killing them.
                        # A worker forked from the fork server has the environment and the
                        # folder the fork server started in: given this process's own now.
                        self._cluster = LocalCluster(  # type: ignore[no-untyped-call]
                            n_workers=workers or os.cpu_count() or 1, threads_per_worker=1,
                            processes=True, dashboard_address=":0",
                            silence_logs=logging.ERROR,
                            preload=["idefix_rules.campaign.simulation.dask_worker_setup"],
                            env={**os.environ, WORKING_FOLDER: os.getcwd()})
                    self._client = Client(self._cluster)  # type: ignore[no-untyped-call]
                except Exception:
                    if not pressed:
                        raise
            if pressed:
                raise KeyboardInterrupt
        except BaseException:
            self.close()  # what was started, and Dask's start method as it was
            raise

    def _submit(self, key: Hashable, payload: Any) -> Any:
        return self._client.submit(
            run_isolated, self.function, key, payload, timeout_of(self.run_timeout, key),
            pure=False, retries=0)

    def map(self, tasks: Iterable[tuple[Hashable, Any]]) -> Iterator[tuple[Hashable, Outcome]]:
        """Run every task; yields ``(key, Outcome)`` as each finishes. Tasks are taken from
        ``tasks`` as runs finish, :data:`IN_FLIGHT_PER_THREAD` per worker thread at most
        submitted at once (each kept until its outcome, to submit it again if lost)."""
        from dask.distributed import as_completed

        pending = iter(tasks)
        payloads: dict[Hashable, Any] = {}  # of the runs submitted
        keys: dict[Any, Hashable] = {}
        completed: Any = as_completed()  # type: ignore[no-untyped-call]
        deaths = _Deaths()
        losses: Counter[Hashable] = Counter()
        watch = _Watch(self._client, None)
        limits = _Limits()

        def submit(key: Hashable, payload: Any) -> None:
            future = self._submit(key, payload)
            keys[future] = key
            completed.add(future)

        def top_up() -> None:
            room = IN_FLIGHT_PER_THREAD * max(self.size, watch.threads) - len(keys)
            for key, payload in itertools.islice(pending, max(0, room)):
                payloads[key] = payload
                watch.stall = limits.add(timeout_of(self.run_timeout, key))
                submit(key, payload)

        finished = False
        try:
            top_up()
            while keys:
                batch = completed.next_batch(block=False)
                if not batch:
                    watch.check()
                    time.sleep(POLL)
                    continue
                watch.progress()
                for future in batch:
                    key = keys.pop(future)
                    outcome = self._outcome(future, key, deaths, losses)
                    future.release()
                    if outcome is None:  # lost to the cluster: run it again
                        submit(key, payloads[key])
                        continue
                    del payloads[key]
                    deaths.forget(key)
                    losses.pop(key, None)
                    yield key, outcome
                top_up()
            finished = True
        finally:
            if not (self.persistent and finished):
                self.close()

    def _outcome(self, future: Any, key: Hashable, deaths: _Deaths,
                 losses: Counter[Hashable]) -> Outcome | None:
        """The run's outcome, or None when the cluster lost it and it is to run again."""
        from dask.distributed import KilledWorker

        status = future.status
        failure: BaseException | None = None
        if status == "finished":
            try:
                # a result lost with its worker is computed again, which may wait for a worker
                value = future.result(timeout=RESULT_WAIT)
            except Exception as error:  # the result vanished with its worker
                failure = error
            else:
                if isinstance(value, Outcome) and value.killed_by:
                    return deaths.killed(key, value.killed_by)
                if isinstance(value, Outcome):
                    return value
                failure = TypeError(f"unexpected result {type(value).__name__}")
        elif status == "error":
            failure = future.exception()
            if isinstance(failure, KilledWorker):
                return deaths.worker_died(key, failure.allowed_failures + 1)
        if self._client.status not in ("running", "connecting"):
            raise ClusterError("lost the connection to the Dask scheduler")
        losses[key] += 1
        if losses[key] >= MAX_LOST_RESULTS:
            what = f"{type(failure).__name__}: {failure}" if failure is not None \
                else f"the cluster lost its result ({status})"
            return Outcome(False, None, f"{INFRASTRUCTURE}{what} ({losses[key]} times)")
        return None

    def close(self) -> None:
        if self._client is not None:
            self._client.close()
        if self._cluster is not None:
            self._cluster.close()
        if self._method is not None:
            import dask

            dask.config.set({MP_METHOD: self._method})
            self._method = None


class _Limits:
    """The largest run timeout among the runs submitted so far (None once one has none):
    how long the cluster may go without finishing a run, plus :data:`STALL_MARGIN`."""

    def __init__(self) -> None:
        self.largest: float | None = None
        self.unlimited = False

    def add(self, timeout: float | None) -> float | None:
        """Count a submitted run's timeout; the stall limit that follows (None: none)."""
        if timeout is None:
            self.unlimited = True
        else:
            self.largest = timeout if self.largest is None else max(self.largest, timeout)
        if self.unlimited or self.largest is None:
            return None
        return self.largest + STALL_MARGIN


class _Deaths:
    """The deaths of each run's processes: its child killed from outside, its Dask worker lost.
    A run is submitted again until they reach :data:`MAX_WORKER_DEATHS`."""

    def __init__(self) -> None:
        self.count: Counter[Hashable] = Counter()
        self.signals: dict[Hashable, list[str]] = {}

    def killed(self, key: Hashable, signal_name: str) -> Outcome | None:
        """Its child was killed by ``signal_name``: None (run it again) or its lost outcome."""
        self.signals.setdefault(key, []).append(signal_name)
        return self._after(key, 1)

    def worker_died(self, key: Hashable, times: int) -> Outcome | None:
        """Its Dask worker died ``times`` times (``KilledWorker``)."""
        return self._after(key, times)

    def forget(self, key: Hashable) -> None:
        """The run has its outcome: its deaths are no longer needed."""
        self.count.pop(key, None)
        self.signals.pop(key, None)

    def _after(self, key: Hashable, times: int) -> Outcome | None:
        self.count[key] += times
        if self.count[key] < MAX_WORKER_DEATHS:
            return None
        signals = self.signals.get(key, [])
        if len(signals) == self.count[key]:  # only ever its child, killed from outside
            return Outcome(False, None, killed_reason(signals))
        return Outcome(False, None, f"{INFRASTRUCTURE}worker died {self.count[key]} times "
                                    "while running it")


class _Watch:
    """Stops a campaign that cannot go on: no workers for a while, or no progress at all."""

    def __init__(self, client: Any, stall: float | None) -> None:
        self.client = client
        self.stall = stall
        self.last_progress = time.monotonic()
        self.last_check = 0.0
        self.no_workers_since: float | None = None
        self.threads = 0  # the cluster's worker threads when last asked

    def progress(self) -> None:
        self.last_progress = time.monotonic()

    def check(self) -> None:
        now = time.monotonic()
        if self.stall is not None and now - self.last_progress > self.stall:
            raise ClusterError(f"no run finished on the Dask cluster for "
                                      f"{now - self.last_progress:.0f} s")
        if now - self.last_check < HEALTH_CHECK:
            return
        self.last_check = now
        if self.client.status not in ("running", "connecting"):
            raise ClusterError("lost the connection to the Dask scheduler")
        try:
            workers = self.client.scheduler_info(n_workers=-1).get("workers", {})
        except (OSError, TimeoutError) as failure:
            raise ClusterError(f"the Dask scheduler does not answer: {failure}") from None
        self.threads = sum(int(worker.get("nthreads", 0) or 0) for worker in workers.values())
        if workers:
            self.no_workers_since = None
        elif self.no_workers_since is None:
            self.no_workers_since = now
        elif now - self.no_workers_since > NO_WORKER_GRACE:
            raise ClusterError(f"the Dask cluster has had no worker for "
                                      f"{NO_WORKER_GRACE:.0f} s")
