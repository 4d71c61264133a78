"""The rulebook's named areas (keep-out, steep, unknown surface) on the ground, and their signals.

A rulebook declares an area by name, kind, obstacle level and buffer
(``area crater keep_out level L3 buffer 10 cm``); the campaign gives its geometry: polygons or a
mask on the terrain's grid for keep-out and unknown areas, and nothing for a steep area, which
is where the terrain's inclination (central differences of the heights, rocks excluded) exceeds
the rulebook's ``above``. Each area is

* an obstacle of its level for the collision check (the same prisms as every other area,
  :mod:`.areas`), so ``collision.*`` and the obstacle index count it, and
* two signals per run and sample from the rover's pose: ``area.NAME.inside`` (1 while a wheel's
  ground contact point lies in the area) and ``area.NAME.buffer`` (1 while one lies within the
  area's buffer of it, inside included).

Contact points are the wheel centres projected on the ground plane, at ``(±half_wheelbase,
±half_track)`` in the body frame turned by the yaw. Polygons are exact (even-odd rule, distance
to the edges); masks are read at the grid's resolution: a point belongs to the cell whose node
is nearest, and a cell is within the buffer when its node is within the buffer of a flagged
node.

>>> square = np.array([[1.0, -1.0], [2.0, -1.0], [2.0, 1.0], [1.0, 1.0]])
>>> area = AreaGeometry("crater", "L3", 0.1, polygons=(square,))
>>> x = np.array([[0.0, 0.75, 0.9]])  # front wheels at 0.2, 0.95 and 1.1 m
>>> inside, near = area_signals(area, x, 0 * x, 0 * x, RoverGeometry())
>>> inside.tolist(), near.tolist()
([[0.0, 0.0, 1.0]], [[0.0, 1.0, 1.0]])
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from idefix_rules.commands import RoverGeometry
from idefix_rules.obstacles.areas import (
    height_range,
    polygon_area,
    steep_mask,
    unknown_terrain,
)
from idefix_rules.obstacles.obstacles import Obstacle


@dataclass(frozen=True)
class AreaGeometry:
    """One named area on the ground: polygons (x, y vertices, m) and/or a boolean mask on the
    grid ``origin`` + ``cell`` (``mask[j, i]`` at ``(origin_x + i·cell, origin_y + j·cell)``)."""

    name: str
    level: str
    buffer: float
    polygons: tuple[np.ndarray, ...] = ()
    mask: np.ndarray | None = None
    origin: tuple[float, float] = (0.0, 0.0)
    cell: float = 0.0
    kind: str = "keep_out"
    # the mask grown by the buffer, computed once (every chunk of runs reads it)
    near_mask: np.ndarray | None = field(init=False, default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.mask is not None and self.mask.any():
            object.__setattr__(self, "near_mask", _dilated(self.mask, self.buffer, self.cell))

    @property
    def empty(self) -> bool:
        return not self.polygons and (self.mask is None or not self.mask.any())

    def obstacles(self, heights: np.ndarray | None = None) -> list[Obstacle]:
        """The area as obstacles of its level for the collision check."""
        several = len(self.polygons) > 1
        found = [polygon_area(points.tolist(), self.level,
                              f"{self.name}{k + 1}" if several else self.name,
                              ground=height_range(heights))
                 for k, points in enumerate(self.polygons)]
        if self.mask is not None and self.mask.any():
            found += unknown_terrain(self.mask, self.origin, self.cell, self.level, self.name,
                                     heights)
        return found


def steep_area(name: str, level: str, buffer: float, above: float, heights: np.ndarray,
               origin: Sequence[float], cell: float) -> AreaGeometry:
    """The terrain where its inclination exceeds ``above`` (rad), as a mask area."""
    mask = steep_mask(heights, cell, above)
    return AreaGeometry(name, level, buffer, mask=mask, origin=(float(origin[0]),
                                                                float(origin[1])),
                        cell=float(cell), kind="steep")


def contact_points(x: np.ndarray, y: np.ndarray, yaw: np.ndarray, rover: RoverGeometry
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Ground contact points of the four wheels: arrays (…, 4) of x and y."""
    offsets = np.array([(rover.half_wheelbase, rover.half_track),
                        (rover.half_wheelbase, -rover.half_track),
                        (-rover.half_wheelbase, rover.half_track),
                        (-rover.half_wheelbase, -rover.half_track)])
    cos, sin = np.cos(yaw)[..., None], np.sin(yaw)[..., None]
    px = x[..., None] + cos * offsets[:, 0] - sin * offsets[:, 1]
    py = y[..., None] + sin * offsets[:, 0] + cos * offsets[:, 1]
    return px, py


def area_signals(area: AreaGeometry, x: np.ndarray, y: np.ndarray, yaw: np.ndarray,
                 rover: RoverGeometry) -> tuple[np.ndarray, np.ndarray]:
    """``area.NAME.inside`` and ``area.NAME.buffer`` (0/1 floats, the shape of ``x``)."""
    if area.empty:  # nothing on the ground (a site without steep terrain): 0, or NaN
        nothing = np.where(np.isfinite(np.asarray(x, float)), 0.0, np.nan)
        return nothing, nothing.copy()
    px, py = contact_points(np.asarray(x, float), np.asarray(y, float),
                            np.asarray(yaw, float), rover)
    inside = np.zeros(px.shape, bool)
    near = np.zeros(px.shape, bool)
    for polygon in area.polygons:
        polygon_inside = _in_polygon(px, py, polygon)
        inside |= polygon_inside
        near |= polygon_inside | (_edge_distance(px, py, polygon) <= area.buffer)
    if area.mask is not None and area.near_mask is not None:
        inside |= _on_mask(px, py, area.mask, area.origin, area.cell)
        near |= _on_mask(px, py, area.near_mask, area.origin, area.cell)
    # NaN poses (samples after a run ended) stay NaN, as every other signal
    missing = ~np.isfinite(np.asarray(x, float))
    inside_any = np.where(missing, np.nan, inside.any(axis=-1).astype(float))
    near_any = np.where(missing, np.nan, near.any(axis=-1).astype(float))
    return inside_any, near_any


def all_area_signals(areas: Mapping[str, AreaGeometry], poses: Mapping[str, np.ndarray],
                     rover: RoverGeometry) -> dict[str, np.ndarray]:
    """Both signals of every area, by signal name."""
    out: dict[str, np.ndarray] = {}
    for name, area in areas.items():
        inside, near = area_signals(area, poses["x"], poses["y"], poses["yaw"], rover)
        out[f"area.{name}.inside"], out[f"area.{name}.buffer"] = inside, near
    return out


def _in_polygon(px: np.ndarray, py: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd rule (a ray towards +x crosses the edges an odd number of times)."""
    result = np.zeros(px.shape, bool)
    xs, ys = polygon[:, 0], polygon[:, 1]
    for k in range(len(polygon)):
        x1, y1, x2, y2 = xs[k - 1], ys[k - 1], xs[k], ys[k]
        if y1 == y2:
            continue
        straddles = (y1 > py) != (y2 > py)
        crossing = x1 + (py - y1) * (x2 - x1) / (y2 - y1)
        result ^= straddles & (px < crossing)
    return result


def _edge_distance(px: np.ndarray, py: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Distance from each point to the polygon's nearest edge."""
    best = np.full(px.shape, math.inf)
    for k in range(len(polygon)):
        ax, ay = polygon[k - 1]
        bx, by = polygon[k]
        dx, dy = bx - ax, by - ay
        length2 = dx * dx + dy * dy
        t = np.clip(((px - ax) * dx + (py - ay) * dy) / length2, 0.0, 1.0) if length2 > 0 \
            else np.zeros(px.shape)
        best = np.minimum(best, np.hypot(px - (ax + t * dx), py - (ay + t * dy)))
    return best


def _on_mask(px: np.ndarray, py: np.ndarray, mask: np.ndarray, origin: Sequence[float],
             cell: float) -> np.ndarray:
    """Whether the nearest grid node of each point is flagged (outside the grid: no)."""
    ny, nx = mask.shape
    with np.errstate(invalid="ignore"):
        i = np.rint((px - origin[0]) / cell)
        j = np.rint((py - origin[1]) / cell)
    valid = np.isfinite(i) & np.isfinite(j) & (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
    result = np.zeros(px.shape, bool)
    result[valid] = mask[j[valid].astype(int), i[valid].astype(int)]
    return result


def _dilated(mask: np.ndarray, radius: float, cell: float) -> np.ndarray:
    """Nodes within ``radius`` of a flagged node."""
    reach = math.floor(radius / cell + 1e-9)
    grown = mask.copy()
    ny, nx = mask.shape
    for dj in range(-reach, reach + 1):
        for di in range(-reach, reach + 1):
            if (dj == 0 and di == 0) or (di * di + dj * dj) * cell * cell > radius * radius + 1e-15:
                continue
            shifted = np.zeros_like(mask)
            shifted[max(dj, 0):ny + min(dj, 0), max(di, 0):nx + min(di, 0)] = \
                mask[max(-dj, 0):ny + min(-dj, 0), max(-di, 0):nx + min(-di, 0)]
            grown |= shifted
    return grown
