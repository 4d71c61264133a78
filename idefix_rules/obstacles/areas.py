"""Areas to avoid: steep terrain (from a DEM), unknown terrain (a mask), user polygons.

An area is a region of the ground plane. It becomes python-fcl geometry as vertical prisms that
reach far above and below any rover pose (``AREA_HALF_HEIGHT`` around the terrain), so a body
intersects the prism exactly when its footprint overlaps the region, and the fcl distance to the
prism is the horizontal distance to the region. That keeps one checker (same broad phase,
clearance, buffer zone) for rocks and areas, instead of a second 2-D code path.

Grid convention (same grid for the DEM and the mask): ``heights[i, j]`` is the terrain height at
``(origin_x + j * cell, origin_y + i * cell)``; each grid node owns the square cell of side
``cell`` centred on it. One connected group of flagged cells (8-neighbour) is one obstacle,
covered by axis-aligned boxes merged from runs of cells.

>>> mask = np.zeros((4, 4), bool); mask[1:3, 1:3] = True
>>> [o.name for o in unknown_terrain(mask, (0.0, 0.0), 0.5, "L2")]
['unknown1']
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from fractions import Fraction

import numpy as np

from idefix_rules.errors import UserInputError, error
from idefix_rules.obstacles.obstacles import Obstacle, Piece, level_index

AREA_HALF_HEIGHT = 20.0  # m above and below the terrain: taller than any rover pose can reach
AREA_PARTS: tuple[str, ...] = ("wheel",)


def steep_terrain(heights: np.ndarray, origin: Sequence[float], cell: float, max_slope: float,
                  level: object, name: str = "steep",
                  parts: tuple[str, ...] = AREA_PARTS) -> list[Obstacle]:
    """Areas where the DEM's slope (rad, from central differences) exceeds ``max_slope``.

    >>> heights = np.zeros((5, 5)); heights[:, 3:] = [[0.0, 1.0]] * 5
    >>> [(o.name, o.level_name) for o in steep_terrain(heights, (0, 0), 0.5, 0.3, "L3")]
    [('steep1', 'L3')]
    """
    heights = _grid(heights, cell, "DEM heights", float)
    return _mask_areas(steep_mask(heights, cell, max_slope), heights, origin, cell, level, name,
                       "steep", parts)


def steep_mask(heights: np.ndarray, cell: float, max_slope: float) -> np.ndarray:
    """Grid nodes where the DEM's slope (rad, from central differences) exceeds
    ``max_slope``."""
    heights = _grid(heights, cell, "DEM heights", float)
    if not (math.isfinite(max_slope) and 0.0 < max_slope < math.pi / 2):
        raise UserInputError(error("E621", f"slope threshold must be in (0, 90) deg, "
                                           f"got {math.degrees(max_slope):.3g} deg"))
    if min(heights.shape) < 2:
        raise UserInputError(error("E620", "a DEM needs at least 2 × 2 heights for a slope"))
    dz_dy, dz_dx = np.gradient(heights, cell)
    mask: np.ndarray = np.arctan(np.hypot(dz_dx, dz_dy)) > max_slope
    return mask


def unknown_terrain(mask: np.ndarray, origin: Sequence[float], cell: float, level: object,
                    name: str = "unknown", heights: np.ndarray | None = None,
                    parts: tuple[str, ...] = AREA_PARTS) -> list[Obstacle]:
    """Areas where ``mask`` is true (terrain the navigation images do not show)."""
    mask = _grid(mask, cell, "unknown-terrain mask", bool)
    ground = np.zeros(mask.shape) if heights is None else _grid(heights, cell, "DEM heights",
                                                                float)
    if ground.shape != mask.shape:
        raise UserInputError(error("E620", f"mask shape {mask.shape} differs from the DEM's "
                                           f"{ground.shape}"))
    return _mask_areas(mask, ground, origin, cell, level, name, "unknown", parts)


def polygon_area(vertices: Sequence[Sequence[float]], level: object, name: str,
                 parts: tuple[str, ...] = AREA_PARTS,
                 ground: tuple[float, float] = (0.0, 0.0)) -> Obstacle:
    """A user polygon (x, y vertices, any orientation, simple, convex or not) as one obstacle,
    cut into triangles (ear clipping), each a vertical prism from ``AREA_HALF_HEIGHT`` below
    the lowest to as far above the highest of the terrain's heights ``ground`` (the DEM's range:
    a DEM at a site's elevation, 100 m up, keeps its areas where the rover drives).

    >>> area = polygon_area([(0, 0), (2, 0), (2, 2), (1, 1), (0, 2)], "L1", "keep-out")
    >>> len(area.pieces)
    3
    """
    points = np.asarray(vertices, float)
    if points.ndim != 2 or points.shape[1] != 2 or len(points) < 3 \
            or not np.all(np.isfinite(points)):
        raise UserInputError(error("E622", f"area {name}: a polygon needs at least 3 finite "
                                           "(x, y) vertices"))
    repeated = np.all(points == np.roll(points, -1, axis=0), axis=1)
    if repeated.any():
        closing = bool(repeated[-1])
        raise UserInputError(error("E622", f"area {name}: " + (
            "the last vertex repeats the first; the polygon closes itself, leave it out"
            if closing else f"vertex {int(np.argmax(repeated)) + 2} repeats the one before it")))
    why = _not_simple(points)
    if why is not None:
        raise UserInputError(error("E622", f"area {name}: polygon is not simple ({why})"))
    area2 = _signed_area2(points)
    if abs(area2) < 1e-12:
        raise UserInputError(error("E622", f"area {name}: polygon has no area (its vertices "
                                           "lie on a line)"))
    if area2 < 0:
        points = points[::-1]
    pieces = tuple(_prism(points[list(tri)], ground) for tri in _ear_clip(points, name))
    return Obstacle(name, "polygon", level_index(level, f"area {name}"), pieces, parts=parts)


def height_range(heights: np.ndarray | None) -> tuple[float, float]:
    """The lowest and highest of a DEM's heights; (0, 0), the datum, without one."""
    if heights is None or np.size(heights) == 0:
        return (0.0, 0.0)
    return (float(np.min(heights)), float(np.max(heights)))


def _grid(values: np.ndarray, cell: float, what: str, dtype: type) -> np.ndarray:
    array = np.asarray(values)
    if array.ndim != 2 or array.size == 0:
        raise UserInputError(error("E620", f"{what} must be a 2-D grid, got shape {array.shape}"))
    if not (math.isfinite(cell) and cell > 0):
        raise UserInputError(error("E620", f"grid cell size must be > 0 m, got {cell!r}"))
    array = array.astype(dtype)
    if dtype is float and not np.all(np.isfinite(array)):
        raise UserInputError(error("E620", f"{what} contain non-finite values"))
    return array


def _mask_areas(mask: np.ndarray, heights: np.ndarray, origin: Sequence[float], cell: float,
                level: object, name: str, kind: str, parts: tuple[str, ...]) -> list[Obstacle]:
    from scipy import ndimage

    level_number = level_index(level, f"{kind} terrain")
    labels, count = ndimage.label(mask, structure=np.ones((3, 3), bool))
    x0, y0 = float(origin[0]), float(origin[1])
    out = []
    for label in range(1, count + 1):
        component = labels == label
        # from below the patch's lowest ground to above its highest (a 25° ramp 100 m high
        # is all one patch): the rover's bodies are inside wherever they stand on it
        z_low, z_high = float(heights[component].min()), float(heights[component].max())
        pieces = []
        for row0, row1, col0, col1 in _rectangles(component):
            lower = np.array([x0 + (col0 - 0.5) * cell, y0 + (row0 - 0.5) * cell])
            upper = np.array([x0 + (col1 + 0.5) * cell, y0 + (row1 + 0.5) * cell])
            centre = np.array([*(lower + upper) / 2.0, (z_low + z_high) / 2.0])
            size = (*(upper - lower), z_high - z_low + 2.0 * AREA_HALF_HEIGHT)
            pieces.append(Piece("box", tuple(float(v) for v in size), centre, np.eye(3)))
        out.append(Obstacle(f"{name}{label}", kind, level_number, tuple(pieces), parts=parts))
    return out


def _rectangles(component: np.ndarray) -> list[tuple[int, int, int, int]]:
    """Cover a boolean grid with rectangles (rows r0..r1, cols c0..c1, inclusive): runs of a row
    are merged with the identical run of the rows below."""
    open_runs: dict[tuple[int, int], int] = {}
    done: list[tuple[int, int, int, int]] = []
    for row in range(component.shape[0] + 1):
        runs = set(_runs(component[row])) if row < component.shape[0] else set()
        for run in list(open_runs):
            if run not in runs:
                done.append((open_runs.pop(run), row - 1, run[0], run[1]))
        for run in runs:
            open_runs.setdefault(run, row)
    return sorted(done)


def _runs(row: np.ndarray) -> list[tuple[int, int]]:
    padded = np.concatenate([[False], row, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def _not_simple(points: np.ndarray) -> str | None:
    """Why the closed polygon is not simple, or None: two edges that share no vertex meet
    (cross, touch, or overlap along a line: a bow-tie, a vertex on another edge), or an edge
    turns back along the one before it (a spike). Vertices all on one line are left to the
    area.

    >>> _not_simple(np.array([(0, 0), (1, 1), (1, 0), (0, 1)], float))
    'its edges cross'
    >>> _not_simple(np.array([(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (1, 1.5), (0, 1)], float))
    'edge 5 turns back along edge 4, a spike'
    >>> _not_simple(np.array([(0, 0), (2, 0), (2, 2), (1, 0), (0, 2)], float))
    'vertex 4 lies on edge 1'
    >>> _not_simple(np.array([(3.1, 4.2), (8.3, 4.1), (8.4, 9.1), (5.7, 4.15), (3.2, 9.2)]))
    'vertex 4 lies on edge 1'
    >>> print(_not_simple(np.array([(0, 0), (1, 0), (1, 1), (0, 1)], float)))
    None
    """
    count = len(points)

    def side(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> float:
        return float((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))

    # "on a line" to the coordinates' precision: decimal coordinates are not exact in binary
    # ((5.7, 4.15) on the edge from (3.1, 4.2) to (8.3, 4.1) is 2e-15 off it)
    tolerance = 1e-9 * max(1.0, float(np.max(np.abs(points))))

    def on_line(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> bool:
        """c lies on the line through a and b, within the tolerance (a distance)."""
        return abs(side(a, b, c)) <= tolerance * float(np.hypot(*(b - a)))

    def within(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> bool:
        """c, on the line through a and b, lies on the segment from a to b."""
        return bool(min(a[0], b[0]) - tolerance <= c[0] <= max(a[0], b[0]) + tolerance
                    and min(a[1], b[1]) - tolerance <= c[1] <= max(a[1], b[1]) + tolerance)

    span = points - points[0]
    if np.all(np.abs(span[:, 0] * span[:, 1][:, None] - span[:, 1] * span[:, 0][:, None])
              <= 1e-12):
        return None  # every vertex on one line: "has no area" says it better
    for i in range(count):
        a, b = points[i], points[(i + 1) % count]
        after = points[(i + 2) % count]
        # the next edge folds back onto this one: collinear, pointing back
        if on_line(a, b, after) and float(np.dot(b - a, after - b)) < 0.0:
            return f"edge {(i + 1) % count + 1} turns back along edge {i + 1}, a spike"
        for j in range(i + 2, count):
            if i == 0 and j == count - 1:
                continue  # the closing edge shares vertex 0 with edge 0
            c, d = points[j], points[(j + 1) % count]
            sides = side(a, b, c), side(a, b, d), side(c, d, a), side(c, d, b)
            if sides[0] * sides[1] < 0 and sides[2] * sides[3] < 0:
                return "its edges cross"
            for point, number, on, ends in ((c, j, i, (a, b)), (d, (j + 1) % count, i, (a, b)),
                                            (a, i, j, (c, d)), (b, (i + 1) % count, j, (c, d))):
                if on_line(*ends, point) and within(*ends, point):
                    return f"vertex {number + 1} lies on edge {on + 1}"
    return None


def _signed_area2(points: np.ndarray) -> float:
    x, y = points[:, 0], points[:, 1]
    return float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def _ear_clip(points: np.ndarray, name: str) -> list[tuple[int, int, int]]:
    """Triangles of a counter-clockwise simple polygon."""
    remaining = list(range(len(points)))
    triangles = []
    guard = 0
    while len(remaining) > 3:
        guard += 1
        if guard > 4 * len(points) ** 2:
            raise UserInputError(error("E622", f"area {name}: polygon is not simple "
                                               "(its edges cross)"))
        n = len(remaining)
        for k in range(n):
            i, j, m = remaining[k - 1], remaining[k], remaining[(k + 1) % n]
            a, b, c = points[i], points[j], points[m]
            if _cross(a, b, c) <= 0:
                continue  # reflex or degenerate corner: not an ear
            if any(_inside(points[p], a, b, c) for p in remaining if p not in (i, j, m)):
                continue
            triangles.append((i, j, m))
            remaining.pop(k)
            break
    triangles.append((remaining[0], remaining[1], remaining[2]))
    return triangles


# Shewchuk's bound on the rounding error of the floating-point orientation determinant, from
# the coordinates (Robust Adaptive Floating-Point Geometric Predicates, 1997: ccwerrboundA)
_ORIENT_BOUND = (3.0 + 16.0 * 2.0 ** -53) * 2.0 ** -53


def _cross(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> float:
    """Twice the signed area of (a, b, c), its sign exact: where rounding could flip it, the
    determinant is worked out exactly. A vertex on an ear's diagonal (three vertices on a
    line, 0.8/0.4/-1.6 m) read as just outside cut an ear that an edge crosses."""
    left = (float(b[0]) - float(a[0])) * (float(c[1]) - float(a[1]))
    right = (float(b[1]) - float(a[1])) * (float(c[0]) - float(a[0]))
    determinant = left - right
    if abs(determinant) > _ORIENT_BOUND * (abs(left) + abs(right)):
        return determinant
    ax, ay, bx, by, cx, cy = (Fraction(float(v)) for v in (*a[:2], *b[:2], *c[:2]))
    exact = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    return float(exact) if exact else 0.0


def _inside(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> bool:
    return _cross(a, b, p) >= 0 and _cross(b, c, p) >= 0 and _cross(c, a, p) >= 0


def _prism(triangle: np.ndarray, ground: tuple[float, float]) -> Piece:
    lo = np.column_stack([triangle, np.full(3, ground[0] - AREA_HALF_HEIGHT)])
    hi = np.column_stack([triangle, np.full(3, ground[1] + AREA_HALF_HEIGHT)])
    vertices = np.vstack([lo, hi])
    centre = vertices.mean(axis=0)
    faces = np.array([[0, 2, 1], [3, 4, 5], [0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4],
                      [2, 0, 3], [2, 3, 5]])
    return Piece("convex", (), centre, np.eye(3), vertices - centre, faces)
