"""python-fcl objects of bodies and pieces, and their fcl distances certified against GJK."""

from __future__ import annotations

import math
from collections.abc import Callable

import fcl
import numpy as np

from idefix_rules.obstacles.bodies import Body
from idefix_rules.obstacles.obstacles import Piece


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
