"""Obstacles to draw on the result map, from the campaign text stored in the results file.

Rocks are drawn as their footprint ellipse (semi-axes ``a``, ``b`` around ``x``, ``y``) and
their buffer zone as the footprint grown by the buffer margin of the rock's level. Keep-out areas
are polygons; their buffer zone (all points closer than the margin) is drawn as the 0.5 contour
of a distance mask computed on a fine grid, which is exact up to the grid step for any polygon,
convex or not. Levels and margins come from the same place the evaluation takes them from: the
rock's explicit level, else the campaign's ``rock_levels``, else the rulebook's obstacle levels.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import yaml

LEVEL_NAMES = ("L1", "L2", "L3")


@dataclass(frozen=True)
class RockShape:
    name: str
    x: float
    y: float
    a: float
    b: float
    level: str  # L1, L2, L3 or "?" when no level could be assigned
    buffer: float


@dataclass(frozen=True)
class AreaShape:
    name: str
    polygon: np.ndarray  # (vertices, 2)
    level: str
    buffer: float


@dataclass(frozen=True)
class MapEnvironment:
    rocks: tuple[RockShape, ...] = ()
    areas: tuple[AreaShape, ...] = ()

    def bounds(self) -> tuple[float, float, float, float] | None:
        """(xmin, xmax, ymin, ymax) of every obstacle with its buffer; None when empty."""
        boxes = [(r.x - r.a - r.buffer, r.x + r.a + r.buffer, r.y - r.b - r.buffer,
                  r.y + r.b + r.buffer) for r in self.rocks]
        boxes += [(float(a.polygon[:, 0].min()) - a.buffer, float(a.polygon[:, 0].max())
                   + a.buffer, float(a.polygon[:, 1].min()) - a.buffer,
                   float(a.polygon[:, 1].max()) + a.buffer) for a in self.areas]
        if not boxes:
            return None
        array = np.array(boxes)
        return (float(array[:, 0].min()), float(array[:, 1].max()), float(array[:, 2].min()),
                float(array[:, 3].max()))


def _segment_distance(px: np.ndarray, py: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Distance of points to the polygon's boundary."""
    best = np.full(px.shape, np.inf)
    for start, end in zip(polygon, np.roll(polygon, -1, axis=0), strict=True):
        edge = end - start
        length2 = float(edge @ edge) or 1e-300
        s = np.clip(((px - start[0]) * edge[0] + (py - start[1]) * edge[1]) / length2, 0, 1)
        best = np.minimum(best, np.hypot(px - start[0] - s * edge[0],
                                         py - start[1] - s * edge[1]))
    return best


def buffer_mask(area: AreaShape, step: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(xs, ys, mask): 1 where a point is inside the area or closer than its buffer."""
    from matplotlib.path import Path as PolygonPath  # geometry only, no drawing

    margin = area.buffer + 2 * step
    xs = np.arange(area.polygon[:, 0].min() - margin, area.polygon[:, 0].max() + margin, step)
    ys = np.arange(area.polygon[:, 1].min() - margin, area.polygon[:, 1].max() + margin, step)
    gx, gy = np.meshgrid(xs, ys)
    inside = PolygonPath(area.polygon).contains_points(np.c_[gx.ravel(), gy.ravel()])
    near = _segment_distance(gx, gy, area.polygon) <= area.buffer
    return xs, ys, (inside.reshape(gx.shape) | near).astype(float)


def map_environment(campaign_text: str, checked: Any | None) -> tuple[MapEnvironment, list[str]]:
    """Rocks and keep-out areas of a stored campaign; notes explain anything left out."""
    from idefix_rules.campaign.schema import EnvironmentSection

    notes: list[str] = []
    try:
        data = yaml.safe_load(campaign_text) or {}
        environment = EnvironmentSection.model_validate(
            data.get("environment", {}) if isinstance(data, dict) else {})
    except Exception as failure:  # a stored campaign the current schema no longer reads
        return MapEnvironment(), [f"obstacles not drawn: the stored campaign's environment "
                                  f"could not be read ({type(failure).__name__})"]
    margins = {spec.level: float(spec.buffer) for spec in
               getattr(checked, "obstacle_levels", ())}
    levels = _rock_levels(environment, checked, notes)
    rocks = []
    for number, rock in enumerate(environment.rocks):
        a, b, _ = rock.axes
        name = f"rock{number + 1}"
        level = rock.level or levels.get(name, "?")
        rocks.append(RockShape(name, rock.x, rock.y, a, b, level, margins.get(level, 0.0)))
    areas = [AreaShape(area.name, np.array(area.polygon, dtype=float), area.level,
                       margins.get(area.level, 0.0)) for area in environment.keep_out]
    return MapEnvironment(tuple(rocks), tuple(areas)), notes


def _rock_levels(environment: Any, checked: Any | None, notes: list[str]) -> dict[str, str]:
    """Levels the obstacle checker assigns (by rock name), from the campaign's environment."""
    if not environment.rocks:
        return {}
    try:
        from idefix_rules.campaign.environment import obstacle_set

        obstacles = obstacle_set(environment, checked)
        return {obstacle.name: obstacle.level_name for obstacle in obstacles.obstacles}
    except Exception as failure:
        notes.append(f"rock levels not assigned from sizes ({type(failure).__name__}): "
                     "rocks without an explicit level are drawn as '?'")
        return {}
