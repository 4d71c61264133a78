"""The campaign's environment for the FMU (terrain file) and for the obstacle checker.

Rocks are written into the terrain file the FMU reads, and the obstacle checker takes the rocks
back from that terrain (heights resolved on the ground), so both see the same rocks. Rock levels
come from the rock's explicit ``level``, else from the campaign's ``rock_levels`` thresholds,
else from the rulebook's obstacle levels; buffer margins come from the rulebook.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from idefix_rules.campaign.input.environment_section import EnvironmentSection, SyntheticTerrain

TERRAIN_FILE = "terrain.dem"


def build_terrain(environment: EnvironmentSection, dem: Path | None) -> Any:
    """The :class:`~idefix_rules.fmu.terrain.Terrain` of the campaign, rocks included."""
    from idefix_rules.fmu import terrain as terrain_module

    rocks = []
    for rock in environment.rocks:
        a, b, c = rock.axes
        rocks.append(terrain_module.Rock(x=rock.x, y=rock.y, a=a, b=b, c=c, embed=rock.embed,
                                         level=rock.level))
    section = environment.terrain
    if dem is not None:
        return terrain_module.load_dem(dem, cell=section.cell, origin=section.origin,
                                       rocks=rocks)
    settings = section.synthetic or SyntheticTerrain()
    return terrain_module.synthetic_terrain(
        size=settings.size, cell=settings.cell, slope=settings.slope,
        slope_direction=settings.slope_direction, roughness=settings.roughness,
        seed=settings.seed, rocks=rocks)


def write_terrain(terrain: Any, folder: Path) -> Path:
    """Write the terrain file the FMU reads into the output folder."""
    from idefix_rules.fmu import terrain as terrain_module

    folder.mkdir(parents=True, exist_ok=True)
    return Path(terrain_module.write_terrain(folder / TERRAIN_FILE, terrain))


def read_terrain(folder: Path) -> Any | None:
    """The terrain a stored campaign used (None when its file is gone)."""
    from idefix_rules.fmu import terrain as terrain_module

    path = folder / TERRAIN_FILE
    return terrain_module.read_terrain(path) if path.is_file() else None


def _thresholds(environment: EnvironmentSection, evaluator: Any) -> Any:
    from idefix_rules.obstacles.obstacles import LevelThresholds

    if environment.rock_levels is not None:
        return LevelThresholds(environment.rock_levels.l1_max_size,
                               environment.rock_levels.l2_max_size)
    levels = {spec.level: spec.below for spec in getattr(evaluator, "obstacle_levels", ())}
    if levels.get("L1") is not None and levels.get("L2") is not None:
        return LevelThresholds(float(levels["L1"]), float(levels["L2"]))
    return None


def buffer_margins(evaluator: Any) -> dict[str, float]:
    return {spec.level: float(spec.buffer) for spec in getattr(evaluator, "obstacle_levels", ())}


def declared_areas(evaluator: Any) -> tuple[Any, ...]:
    """The rulebook's named areas (:class:`~idefix_rules.rulebook.check.AreaSpec`)."""
    checked = getattr(evaluator, "checked", evaluator)
    return tuple(getattr(checked, "areas", ()))


def named_areas(environment: EnvironmentSection, evaluator: Any, terrain: Any
                ) -> dict[str, Any]:
    """Every area the rulebook declares with the geometry the campaign gives it (keep-out and
    unknown: its polygons, none when it gives none; steep: the terrain above the inclination)."""
    from idefix_rules.obstacles.named import AreaGeometry, steep_area

    found: dict[str, Any] = {}
    for spec in declared_areas(evaluator):
        if spec.kind == "steep":
            if terrain is None:  # flat datum: nothing is steep
                found[spec.name] = AreaGeometry(spec.name, spec.level, spec.buffer, kind="steep")
            else:
                found[spec.name] = steep_area(spec.name, spec.level, spec.buffer, spec.above,
                                              terrain.heights, terrain.origin, terrain.cell)
            continue
        given = environment.areas.get(spec.name)
        polygons = tuple(np.asarray(polygon, dtype=float) for polygon in
                         (given.polygons if given is not None else []))
        found[spec.name] = AreaGeometry(spec.name, spec.level, spec.buffer, polygons,
                                        kind=spec.kind)
    return found


def obstacle_set(environment: EnvironmentSection, evaluator: Any, terrain: Any) -> Any:
    """The :class:`~idefix_rules.obstacles.ObstacleSet` of the terrain's rocks, keep-out areas
    and the rulebook's named areas (``terrain`` None: the campaign's rocks resting on the
    datum)."""
    from idefix_rules.obstacles.areas import height_range, polygon_area
    from idefix_rules.obstacles.obstacles import ObstacleSet

    if terrain is not None:
        rocks: list[Any] = list(terrain.rocks)
        ground = (lambda x, y: float(terrain.height_at(x, y)))  # noqa: E731
    else:
        rocks = [{"x": r.x, "y": r.y, "z": r.axes[2] - r.embed, "a": r.axes[0], "b": r.axes[1],
                  "c": r.axes[2], "level": r.level} for r in environment.rocks]
        ground = None
    obstacles = ObstacleSet.from_rocks(rocks, _thresholds(environment, evaluator),
                                       buffer_margins(evaluator), ground)
    heights = terrain.heights if terrain is not None else None
    areas = [polygon_area([tuple(p) for p in area.polygon], area.level, area.name,
                          ground=height_range(heights))
             for area in environment.keep_out]
    for area in named_areas(environment, evaluator, terrain).values():
        areas += area.obstacles(heights)
    return obstacles.extended(areas) if areas else obstacles
