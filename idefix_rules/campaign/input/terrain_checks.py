"""What a campaign places must lie on its terrain: rocks, areas, starts, the driven chains."""

from __future__ import annotations

import math

import numpy as np

from idefix_rules.campaign.input.campaign_values import (
    INITIAL_POSITION,
    nominal_parameters,
    rover_geometry,
    where_set,
)
from idefix_rules.campaign.input.load import Campaign
from idefix_rules.campaign.input.sampling import planned_draws
from idefix_rules.errors import UserInputError, error


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
        if not polygon:  # no vertex: no polygon at all, said as such (C209), not as outside
            return False
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
    # at the coordinate that is off (x when both are), where the campaign gives it
    off = [name for name, value, low, high in (("initial.x", x, x_min, x_max),
                                               ("initial.y", y, y_min, y_max))
           if not low <= value <= high]
    where = [*where_set(campaign, off), ("environment", "terrain")][0]
    raise UserInputError([error(
        "C216", f"the rover starts at ({x:g} m, {y:g} m), outside the terrain (x {x_min:g} … "
                f"{x_max:g} m, y {y_min:g} … {y_max:g} m)", campaign.span(where),
        hint="initial.x and initial.y are world coordinates, in the terrain's frame")],
        sources={str(campaign.source): campaign.text})


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

