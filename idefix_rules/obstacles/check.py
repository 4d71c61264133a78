"""The collision check: every run's poses against every obstacle, with python-fcl.

Three stages per chunk of runs (``docs/obstacles.md`` has the derivations):

1. **Motion bound.** Between two samples the pose is interpolated linearly (position and the
   three angles). A point of body ``b`` then moves at most
   ``|Δp| + (|Δroll| + |Δpitch| + |Δyaw|) · reach_b`` per step, ``reach_b`` bounding the body
   about the rover centre. Its running sum ``u_b`` is a distance-like coordinate along the run:
   the fcl distance of ``b`` to any obstacle changes by at most ``|Δu_b|``.
2. **Broad phase (numpy, all poses at once).** On blocks of 32 samples, each body's bounding
   sphere, grown by how far the body can move within the block, against each obstacle piece's
   axis-aligned box. Only (run, body, piece) stretches of blocks whose lower bound is within the
   clearance cap go on.
3. **Narrow phase (fcl, conservative advancement).** Along each stretch, fcl's exact distance
   ``d`` at an anchor sample holds within ``±Δu`` for the samples that follow. fcl's GJK answers
   are certified first (:func:`certified_distance`: a support-function lower bound, a retry
   with the objects swapped when it disagrees, the remaining uncertainty taken off the
   allowance), since GJK now and then reports a distance far too large. The next anchor is
   the last sample before ``Δu`` reaches an allowance chosen so that no contact or buffer
   decision can flip (``|d - tolerance|``, ``|d - margin|``, in overlap how deep a witness point
   of the body lies inside the obstacle)
   and the clearance error stays within the resolution. When the next sample is beyond the
   allowance it is measured too, and the gap between the two is filled with interpolated poses
   only if a contact or buffer entry could hide in it. So no obstacle is skipped between samples
   however fast the rover moves, and slow drives (sub-millimetre steps) need one fcl call per few
   millimetres near an obstacle.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import fcl
import numpy as np

from idefix_rules.errors import UserInputError, error
from idefix_rules.obstacles.bodies import (
    PARTS,
    Body,
    RoverBodies,
    quaternion_product,
    quaternions,
    rotation_matrices,
)
from idefix_rules.obstacles.obstacles import LEVELS, ObstacleSet, Piece
from idefix_rules.obstacles.result import (
    CheckSettings,
    CollisionResult,
    FirstContact,
    RunCollisions,
)

POSE_NAMES = ("t", "x", "y", "z", "roll", "pitch", "yaw")
_TIME_BLOCK = 32  # samples per block of the broad phase


def fcl_body(body: Body) -> fcl.CollisionObject:
    """A python-fcl object for a rover body (its transform is set per pose)."""
    if body.shape == "cylinder":
        geometry = fcl.Cylinder(body.size[0], body.size[1])
    else:
        geometry = fcl.Box(*body.size)
    return fcl.CollisionObject(geometry, fcl.Transform())


def fcl_piece(piece: Piece) -> fcl.CollisionObject:
    """A python-fcl object for an obstacle piece, placed in the world."""
    if piece.shape == "sphere":
        geometry = fcl.Sphere(piece.size[0])
    elif piece.shape == "ellipsoid":
        geometry = fcl.Ellipsoid(*piece.size)
    elif piece.shape == "box":
        geometry = fcl.Box(*piece.size)
    else:
        assert piece.vertices is not None and piece.faces is not None
        faces = np.column_stack([np.full(len(piece.faces), 3), piece.faces]).ravel()
        geometry = fcl.Convex(np.ascontiguousarray(piece.vertices), len(piece.faces), faces)
    return fcl.CollisionObject(geometry, fcl.Transform(piece.rotation, piece.centre))


def check_poses(poses: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Pose arrays as float64 (runs, samples); ``UserInputError`` naming what is wrong."""
    problems = []
    missing = [name for name in POSE_NAMES if name not in poses]
    if missing:
        raise UserInputError(error("E630", f"poses lack {', '.join(missing)}",
                                   hint=f"collision checks need {', '.join(POSE_NAMES)}"))
    arrays = {name: np.asarray(poses[name], float) for name in POSE_NAMES}
    shape = arrays["x"].shape
    if len(shape) != 2 or shape[1] < 1:
        problems.append(error("E631", f"poses must be shaped (runs, samples), x has {shape}"))
    for name, array in arrays.items():
        if array.shape != shape:
            problems.append(error("E631", f"pose {name} has shape {array.shape}, x has {shape}"))
        elif not np.all(np.isfinite(array)):
            problems.append(error("E632", f"pose {name} contains NaN or infinite values"))
    if problems:
        raise UserInputError(problems)
    return arrays


@dataclass
class Tracks:
    """What a chunk checker accumulates for the runs of one chunk."""

    clearance: np.ndarray  # (runs, samples, bodies)
    contact: np.ndarray  # (runs, samples, part, level) int8
    hit: np.ndarray  # (runs, bodies, obstacles) bool
    nearest: np.ndarray  # (runs, bodies, obstacles) min clearance over the run
    first: dict[tuple[int, int, int], FirstContact]  # (run, part, level) →

    @classmethod
    def empty(cls, runs: int, samples: int, bodies: int, obstacles: int, cap: float) -> Tracks:
        return cls(clearance=np.full((runs, samples, bodies), cap),
                   contact=np.zeros((runs, samples, len(PARTS), len(LEVELS)), np.int8),
                   hit=np.zeros((runs, bodies, obstacles), bool),
                   nearest=np.full((runs, bodies, obstacles), cap),
                   first={})

    def note_contact(self, contact: FirstContact, run: int) -> None:
        """Keep ``contact`` if it is the earliest of its run, part and level."""
        key = (run, PARTS.index(contact.part), LEVELS.index(contact.level))
        known = self.first.get(key)
        if known is None or contact.time < known.time:
            self.first[key] = contact


def collision_signals(poses: Mapping[str, np.ndarray], obstacles: ObstacleSet,
                      bodies: RoverBodies = RoverBodies(),  # noqa: B008 - frozen, immutable
                      settings: CheckSettings = CheckSettings(),  # noqa: B008
                      first_run: int = 0) -> CollisionResult:
    """Collision signals of runs of poses against an obstacle set.

    ``poses``: ``t, x, y, z, roll, pitch, yaw`` shaped (runs, samples), SI. ``first_run`` numbers
    the runs in ``details`` (the campaign calls this per chunk of runs).

    >>> from idefix_rules.obstacles import ObstacleSet
    >>> t = np.linspace(0.0, 100.0, 201)[None, :]
    >>> poses = dict(t=t, x=0.005 * t, y=0 * t, z=0 * t + 0.3, roll=0 * t, pitch=0 * t,
    ...              yaw=0 * t)
    >>> rock = {"name": "r", "x": 0.4, "y": -0.26, "z": 0.0, "radius": 0.06, "level": "L2"}
    >>> result = collision_signals(poses, ObstacleSet.from_rocks([rock]))
    >>> result.signals["collision.hits"][0].tolist()  # part × level
    [[0, 1, 0], [0, 0, 0], [0, 0, 0]]
    """
    return collect(check_poses(poses), obstacles, bodies, settings, first_run, _check_chunk)


ChunkChecker = Callable[[dict[str, np.ndarray], ObstacleSet, tuple[Body, ...], list[Piece],
                         np.ndarray, CheckSettings, float], "Tracks"]


def collect(arrays: dict[str, np.ndarray], obstacles: ObstacleSet, bodies: RoverBodies,
            settings: CheckSettings, first_run: int, checker: ChunkChecker) -> CollisionResult:
    """Run ``checker`` chunk by chunk and turn its :class:`Tracks` into the signals."""
    runs, samples = arrays["x"].shape
    body_list = bodies.bodies()
    n_obstacles = len(obstacles.obstacles)
    cap = settings.cap(obstacles.buffer_margins)
    clearance = np.full((runs, samples, len(PARTS)), cap)
    contact = np.zeros((runs, samples, len(PARTS), len(LEVELS)), np.int8)
    hits = np.zeros((runs, len(PARTS), len(LEVELS)), np.int64)
    buffers = np.zeros_like(hits)
    details: list[RunCollisions] = []
    pieces, piece_owner = _pieces(obstacles)
    levels = np.array([o.level for o in obstacles.obstacles], int)
    margins = np.array(obstacles.buffer_margins)[levels] if n_obstacles else np.zeros(0)
    runs_per_chunk = max(1, settings.chunk_poses // samples)
    for start in range(0, runs, runs_per_chunk):
        stop = min(runs, start + runs_per_chunk)
        chunk = {name: array[start:stop] for name, array in arrays.items()}
        tracks = checker(chunk, obstacles, body_list, pieces, piece_owner, settings, cap)
        part_hit = np.zeros((stop - start, len(PARTS), n_obstacles), bool)
        part_nearest = np.full(part_hit.shape, cap)
        for part in range(len(PARTS)):
            members = [i for i, b in enumerate(body_list) if b.part == part]
            clearance[start:stop, :, part] = tracks.clearance[:, :, members].min(axis=2)
            part_hit[:, part] = tracks.hit[:, members].any(axis=1)
            part_nearest[:, part] = tracks.nearest[:, members].min(axis=1)
        contact[start:stop] = tracks.contact
        entered = (part_nearest < margins[None, None, :]) & ~part_hit
        for level in range(len(LEVELS)):
            of_level = levels == level
            hits[start:stop, :, level] = part_hit[:, :, of_level].sum(axis=2)
            buffers[start:stop, :, level] = entered[:, :, of_level].sum(axis=2)
        details.extend(_details(tracks, part_hit, entered, body_list, obstacles, start,
                                first_run, cap))
    signals: dict[str, np.ndarray] = {
        "collision.hits": hits, "collision.buffer": buffers, "collision.contact": contact,
        "collision.clearance": clearance}
    return CollisionResult(signals, details, cap)


def _pieces(obstacles: ObstacleSet) -> tuple[list[Piece], np.ndarray]:
    pieces: list[Piece] = []
    owner: list[int] = []
    for index, obstacle in enumerate(obstacles.obstacles):
        pieces.extend(obstacle.pieces)
        owner.extend([index] * len(obstacle.pieces))
    return pieces, np.array(owner, int)


def _details(tracks: Tracks, part_hit: np.ndarray, entered: np.ndarray,
             body_list: tuple[Body, ...], obstacles: ObstacleSet, start: int, first_run: int,
             cap: float) -> list[RunCollisions]:
    names = obstacles.names

    def named(flags: np.ndarray) -> tuple[str, ...]:
        return tuple(names[o] for o in np.flatnonzero(flags))

    out = []
    for local in range(part_hit.shape[0]):
        contacts = tuple(tracks.first[key] for key in sorted(tracks.first) if key[0] == local)
        nearest = tracks.nearest[local].min(axis=0)
        out.append(RunCollisions(
            run=first_run + start + local,
            first_contacts=contacts,
            hits={PARTS[p]: named(part_hit[local, p]) for p in range(len(PARTS))},
            buffers={PARTS[p]: named(entered[local, p]) for p in range(len(PARTS))},
            min_clearance={name: float(v) for name, v in zip(names, nearest, strict=True)},
            clearance_cap=cap,
            body_hits={body.name: named(tracks.hit[local, b])
                       for b, body in enumerate(body_list)},
        ))
    return out


def _check_chunk(chunk: dict[str, np.ndarray], obstacles: ObstacleSet, body_list: tuple[Body, ...],
                 pieces: list[Piece], piece_owner: np.ndarray, settings: CheckSettings,
                 cap: float) -> Tracks:
    runs, samples = chunk["x"].shape
    n_obstacles = len(obstacles.obstacles)
    tracks = Tracks.empty(runs, samples, len(body_list), n_obstacles, cap)
    if not pieces:
        return tracks
    rotation = rotation_matrices(chunk["roll"], chunk["pitch"], chunk["yaw"])
    position = np.stack([chunk["x"], chunk["y"], chunk["z"]], axis=-1)
    reach = np.array([b.reach for b in body_list])
    step_move = np.linalg.norm(np.diff(position, axis=1), axis=2)
    step_turn = (np.abs(np.diff(chunk["roll"], axis=1)) + np.abs(np.diff(chunk["pitch"], axis=1))
                 + np.abs(np.diff(chunk["yaw"], axis=1)))
    cum = np.zeros((runs, samples, len(body_list)))
    cum[:, 1:] = np.cumsum(step_move[..., None] + step_turn[..., None] * reach, axis=1)
    candidates = _broad_phase(position, rotation, cum, body_list, pieces, piece_owner,
                              obstacles, cap)
    walker = _Walker(chunk, rotation, position, cum, body_list, pieces, piece_owner, obstacles,
                     settings, cap, tracks)
    for run, body, piece, first, last in candidates:
        walker.walk(run, body, piece, first, last)
    return tracks


def _aabb_gap(points: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Distance from points (..., 3) to boxes (lower/upper broadcastable)."""
    gap = np.maximum(np.maximum(lower - points, points - upper), 0.0)
    distance: np.ndarray = np.sqrt((gap * gap).sum(axis=-1))
    return distance


def _broad_phase(position: np.ndarray, rotation: np.ndarray, cum: np.ndarray,
                 body_list: tuple[Body, ...], pieces: list[Piece], piece_owner: np.ndarray,
                 obstacles: ObstacleSet, cap: float) -> list[tuple[int, int, int, int, int]]:
    """Stretches ``(run, body, piece, first sample, last sample)`` that need fcl.

    Conservative, on blocks of ``_TIME_BLOCK`` samples: each body's bounding sphere at the
    block's first pose, grown by how far any point of the body can move within the block and the
    steps just outside it, against each piece's axis-aligned box. Consecutive blocks within the
    clearance cap form one stretch.
    """
    samples = position.shape[1]
    lower = np.array([p.lower for p in pieces])
    upper = np.array([p.upper for p in pieces])
    starts = np.arange(0, samples, _TIME_BLOCK)
    stops = np.minimum(starts + _TIME_BLOCK, samples) - 1
    offsets = np.array([body.offset for body in body_list])
    # Body centres at the first sample of each block: (runs, blocks, bodies, 3).
    centres = position[:, starts, None, :] + np.einsum("rkij,bj->rkbi", rotation[:, starts],
                                                       offsets)
    # How far any point of a body can move from there within the block and its outer steps.
    growth = (cum[:, np.minimum(stops + 1, samples - 1)] - cum[:, np.maximum(starts - 1, 0)])
    radius = np.array([body.radius for body in body_list])
    allowed = np.array([[PARTS[b.part] in o.parts for o in obstacles.obstacles]
                        for b in body_list])[:, piece_owner]  # (bodies, pieces)
    hits = []
    for m in range(len(pieces)):
        bound = _aabb_gap(centres, lower[m], upper[m]) - radius - growth  # (runs, blocks, bodies)
        run, block, body = np.nonzero((bound <= cap) & allowed[None, None, :, m])
        hits.append(((run * len(body_list) + body) * len(pieces) + m, block))
    key = np.concatenate([h[0] for h in hits])
    block = np.concatenate([h[1] for h in hits])
    if len(key) == 0:
        return []
    order = np.lexsort((block, key))
    key, block = key[order], block[order]
    # A new stretch where the track changes or blocks are not consecutive.
    breaks = np.flatnonzero((np.diff(key) != 0) | (np.diff(block) > 1)) + 1
    stretch_starts = np.concatenate([[0], breaks])
    stretch_ends = np.concatenate([breaks - 1, [len(key) - 1]])
    out = []
    for s, e in zip(stretch_starts.tolist(), stretch_ends.tolist(), strict=True):
        run_body, m = divmod(int(key[s]), len(pieces))
        r, b = divmod(run_body, len(body_list))
        # One sample of margin each side covers the motion into and out of the stretch.
        out.append((r, b, m, max(0, int(starts[block[s]]) - 1),
                    min(samples - 1, int(stops[block[e]]) + 1)))
    return out


Support = Callable[[float, float, float], float]


def support_function(shape: str, size: tuple[float, ...], vertices: np.ndarray | None = None
                     ) -> Support:
    """The support function ``h(v) = max over the shape of v · x`` in the shape's own frame
    (fcl's conventions: box full lengths, cylinder axis along z, ellipsoid semi-axes); plain
    floats, as it runs once or twice per fcl distance call."""
    if shape == "box":
        hx, hy, hz = (float(s) / 2.0 for s in size)
        return lambda x, y, z: abs(x) * hx + abs(y) * hy + abs(z) * hz
    if shape == "cylinder":
        radius, half_length = float(size[0]), float(size[1]) / 2.0
        return lambda x, y, z: radius * math.sqrt(x * x + y * y) + half_length * abs(z)
    if shape == "ellipsoid":
        a, b, c = (float(s) for s in size)
        return lambda x, y, z: math.sqrt((a * x) ** 2 + (b * y) ** 2 + (c * z) ** 2)
    if shape == "sphere":
        radius = float(size[0])
        return lambda x, y, z: radius * math.sqrt(x * x + y * y + z * z)
    assert vertices is not None
    points = np.asarray(vertices, float)
    return lambda x, y, z: float((points @ np.array([x, y, z])).max())


def piece_support(piece: Piece) -> Support:
    """The support function of a placed obstacle piece in world directions: ``n · c + h(Rᵀ n)``
    (pieces do not move, so this is set up once)."""
    local = support_function(piece.shape, piece.size, piece.vertices)
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = np.asarray(piece.rotation,
                                                                   float).tolist()
    cx, cy, cz = np.asarray(piece.centre, float).tolist()
    return lambda x, y, z: x * cx + y * cy + z * cz + local(
        r00 * x + r10 * y + r20 * z, r01 * x + r11 * y + r21 * z, r02 * x + r12 * y + r22 * z)


_NEAREST_REQUEST = fcl.DistanceRequest(enable_nearest_points=True)


def certified_distance(body_object: fcl.CollisionObject, body_support: Support,
                       piece_object: fcl.CollisionObject, piece_world: Support,
                       slack: float) -> tuple[float, float]:
    """fcl's distance of a body to a piece with a proven lower bound: ``(distance, lower)``.

    fcl answers shape pairs without a closed form (box or cylinder against ellipsoid, box or
    convex hull) with GJK, which now and then stops at a wrong simplex and reports a distance
    far too large (0.29 m for an exact 0.146 m, chassis against an ellipsoid; about one call in
    2000 off by more than 1 mm, in any world frame). The distance it returns is that of two
    points of the shapes, so it bounds the exact distance from above. Any unit direction ``n``
    bounds it from below: ``min over the piece of n · x − max over the body of n · x``, from
    the support functions (``body_support`` in the body's frame, ``piece_world`` of the placed
    piece, :func:`piece_support`). Along the direction between fcl's nearest points this bound
    equals the distance when GJK converged. When the two differ by more than ``slack``, the
    query is repeated with the objects swapped (GJK starts elsewhere) and the best bounds of
    both are kept. Overlap (fcl's ``-1``) is returned as it is.
    """
    result = fcl.DistanceResult()
    distance = fcl.distance(body_object, piece_object, _NEAREST_REQUEST, result)
    if distance <= 0.0:
        return distance, distance
    lower = _lower_bound(body_object, body_support, piece_world, result.nearest_points[0],
                         result.nearest_points[1])
    if distance - lower <= slack:
        return distance, lower
    result = fcl.DistanceResult()
    swapped = fcl.distance(piece_object, body_object, _NEAREST_REQUEST, result)
    if swapped <= 0.0:
        return swapped, swapped
    lower = max(lower, _lower_bound(body_object, body_support, piece_world,
                                    result.nearest_points[1], result.nearest_points[0]))
    distance = min(distance, swapped)
    return distance, min(lower, distance)


def _lower_bound(body_object: fcl.CollisionObject, body_support: Support, piece_world: Support,
                 on_body: np.ndarray, on_piece: np.ndarray) -> float:
    """Separation of the two shapes along the direction from ``on_body`` to ``on_piece``
    (a lower bound of their distance for any direction; 0 if the points coincide)."""
    (bx, by, bz), (px, py, pz) = on_body.tolist(), on_piece.tolist()
    nx, ny, nz = px - bx, py - by, pz - bz
    length = math.sqrt(nx * nx + ny * ny + nz * nz)
    if length <= 1e-12:
        return 0.0
    nx, ny, nz = nx / length, ny / length, nz / length
    # The body's support in the world direction n: n · t + h(Rᵀ n).
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = body_object.getRotation().tolist()
    tx, ty, tz = body_object.getTranslation().tolist()
    body_reach = nx * tx + ny * ty + nz * tz + body_support(
        r00 * nx + r10 * ny + r20 * nz, r01 * nx + r11 * ny + r21 * nz,
        r02 * nx + r12 * ny + r22 * nz)
    piece_start = -float(piece_world(-nx, -ny, -nz))
    return max(0.0, piece_start - float(body_reach))


Inside = Callable[[float, float, float], float]


def piece_inside(piece: Piece) -> Inside:
    """``inside(x, y, z)``: a lower bound of how deep the world point lies inside the piece
    (the radius of a ball around it that the piece contains; ≤ 0 outside)."""
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = np.asarray(piece.rotation,
                                                                   float).tolist()
    cx, cy, cz = np.asarray(piece.centre, float).tolist()

    def local(x: float, y: float, z: float) -> tuple[float, float, float]:
        x, y, z = x - cx, y - cy, z - cz
        return (r00 * x + r10 * y + r20 * z, r01 * x + r11 * y + r21 * z,
                r02 * x + r12 * y + r22 * z)

    if piece.shape == "sphere":
        radius = float(piece.size[0])
        return lambda x, y, z: radius - math.sqrt(sum(v * v for v in local(x, y, z)))
    if piece.shape == "ellipsoid":
        # At scaled radius ρ = |D⁻¹ v| < 1 the ball of radius (1 − ρ)·min(a, b, c) is inside.
        a, b, c = (float(s) for s in piece.size)
        shortest = min(a, b, c)

        def in_ellipsoid(x: float, y: float, z: float) -> float:
            u, v, w = local(x, y, z)
            return (1.0 - math.sqrt((u / a) ** 2 + (v / b) ** 2 + (w / c) ** 2)) * shortest

        return in_ellipsoid
    if piece.shape == "box":
        hx, hy, hz = (float(s) / 2.0 for s in piece.size)

        def in_box(x: float, y: float, z: float) -> float:
            u, v, w = local(x, y, z)
            return min(hx - abs(u), hy - abs(v), hz - abs(w))

        return in_box
    assert piece.vertices is not None and piece.faces is not None
    vertices = np.asarray(piece.vertices, float)
    corners = vertices[np.asarray(piece.faces, int)]  # (faces, 3, 3)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    offsets = np.einsum("fi,fi->f", normals, corners[:, 0])
    outward = np.where(offsets >= normals @ vertices.mean(axis=0), 1.0, -1.0)
    normals, offsets = normals * outward[:, None], offsets * outward
    return lambda x, y, z: float((offsets - normals @ np.array(local(x, y, z))).min())


def body_point_near(body: Body) -> Callable[[fcl.CollisionObject, float, float, float],
                                             tuple[float, float, float]]:
    """``near(placed, x, y, z)``: the point of the placed body nearest the world point (the box
    or cylinder clamps it in its own frame), as a witness of an overlap."""
    if body.shape == "cylinder":
        radius, half_length = float(body.size[0]), float(body.size[1]) / 2.0
    else:
        hx, hy, hz = (float(s) / 2.0 for s in body.size)

    def near(placed: fcl.CollisionObject, x: float, y: float, z: float
             ) -> tuple[float, float, float]:
        (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = placed.getRotation().tolist()
        tx, ty, tz = placed.getTranslation().tolist()
        x, y, z = x - tx, y - ty, z - tz
        u = r00 * x + r10 * y + r20 * z
        v = r01 * x + r11 * y + r21 * z
        w = r02 * x + r12 * y + r22 * z
        if body.shape == "cylinder":
            w = min(max(w, -half_length), half_length)
            radial = math.sqrt(u * u + v * v)
            if radial > radius:
                u, v = u * radius / radial, v * radius / radial
        else:
            u, v, w = min(max(u, -hx), hx), min(max(v, -hy), hy), min(max(w, -hz), hz)
        return (tx + r00 * u + r01 * v + r02 * w, ty + r10 * u + r11 * v + r12 * w,
                tz + r20 * u + r21 * v + r22 * w)

    return near


class _Walker:
    """Conservative advancement along one (run, body, piece) stretch, writing into tracks."""

    def __init__(self, chunk: dict[str, np.ndarray], rotation: np.ndarray, position: np.ndarray,
                 cum: np.ndarray, body_list: tuple[Body, ...], pieces: list[Piece],
                 piece_owner: np.ndarray, obstacles: ObstacleSet, settings: CheckSettings,
                 cap: float, tracks: Tracks) -> None:
        self.chunk, self.rotation, self.position, self.cum = chunk, rotation, position, cum
        self.body_list, self.piece_owner = body_list, piece_owner
        self.obstacles, self.settings, self.cap, self.tracks = obstacles, settings, cap, tracks
        self.body_objects = [fcl_body(b) for b in body_list]
        self.piece_objects = [fcl_piece(p) for p in pieces]
        self.body_supports = [support_function(b.shape, b.size) for b in body_list]
        self.piece_supports = [piece_support(p) for p in pieces]
        self.exact = [p.shape == "sphere" for p in pieces]  # fcl has closed forms for these
        self.pieces = pieces
        self.piece_insides = [piece_inside(p) for p in pieces]
        self.body_nears = [body_point_near(b) for b in body_list]
        self.request = fcl.DistanceRequest()

    def _measurer(self, b: int, m: int, margin: float) -> Callable[[], tuple[float, float]]:
        """``measure() -> (value, allowance)`` at body ``b``'s current pose against piece ``m``:
        value is the clearance (0 in contact, capped), allowance how far (in ``u``) every
        decision and the clearance value within its error bound are sure to hold."""
        settings, tol, cap = self.settings, self.settings.contact_tolerance, self.cap
        min_step = settings.min_step
        resolution, relative = settings.clearance_resolution, settings.clearance_relative
        check_margin = margin > tol
        body_object, piece_object = self.body_objects[b], self.piece_objects[m]
        body_support, piece_world = self.body_supports[b], self.piece_supports[m]
        exact = self.exact[m]
        inside, near = self.piece_insides[m], self.body_nears[b]
        cx, cy, cz = np.asarray(self.pieces[m].centre, float).tolist()
        distance_of, new_result, request = fcl.distance, fcl.DistanceResult, self.request

        def measure() -> tuple[float, float]:
            if exact:
                distance = distance_of(body_object, piece_object, request, new_result())
                uncertain = 0.0
            else:  # GJK: the exact distance lies in [distance - uncertain, distance]
                distance, lower = certified_distance(body_object, body_support, piece_object,
                                                     piece_world, min_step)
                uncertain = distance - lower
            if distance <= tol:
                if distance > 0.0:
                    return 0.0, tol - distance
                # fcl reports -1 for overlap. A point q of the body inside the piece with a
                # ball of radius s around it inside too keeps the overlap while every point of
                # the body moves less than s, and the contact (distance ≤ tol) for s + tol.
                # q: the point of the body nearest the piece's centre.
                witness = inside(*near(body_object, cx, cy, cz))
                return 0.0, tol + (witness if witness > 0.0 else 0.0)
            # Keep the contact and buffer decisions, bound the clearance error.
            allowance = distance - tol
            if check_margin:
                to_margin = distance - margin if distance > margin else margin - distance
                if to_margin < allowance:
                    allowance = to_margin
            error_bound = relative * distance
            if error_bound < resolution:
                error_bound = resolution
            if distance - cap > error_bound:
                error_bound = distance - cap
            if error_bound < allowance:
                allowance = error_bound
            allowance -= uncertain  # every bound above holds from the lower end as well
            return (distance if distance < cap else cap), (
                allowance if allowance > min_step else min_step)

        return measure

    def walk(self, run: int, b: int, m: int, first: int, last: int) -> None:
        """Anchors at samples as far apart as their allowances permit; a gap between two
        consecutive samples is filled with interpolated anchors only when a contact or buffer
        entry could hide in it (both ends clear of a threshold, but not by enough)."""
        tol = self.settings.contact_tolerance
        body, body_object = self.body_list[b], self.body_objects[b]
        owner = int(self.piece_owner[m])
        margin = self.obstacles.buffer_margins[self.obstacles.obstacles[owner].level]
        measure = self._measurer(b, m, margin)
        span = slice(first, last + 1)
        cum = self.cum[run, span, b].tolist()
        rotations = quaternion_product(
            quaternions(self.chunk["roll"][run, span], self.chunk["pitch"][run, span],
                        self.chunk["yaw"][run, span]), body.quaternion)
        positions = self.position[run, span] + self.rotation[run, span] @ body.offset
        set_rotation, set_translation = body_object.setQuatRotation, body_object.setTranslation
        end = last - first
        values: list[float] = []
        counts: list[int] = []
        between: list[int] = []  # samples marked for contacts found between two samples
        fill_min = self.cap
        set_rotation(rotations[0])
        set_translation(positions[0])
        value, allowance = measure()
        first_contact: tuple[int, float] | None = (0, 0.0) if value == 0.0 else None
        j = 0
        while True:
            k = bisect_right(cum, cum[j] + allowance) - 1
            values.append(value)
            if k >= end:
                counts.append(end - j + 1)
                break
            if k > j:  # samples j..k-1 are covered by the anchor at j
                counts.append(k - j)
                j = k
                set_rotation(rotations[j])
                set_translation(positions[j])
                value, allowance = measure()
                if value == 0.0 and first_contact is None:
                    first_contact = (j, 0.0)
                continue
            counts.append(1)  # the next sample lies beyond the allowance: measure it too
            set_rotation(rotations[j + 1])
            set_translation(positions[j + 1])
            next_value, next_allowance = measure()
            step = cum[j + 1] - cum[j]
            if _gap_may_hide(value, next_value, step, tol, margin):
                low, contact_at = self._fill(run, body, first + j, measure, cum[j] + allowance,
                                             cum[j + 1] - next_allowance, cum[j], step)
                fill_min = min(fill_min, low)
                if contact_at is not None:
                    between.append(j if contact_at < 0.5 else j + 1)
                    if first_contact is None:
                        first_contact = (j, contact_at)
            j += 1
            value, allowance = next_value, next_allowance
            if value == 0.0 and first_contact is None:
                first_contact = (j, 0.0)
        self._record(run, b, owner, first, np.repeat(values, counts), between, first_contact,
                     fill_min)

    def _fill(self, run: int, body: Body, sample: int, measure: Callable[[], tuple[float, float]],
              u: float, u_end: float, u_sample: float, step: float) -> tuple[float, float | None]:
        """Interpolated anchors from ``u`` to ``u_end`` between ``sample`` and the next one:
        the smallest clearance seen and the fraction of the step where contact starts, if any."""
        body_object = self.body_objects[self.body_list.index(body)]
        low = self.cap
        while u < u_end:
            frac = (u - u_sample) / step
            quaternion, position = self._pose_between(run, sample, frac, body)
            body_object.setQuatRotation(quaternion)
            body_object.setTranslation(position)
            value, allowance = measure()
            low = min(low, value)
            if value == 0.0:
                return 0.0, frac
            u += allowance
        return low, None

    def _pose_between(self, run: int, sample: int, frac: float, body: Body
                      ) -> tuple[np.ndarray, np.ndarray]:
        """Quaternion and position of ``body`` at the pose interpolated linearly between two
        samples (the motion bound assumes exactly this interpolation); plain floats, as this
        runs once per interpolated anchor."""
        c = self.chunk

        def lerp(name: str) -> float:
            a = float(c[name][run, sample])
            return a + frac * (float(c[name][run, sample + 1]) - a)

        roll, pitch, yaw = lerp("roll") / 2, lerp("pitch") / 2, lerp("yaw") / 2
        cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
        cy, sy = math.cos(yaw), math.sin(yaw)
        w = cy * cp * cr + sy * sp * sr
        x = cy * cp * sr - sy * sp * cr
        y = cy * sp * cr + sy * cp * sr
        z = sy * cp * cr - cy * sp * sr
        ox, oy, oz = (float(v) for v in body.offset)
        # v + 2w (q × v) + 2 q × (q × v): the offset rotated by the pose.
        tx, ty, tz = 2 * (y * oz - z * oy), 2 * (z * ox - x * oz), 2 * (x * oy - y * ox)
        px = lerp("x") + ox + w * tx + (y * tz - z * ty)
        py = lerp("y") + oy + w * ty + (z * tx - x * tz)
        pz = lerp("z") + oz + w * tz + (x * ty - y * tx)
        bw, bx, by, bz = (float(v) for v in body.quaternion)
        quaternion = np.array([w * bw - x * bx - y * by - z * bz,
                               w * bx + x * bw + y * bz - z * by,
                               w * by - x * bz + y * bw + z * bx,
                               w * bz + x * by - y * bx + z * bw])
        return quaternion, np.array([px, py, pz])

    def _record(self, run: int, b: int, owner: int, first: int, per_sample: np.ndarray,
                between: list[int], first_contact: tuple[int, float] | None,
                fill_min: float) -> None:
        tracks = self.tracks
        body = self.body_list[b]
        span = slice(first, first + len(per_sample))
        np.minimum(tracks.clearance[run, span, b], per_sample, out=tracks.clearance[run, span, b])
        part = body.part
        tracks.nearest[run, b, owner] = min(tracks.nearest[run, b, owner],
                                            float(per_sample.min()), fill_min)
        if first_contact is None:
            return
        level = self.obstacles.obstacles[owner].level
        touching = np.concatenate([np.flatnonzero(per_sample == 0.0), between]).astype(int)
        tracks.contact[run, touching + first, part, level] = 1
        tracks.clearance[run, touching + first, b] = 0.0
        tracks.hit[run, b, owner] = True
        j, frac = first_contact
        sample = first + j
        nxt = min(sample + 1, self.chunk["t"].shape[1] - 1)
        pose = {name: (1 - frac) * float(self.chunk[name][run, sample])
                + frac * float(self.chunk[name][run, nxt]) for name in ("t", "x", "y", "z")}
        tracks.note_contact(FirstContact(PARTS[part], LEVELS[level], pose["t"], pose["x"],
                                         pose["y"], pose["z"], body.name,
                                         self.obstacles.obstacles[owner].name), run)


def _gap_may_hide(value: float, next_value: float, step: float, tol: float,
                  margin: float) -> bool:
    """Whether a contact or buffer entry could lie strictly between two measured samples that
    both show none: the distance can dip at most to ``(d0 + d1 - step) / 2`` in between."""
    if value == 0.0 or next_value == 0.0:
        return False  # a contact at either end already counts
    lowest = (value + next_value - step) / 2.0
    if lowest <= tol:
        return True
    return margin > tol and value >= margin and next_value >= margin and lowest < margin
