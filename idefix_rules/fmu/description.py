"""What an FMU declares about its variables, read once for the mapping checks and the runner.

:func:`describe_fmu` reads ``modelDescription.xml`` (FMI 2.0 or 3.0) through fmpy into
:class:`FmuDescription`: per variable its type, causality, variability, declared unit and the
getter family that reads it (``real``, ``integer``, ``boolean``). Units are understood by name
(FMI spellings such as ``m/s2`` or ``N.m`` included) or, failing that, by the FMU's own
``<UnitDefinitions>`` base-unit exponents.

>>> description = describe_fmu("rover.fmu")                   # doctest: +SKIP
>>> description.variables["x"].unit, description.variables["x"].reader  # doctest: +SKIP
('m', 'real')
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any, Literal

from idefix_rules.errors import Span, UserInputError, error
from idefix_rules.units import Dimension, Unit, UnitError, parse_unit

Reader = Literal["real", "integer", "boolean", "string", "unsupported"]

# FMI 2.0 and 3.0 type names → the getter family reading them (FMI 3.0 enumerations are Int64).
_READERS: dict[str, Reader] = {
    "Real": "real", "Float64": "real", "Float32": "real",
    "Integer": "integer", "Enumeration": "integer", "Int8": "integer", "UInt8": "integer",
    "Int16": "integer", "UInt16": "integer", "Int32": "integer", "UInt32": "integer",
    "Int64": "integer", "UInt64": "integer",
    "Boolean": "boolean", "String": "string",
}
_FMI_POWER = re.compile(r"([A-Za-z])(-?\d+)")


@dataclass(frozen=True)
class FmuVariable:
    """One variable as the FMU declares it."""

    name: str
    type: str  # as declared: Real, Integer, Boolean, Float64, Int32, Enumeration …
    causality: str
    variability: str
    unit: str  # declared unit ("" when none)
    value_reference: int
    reader: Reader
    si: Unit | None  # the declared unit understood (None: no unit or one we cannot read)
    # the range it declares (min, max attributes, its own or its declared type's), in its unit
    minimum: float | None = None
    maximum: float | None = None
    array: bool = False  # an FMI 3 array (<Dimension>): no getter here reads it

    @property
    def settable(self) -> bool:
        """A parameter or input the tool may set before or during a run."""
        return self.causality in ("parameter", "input") and self.variability != "constant"


@dataclass(frozen=True)
class FmuDescription:
    """The parts of ``modelDescription.xml`` the tool relies on."""

    path: Path
    fmi_version: str  # "2.0" or "3.0" (others are read but refused by the checks)
    token: str  # FMI 2.0 guid or FMI 3.0 instantiationToken
    co_simulation: str | None  # model identifier of the co-simulation interface
    model_exchange: str | None
    variables: dict[str, FmuVariable]
    default_stop_time: float | None

    @property
    def major(self) -> int:
        return int(self.fmi_version.split(".", 1)[0]) if self.fmi_version[:1].isdigit() else 0


def fmi_unit(name: str, definitions: dict[str, Any] | None = None) -> Unit | None:
    """The SI scale and dimension of an FMI unit name (``m/s2``, ``N.m``, ``mm``, ``deg``),
    else of its ``<BaseUnit>`` definition; None when neither is understood.

    >>> fmi_unit("rad/s2").dimension == parse_unit("rad/s^2").dimension
    True
    >>> fmi_unit("mm").scale
    0.001
    """
    text = _FMI_POWER.sub(r"\1^\2", name.replace(".", "*"))
    try:
        return parse_unit(text)
    except UnitError:
        pass
    definition = (definitions or {}).get(name)
    base = getattr(definition, "baseUnit", None)
    if base is None or any(getattr(base, key, 0) for key in ("K", "mol", "cd")) \
            or float(getattr(base, "offset", 0.0) or 0.0) != 0.0:
        return None
    dimension = Dimension(length=int(base.m), mass=int(base.kg), time=int(base.s),
                          current=int(base.A), angle=int(base.rad))
    return Unit(name, Fraction(float(base.factor)), dimension)


def _bound(variable: Any, declared: Any, which: str) -> float | None:
    """A numeric variable's declared ``min`` or ``max`` (its own, else its type's)."""
    for source in (variable, declared):
        text = getattr(source, which, None) if source is not None else None
        if text not in (None, ""):
            try:
                value = float(text)
            except (TypeError, ValueError):
                return None
            return value if math.isfinite(value) else None
    return None


def describe_fmu(path: str | Path, span: Span | None = None) -> FmuDescription:
    """Read an FMU's (or an extracted FMU folder's) model description; F102 when unreadable."""
    from fmpy import read_model_description

    from idefix_rules.fmu.description_text import description_problem

    path = Path(path)
    problem = description_problem(path)
    if problem is not None:  # fmpy's own words name the wrong file, or none
        raise UserInputError(error("F102", f"not a readable FMU: {problem}",
                                   span or Span(str(path))))
    try:
        description = read_model_description(str(path), validate=False)
    except Exception as failure:  # fmpy and zipfile raise plain exceptions for bad archives
        raise UserInputError(error("F102", f"not a readable FMU: {failure}",
                                   span or Span(str(path)))) from None
    definitions = {unit.name: unit for unit in description.unitDefinitions}
    variables = {}
    for variable in description.modelVariables:
        unit = getattr(variable, "unit", None) or ""
        declared = variable.declaredType
        if not unit and declared is not None:
            unit = getattr(declared, "unit", None) or ""
        # an FMI 3 array (<Dimension>) is several values under one reference: no getter here
        # reads one of them, so it is no signal, set-point or parameter (read as a scalar, its
        # first element stood for it)
        array = bool(getattr(variable, "dimensions", None))
        variables[variable.name] = FmuVariable(
            name=variable.name, type=f"{variable.type} array" if array else str(variable.type),
            causality=str(variable.causality or "local"),
            variability=str(variable.variability or "continuous"),
            unit=unit, value_reference=int(variable.valueReference),
            reader="unsupported" if array else _READERS.get(str(variable.type), "unsupported"),
            si=fmi_unit(unit, definitions) if unit else None,
            minimum=_bound(variable, declared, "min"), maximum=_bound(variable, declared, "max"),
            array=array)
    experiment = description.defaultExperiment
    stop = getattr(experiment, "stopTime", None) if experiment is not None else None
    token = description.guid if description.fmiVersion.startswith("2") \
        else getattr(description, "instantiationToken", None) or description.guid
    return FmuDescription(
        path=path, fmi_version=str(description.fmiVersion), token=str(token or ""),
        co_simulation=description.coSimulation.modelIdentifier
        if description.coSimulation is not None else None,
        model_exchange=description.modelExchange.modelIdentifier
        if description.modelExchange is not None else None,
        variables=variables, default_stop_time=float(stop) if stop is not None else None)
