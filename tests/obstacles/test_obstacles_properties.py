"""Properties of the collision check (hypothesis): rigid motions of the whole scene change
nothing, clearance is zero exactly where there is contact, shrinking an obstacle never adds
collisions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from idefix_rules.obstacles import (
    CheckSettings,
    ObstacleSet,
    RoverBodies,
    collision_signals,
    rotation_matrices,
)
from idefix_rules.obstacles.distances import (
    certified_distance,
    fcl_body,
    fcl_piece,
    piece_support,
    support_function,
)
from idefix_rules.obstacles.reference import reference_collision_signals

SETTINGS = CheckSettings()
SAMPLES = 30
finite = {"allow_nan": False, "allow_infinity": False}


@st.composite
def scenes(draw: st.DrawFn) -> tuple[dict[str, np.ndarray], list[dict[str, float]]]:
    """A short drive (fast enough for steps of several cm) and up to three rocks near it."""
    heading = draw(st.floats(-math.pi, math.pi, **finite))
    length = draw(st.floats(0.2, 2.0, **finite))
    turn = draw(st.floats(-0.8, 0.8, **finite))
    roll = draw(st.floats(-0.1, 0.1, **finite))
    pitch = draw(st.floats(-0.1, 0.1, **finite))
    s = np.linspace(0.0, 1.0, SAMPLES)
    yaw = heading + turn * s
    step = length / (SAMPLES - 1)
    x = np.concatenate([[0.0], np.cumsum(step * np.cos(yaw[:-1]))])
    y = np.concatenate([[0.0], np.cumsum(step * np.sin(yaw[:-1]))])
    poses = {"t": 10.0 * s, "x": x, "y": y, "z": 0.3 + 0.0 * s, "roll": roll + 0.0 * s,
             "pitch": pitch + 0.0 * s, "yaw": yaw}
    rocks = []
    for number in range(draw(st.integers(1, 3))):
        at = draw(st.integers(0, SAMPLES - 1))
        side = draw(st.floats(-0.8, 0.8, **finite))
        rocks.append({
            "name": f"r{number}",
            "x": float(x[at] - side * math.sin(yaw[at])),
            "y": float(y[at] + side * math.cos(yaw[at])),
            "z": draw(st.floats(-0.05, 0.1, **finite)),
            "a": draw(st.floats(0.02, 0.2, **finite)),
            "b": draw(st.floats(0.02, 0.2, **finite)),
            "c": draw(st.floats(0.02, 0.4, **finite)),
            "yaw": draw(st.floats(-math.pi, math.pi, **finite)),
            "level": draw(st.integers(1, 3)),
        })
    return {name: a[None, :] for name, a in poses.items()}, rocks


def check(poses: dict[str, np.ndarray], rocks: list[dict[str, float]]):
    obstacles = ObstacleSet.from_rocks(rocks, buffer_margins=[0.02, 0.05, 0.1])
    return collision_signals(poses, obstacles, settings=SETTINGS)


def error_bound(clearance: np.ndarray) -> np.ndarray:
    """The documented clearance error, relative to the value reported: two reports of the same
    exact value differ by at most ``error_bound(a) + error_bound(b)``."""
    return np.maximum(SETTINGS.clearance_resolution, SETTINGS.clearance_relative * clearance)


def _moved(poses: dict[str, np.ndarray], rocks: list[dict[str, float]], dx: float, dy: float,
           dz: float, angle: float) -> tuple[dict[str, np.ndarray], list[dict[str, float]]]:
    """Rover and rocks turned by ``angle`` about the z axis, then shifted by (dx, dy, dz)."""
    c, s = math.cos(angle), math.sin(angle)
    moved = dict(poses)
    moved["x"] = c * poses["x"] - s * poses["y"] + dx
    moved["y"] = s * poses["x"] + c * poses["y"] + dy
    moved["z"] = poses["z"] + dz
    moved["yaw"] = poses["yaw"] + angle
    moved_rocks = [{**r, "x": c * r["x"] - s * r["y"] + dx, "y": s * r["x"] + c * r["y"] + dy,
                    "z": r["z"] + dz, "yaw": r["yaw"] + angle} for r in rocks]
    return moved, moved_rocks


@settings(max_examples=40, deadline=None)
@given(scenes(), st.floats(-50, 50, **finite), st.floats(-50, 50, **finite),
       st.floats(-1, 1, **finite), st.floats(-math.pi, math.pi, **finite))
def test_moving_rover_and_obstacles_together_changes_nothing(scene, dx, dy, dz, angle):
    poses, rocks = scene
    moved, moved_rocks = _moved(poses, rocks, dx, dy, dz, angle)
    before, after = check(poses, rocks), check(moved, moved_rocks)
    for name in ("collision.hits", "collision.buffer"):
        assert np.array_equal(before.signals[name], after.signals[name]), name
    assert before.details[0].body_hits == after.details[0].body_hits
    a = before.signals["collision.clearance"]
    b = after.signals["collision.clearance"]
    free = (a > 0) & (b > 0)
    assert np.all((np.abs(a - b) <= error_bound(a) + error_bound(b) + 1e-6)[free])


@settings(max_examples=40, deadline=None)
@given(scenes())
def test_clearance_is_zero_exactly_where_there_is_contact(scene):
    result = check(*scene)
    clearance = result.signals["collision.clearance"]
    contact = result.signals["collision.contact"].any(axis=-1)
    assert np.all(clearance >= 0.0)
    assert np.array_equal(clearance == 0.0, contact)
    hit = result.signals["collision.hits"].sum(axis=-1) > 0  # (runs, part)
    assert np.array_equal(hit, contact.any(axis=1))


@settings(max_examples=40, deadline=None)
@given(scenes(), st.floats(0.2, 0.99, **finite))
def test_shrinking_an_obstacle_never_adds_collisions(scene, factor):
    poses, rocks = scene
    shrunk = [{**r, "a": r["a"] * factor, "b": r["b"] * factor, "c": r["c"] * factor}
              for r in rocks]
    before, after = check(poses, rocks), check(poses, shrunk)
    assert np.all(after.signals["collision.hits"] <= before.signals["collision.hits"])
    for body, names in after.details[0].body_hits.items():
        assert set(names) <= set(before.details[0].body_hits[body])
    a = before.signals["collision.clearance"]
    b = after.signals["collision.clearance"]
    assert np.all(b >= a - error_bound(a) - error_bound(b) - 1e-6)


# A case the property above found: chassis against an ellipsoid rock, where fcl's GJK (python-fcl
# 0.7.0.11) stops early at the middle pose and reports 0.2919 m for an exact 0.1455 m; its
# neighbours, 2 cm away, are 0.1466 m and 0.1442 m. Exact values: fcl with the objects swapped,
# confirmed by the support-function lower bound to 1e-5 m.
GJK_CASE_ROCKS = [
    {"name": "r0", "x": -0.1133878409857203, "y": -0.7144535942688136,
     "z": 0.0061926262734247756, "a": 0.1893697103040425, "b": 0.08736657562042882,
     "c": 0.2718084401862133, "yaw": -2.9628314511003033, "level": 3},
    {"name": "r1", "x": -0.5461710511318165, "y": 0.3254366897612746,
     "z": 0.0883693249204736, "a": 0.14481984161497632, "b": 0.1852176153628496,
     "c": 0.3946452303767167, "yaw": -0.33287233636287983, "level": 2}]
GJK_CASE_POSES = {
    "t": np.array([[7.586206896551724, 7.931034482758621, 8.275862068965518]]),
    "x": np.array([[-0.47352114308253984, -0.494249179895345, -0.5149000624763429]]),
    "y": np.array([[-0.20859666622256387, -0.21975782144643763, -0.2310610928609551]]),
    "z": np.full((1, 3), 0.3), "roll": np.full((1, 3), -0.08159556875068924),
    "pitch": np.full((1, 3), 0.04005803795370533),
    "yaw": np.array([[-2.647654851430268, -2.6407858643258955, -2.6339168772215236]])}
GJK_CASE_EXACT = np.array([0.146632, 0.145523, 0.144222])  # chassis clearance per sample


def test_a_distance_gjk_gets_wrong_is_certified_and_corrected():
    rocks = ObstacleSet.from_rocks(GJK_CASE_ROCKS, buffer_margins=[0.02, 0.05, 0.1])
    piece = rocks.obstacles[1].pieces[0]
    chassis = next(b for b in RoverBodies().bodies() if b.name == "chassis")
    body_object, piece_object = fcl_body(chassis), fcl_piece(piece)
    pose = {name: float(a[0, 1]) for name, a in GJK_CASE_POSES.items()}
    body_object.setRotation(rotation_matrices(np.array(pose["roll"]), np.array(pose["pitch"]),
                                              np.array(pose["yaw"])))
    body_object.setTranslation(np.array([pose["x"], pose["y"], pose["z"]]))
    distance, lower = certified_distance(
        body_object, support_function(chassis.shape, chassis.size), piece_object,
        piece_support(piece), SETTINGS.min_step)
    assert lower <= distance <= lower + SETTINGS.min_step
    assert abs(distance - GJK_CASE_EXACT[1]) < 1e-5


def test_moving_the_scene_where_gjk_failed_changes_nothing():
    """The failing example of the rigid-motion property, pinned: clearance in the original frame
    (where fcl's first answer is wrong) and in the moved one, fast and exhaustive checker."""
    moved_poses, moved_rocks = _moved(GJK_CASE_POSES, GJK_CASE_ROCKS, -18.92642400181259,
                                      -31.276379655918017, -0.1576709243079879,
                                      2.2427988923337834)
    for poses, rocks in ((GJK_CASE_POSES, GJK_CASE_ROCKS), (moved_poses, moved_rocks)):
        obstacles = ObstacleSet.from_rocks(rocks, buffer_margins=[0.02, 0.05, 0.1])
        for checker in (collision_signals, reference_collision_signals):
            clearance = checker(poses, obstacles, settings=SETTINGS).signals[
                "collision.clearance"][0, :, 2]
            assert np.all(np.abs(clearance - GJK_CASE_EXACT) <= error_bound(clearance)), (
                checker.__name__, clearance)


def _point_in_polygon(x: float, y: float, polygon: np.ndarray) -> bool:
    inside = False
    for (x1, y1), (x2, y2) in zip(polygon, np.roll(polygon, -1, axis=0), strict=True):
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            inside = not inside
    return inside


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.integers(-12, 12), st.integers(-12, 12)), min_size=3,
                max_size=10, unique=True),
       st.sampled_from([0.1, 0.2, 0.3]), st.integers(0, 9))
def test_a_polygon_is_cut_into_triangles_inside_it_whatever_vertex_comes_first(
        grid_points, step, start):
    """On a coarse grid three vertices often lie on a line: a vertex on an ear's diagonal,
    read as just outside by rounding, let an edge cross the ear (0.36 m² outside a keep-out
    and a chain excluded for ground it never entered)."""
    from hypothesis import assume, event

    from idefix_rules.errors import UserInputError
    from idefix_rules.obstacles.areas import _ear_clip, _not_simple, _signed_area2

    points = np.array(grid_points, float) * step
    # a star-shaped order about the centroid: often simple, not always
    centre = points.mean(axis=0)
    points = points[np.argsort(np.arctan2(points[:, 1] - centre[1], points[:, 0] - centre[0]))]
    points = np.roll(points, start % len(points), axis=0)
    assume(_not_simple(points) is None and abs(_signed_area2(points)) > 1e-9)
    if _signed_area2(points) < 0:
        points = points[::-1]
    try:
        triangles = _ear_clip(points, "area")
    except UserInputError:
        raise AssertionError("a simple polygon was refused") from None
    doubled = [(b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
               for a, b, c in (points[list(t)] for t in triangles)]
    from itertools import combinations
    collinear = any(abs((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])) < 1e-12
                    for a, b, c in combinations(points, 3))
    event(f"three vertices on a line: {collinear}")
    assert min(doubled) >= -1e-12  # every triangle counter-clockwise, none turned inside out
    assert sum(doubled) == pytest.approx(_signed_area2(points), abs=1e-9)  # they tile it
    for triangle in triangles:
        a, b, c = points[list(triangle)]
        if abs((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])) > 1e-9:
            centroid = (a + b + c) / 3
            assert _point_in_polygon(centroid[0], centroid[1], points)


# A site's keep-out: 9 vertices on a 0.2 m grid, (0.8, -1.8), (0.4, -1.2) and (-1.6, 1.8) on
# one line, so that a diagonal of the ear cut from its first vertex passes through a vertex.
NOTCHED = [(0.8, -1.8), (0.4, -1.2), (-0.4, -1.8), (-2.0, -1.2), (-1.6, -0.2), (-4.8, 3.0),
           (-1.6, 1.8), (-0.4, 3.0), (2.6, 4.4)]


@pytest.mark.parametrize("start", range(len(NOTCHED)))
@pytest.mark.parametrize("reverse", [False, True])
def test_a_notched_keep_out_is_tiled_from_any_first_vertex(start: int, reverse: bool) -> None:
    from idefix_rules.obstacles.areas import _ear_clip, _signed_area2

    points = np.roll(np.array(NOTCHED[::-1] if reverse else NOTCHED), start, axis=0)
    if _signed_area2(points) < 0:
        points = points[::-1]
    doubled = [(b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
               for a, b, c in (points[list(t)] for t in _ear_clip(points, "keep-out"))]
    assert min(doubled) >= 0  # none turned inside out (the last one was, -0.72)
    assert sum(doubled) == pytest.approx(2 * 18.76)
