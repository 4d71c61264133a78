"""What a run gives an FMU: its start values in the FMU's units, its chain as inputs."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from idefix_rules.commands import Command, RoverGeometry
from idefix_rules.errors import Span, UserInputError, error
from idefix_rules.fmu.description import FmuVariable
from idefix_rules.fmu.mapping import (
    CHAIN_ARRAYS,
    CHAIN_COUNT,
    TERRAIN_FILE,
    missing_variable,
    si_scale,
)
from idefix_rules.fmu.setpoints import SETPOINTS, chain_setpoints
from idefix_rules.fmu.terrain import read_terrain
from idefix_rules.units import UnitError, parse_quantity, parse_unit

ChainInput = tuple[FmuVariable, str, float]  # the FMU input, its set-point, the SI scale


def plan_inputs(variables: Mapping[str, FmuVariable], chain_delivery: str,
                chain_inputs: Mapping[str, str], fmu_path: Path) -> list[ChainInput]:
    """The FMU inputs fed with set-points each communication step (delivery ``inputs``)."""
    inputs: list[ChainInput] = []
    if chain_delivery != "inputs":
        return inputs
    for fmu_name, setpoint in chain_inputs.items():
        variable = variables.get(fmu_name)
        if variable is None:
            raise missing_variable(fmu_name, "chain input", fmu_path)
        if setpoint not in SETPOINTS:
            raise UserInputError(error(
                "F402", f"'{setpoint}' is not a set-point; one of "
                f"{', '.join(SETPOINTS)}", Span(str(fmu_path))))
        scale = si_scale(variable, f"set-point '{setpoint}'", SETPOINTS[setpoint],
                         Span(str(fmu_path)))
        inputs.append((variable, setpoint, scale))
    return inputs


def input_rows(inputs: list[ChainInput], chain: Sequence[Command], rover: RoverGeometry,
               interval: float, steps: int) -> list[tuple[FmuVariable, np.ndarray]]:
    """Per chain input its value for every step (and the initial value), FMU units."""
    if not inputs:
        return []
    values = chain_setpoints(chain, rover, interval, max(steps, 1))
    rows = []
    for variable, setpoint, scale in inputs:
        series = values[setpoint] / scale if scale != 1.0 else values[setpoint]
        rows.append((variable, series))
    return rows


def value_in_fmu_unit(name: str, variable: FmuVariable, value: float | str) -> float:
    """``value`` in the unit ``variable`` declares (a string with its unit, or a plain number
    in SI)."""
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


class StartValues:
    """A run's start values: its parameters in the FMU's units (renamed by ``parameter_map``)
    and, delivered as ``parameters``, its chain; a terrain file is read once per change."""

    def __init__(self, variables: Mapping[str, FmuVariable], parameter_map: Mapping[str, str],
                 chain_delivery: str, fmu_path: Path) -> None:
        self.variables = variables
        self.parameter_map = parameter_map
        self.chain_delivery = chain_delivery
        self.fmu_path = fmu_path
        self._checked_terrain: tuple[str, int, int] | None = None

    def fmu_name(self, name: str) -> str:
        return self.parameter_map.get(name, name)

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

    def for_run(self, parameters: Mapping[str, float | str], chain: Sequence[Command]
                ) -> list[tuple[FmuVariable, float | int | str]]:
        """The start values of one run, in the order they are set."""
        values: list[tuple[FmuVariable, float | int | str]] = []
        for name, value in parameters.items():
            fmu_name = self.fmu_name(name)
            variable = self.variables.get(fmu_name)
            if variable is None:
                raise missing_variable(fmu_name, "parameter", self.fmu_path)
            if variable.reader == "string":
                if fmu_name == TERRAIN_FILE and value:
                    self._check_terrain(str(value))
                values.append((variable, str(value)))
            elif variable.reader == "integer":
                values.append((variable, int(value)))
            elif variable.reader == "boolean":
                raise UserInputError(error("F108", f"Boolean parameter '{name}' not supported"))
            else:
                values.append((variable, value_in_fmu_unit(name, variable, value)))
        if chain and self.chain_delivery == "parameters":
            count = self.variables.get(self.fmu_name(CHAIN_COUNT))
            if count is None:
                raise missing_variable(self.fmu_name(CHAIN_COUNT), "chain", self.fmu_path)
            values.append((count, len(chain)))
            for array, field in zip(CHAIN_ARRAYS, ("max_wheel_rate", "delta_position",
                                                   "delta_heading"), strict=True):
                for i, command in enumerate(chain):
                    name = self.fmu_name(f"{array}[{i}]")
                    variable = self.variables.get(name)
                    if variable is None:
                        raise missing_variable(name, "chain", self.fmu_path)
                    values.append((variable, value_in_fmu_unit(
                        name, variable, float(getattr(command, field)))))
        return values
