"""The checks of a campaign's chain delivery: parameters or set-points the FMU can take."""

from __future__ import annotations

from idefix_rules.campaign.input.fmu_variable_checks import (
    Loc,
    article,
    did_you_mean,
    fmu_loc,
    fmu_names,
    loc_span,
    unit_problem,
)
from idefix_rules.campaign.input.load import Campaign
from idefix_rules.campaign.input.yamlsource import format_loc
from idefix_rules.errors import Diagnostic, error
from idefix_rules.fmu.description import FmuDescription
from idefix_rules.fmu.mapping import CHAIN_ARRAYS, CHAIN_COUNT
from idefix_rules.fmu.setpoints import SETPOINTS


def chain_problems(campaign: Campaign, description: FmuDescription) -> list[Diagnostic]:
    """The chain delivery the campaign asks for must fit the FMU."""
    chain = campaign.model.fmu.chain
    if chain.delivery == "inputs":
        return _input_problems(campaign, description)
    problems = []
    if chain.inputs:
        problems.append(error(
            "C508", f"fmu.chain.inputs: set-points given, but fmu.chain.delivery is "
                    f"{chain.delivery!r}", loc_span(campaign, ("fmu", "chain", "inputs")),
            hint="set fmu.chain.delivery: inputs to feed them"))
    if chain.delivery == "none":
        return problems
    return problems + _parameter_chain(campaign, description)


def _parameter_chain(campaign: Campaign, description: FmuDescription) -> list[Diagnostic]:
    renamed = fmu_names(campaign)
    variables = description.variables
    loc: Loc = ("fmu", "chain") if campaign.locations.keys.get(("fmu", "chain")) \
        else fmu_loc(campaign)
    count_name = renamed.get(CHAIN_COUNT, CHAIN_COUNT)
    first = [renamed.get(f"{array}[0]", f"{array}[0]") for array in CHAIN_ARRAYS]
    absent = [name for name in (count_name, *first) if name not in variables]
    if absent:
        return [error(
            "C507", f"{description.path.name} takes no command chain as parameters: it has no "
                    f"{', '.join(map(repr, absent))}", loc_span(campaign, loc),
            hint="map its chain parameters in fmu.parameters (FMU variable: chain.count, …), "
                 "or set fmu.chain.delivery to 'inputs' (set-points each step) or 'none'")]
    problems = []
    for name in (count_name, *first):
        variable = variables[name]
        if not variable.settable:
            problems.append(error(
                "C507", f"chain variable {name!r} is {article(variable.causality)}"
                        f" ({variable.variability}); the chain is set as parameters",
                loc_span(campaign, loc)))
    if variables[count_name].reader != "integer":
        problems.append(error(
            "C507", f"chain variable {count_name!r} is a {variables[count_name].type}; the "
                    "command count is an Integer", loc_span(campaign, loc)))
    capacity = 0
    while all(renamed.get(f"{array}[{capacity}]", f"{array}[{capacity}]") in variables
              for array in CHAIN_ARRAYS):
        capacity += 1
    problems += [error("C403", f"paths.{spec.name}: {len(spec.chain)} commands, but "
                               f"{description.path.name} takes at most {capacity} per chain "
                               f"(chain.max_wheel_rate[0] … [{capacity - 1}])",
                       campaign.locations.span(("paths", spec.name), at_key=True),
                       hint="split the chain, or use an FMU built for longer chains")
                 for spec in campaign.paths if len(spec.chain) > capacity]
    return problems


def _input_problems(campaign: Campaign, description: FmuDescription) -> list[Diagnostic]:
    inputs = campaign.model.fmu.chain.inputs
    if not inputs:
        return [error("C508", "fmu.chain: delivery 'inputs' needs fmu.chain.inputs (FMU input: "
                              "set-point)", loc_span(campaign, ("fmu", "chain")),
                      hint=f"set-points: {', '.join(SETPOINTS)}")]
    problems = []
    for fmu_name, setpoint in inputs.items():
        loc: Loc = ("fmu", "chain", "inputs", fmu_name)
        where = format_loc(loc)
        variable = description.variables.get(fmu_name)
        if variable is None:
            inputs_known = [v.name for v in description.variables.values()
                            if v.causality == "input"] or list(description.variables)
            problems.append(error("C401", f"{where}: unknown FMU variable {fmu_name!r} in "
                                          f"{description.path.name}", loc_span(campaign, loc),
                                  did_you_mean(fmu_name, inputs_known)))
            continue
        if setpoint not in SETPOINTS:
            problems.append(error(
                "C509", f"{where}: {setpoint!r} is not a set-point",
                loc_span(campaign, loc, at_key=False),
                did_you_mean(setpoint, SETPOINTS) or f"one of {', '.join(SETPOINTS)}"))
            continue
        if variable.causality != "input":
            problems.append(error(
                "C501", f"{where}: {fmu_name!r} is {article(variable.causality)}; set-points "
                        "are fed to inputs of the FMU every step", loc_span(campaign, loc)))
        if variable.reader not in ("real", "integer"):
            problems.append(error(
                "C502", f"{where}: {fmu_name!r} is a {variable.type}; a set-point is a Real "
                        "(or, for 'command', an Integer) input", loc_span(campaign, loc)))
        problems += unit_problem(campaign, loc, variable, setpoint, SETPOINTS[setpoint])
    return problems
