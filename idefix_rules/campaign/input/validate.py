"""Checks of a campaign before anything is simulated: the size of its runs, a start position
certain where the rulebook needs it uncertain, the output folder. Mistakes point at the
campaign line.

The FMU's parameters are checked in :mod:`idefix_rules.campaign.input.parameter_checks`, the
rest of the FMU mapping in :mod:`idefix_rules.campaign.input.fmu_checks` (its signal map in
:mod:`~idefix_rules.campaign.input.signal_map_checks`, its chain delivery in
:mod:`~idefix_rules.campaign.input.chain_checks`), what lies on the terrain in
:mod:`idefix_rules.campaign.input.terrain_checks`.
"""

from __future__ import annotations

import math
import os
import tempfile
from typing import Any

from idefix_rules.campaign.input.campaign_values import (
    CONTRACT_PARAMETERS,
    GEOMETRY_PARAMETERS,
    INITIAL_POSITION,
    initial_position_sigma,
    nominal_parameters,
    regolith_parameter,
    rover_geometry,
    where_set,
)
from idefix_rules.campaign.input.load import Campaign
from idefix_rules.campaign.input.schema import DEFAULT_DURATION_MARGIN
from idefix_rules.campaign.input.yamlsource import format_loc
from idefix_rules.errors import Span, UserInputError, error

# Output samples per run: 300 s at 10 Hz is 3000; a million means a stop time or output interval
# off by orders of magnitude, which would exhaust memory rather than simulate.
MAX_SAMPLES = 1_000_000

# The output interval a campaign gets when it gives none (schema.SimulationSection), s.
DEFAULT_OUTPUT_INTERVAL = 0.1


def check_geometry(campaign: Campaign) -> bool:
    """The rover geometry the tool reads (``rover.wheel_radius``, ``rover.half_track``,
    ``rover.half_wheelbase``: positive lengths; ``controller.wheel_acceleration``: not
    negative), as the campaign gives it (its nominal value); True when sound: a chain's ideal
    durations, set-points and the collision bodies are computed from them before any FMU
    range is looked at. A regolith key given under its short and its full name (``cohesion`` and
    ``soil.cohesion``) is refused too: one of the two would be dropped without a word."""
    problems = []
    seen: dict[str, str] = {}
    for key in campaign.model.environment.regolith:
        name = regolith_parameter(key)
        if name in seen:
            loc: tuple[str | int, ...] = ("environment", "regolith", key)
            problems.append(error(
                "C100", f"{format_loc(loc)}: sets {name} again (as {seen[name]!r} above); "
                        "one of the two values would be dropped",
                campaign.locations.span(loc, at_key=True),
                hint="give each parameter once"))
        seen.setdefault(name, key)
    values = nominal_parameters(campaign)
    for name in GEOMETRY_PARAMETERS:
        if name not in values:
            continue
        value = float(values[name])
        acceleration = name == "controller.wheel_acceleration"
        if math.isfinite(value) and (value >= 0 if acceleration else value > 0):
            continue
        places = where_set(campaign, [name])
        where: tuple[str | int, ...] = places[0] if places else ("environment", "regolith")
        if where[0] == "uncertainty":  # at the distribution's nominal: its value, mean, median
            spec = campaign.model.uncertainty.parameters[name]
            nominal_key = next((key for key in ("value", "mean", "median")
                                if hasattr(spec, key)), None)
            where = (*where, nominal_key) if nominal_key is not None else where
        contract = CONTRACT_PARAMETERS[name]
        wanted = "not negative" if acceleration else "a positive length"
        problems.append(error(
            "C221", f"{format_loc(where)}: {name} is {contract.what}: it must be {wanted}, got "
                    f"{value:g} {contract.unit}", campaign.span(where)))
    if problems:
        raise UserInputError(problems, sources={str(campaign.source): campaign.text})
    return True


def check_simulation_size(campaign: Campaign) -> None:
    """Refuse a run longer than :data:`MAX_SAMPLES` output samples before simulating."""
    from idefix_rules.campaign.input.campaign_values import stop_limit

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
        else:  # extra_time, which only a value written makes this long
            where = ("simulation", "extra_time")
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
            campaign.locations.span(where, at_key=where[0] == "paths"),
            hint="stop time = chain duration × duration_margin + extra_time; check the "
                 "simulation section and the chain's wheel rates"))
    if problems:
        raise UserInputError(problems, sources={str(campaign.source): campaign.text})



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



def prepare_output(campaign: Campaign) -> None:
    """Create the output folder, or say why it cannot be (a file, no permission …)."""
    folder = campaign.output
    from_file = folder == (campaign.source.parent / campaign.model.output).resolve()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        # a probe of this process's own: two campaigns started together each remove theirs
        # (a shared name: one removed the other's, which then failed as "No such file")
        handle, probe = tempfile.mkstemp(prefix=".idefix-write-test-", dir=folder)
        os.close(handle)
        os.unlink(probe)
    except OSError as failure:
        reason = ("it is a file" if folder.is_file() or isinstance(failure, FileExistsError)
                  else failure.strerror or str(failure))
        raise UserInputError(error(
            "C205", f"output folder {folder} cannot be used: {reason}",
            campaign.span(("output",)) if from_file else Span(str(folder)),
            hint=None if from_file else "given by --out"),
            sources={str(campaign.source): campaign.text}) from None

