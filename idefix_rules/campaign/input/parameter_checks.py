"""A campaign's parameters against its FMU: known, settable, of the right unit, in range."""

from __future__ import annotations

import difflib
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from idefix_rules.campaign.input.campaign_values import (
    CONTRACT_PARAMETERS,
    GEOMETRY_PARAMETERS,
    REGOLITH_PREFIX,
    regolith_parameter,
    tool_only_parameters,
)
from idefix_rules.campaign.input.load import Campaign
from idefix_rules.campaign.input.sampling import planned_draws
from idefix_rules.campaign.input.yamlsource import format_loc
from idefix_rules.errors import Diagnostic, error
from idefix_rules.fmu.description import FmuDescription, FmuVariable
from idefix_rules.fmu.mapping import CHAIN_ARRAYS, CHAIN_COUNT
from idefix_rules.units import Dimension, describe


def parameter_problems(campaign: Campaign, description: FmuDescription) -> list[Diagnostic]:
    """Parameter names (uncertainty, regolith, ``fmu.parameters``) against the FMU: each must
    name a settable variable of a numeric type, with a value of its unit's dimension."""
    variables = description.variables
    fmu_path = description.path
    fmu = campaign.model.fmu
    problems: list[Diagnostic] = []
    parameter_names = {name: name for name, variable in variables.items() if variable.settable}
    if fmu.parameters is not None:
        mapped_from: dict[str, str] = {}  # our name → the first FMU variable mapped to it
        for fmu_name, our_name in fmu.parameters.items():
            map_loc = ("fmu", "parameters", fmu_name)
            if our_name in mapped_from:  # one value, two variables: one would get nothing
                problems.append(error(
                    "C516", f"{format_loc(map_loc)}: {our_name!r} is mapped from both "
                            f"{mapped_from[our_name]!r} and {fmu_name!r}; a campaign name sets "
                            "one FMU variable", campaign.locations.span(map_loc, at_key=True),
                    hint="map each FMU variable to a name of its own"))
                continue
            mapped_from[our_name] = fmu_name
            variable = variables.get(fmu_name)
            if variable is None:
                problems.append(_unknown(campaign, map_loc, fmu_name, variables, "FMU variable",
                                         fmu_path))
                parameter_names[our_name] = ""  # reported already; skip its unit check
                continue
            if not variable.settable:
                problems.append(_not_settable(campaign, map_loc, variable))
                parameter_names[our_name] = ""
                continue
            parameter_names[our_name] = fmu_name
    entries: list[tuple[tuple[str, ...], str, Dimension | None]] = [
        (("uncertainty", "parameters", name), name, spec.dimension)
        for name, spec in campaign.model.uncertainty.parameters.items()]
    written = campaign.model.environment.regolith_dimensions
    entries += [(("environment", "regolith", key), regolith_parameter(key), written.get(key))
                for key in campaign.model.environment.regolith]
    chain_set = fmu.chain.delivery == "parameters"
    # the FMU variables the chain delivery writes: those fmu.parameters maps to a chain
    # parameter's name (an FMU's own name for chain.count), the others by their own name
    renamed = {fmu_name for fmu_name, ours in (fmu.parameters or {}).items()
               if is_chain_parameter(ours)}
    ranged: list[tuple[tuple[str, ...], str, FmuVariable]] = []  # to hold to their range
    tool_only = tool_only_parameters(
        campaign, (name for name, variable in variables.items() if variable.settable))
    for loc, name, dimension in entries:
        if name in tool_only and variables.get(name) is None:
            # the tool's own geometry for an FMU that has its own: of the contract's dimension
            if dimension != CONTRACT_PARAMETERS[name].dimension:
                problems.append(_not_its_dimension(campaign, loc, name, dimension))
            continue
        if chain_set and (is_chain_parameter(name) or parameter_names.get(name) in renamed):
            problems.append(error(
                "C515", f"{format_loc(loc)}: {name!r} is set by each run's command chain (the "
                        "chain delivery 'parameters'); a value given here would be overwritten",
                campaign.locations.span(loc, at_key=True),
                hint="give the commands in the campaign's paths; an FMU that takes its chain "
                     "otherwise says so with fmu.chain.delivery: inputs or none"))
            continue
        if name not in parameter_names:
            variable = variables.get(name)
            problems.append(_not_settable(campaign, loc, variable) if variable is not None
                            else _unknown(campaign, loc, name, parameter_names, "FMU parameter",
                                          fmu_path))
            continue
        if not parameter_names[name]:
            continue
        variable = variables[parameter_names[name]]
        if variable.reader not in ("real", "integer"):
            problems.append(error(
                "C505", f"{format_loc(loc)}: FMU parameter {variable.name!r} is a "
                        f"{variable.type}; a sampled or regolith value needs a Real or Integer",
                campaign.locations.span(loc, at_key=True)))
            continue
        if variable.reader == "integer":
            fractional = _not_whole(campaign, loc)
            if fractional is not None:
                problems.append(error(
                    "C505", f"{format_loc(loc)}: FMU parameter {variable.name!r} is an "
                            f"{variable.type}, {fractional}: it would be cut to a whole number",
                    campaign.locations.span(loc, at_key=True),
                    hint="give whole numbers (distribution fixed), or map a Real parameter"))
                continue
        if dimension is None:
            ranged.append((loc, name, variable))
            continue
        expected = variable.si.dimension if variable.si is not None else None
        contract = CONTRACT_PARAMETERS.get(name)
        if contract is not None and expected is not None and expected != contract.dimension:
            # the FMU's variable is of another dimension than the tool reads the name in: no
            # value could be right for both
            problems.append(error(
                "C402", f"{format_loc(loc)}: {name} is {contract.what}, read by this tool "
                        f"as {describe(contract.dimension)} in {contract.unit}, but FMU "
                        f"variable {variable.name!r} is in {variable.unit}",
                campaign.span(loc), hint=f"map {name} to an FMU variable of that dimension"))
            continue
        if expected is not None and expected != dimension:
            problems.append(error(
                "C402", f"{format_loc(loc)}: expected {describe(expected)} (FMU unit "
                        f"{variable.unit}), got {describe(dimension)}", campaign.span(loc)))
            continue
        if contract is not None and contract.dimension != dimension:
            # the FMU declares no unit: the tool's own reading of the name decides
            problems.append(_not_its_dimension(campaign, loc, name, dimension))
            continue
        ranged.append((loc, name, variable))
    return problems + _outside_declared_range(campaign, description, ranged)


def _outside_declared_range(campaign: Campaign, description: FmuDescription,
                            entries: Sequence[tuple[tuple[str, ...], str, FmuVariable]]
                            ) -> list[Diagnostic]:
    """A regolith value, or a planned draw of an uncertain parameter, outside the range the FMU
    declares for its variable (min, max) is F110 at its line, naming the run that draws it,
    before any run: the FMU would refuse it (fmi2SetReal) and the runs fail one by one."""
    entries = [entry for entry in entries
               if entry[2].minimum is not None or entry[2].maximum is not None]
    if not entries:
        return []
    draws: dict[str, dict[str, np.ndarray]] | None = None
    planned = 0
    problems = []
    for loc, name, variable in entries:
        candidates: list[tuple[float, str]] = []
        if loc[0] == "uncertainty":
            if draws is None:
                planned, draws = planned_draws(campaign, [spec.name for spec in campaign.paths])
            for path, drawn in draws.items():
                values = np.asarray(drawn.get(name, ()), dtype=float)
                candidates += [(float(values[run]), f"run {run} of path {path} draws")
                               for run in (values.argmin(), values.argmax()) if values.size]
        else:
            candidates = [(float(campaign.model.environment.regolith[loc[-1]]), "the value is")]
        for value, who in candidates:
            own = variable.si.from_si(value) if variable.si is not None else value
            side = _beyond(own, variable)
            if side is None:
                continue
            unit = f" {variable.unit}" if variable.unit else ""
            planned_text = f" (of {planned} planned)" if loc[0] == "uncertainty" else ""
            problems.append(error(
                "F110", f"{format_loc(loc)}: {who} {own:g}{unit}{planned_text}, "
                        f"{side[0]} {side[1]:g}{unit} {description.path.name} declares for "
                        f"{variable.name!r}, before any run was simulated",
                campaign.locations.span(loc, at_key=True),
                hint="bound the distribution inside the range the FMU allows (a "
                     "truncated_normal with low and high, a uniform), or narrow it"))
            break
    return problems


def _not_its_dimension(campaign: Campaign, loc: tuple[str, ...], name: str,
                       dimension: Dimension | None) -> Diagnostic:
    """C402: a value for a name the tool reads itself, of another dimension than its own."""
    own = CONTRACT_PARAMETERS[name]
    got = "a bare number" if dimension is None else describe(dimension)
    return error("C402", f"{format_loc(loc)}: expected {describe(own.dimension)} ({name} is "
                         f"{own.what}, read by this tool in {own.unit}), got {got}",
                 campaign.span(loc))


def _beyond(value: float, variable: FmuVariable) -> tuple[str, float] | None:
    """Which bound of the range ``variable`` declares ``value`` (in its unit) breaks."""
    if variable.minimum is not None and value < variable.minimum:
        return "below the minimum", variable.minimum
    if variable.maximum is not None and value > variable.maximum:
        return "above the maximum", variable.maximum
    return None


def _not_whole(campaign: Campaign, loc: tuple[str, ...]) -> str | None:
    """What in a sampled or regolith value is no whole number (an Integer parameter takes
    one): a distribution other than ``fixed`` draws fractions; a value may be one."""
    if loc[0] == "uncertainty":
        spec = campaign.model.uncertainty.parameters[loc[-1]]
        if spec.distribution != "fixed":
            return f"but a {spec.distribution} distribution draws fractions"
        value = float(spec.value)
    else:
        value = float(campaign.model.environment.regolith[loc[-1]])
    return None if value == int(value) else f"but {value:g} is not a whole number"


def is_chain_parameter(name: str) -> bool:
    """Whether a campaign parameter is one the chain delivery ``parameters`` sets itself.

    >>> [is_chain_parameter(n) for n in ("chain.count", "chain.delta_heading[3]",
    ...                                  "chain.delta_heading", "soil.n")]
    [True, True, False, False]
    """
    return name == CHAIN_COUNT or re.fullmatch(
        r"(" + "|".join(re.escape(array) for array in CHAIN_ARRAYS) + r")\[\d+\]",
        name) is not None


def _not_settable(campaign: Campaign, loc: tuple[str, ...], variable: FmuVariable
                  ) -> Diagnostic:
    kind = f"{variable.causality} ({variable.variability})" \
        if variable.causality in ("parameter", "input") else variable.causality
    return error("C504", f"{format_loc(loc)}: FMU variable {variable.name!r} is {kind}; a "
                         "parameter must be settable (a parameter or input, not constant)",
                 campaign.locations.span(loc, at_key=True),
                 hint="`fmpy info` lists the FMU's parameters and inputs")



def _unknown(campaign: Campaign, loc: tuple[str, ...], name: str, known: Mapping[str, object],
             what: str, fmu_path: Path) -> Diagnostic:
    if loc[:2] == ("environment", "regolith") and name.startswith(REGOLITH_PREFIX) \
            and loc[-1] == name[len(REGOLITH_PREFIX):]:
        return _unknown_regolith(campaign, loc, name, known, fmu_path)
    # a variable's own name without its group (`k_c` for `soil.k_c`) first, then spelling
    grouped = sorted(n for n in known if "." not in name and n.rsplit(".", 1)[-1] == name)
    close = grouped[:1] or difflib.get_close_matches(name, list(known), n=1)
    hint = f"did you mean {close[0]!r}?" if close else None
    if grouped:
        hint = f"{hint} (a variable is named with its group)"
    if hint is None and what == "FMU parameter" and name in GEOMETRY_PARAMETERS \
            and loc[0] == "uncertainty":
        hint = (f"{fmu_path.name} has no {name}: the tool reads one geometry per campaign, so "
                "give it a fixed value (distribution: fixed) or a regolith value; drawn, it "
                "would change no run")
    if hint is None and what == "FMU parameter":
        # `fmpy info` lists inputs and outputs only: name the parameters there are
        names = [n for n in known if n]
        listing = ", ".join(names[:8]) + (" …" if len(names) > 8 else "")
        hint = (f"settable variables of {fmu_path.name}: {listing or 'none'}; or map one to "
                f"this name: fmu.parameters: {{its_name: {name}}}")
    return error("C401", f"{format_loc(loc)}: unknown {what} {name!r} in {fmu_path.name}",
                 campaign.locations.span(loc, at_key=True), hint)


def _unknown_regolith(campaign: Campaign, loc: tuple[str, ...], name: str,
                      known: Mapping[str, object], fmu_path: Path) -> Diagnostic:
    """A regolith key the FMU has no soil parameter for: the hint names the regolith keys
    there are (the soil parameters without ``soil.``), and how another group's parameter is
    written (its full name)."""
    keys = sorted(n[len(REGOLITH_PREFIX):] for n in known if n.startswith(REGOLITH_PREFIX))
    close = difflib.get_close_matches(str(loc[-1]), keys, n=1)
    listing = ", ".join(keys) or "none"
    hint = (f"did you mean {close[0]!r}? " if close else "") + (
        f"regolith keys are {fmu_path.name}'s soil parameters without 'soil.': {listing}; a "
        "parameter of another group is written with its full name (rover.half_track)")
    return error("C401", f"{format_loc(loc)}: unknown FMU parameter {name!r} in "
                         f"{fmu_path.name}", campaign.locations.span(loc, at_key=True), hint)
