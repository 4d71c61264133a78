"""Checks of a campaign against its FMU, before anything is simulated.

Parameter names (uncertainty, regolith) and the ``signals``/``parameters`` maps must name
variables the FMU has; a value's dimension must match the FMU variable's unit where that unit is
one we know. Mistakes point at the campaign line.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from pathlib import Path

from idefix_rules.campaign.load import Campaign, format_loc
from idefix_rules.errors import Diagnostic, UserInputError, error
from idefix_rules.units import Dimension, UnitError, describe, parse_unit

# FMI unit spellings → our unit parser's.
_FMI_UNIT_SPELLING = {"m/s2": "m/s^2", "N/m2": "N/m^2", "N/m3": "N/m^3", "N.m": "N*m",
                      "N.m/A": "N*m/A", "A.s": "A*s"}


def model_variables(fmu_path: Path) -> dict[str, tuple[str, str]]:
    """FMU variable name → (causality, unit)."""
    from fmpy import read_model_description

    try:
        description = read_model_description(str(fmu_path))
    except Exception as failure:
        raise UserInputError(error("C400", f"{fmu_path}: not a readable FMU ({failure})")) \
            from None
    found = {}
    for variable in description.modelVariables:
        unit = ""
        if variable.declaredType is not None and getattr(variable.declaredType, "unit", None):
            unit = variable.declaredType.unit
        if getattr(variable, "unit", None):
            unit = variable.unit
        found[variable.name] = (str(variable.causality), unit or "")
    return found


def check_parameters(campaign: Campaign, fmu_path: Path) -> dict[str, tuple[str, str]]:
    """Validate parameter and signal names against the FMU; returns its variables."""
    variables = model_variables(fmu_path)
    fmu = campaign.model.fmu
    problems: list[Diagnostic] = []
    parameter_names = {name: name for name, (causality, _) in variables.items()
                       if causality in ("parameter", "input")}
    if fmu.parameters is not None:
        for fmu_name, our_name in fmu.parameters.items():
            if fmu_name not in variables:
                problems.append(_unknown(campaign, ("fmu", "parameters", fmu_name), fmu_name,
                                         variables, "FMU variable", fmu_path))
                parameter_names[our_name] = ""  # reported already; skip its unit check
                continue
            parameter_names[our_name] = fmu_name
    if fmu.signals is not None:
        for fmu_name in fmu.signals:
            if fmu_name not in variables:
                problems.append(_unknown(campaign, ("fmu", "signals", fmu_name), fmu_name,
                                         variables, "FMU variable", fmu_path))
    entries: list[tuple[tuple[str, ...], str, Dimension | None]] = [
        (("uncertainty", "parameters", name), name, spec.dimension)
        for name, spec in campaign.model.uncertainty.parameters.items()]
    entries += [(("environment", "regolith", key), key if "." in key else f"soil.{key}", None)
                for key in campaign.model.environment.regolith]
    for loc, name, dimension in entries:
        if name not in parameter_names:
            problems.append(_unknown(campaign, loc, name, parameter_names, "FMU parameter",
                                     fmu_path))
            continue
        if dimension is None or not parameter_names[name]:
            continue
        unit = variables[parameter_names[name]][1]
        try:
            expected = parse_unit(_FMI_UNIT_SPELLING.get(unit, unit)).dimension if unit else None
        except UnitError:
            expected = None
        if expected is not None and expected != dimension:
            problems.append(error(
                "C402", f"{format_loc(loc)}: expected {describe(expected)} (FMU unit {unit}), "
                        f"got {describe(dimension)}", campaign.span(loc)))
    if problems:
        raise UserInputError(problems, sources={str(campaign.source): campaign.text})
    return variables


def _unknown(campaign: Campaign, loc: tuple[str, ...], name: str, known: Mapping[str, object],
             what: str, fmu_path: Path) -> Diagnostic:
    close = difflib.get_close_matches(name, list(known), n=1)
    hint = f"did you mean {close[0]!r}?" if close else None
    return error("C401", f"{format_loc(loc)}: unknown {what} {name!r} in {fmu_path.name}",
                 campaign.locations.span(loc, at_key=True), hint)
