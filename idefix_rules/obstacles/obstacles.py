"""Obstacles as geometry: rocks and areas to avoid, each with a level L1/L2/L3.

An :class:`Obstacle` is one thing that counts once in ``n_obs,k,l`` (a rock, or one connected
area); it is made of convex :class:`Piece` s that python-fcl checks. Its buffer zone is the set of
points closer than the margin of its level (``ObstacleSet.buffer_margins``): a body enters the
buffer zone when its distance to the obstacle drops below the margin, which is exact for the
obstacle grown by the margin and needs no extra geometry.

Rocks: sphere, ellipsoid or convex hull of points. Their level is given or assigned from their
size by :class:`LevelThresholds`; a rock's *size* is its height above the ground (top of the rock
minus the ground height under its centre), which is what decides whether a wheel climbs it and
whether the chassis clears it.

>>> rocks = [{"x": 0.5, "y": -0.26, "z": 0.0, "radius": 0.08}]
>>> obstacles = ObstacleSet.from_rocks(rocks, thresholds=LevelThresholds(0.05, 0.15),
...                                    buffer_margins={"L1": 0.0, "L2": 0.05, "L3": 0.1})
>>> obstacles.obstacles[0].level_name, obstacles.obstacles[0].size
('L2', 0.08)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from idefix_rules.errors import Diagnostic, UserInputError, error
from idefix_rules.obstacles.bodies import PARTS
from idefix_rules.signals import AXIS_LABELS

LEVELS: tuple[str, ...] = AXIS_LABELS["level"]


def level_index(value: object, what: str = "level") -> int:
    """Position in :data:`LEVELS` of ``"L2"``, ``"l2"``, ``2`` …; ``UserInputError`` otherwise.

    >>> level_index("L3"), level_index(1)
    (2, 0)
    """
    if isinstance(value, str) and value.upper() in LEVELS:
        return LEVELS.index(value.upper())
    if isinstance(value, int | np.integer) and not isinstance(value, bool) and 1 <= value <= 3:
        return int(value) - 1
    raise UserInputError(error("E610", f"{what}: unknown obstacle level {value!r}",
                               hint="use L1, L2 or L3"))


@dataclass(frozen=True)
class LevelThresholds:
    """Sizes (m) that split rocks into levels, as the rulebook defines them: a rock is L1 when
    its size is below ``l1_max_size``, L2 when below ``l2_max_size``, L3 otherwise.

    >>> LevelThresholds(0.05, 0.15).level_of(0.10)
    1
    """

    l1_max_size: float
    l2_max_size: float

    def __post_init__(self) -> None:
        a, b = self.l1_max_size, self.l2_max_size
        if not (math.isfinite(a) and math.isfinite(b) and 0 < a <= b):
            raise UserInputError(error(
                "E611", f"level thresholds must satisfy 0 < l1_max_size <= l2_max_size, "
                        f"got {a!r} m and {b!r} m"))

    def level_of(self, size: float) -> int:
        if size < self.l1_max_size:
            return 0
        return 1 if size < self.l2_max_size else 2


@dataclass(frozen=True, eq=False)
class Piece:
    """One convex fcl shape, world frame.

    ``shape`` / ``size``: ``"sphere"`` (radius,), ``"ellipsoid"`` (a, b, c semi-axes),
    ``"box"`` (full lengths), ``"convex"`` (``vertices`` relative to ``centre``, ``faces``
    triangles). ``lower``/``upper`` are its axis-aligned bounds, for the broad phase.
    """

    shape: str
    size: tuple[float, ...]
    centre: np.ndarray
    rotation: np.ndarray
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None

    @property
    def lower(self) -> np.ndarray:
        return np.asarray(self.centre - self._half_extent(), float)

    @property
    def upper(self) -> np.ndarray:
        return np.asarray(self.centre + self._half_extent(), float)

    def _half_extent(self) -> np.ndarray:
        extent: np.ndarray
        if self.shape == "sphere":
            extent = np.full(3, self.size[0])
        elif self.shape == "convex":
            assert self.vertices is not None
            extent = np.abs(self.vertices @ self.rotation.T).max(axis=0)
        elif self.shape == "box":  # extent of a rotated box along each world axis
            extent = np.abs(self.rotation) @ (0.5 * np.asarray(self.size, float))
        else:  # ellipsoid: support along each world axis
            extent = np.sqrt((self.rotation ** 2) @ (np.asarray(self.size, float) ** 2))
        return extent


@dataclass(frozen=True, eq=False)
class Obstacle:
    """A rock or an area: counts once per part in ``n_obs,k,l`` however many pieces it has.

    ``parts`` lists the body parts it is checked against (rocks: all; areas: the wheels by
    default, since the rover is *on* terrain where its wheels are). ``size`` is the rock size
    (m) used for its level, ``None`` for areas.
    """

    name: str
    kind: str  # rock | steep | unknown | polygon
    level: int
    pieces: tuple[Piece, ...]
    size: float | None = None
    parts: tuple[str, ...] = PARTS

    @property
    def level_name(self) -> str:
        return LEVELS[self.level]

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "kind": self.kind, "level": self.level_name,
                "size": self.size, "parts": list(self.parts), "pieces": len(self.pieces)}


def buffer_margins_tuple(margins: Mapping[str, float] | Sequence[float] | None
                         ) -> tuple[float, float, float]:
    """``{"L1": m, "L2": m, "L3": m}`` (missing levels: 0) or a 3-sequence → tuple in level
    order; negative or non-finite margins are an input error."""
    if margins is None:
        values = [0.0, 0.0, 0.0]
    elif isinstance(margins, Mapping):
        values = [0.0, 0.0, 0.0]
        for key, value in margins.items():
            values[level_index(key, "buffer margin")] = float(value)
    else:
        values = [float(v) for v in margins]
        if len(values) != 3:
            raise UserInputError(error("E612", "buffer margins need one value per level L1-L3"))
    bad = [v for v in values if not (math.isfinite(v) and v >= 0)]
    if bad:
        raise UserInputError(error("E612", f"buffer margins must be lengths >= 0 m, got {bad}"))
    return values[0], values[1], values[2]


@dataclass(frozen=True, eq=False)
class ObstacleSet:
    """All obstacles of an environment plus the buffer margin (m) of each level."""

    obstacles: tuple[Obstacle, ...] = ()
    buffer_margins: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "obstacles", tuple(self.obstacles))
        object.__setattr__(self, "buffer_margins", buffer_margins_tuple(self.buffer_margins))
        names = [o.name for o in self.obstacles]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise UserInputError(error("E613", f"obstacle names must be unique: {duplicates}"))

    @classmethod
    def from_rocks(cls, rocks: Iterable[Any], thresholds: LevelThresholds | None = None,
                   buffer_margins: Mapping[str, float] | Sequence[float] | None = None,
                   ground: Callable[[float, float], float] | None = None) -> ObstacleSet:
        """Rocks from simple records (mappings or objects, e.g. ``idefix_rules.fmu.terrain.Rock``).

        A record has a centre (``x, y, z`` or ``centre``/``center``), a shape (``radius``, or
        semi-axes ``a, b, c`` / ``semi_axes``, optionally rotated by ``yaw``; or ``points`` for a
        convex hull in world coordinates), optionally ``level`` (L1/L2/L3 or 1-3) and ``name``.
        Rocks without a level take it from ``thresholds`` and their size (height above
        ``ground(x, y)``, default 0 = terrain datum).
        """
        obstacles = []
        problems: list[Diagnostic] = []
        for number, record in enumerate(rocks):
            try:
                obstacles.append(rock_obstacle(record, number, thresholds, ground))
            except UserInputError as failure:
                problems.extend(failure.diagnostics)
        if problems:
            raise UserInputError(problems)
        return cls(tuple(obstacles), buffer_margins_tuple(buffer_margins))

    @classmethod
    def from_terrain(cls, terrain: Any, thresholds: LevelThresholds | None = None,
                     buffer_margins: Mapping[str, float] | Sequence[float] | None = None
                     ) -> ObstacleSet:
        """The rocks of an :class:`idefix_rules.fmu.terrain.Terrain` (its resolved rock list),
        sized against its DEM: the same rocks the rover FMU drives over."""

        def ground(x: float, y: float) -> float:
            return float(terrain.height_at(x, y))

        return cls.from_rocks(terrain.rocks, thresholds, buffer_margins, ground)

    def extended(self, obstacles: Iterable[Obstacle]) -> ObstacleSet:
        """The same set with more obstacles (e.g. areas) added."""
        return ObstacleSet((*self.obstacles, *obstacles), self.buffer_margins)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(o.name for o in self.obstacles)

    def to_dict(self) -> dict[str, Any]:
        return {"buffer_margins": dict(zip(LEVELS, self.buffer_margins, strict=True)),
                "obstacles": [o.to_dict() for o in self.obstacles]}


def _field(record: Any, *names: str) -> Any:
    for name in names:
        if isinstance(record, Mapping):
            if name in record and record[name] is not None:
                return record[name]
        elif getattr(record, name, None) is not None:
            return getattr(record, name)
    return None


def rock_obstacle(record: Any, number: int, thresholds: LevelThresholds | None,
                  ground: Callable[[float, float], float] | None = None) -> Obstacle:
    """One rock record (see :meth:`ObstacleSet.from_rocks`) → :class:`Obstacle`."""
    name = str(_field(record, "name") or f"rock{number + 1}")
    where = f"rock {name}"

    def fail(message: str) -> UserInputError:
        return UserInputError(error("E614", f"{where}: {message}"))

    points = _field(record, "points")
    yaw = float(_field(record, "yaw") or 0.0)
    rotation = np.array([[math.cos(yaw), -math.sin(yaw), 0.0],
                         [math.sin(yaw), math.cos(yaw), 0.0], [0.0, 0.0, 1.0]])
    if points is not None:
        piece = _hull_piece(np.asarray(points, float), fail)
        centre = piece.centre
        top = float(piece.upper[2])
    else:
        centre_value = _field(record, "centre", "center")
        if centre_value is None:
            centre_value = [_field(record, axis) for axis in ("x", "y", "z")]
        if len(centre_value) != 3 or any(v is None for v in centre_value):
            raise fail("needs a centre (x, y, z)")
        centre = np.asarray([float(v) for v in centre_value])
        radius = _field(record, "radius")
        axes = _field(record, "semi_axes")
        if axes is None and radius is None:
            axes = [_field(record, axis) for axis in ("a", "b", "c")]
        if radius is not None:
            size: tuple[float, ...] = (float(radius),)
            shape = "sphere"
        elif axes is not None and len(axes) == 3 and all(v is not None for v in axes):
            size = tuple(float(v) for v in axes)
            shape = "ellipsoid"
        else:
            raise fail("needs a radius, semi-axes a, b, c, or points")
        if not all(math.isfinite(v) and v > 0 for v in size) or not np.all(np.isfinite(centre)):
            raise fail(f"dimensions must be finite and positive, got {size}")
        piece = Piece(shape, size, centre, rotation)
        top = float(centre[2] + size[-1])
    # the size as stored and shown, to the picometre: a rock whose top stands 10 cm above the
    # ground by its numbers (6 cm radius, 2 cm embedded; or on a DEM 100 m up) is 10 cm, not
    # the 0.09999999999999999 m of the subtraction, whichever side of a level boundary
    rock_size = round(top - (ground(float(centre[0]), float(centre[1])) if ground else 0.0), 12)
    level_value = _field(record, "level")
    if level_value is not None:
        level = level_index(level_value, where)
    elif thresholds is not None:
        level = thresholds.level_of(rock_size)
    else:
        raise fail("has no level and no size thresholds were given to assign one")
    return Obstacle(name, "rock", level, (piece,), size=rock_size)


def _hull_piece(points: np.ndarray, fail: Callable[[str], UserInputError]) -> Piece:
    from scipy.spatial import ConvexHull, QhullError

    if points.ndim != 2 or points.shape[1] != 3 or len(points) < 4 \
            or not np.all(np.isfinite(points)):
        raise fail("points must be at least 4 finite (x, y, z) triples")
    try:
        hull = ConvexHull(points)
    except QhullError as exc:
        raise fail(f"points do not span a volume ({str(exc).splitlines()[0]})") from None
    vertices = points[hull.vertices]
    centre = vertices.mean(axis=0)
    remap = {int(old): new for new, old in enumerate(hull.vertices)}
    faces = np.array([[remap[int(i)] for i in simplex] for simplex in hull.simplices])
    return Piece("convex", (), centre, np.eye(3), vertices - centre, faces)
