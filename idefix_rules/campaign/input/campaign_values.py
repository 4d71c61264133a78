"""What a campaign says of the rover and its runs: nominal values, geometry, σ, stop time."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from idefix_rules.campaign.input.load import Campaign
from idefix_rules.commands import Command, RoverGeometry, chain_duration
from idefix_rules.units import ANGLE, ANGULAR_RATE, LENGTH, TIME, Dimension

# Campaign regolith keys are the FMU's soil parameters without their prefix.
REGOLITH_PREFIX = "soil."
GEOMETRY_PARAMETERS = {"rover.wheel_radius": "wheel_radius", "rover.half_track": "half_track",
                       "rover.half_wheelbase": "half_wheelbase",
                       "controller.wheel_acceleration": "wheel_acceleration"}
INITIAL_POSITION = ("initial.x", "initial.y")


@dataclass(frozen=True)
class ContractParameter:
    """A campaign parameter the tool reads itself, whatever FMU it is mapped to: its dimension,
    the SI unit its value is read in, and what it is."""

    dimension: Dimension
    unit: str
    what: str


# The start pose (terrain checks, the tolerance radius, the report's units) and the kinematic
# geometry (the chain's ideal durations, its set-points, the stop time): a value of another
# dimension would be read as these SI units (5 s as 5 m) even where the FMU declares no unit.
CONTRACT_PARAMETERS: dict[str, ContractParameter] = {
    "initial.x": ContractParameter(LENGTH, "m", "the rover's start position"),
    "initial.y": ContractParameter(LENGTH, "m", "the rover's start position"),
    "initial.yaw": ContractParameter(ANGLE, "rad", "the rover's start heading"),
    "rover.wheel_radius": ContractParameter(LENGTH, "m", "the rover's geometry"),
    "rover.half_track": ContractParameter(LENGTH, "m", "the rover's geometry"),
    "rover.half_wheelbase": ContractParameter(LENGTH, "m", "the rover's geometry"),
    "controller.wheel_acceleration": ContractParameter(ANGULAR_RATE / TIME, "rad/s^2",
                                                       "the controller's wheel ramp"),
}


def stop_limit(campaign: Campaign, chain: Sequence[Command], rover: RoverGeometry
               ) -> tuple[float, int, float]:
    """When a run of ``chain`` is stopped: (stop time, output samples, ideal duration). The stop
    time is the chain's ideal duration × ``duration_margin`` + ``extra_time``, rounded up to a
    whole output interval (``docs/campaign-format.md``, "simulation")."""
    settings = campaign.model.simulation
    ideal = chain_duration(tuple(chain), rover)
    raw_stop = ideal * settings.duration_margin + settings.extra_time
    if not math.isfinite(raw_stop / settings.output_interval):  # longer than a double holds
        return math.inf, UNBOUNDED_SAMPLES, ideal
    steps = max(1, math.ceil(raw_stop / settings.output_interval - 1e-9))
    return steps * settings.output_interval, steps + 1, ideal


# The sample count of a run whose stop time is beyond a double (a command 1e308 m long): more
# than any limit, so it is refused before anything is simulated.
UNBOUNDED_SAMPLES = 2 ** 63


def rover_geometry(campaign: Campaign) -> RoverGeometry:
    """Kinematic geometry: defaults, or fixed/nominal values the campaign gives."""
    values = nominal_parameters(campaign)
    overrides = {field_name: float(values[name]) for name, field_name in
                 GEOMETRY_PARAMETERS.items() if name in values}
    return RoverGeometry(**overrides)


def tool_only_parameters(campaign: Campaign, settable: Iterable[str]) -> frozenset[str]:
    """The geometry names the campaign gives (``rover.half_track`` …, as a regolith value or a
    fixed parameter) that the FMU has no settable variable for, by that name or mapped in
    ``fmu.parameters``: values the tool alone reads (the set-points, the ideal durations, the
    stop time), never set in the FMU. The tool reads one geometry per campaign: a drawn value
    is no tool-only value (the FMU must take it, else C401).
    A foreign FMU with a geometry of its own is described so (docs/bring-your-own-fmu.md)."""
    mapped = set((campaign.model.fmu.parameters or {}).values())
    takes = set(settable) | mapped
    given = {regolith_parameter(key) for key in campaign.model.environment.regolith}
    given |= {name for name, spec in campaign.model.uncertainty.parameters.items()
              if spec.distribution == "fixed"}  # a drawn value would reach no run
    return frozenset(name for name in given & set(GEOMETRY_PARAMETERS) if name not in takes)


def regolith_parameter(key: str) -> str:
    """The FMU parameter a regolith key sets: ``cohesion`` → ``soil.cohesion``; a name with a
    dot as given."""
    return key if "." in key else REGOLITH_PREFIX + key


def where_set(campaign: Campaign, names: Iterable[str]) -> list[tuple[str | int, ...]]:
    """Where the campaign sets any of the FMU parameters ``names``: an uncertain parameter
    (which overrides a fixed value per run) before a regolith value."""
    wanted = set(names)
    model = campaign.model
    places: list[tuple[str | int, ...]] = [
        ("uncertainty", "parameters", name) for name in model.uncertainty.parameters
        if name in wanted]
    places += [("environment", "regolith", key) for key in model.environment.regolith
               if regolith_parameter(key) in wanted]
    return places


def nominal_parameters(campaign: Campaign) -> dict[str, float]:
    """Parameter values of the reference run: regolith values, then uncertainty nominals."""
    from idefix_rules.campaign.input.sampling import nominal_values  # scipy: only when needed

    values = {regolith_parameter(key): value
              for key, value in campaign.model.environment.regolith.items()}
    values.update(nominal_values(campaign.model.uncertainty.parameters))
    return values


def initial_position_sigma(campaign: Campaign) -> float:
    """σ of the initial position (the larger of x and y): the starting tolerance radius."""
    from idefix_rules.campaign.input.sampling import standard_deviation

    parameters = campaign.model.uncertainty.parameters
    sigmas = [standard_deviation(parameters[name]) for name in INITIAL_POSITION
              if name in parameters]
    return max(sigmas, default=0.0)
