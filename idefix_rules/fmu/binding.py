"""One FMU instance behind a small interface for FMI 2.0 and FMI 3.0 co-simulation.

:class:`FmuInstance` hides the differences the runner meets: how an instance is made and
initialised, which setter takes a variable of a given type, and which getter (with which C
type) reads it. Outputs are read by raw ``fmi2Get*``/``fmi3Get*`` calls straight into numpy
rows (one call per getter family and communication step); everything else goes through fmpy.
The FMU's log messages are kept (the last 20) to explain a failed call, and what a failed call
left the instance in decides how it is closed (:meth:`FmuInstance.record`).
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from idefix_rules.fmu.description import FmuDescription, FmuVariable

OK_STATUSES = (0, 1)  # OK, Warning (FMI 2.0 and 3.0 alike)
DISCARD, ERROR = 2, 3
# What a failed call leaves behind, FMI 2.0.x section 2.1.3 "Status Returned by Functions" (FMI
# 3.0, "Status Returned by Functions and Logging Mechanism", says the same of fmi3Error and
# fmi3Fatal):
# - Discard: the instance goes on; a failed step's instance is terminated and freed as usual.
# - Error: "The simulation cannot be continued with this FMU instance … fmi2FreeInstance or
#   fmi2Reset must be called afterwards … especially other FMU instances are not affected": the
#   instance is freed without fmi2Terminate, and a fresh instance in the same process is sound.
# - Fatal: "the model computations are irreparably corrupted for all FMU instances … It is not
#   possible to call any other function for any of the FMU instances": nothing of the FMU is
#   called again, not even fmi2FreeInstance or the unloading of its library (whose destructors
#   are its code too), and no instance of it may be made in this process again.
# A status FMI does not define there (Pending from a step not asked to run asynchronously, a
# number outside the enumeration) leaves the state undefined: it is taken as Fatal.


def corrupts_process(status: int) -> bool:
    """Whether a failed call's status forbids every later call of the FMU in this process.

    >>> corrupts_process(3), corrupts_process(4), corrupts_process(5)
    (False, True, True)
    """
    return status not in (*OK_STATUSES, DISCARD, ERROR)


# The extracted FMUs (folders) whose library returned Fatal in this process: loading the same
# file again gives the same corrupted library, so none of them is called here again.
_CORRUPTED: set[str] = set()


def corrupted_here(unzipped: str | Path) -> bool:
    """Whether the FMU extracted to ``unzipped`` returned Fatal in this process."""
    return str(unzipped) in _CORRUPTED


def mark_corrupted(unzipped: str | Path) -> None:
    """Remember that the FMU extracted to ``unzipped`` returned Fatal in this process."""
    _CORRUPTED.add(str(unzipped))

# FMI 3.0 type → (getter/setter suffix, C type, numpy type).
_FMI3_TYPES: dict[str, tuple[str, Any, Any]] = {
    "Float64": ("Float64", ctypes.c_double, np.float64),
    "Float32": ("Float32", ctypes.c_float, np.float32),
    "Int8": ("Int8", ctypes.c_int8, np.int8), "UInt8": ("UInt8", ctypes.c_uint8, np.uint8),
    "Int16": ("Int16", ctypes.c_int16, np.int16),
    "UInt16": ("UInt16", ctypes.c_uint16, np.uint16),
    "Int32": ("Int32", ctypes.c_int32, np.int32),
    "UInt32": ("UInt32", ctypes.c_uint32, np.uint32),
    "Int64": ("Int64", ctypes.c_int64, np.int64),
    "UInt64": ("UInt64", ctypes.c_uint64, np.uint64),
    "Enumeration": ("Int64", ctypes.c_int64, np.int64),
    "Boolean": ("Boolean", ctypes.c_bool, np.bool_),
    "String": ("String", None, None),
}
# FMI 2.0 type → (getter/setter suffix, C type, numpy type); fmi2Boolean is an int.
_FMI2_TYPES: dict[str, tuple[str, Any, Any]] = {
    "Real": ("Real", ctypes.c_double, np.float64),
    "Integer": ("Integer", ctypes.c_int, np.intc),
    "Enumeration": ("Integer", ctypes.c_int, np.intc),
    "Boolean": ("Boolean", ctypes.c_int, np.intc),
    "String": ("String", None, None),
}


@dataclass
class OutputGroup:
    """Outputs read by one getter: its C function, value references and row buffer type."""

    function: Any
    refs: Any  # ctypes array of value references
    count: int
    dtype: Any
    positions: list[int]  # columns of these outputs in the runner's slot order
    fmi3: bool  # FMI 3.0 getters take the number of values as a fifth argument


class InstantiationFailed(Exception):
    """The FMU refused to be instantiated; the message carries its last log line."""


class ResetFailed(Exception):
    """The reset of a reused instance failed: what the previous run left, not the next run's
    doing (``status``: the reset's)."""

    def __init__(self, status: int) -> None:
        super().__init__(f"status {status}")
        self.status = status


class FmuInstance:
    """An instantiated co-simulation FMU (FMI 2.0 or 3.0), reset between runs."""

    def __init__(self, description: FmuDescription, unzipped: str, instance_name: str) -> None:
        if corrupted_here(unzipped):
            raise InstantiationFailed("it returned Fatal in this process before, and FMI allows "
                                      "no further call of it here")
        self.unzipped = unzipped
        self.fmi3 = description.major == 3
        self.types = _FMI3_TYPES if self.fmi3 else _FMI2_TYPES
        self.log: list[str] = []
        identifier = description.co_simulation
        if self.fmi3:
            from fmpy.fmi3 import FMU3Slave

            self.slave: Any = FMU3Slave(guid=description.token, unzipDirectory=unzipped,
                                        modelIdentifier=identifier, instanceName=instance_name)
            instantiate = functools.partial(self.slave.instantiate, loggingOn=True,
                                            logMessage=self._fmi3_logger)
        else:
            from fmpy.fmi2 import FMU2Slave

            self.slave = FMU2Slave(guid=description.token, unzipDirectory=unzipped,
                                   modelIdentifier=identifier, instanceName=instance_name)
            instantiate = functools.partial(self.slave.instantiate, loggingOn=True,
                                            callbacks=self._fmi2_callbacks())
        try:
            instantiate()
        except Exception as failure:  # fmpy's plain Exception: the FMU's own reason is logged
            logged = f"; the FMU logged: {self.log[-1]}" if self.log else ""
            raise InstantiationFailed(f"{failure}{logged}") from None
        # Logging on (all categories: exporters file errors under categories of their own), so
        # that FMUs which log only then, like pythonfmu's, explain a failed call.
        self.component = self.slave.component
        self.do_step: Callable[..., int] | None = None
        if not self.fmi3:
            do_step = self.slave.dll.fmi2DoStep
            do_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
            do_step.restype = ctypes.c_int
            self.do_step = do_step
        self._started = False
        self.failed = False  # a call returned Error: the instance may only be freed

    # ------------------------------------------------------------------ logging
    def _keep(self, message: bytes | None) -> None:
        self.log.append((message or b"").decode("utf-8", "replace"))
        del self.log[:-20]

    def _fmi2_callbacks(self) -> Any:
        """Callbacks whose logger reads the format string as the message (the rover FMU
        passes its text as the format); fmpy's variadic logger proxy is process-wide."""
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
            self._keep(message)

        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(logger)
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        return callbacks

    def _fmi3_logger(self, environment: Any, status: int, category: bytes,
                     message: bytes) -> None:
        self._keep(message)

    # ------------------------------------------------------------------ status
    @property
    def fatal(self) -> bool:
        """Whether this FMU returned Fatal in this process (through any instance)."""
        return corrupted_here(self.unzipped)

    def record(self, status: int) -> None:
        """Remember what a failed call (its status) left this instance and the process in."""
        if status == ERROR:
            self.failed = True
        elif corrupts_process(status):
            mark_corrupted(self.unzipped)

    def failure(self, status: int) -> str:
        """What a raw call's failed status says, recorded."""
        self.record(status)
        return f"status {status}"

    def _call(self, function: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        """An fmpy call whose failed status is recorded before fmpy's exception goes on."""
        from fmpy.fmi1 import FMICallException

        try:
            return function(*args, **kwargs)
        except FMICallException as failure:
            self.record(failure.status)
            raise

    # ------------------------------------------------------------------ runs
    def start(self, stop_time: float) -> None:
        """Reset (after the first run) and enter initialisation mode for 0 … ``stop_time``."""
        if self._started:
            from fmpy.fmi1 import FMICallException

            try:
                self._call(self.slave.reset)
            except FMICallException as failure:  # recorded: Error or Fatal, as any call's
                raise ResetFailed(failure.status) from None
            self.failed = False  # reset after an Error: the instance is as new
        self._started = True
        if self.fmi3:
            self._call(self.slave.enterInitializationMode, startTime=0.0, stopTime=stop_time)
        else:
            self._call(self.slave.setupExperiment, startTime=0.0, stopTime=stop_time)
            self._call(self.slave.enterInitializationMode)

    def end_initialisation(self) -> None:
        self._call(self.slave.exitInitializationMode)

    def set_values(self, values: Sequence[tuple[FmuVariable, float | int | str]]) -> None:
        """Set variables by type, one setter call per type."""
        by_setter: dict[str, tuple[list[int], list[Any]]] = {}
        for variable, value in values:
            suffix = self.types[variable.type][0]
            refs, items = by_setter.setdefault(suffix, ([], []))
            refs.append(variable.value_reference)
            if suffix == "String":
                items.append(str(value))
            elif suffix in ("Real", "Float64", "Float32"):
                items.append(float(value))
            elif suffix == "Boolean":
                items.append(bool(value))
            else:
                items.append(int(value))
        for suffix, (refs, items) in by_setter.items():
            self._call(getattr(self.slave, f"set{suffix}"), refs, items)

    def step(self, time: float, step: float) -> str | None:
        """One communication step; None when it succeeded, else why not."""
        if self.do_step is not None:
            status = self.do_step(self.component, time, step, 1)
            return None if status in OK_STATUSES else self.failure(status)
        from fmpy.fmi1 import FMICallException

        try:
            _, terminate, _, _ = self._call(self.slave.doStep, time, step)
        except FMICallException as failure:  # recorded; said as a raw call's status is
            return f"status {failure.status}"
        return "the FMU asked to terminate the simulation" if terminate else None

    def output_groups(self, variables: Sequence[FmuVariable]) -> list[OutputGroup]:
        """Getter calls reading ``variables`` (in that column order), one per getter type."""
        grouped: dict[str, list[int]] = {}
        for position, variable in enumerate(variables):
            grouped.setdefault(self.types[variable.type][0], []).append(position)
        groups = []
        prefix = "fmi3Get" if self.fmi3 else "fmi2Get"
        for suffix, positions in grouped.items():
            _, c_type, dtype = self.types[variables[positions[0]].type]
            function = getattr(self.slave.dll, prefix + suffix)
            arguments = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p]
            function.argtypes = arguments + ([ctypes.c_size_t] if self.fmi3 else [])
            function.restype = ctypes.c_int
            reference_type = ctypes.c_uint32 if self.fmi3 else ctypes.c_uint
            refs = (reference_type * len(positions))(
                *(variables[p].value_reference for p in positions))
            assert c_type is not None
            groups.append(OutputGroup(function, refs, len(positions), dtype, positions,
                                      self.fmi3))
        return groups

    def close(self) -> None:
        """End the instance as far as its state allows (the statuses above): terminated and
        freed; after an Error freed only; after a Fatal left alone."""
        if self.fatal:
            return
        if not self.failed:
            from fmpy.fmi1 import FMICallException

            # an instance that refuses to terminate (recorded) is freed all the same
            with contextlib.suppress(FMICallException):
                self._call(self.slave.terminate)
            if self.fatal:
                return
        self.slave.freeInstance()
