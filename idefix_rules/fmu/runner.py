"""Run an FMI 2.0 or 3.0 co-simulation FMU many times, cheaply: :class:`FmuRunner`.

One runner per process: the FMU is instantiated once; every run resets the instance, applies
start values (with units), and steps it on the caller's time grid, reading the outputs with one
getter call per type (``fmi2GetReal``, ``fmi3GetInt32`` …) per communication step straight
into numpy rows, then converting them to float64 in SI (the FMU's declared unit) by contract
name. Given a ``.fmu`` the runner extracts it itself (and removes the folder on close); given
``unzipped``, a folder the caller extracted once with
:func:`~idefix_rules.fmu.archive.extract_fmu` and owns, many
runners (one per worker process) share it.

A run ends when its chain is complete: once the ``command`` output reads -1 (or, without
``command``, a ``done`` output reaches ``done_at``) at sample T, the FMU is stepped once more, to
sample T + 1, and no further while the rover is at rest (its pose unchanged over that sample; a
rover still sliding is simulated on until it stops or the stop time); the remaining samples hold
the values of that sample, ``t`` going on along its grid
(:func:`~idefix_rules.fmu.run_end.hold_after_end`), so every run
keeps the shape of the caller's grid.
The one step past the end is the sample in which the rover stands with its motors off: sample T
still shows the wheel rates, currents and slip of the chain's last step.

>>> from idefix_rules.commands import Command
>>> runner = FmuRunner(default_fmu_path())                      # doctest: +SKIP
>>> out = runner.run({"soil.cohesion": "300 Pa"}, [Command(0.05, 0.2, 0.0)], 60.0, 0.1)
...                                                               # doctest: +SKIP
>>> out["wheel.slip"].shape                                       # doctest: +SKIP
(601, 4)
"""

from __future__ import annotations

import math
import shutil
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from idefix_rules.commands import Command, RoverGeometry
from idefix_rules.errors import InfrastructureError, Span, UserInputError, error
from idefix_rules.fmu.archive import default_signal_map, extract_fmu
from idefix_rules.fmu.binding import (
    OK_STATUSES,
    FmuInstance,
    OutputGroup,
    ResetFailed,
    corrupted_here,
    corrupts_process,
    mark_corrupted,
)
from idefix_rules.fmu.description import describe_fmu
from idefix_rules.fmu.exchange import simulate_model_exchange
from idefix_rules.fmu.mapping import PARAMETER_REJECTED
from idefix_rules.fmu.outputs import OutputPlan
from idefix_rules.fmu.run_end import hold_after_end
from idefix_rules.fmu.run_inputs import StartValues, input_rows, plan_inputs


class ProcessCorrupted(InfrastructureError):
    """The FMU returned Fatal (or a status FMI leaves undefined) where the run about to start
    is not to blame (the reset of the instance the previous run left): the run has to go to a
    fresh process, and this one runs the FMU no more."""


class FmuRunner:
    """Runs one FMU repeatedly in this process (see the module docstring).

    ``unzipped``: the FMU already extracted by the caller
    (:func:`~idefix_rules.fmu.archive.extract_fmu`), who keeps the
    folder; ``fmu_path`` then only names the FMU in messages. ``chain_delivery`` says how a
    chain reaches the FMU: ``parameters`` (``chain.count`` and the chain arrays, renamed by
    ``parameter_map``), ``inputs`` (the set-points of ``chain_inputs``, FMU input → set-point
    name of :data:`~idefix_rules.fmu.setpoints.SETPOINTS`, fed every communication step) or
    ``none``. A signal mapped to ``done`` is 1 from the sample where the FMU's variable
    reaches ``done_at``.
    """

    def __init__(self, fmu_path: str | Path, signal_map: Mapping[str, str] | None = None,
                 parameter_map: Mapping[str, str] | None = None,
                 extra_outputs: Sequence[str] = (), unzipped: str | Path | None = None,
                 chain_delivery: str = "parameters",
                 chain_inputs: Mapping[str, str] | None = None, done_at: float = 1.0) -> None:
        self.fmu_path = Path(fmu_path)
        if unzipped is None and not self.fmu_path.exists():
            raise UserInputError(error("F101", "FMU file not found", Span(str(self.fmu_path))))
        source = self.fmu_path if unzipped is None else Path(unzipped)
        self.description = describe_fmu(source)
        if self.description.major not in (2, 3):
            raise UserInputError(error("F103", f"FMI {self.description.fmi_version} FMU; the "
                                       "runner supports FMI 2.0 and 3.0",
                                       Span(str(self.fmu_path))))
        if self.description.co_simulation is None and self.description.model_exchange is None:
            raise UserInputError(error(
                "F103", "the FMU has neither a co-simulation nor a model-exchange interface",
                Span(str(self.fmu_path))))
        # Co-simulation when the FMU has it; else model exchange with fmpy's solver.
        self.model_exchange = self.description.co_simulation is None
        self._variables = self.description.variables
        self.signal_map = dict(signal_map) if signal_map is not None else \
            default_signal_map(self.description, source)
        self.parameter_map = dict(parameter_map or {})
        self.chain_delivery = chain_delivery
        self.chain_inputs = dict(chain_inputs or {})
        self.done_at = float(done_at)
        self._plan = OutputPlan(self._variables, self.signal_map, list(extra_outputs),
                                self.fmu_path, self.done_at)
        self._inputs = plan_inputs(self._variables, self.chain_delivery, self.chain_inputs,
                                   self.fmu_path)
        self._start_values = StartValues(self._variables, self.parameter_map,
                                         self.chain_delivery, self.fmu_path)
        # Only a folder the runner extracted itself is removed on close.
        self._owns_unzipdir = unzipped is None
        self._unzipdir = extract_fmu(self.fmu_path) if unzipped is None else Path(unzipped)
        self._log: list[str] = []
        self._instance: FmuInstance | None = None
        self._groups: list[OutputGroup] = []
        if not self.model_exchange:
            try:
                self._instantiate()
            except InfrastructureError:
                self._remove_unzipdir()
                raise
        self._runs = 0
        self._closed = False

    def _instantiate(self) -> FmuInstance:
        """A new instance of the co-simulation FMU, the one runs use from now on."""
        try:
            instance = FmuInstance(self.description, str(self._unzipdir), "idefix")
        except Exception as exc:  # fmpy raises a plain Exception when instantiation fails
            raise InfrastructureError(f"{self.fmu_path.name}: cannot instantiate ({exc})") \
                from None
        self._instance = instance
        self._slave = instance.slave
        self._log = instance.log
        self._do_step = instance.do_step
        self._groups = instance.output_groups([v for v, _ in self._plan.outputs])
        return instance

    def _start(self, instance: FmuInstance, stop_time: float) -> FmuInstance:
        """``instance`` reset (after its first run) and in initialisation mode; the instance
        to use. A reset that fails is what the previous run left, not this run's doing: after
        Error (the instance alone unusable, FMI 2.0.x section 2.1.3) a fresh instance in this
        process takes the run; after Fatal, :class:`ProcessCorrupted` (a fresh process must)."""
        try:
            instance.start(stop_time)
            return instance
        except ResetFailed as failed:
            if corrupts_process(failed.status):
                raise ProcessCorrupted(
                    f"{self.fmu_path.name}: its reset after the previous run of this process "
                    f"failed (status {failed.status}){self._log_detail()}") from None
        instance.close()  # after Error: freed only
        fresh = self._instantiate()
        fresh.start(stop_time)
        return fresh

    # ------------------------------------------------------------------ set-up
    def _initialisation_error(self, exc: Exception) -> Exception:
        """A parameter the FMU rejects is the user's mistake; anything else is not."""
        for message in reversed(self._log):
            match = PARAMETER_REJECTED.match(message)
            if match:
                fmu_name = match["name"]
                user_names = [k for k, v in self.parameter_map.items() if v == fmu_name]
                name = user_names[0] if user_names else fmu_name
                text = message if name == fmu_name else f"{message} (FMU variable of '{name}')"
                return UserInputError(error("F110", text, Span(str(self.fmu_path)),
                                            hint=f"set '{name}' within the allowed range"))
        return InfrastructureError(f"{self.fmu_path.name}: initialisation failed "
                                   f"({exc}){self._log_detail()}")

    def _log_detail(self) -> str:
        return f": {self._log[-1]}" if self._log else "; the FMU logged no reason"

    @property
    def fatal(self) -> bool:
        """Whether the FMU returned Fatal, or a status that leaves its state undefined: no
        function of it may be called again in this process, for any instance (FMI 2.0.x
        section 2.1.3; :mod:`~idefix_rules.fmu.binding`). The runner then calls nothing more
        on close, and a process that ran it must run the FMU no more: a campaign's worker
        ends once it has answered (docs/bring-your-own-fmu.md)."""
        return corrupted_here(self._unzipdir)

    @property
    def unzipped(self) -> Path:
        """The folder the FMU is extracted to (the caller's when given, else the runner's)."""
        return self._unzipdir

    @property
    def variables(self) -> tuple[str, ...]:
        """Names of all variables of the FMU."""
        return tuple(self._variables)

    # ------------------------------------------------------------------ running
    def run(self, parameters: Mapping[str, float | str], chain: Sequence[Command],
            stop_time: float, output_interval: float,
            rover: RoverGeometry | None = None,
            hold_after_chain: bool = True) -> dict[str, np.ndarray]:
        """Simulate one run and return its signals by contract name.

        Samples are at ``k * output_interval`` for ``k = 0 .. round(stop_time /
        output_interval)``; time signals have shape (samples,), wheel signals (samples, 4).
        ``rover``: the geometry the ``inputs`` delivery computes set-points with.
        ``hold_after_chain``: once the chain is complete at sample T (:func:`end_sample`) the
        FMU is stepped to T + 1 and no further, and later samples hold the values of sample
        T + 1 (``t`` keeps its grid); a model-exchange FMU is integrated to the stop time and
        then held the same way. False: every sample is simulated.
        """
        if self._closed:
            raise InfrastructureError("FmuRunner used after close()")
        if self.fatal:
            raise InfrastructureError(
                f"{self.fmu_path.name}: returned Fatal in an earlier run (or failed inside "
                "fmpy's solver, which hides the status), and FMI allows no further call of it "
                "in this process")
        if not (output_interval > 0 and stop_time >= 0 and math.isfinite(stop_time)):
            raise UserInputError(error("F109", "need output_interval > 0 and stop_time >= 0"))
        from fmpy.fmi1 import FMICallException

        steps = round(stop_time / output_interval)
        feed = input_rows(self._inputs, chain, rover or RoverGeometry(), output_interval, steps)
        if self._instance is None:  # model exchange: fmpy's solver, a new instance per run
            self._runs += 1
            try:
                columns = simulate_model_exchange(
                    self._unzipdir, self.fmu_path.name,
                    self._start_values.for_run(parameters, chain), feed,
                    [variable for variable, _ in self._plan.outputs], steps, output_interval)
            except InfrastructureError as problem:
                cause = problem.__cause__  # fmpy's failed call, with its status
                if isinstance(cause, FMICallException):
                    if corrupts_process(cause.status):
                        mark_corrupted(self._unzipdir)
                elif cause is not None:
                    # fmpy's solver calls the FMU from C callbacks (derivatives, states, event
                    # indicators), where a failed call's exception is swallowed and the solver
                    # fails with an error of its own: whether the FMU returned Fatal there
                    # cannot be known, so the process is taken as corrupted (its worker ends)
                    mark_corrupted(self._unzipdir)
                raise
            # fmpy's solver runs to the stop time: the same hold afterwards, so the stored
            # samples mean the same whatever the FMU's interface
            end = self._plan.end_of(columns, chain) if hold_after_chain else None
            held = None if end is None else min(end + 1, steps)
            if held is not None:
                hold_after_end(columns, held)
            return self._plan.collect(columns, steps, output_interval, held)
        buffers = [np.empty((steps + 1, group.count), dtype=group.dtype)
                   for group in self._groups]
        self._log.clear()
        instance = self._instance
        try:
            self._runs += 1
            instance = self._start(instance, steps * output_interval)
            instance.set_values(self._start_values.for_run(parameters, chain))
            if feed:
                instance.set_values([(v, row[0]) for v, row in feed])
            instance.end_initialisation()
        except FMICallException as exc:
            raise self._initialisation_error(exc) from None
        component = instance.component
        # The raw getter calls, unpacked once: this loop runs for every communication step.
        reads = [(group.function, group.refs, group.count, buffer.ctypes.data,
                  buffer.strides[0], (group.count,) if group.fmi3 else ())
                 for group, buffer in zip(self._groups, buffers, strict=True)]
        for get, refs, count, base, _, tail in reads:
            status = get(component, refs, count, base, *tail)
            if status not in OK_STATUSES:
                raise self._read_error(0.0, status)
        do_step = self._do_step
        watch = self._plan.end_watch(self._groups, buffers, chain) if hold_after_chain \
            else None
        rest = self._plan.rest_watch(self._groups, buffers) if watch is not None else None
        ended = watch is not None and watch(0)
        held = None
        for k in range(steps):
            if feed:
                instance.set_values([(v, row[k]) for v, row in feed])
            if do_step is not None:
                status = do_step(component, k * output_interval, output_interval, 1)
                failure = None if status in OK_STATUSES else instance.failure(status)
            else:
                failure = instance.step(k * output_interval, output_interval)
            if failure is not None:
                call = "fmi3DoStep" if instance.fmi3 else "fmi2DoStep"
                raise InfrastructureError(f"{self.fmu_path.name}: {call} failed at t = "
                                          f"{k * output_interval:g} s ({failure})"
                                          f"{self._log_detail()}")
            for get, refs, count, base, row_bytes, tail in reads:
                status = get(component, refs, count, base + (k + 1) * row_bytes, *tail)
                if status not in OK_STATUSES:
                    raise self._read_error((k + 1) * output_interval, status)
            if ended and (rest is None or rest(k + 1)):
                # past the chain's end with the rover at rest: the motors hold, nothing moves
                held = k + 1
                break
            ended = ended or (watch is not None and watch(k + 1))
        if held is not None:
            hold_after_end(buffers, held)
        read: list[np.ndarray] = [np.empty(0)] * len(self._plan.outputs)
        for group, buffer in zip(self._groups, buffers, strict=True):
            for offset, position in enumerate(group.positions):
                read[position] = buffer[:, offset]
        return self._plan.collect(read, steps, output_interval, held)

    def _read_error(self, time: float, status: int) -> InfrastructureError:
        if self._instance is not None:
            self._instance.record(status)
        return InfrastructureError(f"{self.fmu_path.name}: reading the outputs failed at "
                                   f"t = {time:g} s{self._log_detail()}")

    def _remove_unzipdir(self) -> None:
        if self._owns_unzipdir:
            shutil.rmtree(self._unzipdir, ignore_errors=True)

    def close(self) -> None:
        """Free the instance and remove the extracted files (if the runner extracted them)."""
        if self._closed:
            return
        self._closed = True
        try:
            if self._instance is not None:
                self._instance.close()
        finally:
            self._remove_unzipdir()

    def __enter__(self) -> FmuRunner:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
