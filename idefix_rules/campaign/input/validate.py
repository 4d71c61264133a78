"""Checks of a campaign before anything is simulated: parameters against the FMU, run sizes,
rocks on the terrain, the output folder. Mistakes point at the campaign line.

Parameter names (uncertainty, regolith, ``fmu.parameters``) must name settable variables the FMU
has; a value's dimension must match the FMU variable's unit where that unit is one we know. The
rest of the FMU mapping is checked by :mod:`idefix_rules.campaign.input.fmu_checks`.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from idefix_rules.campaign.input.load import (
    INITIAL_POSITION,
    REGOLITH_PREFIX,
    Campaign,
    format_loc,
    initial_position_sigma,
    nominal_parameters,
    regolith_parameter,
    rover_geometry,
    where_set,
)
from idefix_rules.campaign.input.schema import DEFAULT_DURATION_MARGIN
from idefix_rules.errors import Diagnostic, Span, UserInputError, error
from idefix_rules.fmu.description import FmuDescription, FmuVariable
from idefix_rules.fmu.mapping import CHAIN_ARRAYS, CHAIN_COUNT
from idefix_rules.units import Dimension, describe

# Output samples per run: 300 s at 10 Hz is 3000; a million means a stop time or output interval
# off by orders of magnitude, which would exhaust memory rather than simulate.
MAX_SAMPLES = 1_000_000

def parameter_problems(campaign: Campaign, description: FmuDescription) -> list[Diagnostic]:
    """Parameter names (uncertainty, regolith, ``fmu.parameters``) against the FMU: each must
    name a settable variable of a numeric type, with a value of its unit's dimension."""
    variables = description.variables
    fmu_path = description.path
    fmu = campaign.model.fmu
    problems: list[Diagnostic] = []
    parameter_names = {name: name for name, variable in variables.items() if variable.settable}
    if fmu.parameters is not None:
        for fmu_name, our_name in fmu.parameters.items():
            map_loc = ("fmu", "parameters", fmu_name)
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
    for loc, name, dimension in entries:
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
        if expected is not None and expected != dimension:
            problems.append(error(
                "C402", f"{format_loc(loc)}: expected {describe(expected)} (FMU unit "
                        f"{variable.unit}), got {describe(dimension)}", campaign.span(loc)))
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


# The output interval a campaign gets when it gives none (schema.SimulationSection), s.
DEFAULT_OUTPUT_INTERVAL = 0.1


def check_simulation_size(campaign: Campaign) -> None:
    """Refuse a run longer than :data:`MAX_SAMPLES` output samples before simulating."""
    from idefix_rules.campaign.input.load import rover_geometry, stop_limit

    rover = rover_geometry(campaign)
    settings = campaign.model.simulation
    problems = []
    # the stop time is rounded up to a whole interval: an interval longer than a run makes it
    # one sample as long as the interval (1e9 s would be simulated to its end); said once, for
    # the shortest run
    limits = {spec.name: stop_limit(campaign, spec.chain, rover) for spec in campaign.paths}
    wanted = {name: ideal * settings.duration_margin + settings.extra_time
              for name, (_, _, ideal) in limits.items()}
    shortest = min(wanted, key=lambda name: wanted[name]) if wanted else None
    if shortest is not None and settings.output_interval > wanted[shortest]:
        raise UserInputError([error(
            "C404", f"simulation.output_interval: {settings.output_interval:.6g} s is longer "
                    f"than a run of path {shortest} ({wanted[shortest]:.6g} s): a run would be "
                    f"a single output interval, simulated to its end",
            campaign.locations.span(("simulation", "output_interval")),
            hint="an output interval of a fraction of a second (the default 0.1 s)")],
            sources={str(campaign.source): campaign.text})
    interval_said = False
    settings_said: set[tuple[str, ...]] = set()
    for spec in campaign.paths:
        stop, samples, ideal = limits[spec.name]
        if samples <= MAX_SAMPLES:
            continue
        # at the output interval when the run would fit at the default one (said once, for
        # the first path), else at the path when its chain makes it long (a tiny wheel rate),
        # else at the settings stretching it (extra_time, duration_margin)
        if stop / DEFAULT_OUTPUT_INTERVAL <= MAX_SAMPLES:
            if interval_said:
                continue
            interval_said = True
            where: tuple[str, ...] = ("simulation", "output_interval")
        elif ideal * settings.duration_margin > settings.extra_time:
            # the chain, unless it fits with the default margin: then the margin (1e308)
            usual = ideal * DEFAULT_DURATION_MARGIN + settings.extra_time
            where = ("paths", spec.name) if usual / settings.output_interval > MAX_SAMPLES \
                else ("simulation", "duration_margin")
        else:
            where = ("simulation",)
        if where[0] == "simulation":  # a setting stretches every path: said once, at it
            if where in settings_said:
                continue
            settings_said.add(where)
        if math.isfinite(stop):
            length = (f"{samples * settings.output_interval:.6g} s at an output interval of "
                      f"{settings.output_interval:.6g} s: {samples:.3g} samples per run, more "
                      f"than {MAX_SAMPLES}")
        else:
            beyond = ("duration_margin × the chain's duration" if math.isfinite(ideal)
                      else "its chain's duration")
            length = (f"longer than a number can say ({beyond} is beyond a double): more than "
                      f"{MAX_SAMPLES} samples")
        problems.append(error(
            "C404", f"paths.{spec.name}: a run would last {length}",
            campaign.locations.span(where, at_key=where[-1] not in ("output_interval",
                                                                    "duration_margin")),
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


def check_polygons_on_terrain(campaign: Campaign, extent: tuple[float, float, float, float]
                              ) -> None:
    """A keep-out polygon or a named area's polygon must reach the terrain grid: one whose
    every vertex lies beyond one of its edges covers none of it, almost always coordinates in
    another frame (C206, as for a rock). A polygon partly on the terrain is fine."""
    x_min, x_max, y_min, y_max = extent

    def outside(polygon: list[tuple[float, float]]) -> bool:
        xs, ys = [x for x, _ in polygon], [y for _, y in polygon]
        return max(xs) < x_min or min(xs) > x_max or max(ys) < y_min or min(ys) > y_max

    where = f"the terrain (x {x_min:g} … {x_max:g} m, y {y_min:g} … {y_max:g} m)"
    environment = campaign.model.environment
    problems = [
        error("C206", f"environment.keep_out[{index}] ({area.name}) lies entirely outside "
                      f"{where}", campaign.span(("environment", "keep_out", index)),
              hint="polygon vertices are world coordinates, in the terrain's frame")
        for index, area in enumerate(environment.keep_out) if outside(area.polygon)]
    problems += [
        error("C206", f"environment.areas.{name}.polygons[{index}] lies entirely outside "
                      f"{where}",
              campaign.span(("environment", "areas", name, "polygons", index)),
              hint="polygon vertices are world coordinates, in the terrain's frame")
        for name, geometry in environment.areas.items()
        for index, polygon in enumerate(geometry.polygons) if outside(polygon)]
    if problems:
        raise UserInputError(problems, sources={str(campaign.source): campaign.text})


def check_start_on_terrain(campaign: Campaign, extent: tuple[float, float, float, float]
                           ) -> None:
    """The rover's nominal start (``initial.x``, ``initial.y`` of the reference run) must lie
    on the terrain grid ``(x_min, x_max, y_min, y_max)``: off it the rover model would drive on
    the grid's edge heights carried on, a terrain no one gave it."""
    x_min, x_max, y_min, y_max = extent
    nominal = nominal_parameters(campaign)
    x, y = float(nominal.get("initial.x", 0.0)), float(nominal.get("initial.y", 0.0))
    if x_min <= x <= x_max and y_min <= y <= y_max:
        return
    where = [*where_set(campaign, ("initial.x", "initial.y")), ("environment", "terrain")][0]
    raise UserInputError([error(
        "C216", f"the rover starts at ({x:g} m, {y:g} m), outside the terrain (x {x_min:g} … "
                f"{x_max:g} m, y {y_min:g} … {y_max:g} m)", campaign.span(where),
        hint="initial.x and initial.y are world coordinates, in the terrain's frame")],
        sources={str(campaign.source): campaign.text})


def planned_draws(campaign: Campaign, names: Sequence[str]
                  ) -> tuple[int, dict[str, dict[str, np.ndarray]]]:
    """The runs planned per path (an adaptive campaign's cap) and every uncertain parameter's
    draws for them, per path of ``names``: the values the Monte Carlo stage draws (the same
    method, seed and stream), known before any run is simulated."""
    from idefix_rules.campaign.input import sampling

    if campaign.adaptive is not None:
        planned, method = campaign.adaptive.max_runs, sampling.ADAPTIVE_SAMPLING
    else:
        planned, method = campaign.runs, campaign.model.uncertainty.method
    parameters = campaign.model.uncertainty.parameters
    if not parameters:
        return planned, {name: {} for name in names}
    paired = campaign.model.uncertainty.paired
    if paired:  # every path draws the same worlds: drawn once, shared
        shared = sampling.sample_path(parameters, method, campaign.seed,
                                      sampling.path_stream("", True), planned)
        return planned, {name: shared for name in names}
    return planned, {name: sampling.sample_path(parameters, method, campaign.seed,
                                                sampling.path_stream(name, False), planned)
                     for name in names}


def check_drawn_starts_on_terrain(campaign: Campaign,
                                  extent: tuple[float, float, float, float]) -> None:
    """Every planned run's drawn start (``initial.x``, ``initial.y``) must lie on the terrain
    grid, as the nominal one must (C216): off it the rover model drives on the grid's edge
    heights carried on. The first run of the first path off it is named."""
    uncertain = [name for name in INITIAL_POSITION
                 if name in campaign.model.uncertainty.parameters]
    if not uncertain:
        return
    x_min, x_max, y_min, y_max = extent
    nominal = nominal_parameters(campaign)
    planned, draws = planned_draws(campaign, [spec.name for spec in campaign.paths])
    for path, drawn in draws.items():
        x, y = (np.asarray(drawn[name]) if name in drawn
                else np.full(planned, float(nominal.get(name, 0.0))) for name in INITIAL_POSITION)
        off = np.flatnonzero((x < x_min) | (x > x_max) | (y < y_min) | (y > y_max))
        if not off.size:
            continue
        run = int(off[0])
        # at the distribution of the coordinate that leaves the terrain in that run
        x_off = bool(x[run] < x_min or x[run] > x_max)
        axis = next((name for name in (INITIAL_POSITION if x_off else INITIAL_POSITION[::-1])
                     if name in uncertain), uncertain[0])
        raise UserInputError([error(
            "C216", f"run {run} of path {path} starts at ({x[run]:g} m, {y[run]:g} m), outside "
                    f"the terrain (x {x_min:g} … {x_max:g} m, y {y_min:g} … {y_max:g} m): "
                    f"{off.size} of its {planned} planned runs draw a start off it",
            campaign.locations.span(("uncertainty", "parameters", axis), at_key=True),
            hint="narrow the start's distribution, or bound it inside the terrain (a "
                 "truncated_normal with low and high, a uniform); or give a larger terrain")],
            sources={str(campaign.source): campaign.text})


def check_tolerance_start(campaign: Campaign, evaluator: Any, stored: bool = False) -> None:
    """A rulebook that reads the tolerance radius needs an uncertain start position: the radius
    starts at the start position's σ (``docs/derived-signals.md``) and grows only while a
    chain turns, so with σ = 0 a chain that does not turn (or any chain, without
    ``tolerance_growth``) divides every run's drift by 0 and every run is critical, for no
    reason of its own (C219, at the campaign's ``uncertainty``, naming those chains); chains
    that all turn are let through. ``stored``: the campaign of a results file (the hint then
    says to run it again)."""
    if "tolerance_radius" not in evaluator.signals_read:
        return
    if initial_position_sigma(campaign) > 0.0:
        return
    # a chain that turns grows the radius above 0 (tolerance_growth per radian): only the
    # chains that never turn, or every chain without a growth, keep it at 0 to their end
    growth = float(evaluator.derived_settings.tolerance_growth)
    straight = [spec.name for spec in campaign.paths
                if growth <= 0.0 or not any(command.delta_heading != 0.0
                                            for command in spec.chain)]
    if not straight:
        return
    given = [name for name in INITIAL_POSITION
             if name in campaign.model.uncertainty.parameters]
    where = ("uncertainty", "parameters", given[0]) if given else ("uncertainty",)
    name = evaluator.name
    certain = f"{' and '.join(given)} fixed" if given else \
        "initial.x and initial.y are not uncertain"
    shown = ", ".join(straight[:3]) + (f" and {len(straight) - 3} more"
                                       if len(straight) > 3 else "")
    why = "no tolerance_growth" if growth <= 0.0 else "chains that do not turn"
    raise UserInputError([error(
        "C219", f"rulebook {name} reads the tolerance radius, which starts at the start "
                "position's standard deviation, and this campaign's start position is certain "
                f"({certain}): with {why} ({shown}) the radius stays 0, so a run's drift "
                "over it is infinite and every run critical",
        campaign.locations.span(where, at_key=True),
        hint=("give the start position its uncertainty, e.g. `initial.x: {distribution: "
              "normal, mean: \"0 m\", std: \"1 cm\"}` and the same for initial.y"
              + (", and run the campaign again" if stored else "")
              + ", or judge with a rulebook whose indices do not read tolerance_radius"))],
        sources={str(campaign.source): campaign.text})


def check_paths_on_terrain(campaign: Campaign, extent: tuple[float, float, float, float]
                           ) -> None:
    """Every chain executed ideally (no slip) from the nominal start pose must keep the rover's
    wheels on the terrain grid ``(x_min, x_max, y_min, y_max)``: where a wheel leaves it the
    model drives on the grid's edge heights carried on, a terrain no one gave it (C218, at the
    path, naming the command and the point)."""
    import numpy as np

    from idefix_rules.commands import command_kinematics, ideal_poses

    x_min, x_max, y_min, y_max = extent
    nominal = nominal_parameters(campaign)
    pose = (float(nominal.get("initial.x", 0.0)), float(nominal.get("initial.y", 0.0)),
            float(nominal.get("initial.yaw", 0.0)))
    rover = rover_geometry(campaign)
    # the wheels' contact points about the body centre, in the body frame
    corners = [(sx * rover.half_wheelbase, sy * rover.half_track)
               for sx in (1.0, -1.0) for sy in (1.0, -1.0)]
    problems = []
    for spec in campaign.paths:
        durations = [command_kinematics(c, rover).duration for c in spec.chain]
        if not all(math.isfinite(d) for d in durations) or sum(durations) <= 0.0:
            continue
        # each command sampled on its own, every centimetre of travel and every 0.02 rad turned
        # (a wheel moves 7 mm), whatever its duration: a slow short command before a fast
        # turn must not take the turn's samples
        times, numbers, start = [np.zeros(1)], [np.zeros(1, dtype=np.int64)], 0.0
        for number, (command, duration) in enumerate(zip(spec.chain, durations, strict=True)):
            if duration <= 0.0:
                continue
            count = int(min(20_000, 2 + abs(command.delta_position) / 0.01
                            + abs(command.delta_heading) / 0.02))
            times.append(np.linspace(start, start + duration, count)[1:])
            numbers.append(np.full(count - 1, number + 1))
            start += duration
        t, commanded = np.concatenate(times), np.concatenate(numbers)
        poses = ideal_poses(spec.chain, rover, t, start=pose)
        cos, sin = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        off = np.zeros(t.size, dtype=bool)
        where = np.zeros((t.size, 2))
        for along, across in corners:
            wx = poses[:, 0] + along * cos - across * sin
            wy = poses[:, 1] + along * sin + across * cos
            out = ((wx < x_min) | (wx > x_max) | (wy < y_min) | (wy > y_max)) & ~off
            where[out] = np.column_stack((wx, wy))[out]
            off |= out
        if not off.any():
            continue
        first = int(np.argmax(off))
        when = "at the start, before any command" if commanded[first] == 0 \
            else f"during command {commanded[first]}"
        problems.append(error(
            "C218", f"paths.{spec.name}: driven as commanded from the nominal start, the "
                    f"rover's wheels leave the terrain (x {x_min:g} … {x_max:g} m, y "
                    f"{y_min:g} … {y_max:g} m) {when}, at ({where[first, 0]:g} m, "
                    f"{where[first, 1]:g} m)",
            campaign.locations.span(("paths", spec.name), at_key=True),
            hint="give a terrain that holds the whole drive (a larger synthetic size, or a "
                 "larger DEM), or a shorter chain"))
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
    if loc[:2] == ("environment", "regolith") and name.startswith(REGOLITH_PREFIX) \
            and loc[-1] == name[len(REGOLITH_PREFIX):]:
        return _unknown_regolith(campaign, loc, name, known, fmu_path)
    # a variable's own name without its group (`k_c` for `soil.k_c`) first, then spelling
    grouped = sorted(n for n in known if "." not in name and n.rsplit(".", 1)[-1] == name)
    close = grouped[:1] or difflib.get_close_matches(name, list(known), n=1)
    hint = f"did you mean {close[0]!r}?" if close else None
    if grouped:
        hint = f"{hint} (a variable is named with its group)"
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
