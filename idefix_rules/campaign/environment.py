"""The campaign's environment for the FMU (terrain file) and for the obstacle checker.

Rocks are written once into the terrain file the FMU reads and turned into the obstacle set the
collision checker uses, from the same list, so both see the same rocks. Rock levels come from
the rock's explicit ``level``, else from the campaign's ``rock_levels`` thresholds, else from
the rulebook's obstacle levels; buffer margins come from the rulebook.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from idefix_rules.campaign.schema import EnvironmentSection, RockSpec

TERRAIN_FILE = "terrain.dem"


def rock_records(environment: EnvironmentSection,
                 ground: Any = None) -> list[dict[str, Any]]:
    """Rocks as plain records: centre (z from the ground and embedding), semi-axes, level."""
    records = []
    for number, rock in enumerate(environment.rocks):
        a, b, c = rock.axes
        base = float(ground(rock.x, rock.y)) if ground is not None else 0.0
        records.append({
            "name": f"rock{number + 1}",
            "x": rock.x, "y": rock.y, "z": base + c - rock.embed,
            "a": a, "b": b, "c": c,
            "embed": rock.embed,
            "level": rock.level,
        })
    return records


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


def obstacle_set(environment: EnvironmentSection, evaluator: Any,
                 ground: Any = None) -> Any:
    """The :class:`~idefix_rules.obstacles.ObstacleSet` of rocks and keep-out areas."""
    from idefix_rules.obstacles.areas import polygon_area
    from idefix_rules.obstacles.obstacles import ObstacleSet

    obstacles = ObstacleSet.from_rocks(rock_records(environment, ground),
                                       _thresholds(environment, evaluator),
                                       buffer_margins(evaluator), ground)
    areas = [polygon_area([tuple(p) for p in area.polygon], area.level, area.name)
             for area in environment.keep_out]
    return obstacles.extended(areas) if areas else obstacles


def write_terrain(environment: EnvironmentSection, dem: Path | None, folder: Path) -> Path:
    """Write the terrain file the FMU reads (synthetic or from the user's DEM, plus rocks)."""
    from idefix_rules.fmu import terrain as terrain_module

    folder.mkdir(parents=True, exist_ok=True)
    target = folder / TERRAIN_FILE
    rocks = [_fmu_rock(terrain_module, rock) for rock in environment.rocks]
    if dem is not None:
        surface = terrain_module.read_terrain(dem)
        surface = _with_rocks(surface, rocks)
    else:
        settings = environment.terrain.synthetic
        if settings is None:
            from idefix_rules.campaign.schema import SyntheticTerrain

            settings = SyntheticTerrain()
        surface = terrain_module.synthetic_terrain(
            size=settings.size, cell=settings.cell, slope=settings.slope,
            slope_direction=settings.slope_direction, roughness=settings.roughness,
            seed=settings.seed, rocks=rocks)
    terrain_module.write_terrain(target, surface)
    return target


def _fmu_rock(terrain_module: Any, rock: RockSpec) -> Any:
    a, b, c = rock.axes
    return terrain_module.Rock(x=rock.x, y=rock.y, a=a, b=b, c=c, embed=rock.embed,
                               level=rock.level)


def _with_rocks(surface: Any, rocks: list[Any]) -> Any:
    import dataclasses

    if not rocks:
        return surface
    return dataclasses.replace(surface, rocks=tuple((*surface.rocks, *rocks)))


def ground_function(terrain_path: Path | None) -> Any:
    """Height of the terrain at (x, y), for rock levels and centres; None if unknown."""
    if terrain_path is None or not terrain_path.exists():
        return None
    try:
        from idefix_rules.fmu import terrain as terrain_module

        surface = terrain_module.read_terrain(terrain_path)
    except Exception:
        return None
    height = getattr(surface, "height_at", None)
    if callable(height):
        return lambda x, y: float(height(x, y))
    heights = np.asarray(surface.heights)
    origin = surface.origin
    cell = surface.cell

    def nearest(x: float, y: float) -> float:
        col = round((x - origin[0]) / cell)
        row = round((y - origin[1]) / cell)
        row = min(max(row, 0), heights.shape[0] - 1)
        col = min(max(col, 0), heights.shape[1] - 1)
        return float(heights[row, col])

    return nearest
