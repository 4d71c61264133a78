"""Checks of a campaign against its FMU, before anything is simulated.

Parameter names (uncertainty, regolith) and the ``signals``/``parameters`` maps must name
variables the FMU has; a value's dimension must match the FMU variable's unit where that unit is
one we know. Mistakes point at the campaign line.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Mapping
from pathlib import Path

from idefix_rules.campaign.load import Campaign, format_loc
from idefix_rules.errors import Diagnostic, Span, UserInputError, error
from idefix_rules.fmu.runner import CHAIN_ARRAYS
from idefix_rules.signals import FMU_SIGNALS
from idefix_rules.units import Dimension, UnitError, describe, parse_unit

# Output samples per run: 300 s at 10 Hz is 3000; a million means a stop time or output interval
# off by orders of magnitude, which would exhaust memory rather than simulate.
MAX_SAMPLES = 1_000_000

# FMI unit spellings → our unit parser's.
_FMI_UNIT_SPELLING = {"m/s2": "m/s^2", "N/m2": "N/m^2", "N/m3": "N/m^3", "N.m": "N*m",
                      "N.m/A": "N*m/A", "A.s": "A*s"}


def model_variables(fmu_path: Path, span: Span | None = None) -> dict[str, tuple[str, str]]:
    """FMU variable name → (causality, unit); ``span`` is where the campaign names the FMU."""
    from fmpy import read_model_description

    try:
        description = read_model_description(str(fmu_path))
    except Exception as failure:
        raise UserInputError(error("C400", f"{fmu_path}: not a readable FMU ({failure})",
                                   span or Span(str(fmu_path)))) from None
    if description.fmiVersion != "2.0" or description.coSimulation is None:
        kinds = ", ".join(kind for kind, part in (("co-simulation", description.coSimulation),
                                                  ("model exchange",
                                                   description.modelExchange)) if part)
        raise UserInputError(error(
            "C400", f"{fmu_path}: an FMI {description.fmiVersion} FMU for {kinds or 'nothing'}; "
                    "the campaign runner needs FMI 2.0 co-simulation", span or Span(str(fmu_path)),
            hint="export the model as an FMI 2.0 co-simulation FMU"))
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
    variables = model_variables(fmu_path, campaign.span(("fmu", "path"))
                                if campaign.fmu is not None else None)
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
    problems += _chain_capacity(campaign, variables, fmu_path)
    if problems:
        raise UserInputError(problems, sources={str(campaign.source): campaign.text})
    return variables


def _chain_capacity(campaign: Campaign, variables: Mapping[str, object],
                    fmu_path: Path) -> list[Diagnostic]:
    """Every chain must fit the FMU's chain arrays (``chain.max_wheel_rate[i]`` …)."""
    fmu_name = {ours: theirs for theirs, ours in (campaign.model.fmu.parameters or {}).items()}
    capacity = 0
    while all(fmu_name.get(f"{array}[{capacity}]", f"{array}[{capacity}]") in variables
              for array in CHAIN_ARRAYS):
        capacity += 1
    if capacity == 0:  # an FMU without chain arrays: the runner names what it lacks
        return []
    return [error("C403", f"paths.{spec.name}: {len(spec.chain)} commands, but "
                          f"{fmu_path.name} takes at most {capacity} per chain "
                          f"(chain.max_wheel_rate[0] … [{capacity - 1}])",
                  campaign.locations.span(("paths", spec.name), at_key=True),
                  hint="split the chain, or use an FMU built for longer chains")
            for spec in campaign.paths if len(spec.chain) > capacity]


def check_signal_map(campaign: Campaign, required: Iterable[str]) -> None:
    """A campaign's own ``fmu.signals`` map must provide every FMU signal the rulebook reads
    (without a map, the FMU's shipped map or its contract names are used as they are)."""
    signals = campaign.model.fmu.signals
    if signals is None:
        return
    provided = {contract.split("[", 1)[0] for contract in signals.values()}
    provided.add("t")  # the runner fills in the output grid's times when the FMU has none
    missing = sorted(name for name in required if name in FMU_SIGNALS and name not in provided)
    if missing:
        raise UserInputError(error(
            "C405", f"fmu.signals: the rulebook reads {', '.join(map(repr, missing))}, which "
                    "the signal map does not provide",
            campaign.locations.span(("fmu", "signals"), at_key=True),
            hint="map an FMU variable to each (FMU variable: signal), e.g. body.pos.y: y"),
            sources={str(campaign.source): campaign.text})


def check_simulation_size(campaign: Campaign) -> None:
    """Refuse a run longer than :data:`MAX_SAMPLES` output samples before simulating."""
    from idefix_rules.campaign.simulate import plan_path, rover_geometry

    rover = rover_geometry(campaign)
    settings = campaign.model.simulation
    problems = []
    for spec in campaign.paths:
        samples = plan_path(campaign, spec, rover).samples
        if samples > MAX_SAMPLES:
            problems.append(error(
                "C404", f"paths.{spec.name}: a run would last "
                        f"{samples * settings.output_interval:.6g} s at an output interval of "
                        f"{settings.output_interval:.6g} s: {samples:.3g} samples per run, more "
                        f"than {MAX_SAMPLES}",
                campaign.locations.span(("simulation",), at_key=True),
                hint="stop time = chain duration × duration_margin + extra_time; check the "
                     "simulation section and the chain's wheel rates"))
    if problems:
        raise UserInputError(problems, sources={str(campaign.source): campaign.text})


def check_rocks_on_terrain(campaign: Campaign, extent: tuple[float, float, float, float]
                           ) -> None:
    """Every rock centre must lie on the terrain grid ``(x_min, x_max, y_min, y_max)``."""
    x_min, x_max, y_min, y_max = extent
    problems = [
        error("C206", f"environment.rocks[{index}]: ({rock.x:g} m, {rock.y:g} m) is outside "
                      f"the terrain (x {x_min:g} … {x_max:g} m, y {y_min:g} … {y_max:g} m)",
              campaign.span(("environment", "rocks", index)),
              hint="rock positions are world coordinates, in the terrain's frame")
        for index, rock in enumerate(campaign.model.environment.rocks)
        if not (x_min <= rock.x <= x_max and y_min <= rock.y <= y_max)]
    if problems:
        raise UserInputError(problems, sources={str(campaign.source): campaign.text})


def prepare_output(campaign: Campaign) -> None:
    """Create the output folder, or say why it cannot be (a file, no permission …)."""
    folder = campaign.output
    from_file = folder == (campaign.source.parent / campaign.model.output).resolve()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / ".idefix-write-test"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as failure:
        reason = ("it is a file" if folder.is_file() or isinstance(failure, FileExistsError)
                  else failure.strerror or str(failure))
        raise UserInputError(error(
            "C205", f"output folder {folder} cannot be used: {reason}",
            campaign.span(("output",)) if from_file else Span(str(folder)),
            hint=None if from_file else "given by --out"),
            sources={str(campaign.source): campaign.text}) from None


def _unknown(campaign: Campaign, loc: tuple[str, ...], name: str, known: Mapping[str, object],
             what: str, fmu_path: Path) -> Diagnostic:
    close = difflib.get_close_matches(name, list(known), n=1)
    hint = f"did you mean {close[0]!r}?" if close else None
    return error("C401", f"{format_loc(loc)}: unknown {what} {name!r} in {fmu_path.name}",
                 campaign.locations.span(loc, at_key=True), hint)
