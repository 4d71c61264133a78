"""Run an FMI 2.0 or 3.0 co-simulation FMU many times, cheaply: :class:`FmuRunner`.

One runner per process: the FMU is instantiated once; every run resets the instance, applies
start values (with units), and steps it on the caller's time grid, reading the outputs with one
getter call per type (``fmi2GetReal``, ``fmi3GetInt32`` …) per communication step straight
into numpy rows, then converting them to float64 in SI (the FMU's declared unit) by contract
name. Given a ``.fmu`` the runner extracts it itself (and removes the folder on close); given
``unzipped``, a folder the caller extracted once with :func:`extract_fmu` and owns, many
runners (one per worker process) share it.

A run ends when its chain is complete: once the ``command`` output reads -1 (or, without
``command``, a ``done`` output reaches ``done_at``) at sample T, the FMU is stepped once more, to
sample T + 1, and no further while the rover is at rest (its pose unchanged over that sample; a
rover still sliding is simulated on until it stops or the stop time); the remaining samples hold
the values of that sample, ``t`` going on along its grid (:func:`hold_after_end`), so every run
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

import json
import math
import re
import shutil
import zipfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from idefix_rules.commands import Command, RoverGeometry
from idefix_rules.errors import InfrastructureError, Span, UserInputError, error
from idefix_rules.fmu.binding import (
    OK_STATUSES,
    FmuInstance,
    OutputGroup,
    ResetFailed,
    corrupted_here,
    corrupts_process,
    mark_corrupted,
)
from idefix_rules.fmu.description import FmuDescription, FmuVariable, describe_fmu
from idefix_rules.fmu.exchange import simulate_model_exchange
from idefix_rules.fmu.setpoints import SETPOINTS, chain_setpoints
from idefix_rules.fmu.terrain import read_terrain
from idefix_rules.signals import AXIS_LABELS, FMU_SIGNALS
from idefix_rules.units import UnitError, parse_quantity, parse_unit

SIGNAL_MAP_FILE = "signal_map.json"
CHAIN_COUNT = "chain.count"
TERRAIN_FILE = "terrain.file"
CHAIN_ARRAYS = ("chain.max_wheel_rate", "chain.delta_position", "chain.delta_heading")
DONE_SIGNAL = "done"
CHAIN_DELIVERIES = ("parameters", "inputs", "none")
_INDEXED = re.compile(r"^(?P<name>[^\[\]]+)\[(?P<index>[A-Za-z0-9_]+)\]$")
# How the rover FMU (and any FMU following its wording) names a parameter it rejects.
PARAMETER_REJECTED = re.compile(r"^parameter (?P<name>[^\s=]+) = (?P<value>\S+) out of range")


def extract_fmu(fmu_path: str | Path, folder: str | Path | None = None) -> Path:
    """Unzip an FMU into ``folder`` (None: a new temporary folder); returns the folder.

    A campaign extracts once and hands the folder to every worker's runner (``unzipped``).
    """
    from fmpy import extract

    path = Path(fmu_path)
    if not path.is_file():
        found = "is not a file" if path.exists() else "not found"
        raise UserInputError(error("F101", f"FMU file {found}", Span(str(path))))
    try:
        return Path(extract(str(path), unzipdir=None if folder is None else str(folder)))
    except Exception as exc:  # fmpy and zipfile raise plain exceptions for unreadable archives
        raise UserInputError(error("F102", f"not a readable FMU: {exc}", Span(str(path)))) \
            from None


def default_signal_map(description: FmuDescription, source: Path) -> dict[str, str]:
    """The map used when a campaign gives none: the FMU's shipped ``signal_map.json``, else
    every variable named like a contract signal."""
    text = None
    try:
        if source.is_dir():
            shipped = source / SIGNAL_MAP_FILE
            text = shipped.read_text(encoding="utf-8") if shipped.is_file() else None
        else:
            with zipfile.ZipFile(source) as archive:
                if SIGNAL_MAP_FILE in archive.namelist():
                    text = archive.read(SIGNAL_MAP_FILE).decode("utf-8")
        shipped_map = None if text is None else json.loads(text)
    except (OSError, UnicodeDecodeError, ValueError, zipfile.BadZipFile) as failure:
        raise UserInputError(error("F102", f"not a readable FMU: its {SIGNAL_MAP_FILE} cannot "
                                   f"be read ({failure})", Span(str(source)))) from None
    if shipped_map is None:
        return {name: name for name in FMU_SIGNALS
                if name in description.variables and name != DONE_SIGNAL}
    if not (isinstance(shipped_map, dict) and all(
            isinstance(key, str) and isinstance(value, str)
            for key, value in shipped_map.items())):
        raise UserInputError(error(
            "F102", f"not a readable FMU: its {SIGNAL_MAP_FILE} must be a JSON object of FMU "
                    "variable names to signal names (strings), e.g. {\"px\": \"x\"}",
            Span(str(source))))
    return dict(shipped_map)


def contract_column(contract: str, span: Span) -> tuple[str, int | None]:
    """The signal and wheel column a map target names (``wheel.rate[FL]`` → wheel.rate, 0)."""
    match = _INDEXED.match(contract)
    base, column = (match["name"], match["index"]) if match else (contract, None)
    spec = FMU_SIGNALS.get(base)
    if spec is None:
        raise UserInputError(error("F105", f"'{contract}' is not an fmu signal of the "
                                   "contract", span))
    if "wheel" not in spec.axes:
        return base, None
    labels = AXIS_LABELS["wheel"]
    if column is None or (column not in labels and not column.isdigit()):
        raise UserInputError(error("F105", f"'{contract}' needs a wheel, e.g. {base}[FL]", span))
    return base, labels.index(column) if column in labels else int(column)


def si_scale(variable: FmuVariable, what: str, unit: str, span: Span) -> float:
    """Factor from the variable's declared unit to ``unit``, the SI unit of ``what`` (a signal
    or set-point): 1 without a declared unit; F403 when the dimensions differ."""
    if variable.si is None:
        return 1.0
    if variable.si.dimension != parse_unit(unit).dimension:
        raise UserInputError(error(
            "F403", f"'{variable.name}' is in {variable.unit}, but {what} is in {unit}", span))
    return variable.si.scale


# A rover is at rest when its pose moved by at most this (m, rad) over a sample: far below
# the creep the contact laws' regularisation allows (10 µm/s, 1 µm per 0.1 s sample).
REST_SIGNALS = ("x", "y", "yaw")
REST_MOTION = 1e-9


def _moved(before: float, after: float) -> bool:
    """Whether a pose coordinate moved over a sample. A non-finite one did not: the run is
    failed by its non-finite output (campaign.worker), simulating on would show nothing more."""
    return math.isfinite(before) and math.isfinite(after) and abs(after - before) > REST_MOTION


def end_sample(command: np.ndarray | None, done: np.ndarray | None,
               done_at: float = 1.0) -> int | None:
    """The first sample where the chain is complete, or None (not within the run).

    Complete: ``command`` (the raw output, index of the active command) rounds to -1; without
    ``command``, the raw ``done`` output is at least ``done_at`` (the evaluator reads a run's
    time the same way, docs/derived-signals.md).

    >>> end_sample(np.array([0.0, 1.0, -1.0, -1.0]), None)
    2
    >>> end_sample(None, np.array([0, 1, 2]), done_at=2)
    2
    >>> end_sample(np.array([0.0, 0.0]), None) is None
    True
    """
    if command is not None:
        ended = np.rint(np.asarray(command, dtype=np.float64)) == -1
    elif done is not None:
        ended = np.asarray(done, dtype=np.float64) >= done_at
    else:
        return None
    return int(np.argmax(ended)) if ended.any() else None


def hold_after_end(columns: Sequence[np.ndarray], held: int) -> None:
    """Hold every column's value of sample ``held`` in all later samples, in place."""
    for column in columns:
        column[held + 1:] = column[held]


class ProcessCorrupted(InfrastructureError):
    """The FMU returned Fatal (or a status FMI leaves undefined) where the run about to start
    is not to blame (the reset of the instance the previous run left): the run has to go to a
    fresh process, and this one runs the FMU no more."""


@dataclass(frozen=True)
class _Slot:
    """Where an output goes: signal, wheel column (None: a time signal), SI factor, done."""

    signal: str
    index: int | None
    scale: float
    done: bool


class FmuRunner:
    """Runs one FMU repeatedly in this process (see the module docstring).

    ``unzipped``: the FMU already extracted by the caller (:func:`extract_fmu`), who keeps the
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
        self._plan_outputs(list(extra_outputs))
        self._plan_inputs()
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
        self._checked_terrain: tuple[str, int, int] | None = None

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
        self._groups = instance.output_groups([v for v, _ in self._outputs])
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

    def _missing(self, name: str, role: str) -> UserInputError:
        return UserInputError(error(
            "F104", f"{role} variable '{name}' does not exist in the FMU",
            Span(str(self.fmu_path)), hint="check the signal/parameter map against "
            "`fmpy info` of the FMU"))

    def _plan_outputs(self, extra: list[str]) -> None:
        """Variable, destination (signal, column), SI scale and kind of every mapped output."""
        outputs: list[tuple[FmuVariable, _Slot]] = []
        for fmu_name, contract in self.signal_map.items():
            variable = self._variables.get(fmu_name)
            if variable is None:
                raise self._missing(fmu_name, "mapped")
            base, index = contract_column(contract, Span(str(self.fmu_path)))
            if variable.reader not in ("real", "integer", "boolean"):
                raise UserInputError(error(
                    "F401", f"'{fmu_name}' is a {variable.type}; a signal needs a Real, Integer, "
                    "Boolean or Enumeration output", Span(str(self.fmu_path))))
            scale = 1.0 if base == DONE_SIGNAL else si_scale(
                variable, f"signal '{base}'", FMU_SIGNALS[base].unit, Span(str(self.fmu_path)))
            outputs.append((variable, _Slot(base, index, scale, base == DONE_SIGNAL)))
        for name in extra:
            variable = self._variables.get(name)
            if variable is None:
                raise self._missing(name, "requested")
            outputs.append((variable, _Slot(name, None, 1.0, False)))
        self._outputs = outputs
        # The output that says the chain is complete: 'command' when mapped, else 'done'
        # (the evaluator's order), as (slot position, is 'done').
        ends = [(position, slot.done) for position, (_, slot) in enumerate(outputs)
                if slot.done or (slot.signal == "command" and slot.index is None)]
        ends.sort(key=lambda end: end[1])
        self._end_output: tuple[int, bool] | None = ends[0] if ends else None

    def _plan_inputs(self) -> None:
        """The FMU inputs fed with set-points each communication step (delivery ``inputs``)."""
        self._inputs: list[tuple[FmuVariable, str, float]] = []
        if self.chain_delivery != "inputs":
            return
        for fmu_name, setpoint in self.chain_inputs.items():
            variable = self._variables.get(fmu_name)
            if variable is None:
                raise self._missing(fmu_name, "chain input")
            if setpoint not in SETPOINTS:
                raise UserInputError(error(
                    "F402", f"'{setpoint}' is not a set-point; one of "
                    f"{', '.join(SETPOINTS)}", Span(str(self.fmu_path))))
            scale = si_scale(variable, f"set-point '{setpoint}'", SETPOINTS[setpoint],
                             Span(str(self.fmu_path)))
            self._inputs.append((variable, setpoint, scale))

    def _fmu_name(self, name: str) -> str:
        return self.parameter_map.get(name, name)

    def _value_in_fmu_unit(self, name: str, variable: FmuVariable, value: float | str) -> float:
        unit, target = variable.unit, variable.si
        if isinstance(value, str):
            try:
                quantity = parse_quantity(value)
            except UnitError as exc:
                raise UserInputError(error("F106", f"parameter '{name}': {exc}")) from None
            if target is None:
                if quantity.dimension != parse_unit("1").dimension:
                    raise UserInputError(error("F106", f"parameter '{name}' has no unit the tool "
                                               f"knows ({unit!r}); give a plain number"))
                return float(quantity.value)
            if quantity.dimension != target.dimension:
                raise UserInputError(error("F107", f"parameter '{name}' expects {unit}, "
                                           f"got {value!r}"))
            return float(target.from_si(quantity.value))
        # plain numbers are SI (the project's convention inside), converted to the FMU's unit;
        # NaN and infinities pass unconverted for the FMU's range check to name them
        if not math.isfinite(float(value)):
            return float(value)
        return float(target.from_si(float(value))) if target is not None else float(value)

    def _check_terrain(self, path: str) -> None:
        """A bad terrain file is a user error with file and line, not an FMU failure."""
        try:
            stat = Path(path).stat()
        except OSError:
            raise UserInputError(error("F203", "terrain file not found", Span(path))) from None
        key = (path, stat.st_mtime_ns, stat.st_size)
        if key != self._checked_terrain:
            read_terrain(path)
            self._checked_terrain = key

    def _start_values(self, parameters: Mapping[str, float | str], chain: Sequence[Command]
                      ) -> list[tuple[FmuVariable, float | int | str]]:
        values: list[tuple[FmuVariable, float | int | str]] = []
        for name, value in parameters.items():
            fmu_name = self._fmu_name(name)
            variable = self._variables.get(fmu_name)
            if variable is None:
                raise self._missing(fmu_name, "parameter")
            if variable.reader == "string":
                if fmu_name == TERRAIN_FILE and value:
                    self._check_terrain(str(value))
                values.append((variable, str(value)))
            elif variable.reader == "integer":
                values.append((variable, int(value)))
            elif variable.reader == "boolean":
                raise UserInputError(error("F108", f"Boolean parameter '{name}' not supported"))
            else:
                values.append((variable, self._value_in_fmu_unit(name, variable, value)))
        if chain and self.chain_delivery == "parameters":
            count = self._variables.get(self._fmu_name(CHAIN_COUNT))
            if count is None:
                raise self._missing(self._fmu_name(CHAIN_COUNT), "chain")
            values.append((count, len(chain)))
            for array, field in zip(CHAIN_ARRAYS, ("max_wheel_rate", "delta_position",
                                                   "delta_heading"), strict=True):
                for i, command in enumerate(chain):
                    name = self._fmu_name(f"{array}[{i}]")
                    variable = self._variables.get(name)
                    if variable is None:
                        raise self._missing(name, "chain")
                    values.append((variable, self._value_in_fmu_unit(
                        name, variable, float(getattr(command, field)))))
        return values

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
        feed = self._input_rows(chain, rover or RoverGeometry(), output_interval, steps)
        if self._instance is None:  # model exchange: fmpy's solver, a new instance per run
            self._runs += 1
            try:
                columns = simulate_model_exchange(
                    self._unzipdir, self.fmu_path.name, self._start_values(parameters, chain),
                    feed, [variable for variable, _ in self._outputs], steps, output_interval)
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
            end = self._end_of(columns) if hold_after_chain else None
            held = None if end is None else min(end + 1, steps)
            if held is not None:
                hold_after_end(columns, held)
            return self._collect(columns, steps, output_interval, held)
        buffers = [np.empty((steps + 1, group.count), dtype=group.dtype)
                   for group in self._groups]
        self._log.clear()
        instance = self._instance
        try:
            self._runs += 1
            instance = self._start(instance, steps * output_interval)
            instance.set_values(self._start_values(parameters, chain))
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
        watch = self._end_watch(buffers) if hold_after_chain else None
        rest = self._rest_watch(buffers) if watch is not None else None
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
        read: list[np.ndarray] = [np.empty(0)] * len(self._outputs)
        for group, buffer in zip(self._groups, buffers, strict=True):
            for offset, position in enumerate(group.positions):
                read[position] = buffer[:, offset]
        return self._collect(read, steps, output_interval, held)

    def _end_watch(self, buffers: list[np.ndarray]) -> Callable[[int], bool] | None:
        """Whether sample k of a co-simulation run says the chain is complete (None: the FMU
        maps no output that says so)."""
        if self._end_output is None:
            return None
        position, is_done = self._end_output
        for group, buffer in zip(self._groups, buffers, strict=True):
            if position in group.positions:
                column = buffer[:, group.positions.index(position)]
                break
        else:  # pragma: no cover - every output belongs to a group
            return None
        item = column.item
        if is_done:
            done_at = self.done_at
            return lambda k: bool(item(k) >= done_at)
        return lambda k: round(float(item(k))) == -1

    def _pose_columns(self) -> list[int]:
        """Slot positions of the pose outputs (x, y, yaw) this runner reads."""
        return [position for position, (_, slot) in enumerate(self._outputs)
                if slot.signal in REST_SIGNALS and slot.index is None]

    def _rest_watch(self, buffers: list[np.ndarray]) -> Callable[[int], bool] | None:
        """Whether the rover is at rest at sample k: its pose (x, y, yaw) moved by at most
        REST_MOTION since sample k - 1 (None: the FMU maps no pose output). After its chain a
        rover may still slide (no balance on a slope its wheels cannot hold): the run goes on
        until it is at rest, so a hold never freezes a moving rover."""
        columns = []
        for position in self._pose_columns():
            for group, buffer in zip(self._groups, buffers, strict=True):
                if position in group.positions:
                    columns.append(buffer[:, group.positions.index(position)])
        if not columns:
            return None
        return lambda k: k > 0 and not any(_moved(float(column.item(k - 1)),
                                                  float(column.item(k))) for column in columns)

    def _end_of(self, columns: list[np.ndarray]) -> int | None:
        """The first sample of read columns (slot order) where the chain is complete."""
        if self._end_output is None:
            return None
        position, is_done = self._end_output
        column = columns[position]
        end = end_sample(None, column, self.done_at) if is_done else end_sample(column, None)
        poses = [columns[position] for position in self._pose_columns()]
        while end is not None and poses and end + 1 < len(column) and any(
                _moved(float(pose[end]), float(pose[end + 1])) for pose in poses):
            end += 1  # still moving after the chain: hold only once at rest
        return end

    def _read_error(self, time: float, status: int) -> InfrastructureError:
        if self._instance is not None:
            self._instance.record(status)
        return InfrastructureError(f"{self.fmu_path.name}: reading the outputs failed at "
                                   f"t = {time:g} s{self._log_detail()}")

    def _input_rows(self, chain: Sequence[Command], rover: RoverGeometry, interval: float,
                    steps: int) -> list[tuple[FmuVariable, np.ndarray]]:
        """Per chain input its value for every step (and the initial value), FMU units."""
        if not self._inputs:
            return []
        values = chain_setpoints(chain, rover, interval, max(steps, 1))
        rows = []
        for variable, setpoint, scale in self._inputs:
            series = values[setpoint] / scale if scale != 1.0 else values[setpoint]
            rows.append((variable, series))
        return rows

    def _collect(self, columns: list[np.ndarray], steps: int, interval: float,
                 held: int | None = None) -> dict[str, np.ndarray]:
        """Signals by contract name from the outputs' columns (slot order), SI, float64;
        ``held``: the sample the columns hold after (``t`` then goes on along the grid)."""
        signals: dict[str, np.ndarray] = {}
        wheels: dict[str, np.ndarray] = {}
        for (_, slot), column in zip(self._outputs, columns, strict=True):
            values = column.astype(np.float64)  # always a copy, whatever the type read
            if slot.done:
                values = (values >= self.done_at).astype(np.float64)
            elif slot.scale != 1.0:
                values *= slot.scale
            if slot.index is None:
                signals[slot.signal] = values
            else:
                array = wheels.setdefault(slot.signal, np.full(
                    (steps + 1, len(AXIS_LABELS["wheel"])), np.nan))
                array[:, slot.index] = values
        signals.update(wheels)
        if "t" not in signals:
            signals["t"] = np.arange(steps + 1) * interval
        elif held is not None:
            # the time an FMU reports after each further step: communication point + step
            signals["t"][held + 1:] = np.arange(held, steps) * interval + interval
        return signals

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
