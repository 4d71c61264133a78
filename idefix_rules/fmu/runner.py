"""Run an FMI 2.0 co-simulation FMU many times, cheaply: :class:`FmuRunner`.

One runner per process: the FMU is instantiated once; every run resets the instance, applies
start values (with units), and steps it on the caller's time grid, reading all outputs with one
``fmi2GetReal`` per communication step straight into a numpy array. Given a ``.fmu`` the runner
extracts it itself (and removes the folder on close); given ``unzipped``, a folder the caller
extracted once with :func:`extract_fmu` and owns, many runners (one per worker process) share
it.

>>> from idefix_rules.commands import Command
>>> runner = FmuRunner(default_fmu_path())                      # doctest: +SKIP
>>> out = runner.run({"soil.cohesion": "300 Pa"}, [Command(0.05, 0.2, 0.0)], 60.0, 0.1)
...                                                               # doctest: +SKIP
>>> out["wheel.slip"].shape                                       # doctest: +SKIP
(601, 4)
"""

from __future__ import annotations

import ctypes
import json
import math
import re
import shutil
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from idefix_rules.commands import Command
from idefix_rules.errors import InfrastructureError, Span, UserInputError, error
from idefix_rules.fmu.terrain import read_terrain
from idefix_rules.signals import AXIS_LABELS, FMU_SIGNALS
from idefix_rules.units import UnitError, parse_quantity, parse_unit

SIGNAL_MAP_FILE = "signal_map.json"
CHAIN_COUNT = "chain.count"
TERRAIN_FILE = "terrain.file"
CHAIN_ARRAYS = ("chain.max_wheel_rate", "chain.delta_position", "chain.delta_heading")
_INDEXED = re.compile(r"^(?P<name>[^\[\]]+)\[(?P<index>[A-Za-z0-9_]+)\]$")
_OK_STATUSES = (0, 1)  # fmi2OK, fmi2Warning
# How the rover FMU (and any FMU following its wording) names a parameter it rejects.
_PARAMETER_REJECTED = re.compile(r"^parameter (?P<name>[^\s=]+) = (?P<value>\S+) out of range")


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


class FmuRunner:
    """Runs one FMU repeatedly in this process (see the module docstring).

    ``unzipped``: the FMU already extracted by the caller (:func:`extract_fmu`), who keeps the
    folder; ``fmu_path`` then only names the FMU in messages.
    """

    def __init__(self, fmu_path: str | Path, signal_map: Mapping[str, str] | None = None,
                 parameter_map: Mapping[str, str] | None = None,
                 extra_outputs: Sequence[str] = (), unzipped: str | Path | None = None) -> None:
        from fmpy import read_model_description
        from fmpy.fmi2 import FMU2Slave

        self.fmu_path = Path(fmu_path)
        if unzipped is None and not self.fmu_path.exists():
            raise UserInputError(error("F101", "FMU file not found", Span(str(self.fmu_path))))
        source = self.fmu_path if unzipped is None else Path(unzipped)
        try:
            description = read_model_description(str(source), validate=False)
        except Exception as exc:  # fmpy raises plain exceptions for unreadable archives
            raise UserInputError(error("F102", f"not a readable FMU: {exc}",
                                       Span(str(source)))) from None
        if description.fmiVersion != "2.0":
            raise UserInputError(error("F103", f"FMI {description.fmiVersion} FMU; the runner "
                                       "supports FMI 2.0 co-simulation", Span(str(self.fmu_path))))
        if description.coSimulation is None:
            raise UserInputError(error("F103", "the FMU has no co-simulation interface",
                                       Span(str(self.fmu_path))))
        # Only a folder the runner extracted itself is removed on close.
        self._owns_unzipdir = unzipped is None
        self._unzipdir = extract_fmu(self.fmu_path) if unzipped is None else Path(unzipped)
        self._variables = {v.name: v for v in description.modelVariables}
        self._units = {u.name for u in description.unitDefinitions}
        if signal_map is None:
            signal_map = self._default_signal_map()
        self.signal_map = dict(signal_map)
        self.parameter_map = dict(parameter_map or {})
        self._plan_outputs(list(extra_outputs))
        self._slave = FMU2Slave(guid=description.guid, unzipDirectory=str(self._unzipdir),
                                modelIdentifier=description.coSimulation.modelIdentifier,
                                instanceName="idefix")
        self._log: list[str] = []
        try:
            self._slave.instantiate(callbacks=self._callbacks())
        except Exception as exc:  # fmpy raises a plain Exception when instantiation fails
            self._remove_unzipdir()
            raise InfrastructureError(f"{self.fmu_path.name}: cannot instantiate ({exc})") \
                from None
        dll = self._slave.dll
        self._do_step = dll.fmi2DoStep
        self._do_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
        self._do_step.restype = ctypes.c_int
        self._get_real = dll.fmi2GetReal
        self._get_real.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t,
                                   ctypes.c_void_p]
        self._get_real.restype = ctypes.c_int
        self._runs = 0
        self._closed = False
        self._checked_terrain: tuple[str, int, int] | None = None

    # ------------------------------------------------------------------ set-up
    def _callbacks(self) -> Any:
        """FMI callbacks whose logger keeps the FMU's messages (to explain a failed call).

        The logger reads the format string as the message (the rover FMU passes its text as the
        format); fmpy's variadic logger proxy is process-wide, so it is not used here.
        """
        from fmpy.fmi2 import (
            calloc,
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
            free,
        )
        def logger(component: Any, instance: bytes, status: int, category: bytes,
                   message: bytes) -> None:
            self._log.append(message.decode("utf-8", "replace"))
            del self._log[:-20]

        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(logger)
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        return callbacks

    def _initialisation_error(self, exc: Exception) -> Exception:
        """A parameter the FMU rejects is the user's mistake; anything else is not."""
        for message in reversed(self._log):
            match = _PARAMETER_REJECTED.match(message)
            if match:
                fmu_name = match["name"]
                user_names = [k for k, v in self.parameter_map.items() if v == fmu_name]
                name = user_names[0] if user_names else fmu_name
                text = message if name == fmu_name else f"{message} (FMU variable of '{name}')"
                return UserInputError(error("F110", text, Span(str(self.fmu_path)),
                                            hint=f"set '{name}' within the allowed range"))
        detail = f": {self._log[-1]}" if self._log else "; see the FMU's log for the reason"
        return InfrastructureError(f"{self.fmu_path.name}: initialisation failed ({exc}){detail}")

    @property
    def unzipped(self) -> Path:
        """The folder the FMU is extracted to (the caller's when given, else the runner's)."""
        return self._unzipdir

    @property
    def variables(self) -> tuple[str, ...]:
        """Names of all variables of the FMU."""
        return tuple(self._variables)

    def _default_signal_map(self) -> dict[str, str]:
        shipped = self._unzipdir / SIGNAL_MAP_FILE
        if shipped.is_file():
            return dict(json.loads(shipped.read_text(encoding="utf-8")))
        return {name: name for name in FMU_SIGNALS if name in self._variables}

    def _missing(self, name: str, role: str) -> UserInputError:
        return UserInputError(error(
            "F104", f"{role} variable '{name}' does not exist in the FMU",
            Span(str(self.fmu_path)), hint="check the signal/parameter map against "
            "`fmpy info` of the FMU"))

    def _plan_outputs(self, extra: list[str]) -> None:
        """Value references and destination (signal, column) of every mapped output."""
        refs: list[int] = []
        slots: list[tuple[str, int | None]] = []
        for fmu_name, contract in self.signal_map.items():
            variable = self._variables.get(fmu_name)
            if variable is None:
                raise self._missing(fmu_name, "mapped")
            match = _INDEXED.match(contract)
            base, column = (match["name"], match["index"]) if match else (contract, None)
            spec = FMU_SIGNALS.get(base)
            if spec is None:
                raise UserInputError(error("F105", f"'{contract}' is not an fmu signal of the "
                                           "contract", Span(str(self.fmu_path))))
            index = None
            if "wheel" in spec.axes:
                labels = AXIS_LABELS["wheel"]
                if column is None or (column not in labels and not column.isdigit()):
                    raise UserInputError(error("F105", f"'{contract}' needs a wheel, e.g. "
                                               f"{base}[FL]", Span(str(self.fmu_path))))
                index = labels.index(column) if column in labels else int(column)
            refs.append(variable.valueReference)
            slots.append((base, index))
        for name in extra:
            variable = self._variables.get(name)
            if variable is None:
                raise self._missing(name, "requested")
            refs.append(variable.valueReference)
            slots.append((name, None))
        self._output_refs = (ctypes.c_uint * len(refs))(*refs)
        self._slots = slots
        self._wheel_columns: dict[str, list[tuple[int, int]]] = {}
        self._scalar_columns: dict[str, int] = {}
        for position, (name, index) in enumerate(slots):
            if index is None:
                self._scalar_columns[name] = position
            else:
                self._wheel_columns.setdefault(name, []).append((index, position))

    def _fmu_name(self, name: str) -> str:
        return self.parameter_map.get(name, name)

    def _value_in_fmu_unit(self, name: str, variable: Any, value: float | str) -> float:
        unit = variable.declaredType.unit if variable.unit is None and variable.declaredType \
            else variable.unit
        target = None
        if unit:
            try:
                target = parse_unit(unit.replace(".", "*"))
            except UnitError:
                target = None
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

    def _apply(self, parameters: Mapping[str, float | str], chain: Sequence[Command]) -> None:
        reals: dict[int, float] = {}
        integers: dict[int, int] = {}
        strings: dict[int, str] = {}
        for name, value in parameters.items():
            fmu_name = self._fmu_name(name)
            variable = self._variables.get(fmu_name)
            if variable is None:
                raise self._missing(fmu_name, "parameter")
            if variable.type == "String":
                if fmu_name == TERRAIN_FILE and value:
                    self._check_terrain(str(value))
                strings[variable.valueReference] = str(value)
            elif variable.type in ("Integer", "Enumeration"):
                integers[variable.valueReference] = int(value)
            elif variable.type == "Boolean":
                raise UserInputError(error("F108", f"Boolean parameter '{name}' not supported"))
            else:
                reals[variable.valueReference] = self._value_in_fmu_unit(name, variable, value)
        if chain:
            count = self._variables.get(self._fmu_name(CHAIN_COUNT))
            if count is None:
                raise self._missing(self._fmu_name(CHAIN_COUNT), "chain")
            integers[count.valueReference] = len(chain)
            for array, field in zip(CHAIN_ARRAYS, ("max_wheel_rate", "delta_position",
                                                   "delta_heading"), strict=True):
                for i, command in enumerate(chain):
                    name = self._fmu_name(f"{array}[{i}]")
                    variable = self._variables.get(name)
                    if variable is None:
                        raise self._missing(name, "chain")
                    reals[variable.valueReference] = self._value_in_fmu_unit(
                        name, variable, float(getattr(command, field)))
        slave = self._slave
        if reals:
            slave.setReal(list(reals), list(reals.values()))
        if integers:
            slave.setInteger(list(integers), list(integers.values()))
        if strings:
            slave.setString(list(strings), list(strings.values()))

    # ------------------------------------------------------------------ running
    def run(self, parameters: Mapping[str, float | str], chain: Sequence[Command],
            stop_time: float, output_interval: float) -> dict[str, np.ndarray]:
        """Simulate one run and return its signals by contract name.

        Samples are at ``k * output_interval`` for ``k = 0 .. round(stop_time /
        output_interval)``; time signals have shape (samples,), wheel signals (samples, 4).
        """
        if self._closed:
            raise InfrastructureError("FmuRunner used after close()")
        if not (output_interval > 0 and stop_time >= 0 and math.isfinite(stop_time)):
            raise UserInputError(error("F109", "need output_interval > 0 and stop_time >= 0"))
        from fmpy.fmi1 import FMICallException

        slave = self._slave
        steps = round(stop_time / output_interval)
        out = np.empty((steps + 1, len(self._slots)), dtype=np.float64)
        self._log.clear()
        try:
            if self._runs:
                slave.reset()
            self._runs += 1
            slave.setupExperiment(startTime=0.0, stopTime=steps * output_interval)
            slave.enterInitializationMode()
            self._apply(parameters, chain)
            slave.exitInitializationMode()
        except FMICallException as exc:
            raise self._initialisation_error(exc) from None
        component = slave.component
        refs, n = self._output_refs, len(self._slots)
        row_bytes = out.strides[0]
        base = out.ctypes.data
        if self._get_real(component, refs, n, base) not in _OK_STATUSES:
            raise InfrastructureError(f"{self.fmu_path.name}: fmi2GetReal failed")
        do_step, get_real = self._do_step, self._get_real
        for k in range(steps):
            status = do_step(component, k * output_interval, output_interval, 1)
            if status not in _OK_STATUSES:
                raise InfrastructureError(f"{self.fmu_path.name}: fmi2DoStep failed at "
                                          f"t = {k * output_interval:g} s (status {status})")
            get_real(component, refs, n, base + (k + 1) * row_bytes)
        return self._collect(out, steps, output_interval)

    def _collect(self, out: np.ndarray, steps: int, interval: float) -> dict[str, np.ndarray]:
        signals: dict[str, np.ndarray] = {}
        for name, position in self._scalar_columns.items():
            signals[name] = out[:, position].copy()
        for name, columns in self._wheel_columns.items():
            array = np.full((out.shape[0], len(AXIS_LABELS["wheel"])), np.nan)
            for index, position in columns:
                array[:, index] = out[:, position]
            signals[name] = array
        if "t" not in signals:
            signals["t"] = np.arange(steps + 1) * interval
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
            self._slave.terminate()
            self._slave.freeInstance()
        finally:
            self._remove_unzipdir()

    def __enter__(self) -> FmuRunner:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
