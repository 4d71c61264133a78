"""The contract's names at an FMU: chain parameters, signal map targets, units scaled to SI."""

from __future__ import annotations

import re
from pathlib import Path

from idefix_rules.errors import Span, UserInputError, error
from idefix_rules.fmu.description import FmuVariable
from idefix_rules.signals import AXIS_LABELS, FMU_SIGNALS
from idefix_rules.units import parse_unit

CHAIN_COUNT = "chain.count"
TERRAIN_FILE = "terrain.file"
CHAIN_ARRAYS = ("chain.max_wheel_rate", "chain.delta_position", "chain.delta_heading")
DONE_SIGNAL = "done"
_INDEXED = re.compile(r"^(?P<name>[^\[\]]+)\[(?P<index>[A-Za-z0-9_]+)\]$")
# How the rover FMU (and any FMU following its wording) names a parameter it rejects.
PARAMETER_REJECTED = re.compile(r"^parameter (?P<name>[^\s=]+) = (?P<value>\S+) out of range")


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


def missing_variable(name: str, role: str, fmu_path: Path) -> UserInputError:
    """F104: a mapped, requested, parameter, chain or chain input variable the FMU lacks."""
    return UserInputError(error(
        "F104", f"{role} variable '{name}' does not exist in the FMU",
        Span(str(fmu_path)), hint="check the signal/parameter map against "
        "`fmpy info` of the FMU"))
