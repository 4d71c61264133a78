"""The task a worker executes: one simulation of one command chain.

The same function runs in the local pool and on Dask workers. Each worker process keeps its
:class:`~idefix_rules.fmu.FmuRunner` (instantiated once) and reuses it through ``reset`` for
every later run; a failing run drops the instance so the next run starts with a fresh one in
the same process (an FMI Error concerns its instance alone), unless the FMU returned Fatal:
then nothing of it may run in this process again (FMI 2.0.x section 2.1.3), and the run's
answer is a :class:`~idefix_rules.campaign.simulation.processes.Retire`, which ends the
process once it is sent (the pool starts a fresh one). The campaign
extracts the FMU once and names the folder in ``RunTask.unzipped``; a task without it (Dask
workers on other machines cannot see the folder) makes each Dask worker extract the FMU itself,
once, into its scratch folder (shared by its run processes, removed by Dask with the worker).
"""

from __future__ import annotations

import contextlib
import functools
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from idefix_rules.campaign.simulation import processes
from idefix_rules.campaign.simulation.processes import Continued, Retire
from idefix_rules.campaign.storage.encoded_chunks import EncodedChunk, encode_run
from idefix_rules.commands import Command, RoverGeometry
from idefix_rules.errors import Diagnostic, Span, UserInputError, error
from idefix_rules.results.format import storage_dtype


@dataclass(frozen=True)
class RunTask:
    """Everything one simulation needs; picklable, sent to a worker."""

    fmu_path: str
    signal_map: tuple[tuple[str, str], ...] | None
    parameter_map: tuple[tuple[str, str], ...] | None
    parameters: tuple[tuple[str, float | str], ...]
    chain: tuple[Command, ...]
    stop_time: float
    output_interval: float
    samples: int
    unzipped: str | None = None  # the FMU extracted once by the campaign (None: extract here)
    chain_delivery: str = "parameters"  # parameters, inputs or none (fmu.chain.delivery)
    chain_inputs: tuple[tuple[str, str], ...] = ()  # FMU input → set-point (delivery inputs)
    done_at: float = 1.0
    rover: RoverGeometry | None = None  # geometry of the set-points (delivery inputs)
    encode: bool = False  # hand back the stored chunks (compressed here), not the arrays
    # the run's collisions are checked here too when this names the check the worker was
    # forked with (:func:`run_checks`); ``run`` is the run's row, for the check's details
    check: str | None = None
    run: int = -1


@dataclass(frozen=True)
class InputProblem:
    """A user mistake found while simulating (bad terrain, unknown variable): not a run
    failure but a campaign error; the parent raises it as :class:`UserInputError`."""

    diagnostics: tuple[Diagnostic, ...]


_RUNNERS: dict[tuple[Any, ...], Any] = {}


def shared_extraction(fmu_path: str, scratch: str) -> str | None:
    """The FMU extracted into ``scratch`` once for every process that shares the folder: named
    by the file's SHA-256, extracted aside and renamed into place, so a process never sees a
    half-extracted FMU and two extracting at once keep one. None when there is no such file
    (the runner then says so)."""
    from idefix_rules.fmu import extract_fmu
    from idefix_rules.results.terrain import file_sha256

    if not os.path.isfile(fmu_path):
        return None
    target = os.path.join(scratch, f"idefix-fmu-{file_sha256(Path(fmu_path))}")
    if os.path.isdir(target):
        return target
    try:
        aside = tempfile.mkdtemp(prefix=".idefix-fmu-", dir=scratch)
    except OSError:  # the scratch folder is gone or full: the runner extracts its own
        return None
    try:
        extract_fmu(fmu_path, aside)
        os.rename(aside, target)
    except OSError:
        if not os.path.isdir(target):  # not another process that got there first
            return None
    finally:
        if os.path.isdir(aside):  # a failed extraction, or one that lost the race
            shutil.rmtree(aside, ignore_errors=True)
    return target


def runner_key(task: RunTask) -> tuple[Any, ...]:
    """What a process's runner is kept for: the task's FMU and maps, and the FMU file as it
    is now (a Dask worker outlives campaigns: an FMU replaced at the same path was run from
    the old runner, its results labelled with the new file's hash)."""
    try:
        stat = os.stat(task.fmu_path)
        identity: tuple[int, ...] = (stat.st_ino, stat.st_size, stat.st_mtime_ns)
    except OSError:
        identity = ()  # the runner says what is wrong with it
    return (task.fmu_path, identity, task.unzipped, task.signal_map, task.parameter_map,
            task.chain_delivery, task.chain_inputs, task.done_at)


def _runner(task: RunTask) -> Any:
    from idefix_rules.fmu import FmuRunner

    key = runner_key(task)
    runner = _RUNNERS.get(key)
    if runner is None:
        for old in _RUNNERS.values():
            old.close()
        _RUNNERS.clear()
        unzipped = task.unzipped
        if unzipped is None and processes.SCRATCH is not None:
            # a Dask worker's process: the worker's scratch folder, not one of its own that a
            # process killed at a timeout, a crash or its worker's end would leave behind
            unzipped = shared_extraction(task.fmu_path, processes.SCRATCH)
        runner = FmuRunner(
            task.fmu_path,
            signal_map=dict(task.signal_map) if task.signal_map is not None else None,
            parameter_map=dict(task.parameter_map) if task.parameter_map is not None else None,
            unzipped=unzipped,
            chain_delivery=task.chain_delivery,
            chain_inputs=dict(task.chain_inputs),
            done_at=task.done_at,
        )
        _RUNNERS[key] = runner
    return runner


@dataclass(frozen=True)
class RunResult:
    """A run's signals — as arrays, or (``RunTask.encode``) as the compressed chunks the results
    file stores, so compression runs in the workers — and the seconds spent inside
    ``FmuRunner.run`` (for the benchmark)."""

    signals: dict[str, np.ndarray]
    seconds: float
    encoded: dict[str, EncodedChunk] | None = None

    @property
    def stored(self) -> Mapping[str, np.ndarray | EncodedChunk]:
        """What :meth:`ResultStore.write_run` takes."""
        return self.encoded if self.encoded is not None else self.signals


def simulate(task: RunTask) -> RunResult | InputProblem | Continued | Retire:
    """Simulate one run; raises on an FMU error or an output that breaks the contract. After
    an FMU's Fatal the run's answer (its failure, or the campaign's mistake) is a
    :class:`~idefix_rules.campaign.simulation.processes.Retire`: this process runs no more.

    When the task asks for the check this worker holds (:func:`run_checks`), the run is
    handed back first and checked after it (:class:`~idefix_rules.campaign.simulation.
    processes.Continued`): the check's time is not the run's (its timeout), and a check that
    fails or crashes leaves the run as it is (the look checks it again)."""
    from idefix_rules.fmu.runner import ProcessCorrupted

    try:
        runner = _runner(task)
    except UserInputError as failure:
        return InputProblem(tuple(failure.diagnostics))
    started = time.perf_counter()
    try:
        signals = runner.run(parameters=dict(task.parameters), chain=list(task.chain),
                             stop_time=task.stop_time, output_interval=task.output_interval,
                             rover=task.rover)
    except UserInputError as failure:
        problem = InputProblem(tuple(failure.diagnostics))
        if runner.fatal:
            _drop(runner)
            return Retire(problem)
        return problem
    except ProcessCorrupted as failure:  # the previous run's doing: a fresh process runs it
        _drop(runner)
        return Retire(failure=failure, again=True)
    except Exception as failure:
        _drop(runner)
        if runner.fatal:
            return Retire(failure=failure)
        raise
    except BaseException:
        _drop(runner)
        raise
    seconds = time.perf_counter() - started
    try:
        checked = check_outputs(signals, task.samples, len(task.chain))
    except UserInputError as failure:  # the map reads an output that is not the signal
        return InputProblem(tuple(failure.diagnostics))
    result = RunResult({}, seconds, encode_run(checked)) if task.encode \
        else RunResult(checked, seconds)
    check = run_check(task)
    if check is None:
        return result
    return Continued(result, functools.partial(check, checked, task.run))


def _drop(runner: Any) -> None:
    """Close a runner whose run failed (after a Fatal it calls nothing of the FMU), so the
    next run of this process makes a fresh one."""
    _RUNNERS.clear()
    with contextlib.suppress(Exception):
        runner.close()


def check_command_range(command: np.ndarray, commands: int) -> None:
    """C520 at the first sample where ``command`` rounds outside -1 … ``commands`` - 1."""
    rounded = np.rint(command)
    outside = np.isfinite(rounded) & ((rounded < -1) | (rounded > commands - 1))
    if not outside.any():
        return
    first = int(np.argmax(outside))
    raise UserInputError([error(
        "C520", f"the FMU output mapped to 'command' reads {command[first]:g} at sample "
                f"{first}, outside -1 … {commands - 1}: 'command' is the 0-based index of the "
                f"active command of the chain ({commands} command{'s' if commands != 1 else ''})"
                ", -1 before and after it",
        Span("fmu.signals"),
        "a phase or a 1-based counter is not 'command': map it to 'done' with fmu.done_at "
        "(docs/bring-your-own-fmu.md)")])


# The obstacle check a worker inherits when it is forked (local pool), named by a token that
# the tasks of the same campaign carry: a worker forked for another campaign, or started
# without it (spawn, Dask), checks nothing and the evaluation checks the run instead.
_RUN_CHECK: tuple[str, Callable[[Mapping[str, np.ndarray], int], dict[str, Any]]] | None = None


@contextlib.contextmanager
def run_checks(check: Callable[[Mapping[str, np.ndarray], int], dict[str, Any]]
               ) -> Iterator[str]:
    """Within: workers forked now hold ``check`` (signals, run) → collision pieces, and
    simulate the tasks that carry the token this yields with it."""
    global _RUN_CHECK
    token = f"{os.getpid()}-{time.monotonic_ns()}-{id(check)}"
    previous, _RUN_CHECK = _RUN_CHECK, (token, check)
    try:
        yield token
    finally:
        _RUN_CHECK = previous


def run_check(task: RunTask) -> Callable[[Mapping[str, np.ndarray], int], dict[str, Any]] | None:
    """The check this worker holds when ``task`` asks for it (carries its token), else None."""
    if task.check is None or _RUN_CHECK is None or _RUN_CHECK[0] != task.check:
        return None
    return _RUN_CHECK[1]


def check_outputs(signals: Mapping[str, np.ndarray], samples: int,
                  commands: int | None = None) -> dict[str, np.ndarray]:
    """Outputs on the expected grid and finite, as float64 arrays; ValueError otherwise (the
    run fails). ``command`` outside -1 … ``commands`` - 1 is no index of the chain's commands:
    the campaign maps an output that is not the signal (a phase, a 1-based counter), C520."""
    if commands is not None and "command" in signals:
        check_command_range(np.asarray(signals["command"], dtype=np.float64), commands)
    checked = {}
    for name, values in signals.items():
        array = np.asarray(values, dtype=np.float64)
        if array.shape[:1] != (samples,):
            raise ValueError(f"signal {name!r} has {array.shape[0] if array.ndim else 0} "
                             f"samples, expected {samples}")
        if not np.all(np.isfinite(array)):
            first = int(np.flatnonzero((~np.isfinite(array.reshape(samples, -1))).any(axis=1))[0])
            raise ValueError(f"signal {name!r} is not finite from sample {first}")
        if name == "t" and array.ndim == 1 and not np.all(np.diff(array) > 0):
            # a mapped output that is no clock (a phase, a counter): every time read from it
            # would be wrong
            at = int(np.argmax(np.diff(array) <= 0)) + 1
            raise ValueError(f"signal 't' does not increase at sample {at} ({array[at - 1]:g} s, "
                             f"then {array[at]:g} s)")
        stored = storage_dtype(name)
        if stored != np.float64 and np.any(np.abs(array) > np.finfo(stored).max):
            # stored as float32 it would read back as infinite: no finite run is stored so
            raise ValueError(f"signal {name!r} exceeds the range of the {stored} it is "
                             f"stored in (|x| up to {float(np.max(np.abs(array))):g})")
        checked[name] = array
    return checked
