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


def map_environment(campaign_text: str, checked: Any | None,
                    terrain: Any = None) -> tuple[MapEnvironment, list[str]]:
    """Rocks, keep-out areas and terrain areas of a stored campaign; notes say what is left out.

    The obstacles come from the campaign's own obstacle set (the one its evaluation checks:
    rocks of the terrain file with their levels, keep-out polygons); rock footprints are the
    horizontal extent of the rock's geometry. Without it, the campaign's rocks are drawn with
    their explicit level or '?'.
    """
    from idefix_rules.campaign.input.environment_section import EnvironmentSection
    from idefix_rules.campaign.input.yamlsource import yaml_data

    notes: list[str] = []
    try:
        data = yaml_data(campaign_text) or {}
        environment = EnvironmentSection.model_validate(
            data.get("environment", {}) if isinstance(data, dict) else {})
    except Exception as failure:  # a stored campaign the current schema no longer reads
        return MapEnvironment(), [f"obstacles not drawn: the stored campaign's environment "
                                  f"could not be read ({type(failure).__name__})"]
    margins = {spec.level: float(spec.buffer) for spec in
               getattr(checked, "obstacle_levels", ())}
    areas = [AreaShape(area.name, np.array(area.polygon, dtype=float), area.level,
                       margins.get(area.level, 0.0)) for area in environment.keep_out]
    # the polygons the campaign gives the rulebook's keep-out and unknown areas, with the
    # area's own level and buffer (steep areas come from the terrain, below)
    from idefix_rules.campaign.input.environment import named_areas

    if checked is not None:
        areas += [AreaShape(area.name if number == 0 else "", polygon, area.level,
                            float(area.buffer))
                  for area in named_areas(environment, checked, None).values()
                  for number, polygon in enumerate(area.polygons)]
    try:
        from idefix_rules.campaign.input.environment import obstacle_set

        obstacles = obstacle_set(environment, checked, terrain).obstacles
    except Exception as failure:
        notes.append(f"rock levels not assigned ({type(failure).__name__}: {failure}): rocks "
                     "without an explicit level are drawn as '?'")
        rocks = [RockShape(f"rock{n + 1}", rock.x, rock.y, rock.axes[0], rock.axes[1],
                           rock.level or "?", margins.get(rock.level or "", 0.0))
                 for n, rock in enumerate(environment.rocks)]
        return MapEnvironment(tuple(rocks), tuple(areas)), notes
    rocks = []
    for obstacle in obstacles:
        if obstacle.kind == "polygon":
            continue  # drawn from the campaign's polygon, with its buffer
        lower = np.min([piece.lower for piece in obstacle.pieces], axis=0)
        upper = np.max([piece.upper for piece in obstacle.pieces], axis=0)
        centre, half = (lower + upper) / 2.0, (upper - lower) / 2.0
        level = obstacle.level_name
        if obstacle.kind == "rock":
            rocks.append(RockShape(obstacle.name, float(centre[0]), float(centre[1]),
                                   float(half[0]), float(half[1]), level,
                                   margins.get(level, 0.0)))
        else:  # steep or unknown terrain: its cells' outline
            for number, piece in enumerate(obstacle.pieces):
                x0, y0, x1, y1 = piece.lower[0], piece.lower[1], piece.upper[0], piece.upper[1]
                areas.append(AreaShape(f"{obstacle.name}" if number == 0 else "",
                                       np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]),
                                       level, 0.0))
    return MapEnvironment(tuple(rocks), tuple(areas)), notes
