"""Running tasks in child processes so that a crash or a hang ends only its own run.

Both executors use what is here: the local pool (:mod:`~idefix_rules.campaign.simulation.pool`)
keeps a few such children, and every Dask task runs in one (:func:`run_isolated`), so a segfault
inside the FMU or a run past its timeout is told apart from the loss of a Dask worker, and is
recorded with the same reason whatever executes the campaign.

A run's process that dies tells by its signal whose fault it was. The faults a program raises
on itself (SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT … and an ``exit()``) are the run's own: the
run fails with them. SIGKILL and SIGTERM are sent by another process (an operator, the kernel's
out-of-memory killer, a batch system); the executors end a run past its timeout themselves and
record that as the timeout, so a run killed by either signal otherwise was killed from outside.
Such a run is marked :attr:`Outcome.killed_by`, and the executors run it again, up to
:data:`MAX_KILLS` attempts, before recording it as lost (``infrastructure: killed by SIGKILL 3
times``), which ``--resume`` runs again.

A child serves one task at a time over a pipe and keeps its state (the FMU instance) between
tasks, unless a task says its process must take no other (:class:`Retire`: an FMU that returned
Fatal leaves every instance of it in the process corrupted): the child ends once it has
answered, and the executors start a fresh one for the next task. Children die with the process
that started them (``PR_SET_PDEATHSIG`` on Linux, and an idle child also watches its parent), so
a killed campaign or Dask worker leaves no hanging FMU behind.
"""

from __future__ import annotations

import contextlib
import ctypes
import faulthandler
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from typing import Any

TaskFunction = Callable[[Any], Any]
# A timeout for every task, one per task key, or none (None or 0: no limit).
Timeouts = float | Callable[[Hashable], float | None] | None
_PR_SET_PDEATHSIG = 1

INFRASTRUCTURE = "infrastructure: "
# Attempts of a run killed from outside before it is recorded as lost to the infrastructure.
MAX_KILLS = 3
# What stands in Outcome.killed_by for a run whose process could not run it (its FMU corrupted
# before the run began, :class:`Retire` ``again``): it runs again in a fresh process, as a run
# killed from outside does.
AGAIN = "a process whose FMU failed before the run"

# Signals only another process sends: no FMU code raises them on its own process by a fault.
OUTSIDE_SIGNALS = frozenset({signal.SIGKILL, signal.SIGTERM})


@dataclass(frozen=True)
class Outcome:
    """What became of one task: ``value`` when ``ok``, else the reason it failed."""

    ok: bool
    value: Any = None
    reason: str = ""
    # the signal that ended the run's process from outside ("SIGKILL"): the run is no failure
    # of its own and is to run again; empty otherwise
    killed_by: str = ""


@dataclass(frozen=True)
class Then(Outcome):
    """What became of a task's work after its value (:class:`Continued`): a second answer
    for the same key, after its :class:`Outcome`. Its time, its failures and a crash of the
    process during it are not the task's: the task's outcome stands."""


@dataclass(frozen=True)
class Continued:
    """What a task function returns to send ``value`` to the parent at once and do ``then``
    after it in the same process, its result or failure following as a :class:`Then`. The
    task's timeout ends with ``value``; ``then`` has a timeout of the same length of its own.
    Dask's children (:class:`IsolatedRunner`) run ``then`` too and leave its answer; off POSIX
    it is not run. Sent to the parent without ``then`` (None): the marker that a second answer
    follows."""

    value: Any
    then: Callable[[], Any] | None = None


@dataclass(frozen=True)
class Retire:
    """What a task function returns when its process must take no other task: the task's
    answer is ``value`` (not a :class:`Continued`), or its failure ``failure`` (with the reason
    an exception of the task function would give), and the process ends once it has sent it.
    Sent to the parent as the marker around the value (``failure`` None), so that the executor
    starts a fresh process for the next task instead of handing it to this one."""

    value: Any = None
    failure: Exception | None = None
    # the task is not this process's to answer (the FMU it holds was corrupted before the task
    # began): the executors run it again in a fresh process instead of recording ``failure``
    again: bool = False


def is_infrastructure(reason: str) -> bool:
    """Whether a failure reason blames the infrastructure rather than the run (``--resume``
    runs such runs again).

    >>> is_infrastructure("infrastructure: killed by SIGKILL 3 times")
    True
    """
    return reason.startswith(INFRASTRUCTURE)


# The longest a single wait on pipes and processes lasts: the system's poll takes milliseconds
# in a C int (about 24.8 days), so a longer timeout (--run-timeout 3000000) is waited for in
# parts of at most this, its deadline kept.
MAX_WAIT = 86_400.0


def wait_until(handles: list[Any], deadline: float | None) -> list[Any]:
    """``multiprocessing.connection.wait`` until one of ``handles`` is ready or the monotonic
    ``deadline`` (None: none) has passed, however far off it is; [] at the deadline."""
    while True:
        left = None if deadline is None else deadline - time.monotonic()
        if left is not None and left <= 0.0:
            return list(wait(handles, timeout=0.0))
        ready = wait(handles, timeout=MAX_WAIT if left is None else min(left, MAX_WAIT))
        if ready:
            return list(ready)


def timeout_of(timeouts: Timeouts, key: Hashable) -> float | None:
    """The timeout of task ``key`` in seconds (None: no limit)."""
    value = timeouts(key) if callable(timeouts) else timeouts
    return value if value is not None and value > 0 else None


def timeout_reason(seconds: float) -> str:
    """The failure reason of a run ended by its timeout (the same on every executor)."""
    return f"exceeded the run timeout of {seconds:g} s"


def _signal_name(number: int) -> str:
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


def describe_death(exitcode: int | None) -> str:
    """The failure reason of a run whose process died while running it."""
    if exitcode is not None and exitcode < 0:
        return f"the simulation process crashed ({_signal_name(-exitcode)})"
    return f"the simulation process exited unexpectedly (exit code {exitcode})"


def killed_reason(signals: list[str]) -> str:
    """The reason of a run whose process was killed from outside at every attempt.

    >>> killed_reason(["SIGKILL", "SIGKILL", "SIGKILL"])
    'infrastructure: killed by SIGKILL 3 times'
    >>> killed_reason(["SIGTERM", "SIGKILL"])
    'infrastructure: killed by SIGTERM, SIGKILL 2 times'
    """
    names = ", ".join(dict.fromkeys(signals))
    times = "once" if len(signals) == 1 else f"{len(signals)} times"
    return f"{INFRASTRUCTURE}killed by {names} {times}"


def death_outcome(exitcode: int | None) -> Outcome:
    """What became of a run whose process died while running it, the executor not having
    killed it: its own failure (a fault, an exit), or killed from outside (run it again)."""
    if exitcode is not None and exitcode < 0 and -exitcode in OUTSIDE_SIGNALS:
        name = _signal_name(-exitcode)
        return Outcome(False, None, killed_reason([name]), killed_by=name)
    return Outcome(False, None, describe_death(exitcode))


def _die_with_parent() -> None:
    """Ask Linux to kill this process when the thread that forked it ends."""
    if not sys.platform.startswith("linux"):
        return
    with contextlib.suppress(OSError, AttributeError):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)


def worker_main(connection: Connection, function: TaskFunction, parent: int,
                inherited: Connection | None = None) -> None:
    """The loop of a child: receive ``(key, payload)``, send ``(key, ok, value, reason)``;
    a :class:`Continued` value is sent without its ``then``, and ``(key, True, Then, "")``
    follows once ``then`` has run; after a :class:`Retire` answer the child ends."""
    # Ctrl-C goes to the parent, which decides; children are ended by it.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    _die_with_parent()
    # A crash is recorded by the parent with its signal; no stack dump in the logs.
    faulthandler.disable()
    if inherited is not None:
        inherited.close()  # the parent's end, copied by fork
    while True:
        try:
            # Other children forked later hold copies of this pipe, so a dead parent does not
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
        then = None
        retire = False
        try:
            value = function(payload)
            if isinstance(value, Continued):  # the value now, then the rest (if any)
                value, then = (Continued(value.value), value.then) \
                    if value.then is not None else (value.value, None)
            result = (key, True, value, "")
            if isinstance(value, Retire):  # answered, then this process ends
                retire = True
                if value.failure is not None:
                    result = (key, False, Retire(again=value.again), _reason(value.failure))
        except Exception as failure:
            result = (key, False, None, _reason(failure))
        try:
            connection.send(result)
        except (OSError, ValueError):
            return
        if retire:
            return
        if then is None:
            continue
        try:
            after = Then(True, then())
        except Exception as failure:
            after = Then(False, None, _reason(failure))
        try:
            connection.send((key, True, after, ""))
        except (OSError, ValueError):
            return


def _reason(failure: Exception) -> str:
    return f"{type(failure).__name__}: {failure}"


def receive(connection: Connection) -> tuple[Any, bool, Any, str] | None:
    """A child's answer if it sent one (None: it died before answering)."""
    if not connection.poll():
        return None
    try:
        message: tuple[Any, bool, Any, str] = connection.recv()
    except (EOFError, OSError):
        return None
    return message


_FORK_LOCK = threading.Lock()


class ForkedChild:
    """A child process made by ``os.fork`` (a Dask worker is a daemonic process, which
    :mod:`multiprocessing` forbids to have children). Mirrors the few members of
    :class:`multiprocessing.Process` the executors use."""

    def __init__(self, target: Callable[..., None], args: tuple[Any, ...]) -> None:
        with _FORK_LOCK:  # no other child may inherit this one's end of the sentinel pipe
            read_end, write_end = os.pipe()
            pid = os.fork()
            if pid == 0:  # pragma: no cover - runs in the child
                code = 1
                try:
                    os.close(read_end)
                    target(*args)
                    code = 0
                finally:
                    os._exit(code)
            os.close(write_end)
        self.pid = pid
        self.sentinel = read_end  # readable (EOF) once the child has ended
        self.exitcode: int | None = None

    def _reap(self, flags: int) -> bool:
        if self.exitcode is not None:
            return True
        try:
            pid, status = os.waitpid(self.pid, flags)
        except ChildProcessError:
            self.exitcode = self.exitcode if self.exitcode is not None else -signal.SIGKILL
            return True
        if pid == 0:
            return False
        self.exitcode = os.waitstatus_to_exitcode(status)
        return True

    def is_alive(self) -> bool:
        return not self._reap(os.WNOHANG)

    def kill(self) -> None:
        with contextlib.suppress(ProcessLookupError):
            os.kill(self.pid, signal.SIGKILL)

    def join(self, timeout: float | None = None) -> None:
        deadline = None if timeout is None else time.monotonic() + timeout
        while not self._reap(os.WNOHANG):
            if deadline is not None and time.monotonic() >= deadline:
                return
            time.sleep(0.005)

    def close(self) -> None:
        with contextlib.suppress(OSError):
            os.close(self.sentinel)


class IsolatedRunner:
    """One child process that runs tasks one at a time, kept from task to task.

    >>> runner = IsolatedRunner(abs)  # doctest: +SKIP
    >>> runner.run("k", -3, timeout=5.0)  # doctest: +SKIP
    Outcome(ok=True, value=3, reason='')
    """

    def __init__(self, function: TaskFunction) -> None:
        self.function = function
        self._child: ForkedChild | None = None
        self._connection: Connection | None = None

    def _start(self) -> tuple[ForkedChild, Connection]:
        parent_end, child_end = multiprocessing.Pipe()
        child = ForkedChild(worker_main, (child_end, self.function, os.getpid(), parent_end))
        child_end.close()
        self._child, self._connection = child, parent_end
        return child, parent_end

    def _end(self, kill: bool) -> None:
        child, connection = self._child, self._connection
        self._child = self._connection = None
        if connection is not None:
            if not kill:
                with contextlib.suppress(OSError, ValueError):
                    connection.send(None)
            connection.close()
        if child is not None:
            if kill:
                child.kill()
            child.join(timeout=5)
            if child.is_alive():
                child.kill()
                child.join(timeout=5)
            child.close()

    def run(self, key: Hashable, payload: Any, timeout: float | None) -> Outcome:
        """Run one task; a crash or a timeout of the task is its failed :class:`Outcome`, a
        child killed from outside one with ``killed_by`` (the caller runs it again)."""
        child, connection = self._child, self._connection
        if child is None or connection is None or not child.is_alive():
            # A child that died while idle (its thread's end, a stray signal) is no run's fault.
            self._end(kill=True)
            child, connection = self._start()
        try:
            connection.send((key, payload))
        except (OSError, ValueError):
            self._end(kill=True)
            child, connection = self._start()
            connection.send((key, payload))
        ready = wait_until([connection, child.sentinel], None if timeout is None
                           else time.monotonic() + timeout)
        if not ready:
            self._end(kill=True)
            assert timeout is not None
            return Outcome(False, None, timeout_reason(timeout))
        message = receive(connection)
        if message is None:
            child.join(timeout=5)
            outcome = death_outcome(child.exitcode)
            self._end(kill=True)
            return outcome
        _, ok, value, reason = message
        if isinstance(value, Retire):  # the child ends: the next task starts a fresh one
            self._end(kill=True)
            return Outcome(ok, value.value, reason, killed_by=AGAIN if value.again else "")
        if isinstance(value, Continued):
            # the work after the value (the local pool's): its answer is waited for and
            # left, so that it is not taken for the next task's
            if not wait_until([connection, child.sentinel], None if timeout is None
                              else time.monotonic() + timeout) \
                    or receive(connection) is None:
                self._end(kill=True)
            value = value.value
        return Outcome(ok, value, reason)

    def close(self) -> None:
        self._end(kill=False)


# One runner per thread of a Dask worker (a worker may run several tasks at once).
_ISOLATED: dict[int, IsolatedRunner] = {}


# The Dask worker's scratch folder (its ``local_directory``, which Dask removes when the worker
# ends), set in the worker before its first child is forked: the children inherit it, and what
# they share there (the FMU, extracted once per worker) outlives any one of them, not the worker.
SCRATCH: str | None = None


def _dask_scratch() -> str | None:
    try:
        from distributed import get_worker

        return str(get_worker().local_directory)
    except (ImportError, ValueError):  # not in a Dask worker (a test calling it directly)
        return None


def run_isolated(function: TaskFunction, key: Hashable, payload: Any,
                 timeout: float | None) -> Outcome:
    """The task a Dask worker executes: ``function(payload)`` in this thread's child process.

    Off POSIX (no fork) the function runs in the worker itself, without crash isolation.
    """
    global SCRATCH
    if SCRATCH is None:
        SCRATCH = _dask_scratch()
    if not hasattr(os, "fork"):  # pragma: no cover - Windows workers
        try:
            value = function(payload)
        except Exception as failure:
            return Outcome(False, None, _reason(failure))
        # no process of its own to end: a Retire is answered like any value, and the runner
        # refuses every later run of an FMU that returned Fatal here (idefix_rules.fmu.binding)
        if isinstance(value, Retire) and value.failure is not None:
            return Outcome(False, None, _reason(value.failure),
                           killed_by=AGAIN if value.again else "")
        return Outcome(True, value.value if isinstance(value, Continued | Retire) else value)
    ident = threading.get_ident()
    runner = _ISOLATED.get(ident)
    if runner is None or runner.function is not function:
        if runner is not None:
            runner.close()
        runner = _ISOLATED[ident] = IsolatedRunner(function)
    return runner.run(key, payload, timeout)
