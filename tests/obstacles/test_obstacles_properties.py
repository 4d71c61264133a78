"""Properties of the collision check (hypothesis): rigid motions of the whole scene change
nothing, clearance is zero exactly where there is contact, shrinking an obstacle never adds
collisions."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from idefix_rules.obstacles import CheckSettings, ObstacleSet, collision_signals

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
    return np.maximum(SETTINGS.clearance_resolution, SETTINGS.clearance_relative * clearance)


@settings(max_examples=40, deadline=None)
@given(scenes(), st.floats(-50, 50, **finite), st.floats(-50, 50, **finite),
       st.floats(-1, 1, **finite), st.floats(-math.pi, math.pi, **finite))
def test_moving_rover_and_obstacles_together_changes_nothing(scene, dx, dy, dz, angle):
    poses, rocks = scene
    c, s = math.cos(angle), math.sin(angle)
    moved = dict(poses)
    moved["x"] = c * poses["x"] - s * poses["y"] + dx
    moved["y"] = s * poses["x"] + c * poses["y"] + dy
    moved["z"] = poses["z"] + dz
    moved["yaw"] = poses["yaw"] + angle
    moved_rocks = [{**r, "x": c * r["x"] - s * r["y"] + dx, "y": s * r["x"] + c * r["y"] + dy,
                    "z": r["z"] + dz, "yaw": r["yaw"] + angle} for r in rocks]
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
