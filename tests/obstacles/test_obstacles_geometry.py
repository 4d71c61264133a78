"""Rover bodies, frames, obstacle construction and input errors."""

from __future__ import annotations

import doctest
import math

import numpy as np
import pytest

import idefix_rules.obstacles.areas
import idefix_rules.obstacles.bodies
import idefix_rules.obstacles.check
import idefix_rules.obstacles.obstacles
from idefix_rules.commands import RoverGeometry
from idefix_rules.errors import UserInputError
from idefix_rules.obstacles import (
    LevelThresholds,
    ObstacleSet,
    RoverBodies,
    collision_signals,
    level_index,
    polygon_area,
    rotation_matrices,
    steep_terrain,
)


@pytest.mark.parametrize("module", [idefix_rules.obstacles.areas, idefix_rules.obstacles.bodies,
                                    idefix_rules.obstacles.check,
                                    idefix_rules.obstacles.obstacles])
def test_docstring_examples(module):
    failures, tried = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
    assert tried > 0 and failures == 0


def test_rotation_convention_positive_roll_lowers_the_right_side_positive_pitch_the_nose():
    right = np.array([0.0, -1.0, 0.0])
    nose = np.array([1.0, 0.0, 0.0])
    assert (rotation_matrices(np.array(0.1), np.array(0.0), np.array(0.0)) @ right)[2] < 0
    assert (rotation_matrices(np.array(0.0), np.array(0.1), np.array(0.0)) @ nose)[2] < 0
    roll, pitch, yaw = 0.1, -0.2, 2.5
    expected = (_axis(2, yaw) @ _axis(1, pitch) @ _axis(0, roll))
    assert np.allclose(rotation_matrices(np.array(roll), np.array(pitch), np.array(yaw)),
                       expected)


def _axis(axis: int, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    out = np.eye(3)
    out[i, i], out[i, j], out[j, i], out[j, j] = c, -s, s, c
    return out


def test_wheels_sit_where_the_kinematics_put_them_and_touch_flat_ground():
    bodies = RoverBodies()
    geometry = RoverGeometry()
    wheels = {b.name: b for b in bodies.bodies() if b.part == 0}
    assert sorted(wheels) == ["FL", "FR", "RL", "RR"]
    assert wheels["FL"].offset[:2].tolist() == [geometry.half_wheelbase, geometry.half_track]
    assert wheels["RR"].offset[:2].tolist() == [-geometry.half_wheelbase, -geometry.half_track]
    # Wheel bottom on the ground (pose z = body-centre height), chassis bottom at the clearance.
    assert bodies.body_centre_height + wheels["FL"].offset[2] - bodies.wheel_radius == \
        pytest.approx(0.0)
    assert bodies.body_centre_height - bodies.chassis_height / 2 == bodies.ground_clearance
    other = RoverBodies.from_geometry(RoverGeometry(0.12, 0.3, 0.25))
    assert {b.name: b.offset[1] for b in other.bodies()}["FL"] == 0.3


def test_a_higher_ground_clearance_clears_the_slab(drive):
    slab = {"name": "slab", "x": 0.8, "y": 0.0, "z": 0.0, "a": 0.15, "b": 0.12, "c": 0.18,
            "level": "L3"}
    obstacles = ObstacleSet.from_rocks([slab])
    assert collision_signals(drive(), obstacles).signals["collision.hits"][0, 2, 2] == 1
    high = RoverBodies(ground_clearance=0.2)
    poses = drive()
    poses["z"] = poses["z"] * 0 + high.body_centre_height
    assert collision_signals(poses, obstacles, high).signals["collision.hits"].sum() == 0


def test_tall_rock_beside_the_rover_hits_the_solar_panel_only(drive):
    # Panels span y 0.185..0.385 at 0.43-0.45 m height; the left wheels' outer face is at 0.29.
    pillar = {"name": "pillar", "x": 0.8, "y": 0.36 + 0.05, "z": 0.0, "a": 0.05, "b": 0.05,
              "c": 0.6, "level": "L3"}
    result = collision_signals(drive(), ObstacleSet.from_rocks([pillar]))
    assert result.signals["collision.hits"][0].tolist() == [[0, 0, 0], [0, 0, 1], [0, 0, 0]]
    assert result.details[0].body_hits["panel_left"] == ("pillar",)


def test_convex_hull_rock(drive):
    points = [(0.7, -0.3, 0.0), (0.9, -0.3, 0.0), (0.8, -0.2, 0.0), (0.8, -0.25, 0.09)]
    obstacles = ObstacleSet.from_rocks([{"points": points}],
                                       thresholds=LevelThresholds(0.05, 0.10))
    rock = obstacles.obstacles[0]
    assert (rock.name, rock.level_name, rock.size) == ("rock1", "L2", pytest.approx(0.09))
    hits = collision_signals(drive(), obstacles).signals["collision.hits"][0]
    assert hits[0, 1] == 1


def test_rock_size_is_its_height_above_the_ground():
    record = {"x": 1.0, "y": 2.0, "z": 0.5, "a": 0.3, "b": 0.3, "c": 0.1}
    thresholds = LevelThresholds(0.2, 0.5)
    on_datum = ObstacleSet.from_rocks([record], thresholds)
    assert on_datum.obstacles[0].size == pytest.approx(0.6)
    assert on_datum.obstacles[0].level_name == "L3"
    on_hill = ObstacleSet.from_rocks([record], thresholds, ground=lambda x, y: 0.45)
    assert on_hill.obstacles[0].size == pytest.approx(0.15)
    assert on_hill.obstacles[0].level_name == "L1"


def test_rock_records_may_be_objects_with_attributes():
    class Rock:
        def __init__(self) -> None:
            self.centre = (0.0, 0.0, 0.0)
            self.semi_axes = (0.1, 0.2, 0.05)
            self.level = 2

    rock = ObstacleSet.from_rocks([Rock()]).obstacles[0]
    assert (rock.level_name, rock.pieces[0].shape, rock.pieces[0].size) == \
        ("L2", "ellipsoid", (0.1, 0.2, 0.05))


@pytest.mark.parametrize(("records", "fragment"), [
    ([{"x": 0, "y": 0, "z": 0, "radius": 0.1}], "no level"),
    ([{"x": 0, "y": 0, "radius": 0.1, "level": "L1"}], "centre"),
    ([{"x": 0, "y": 0, "z": 0, "radius": -0.1, "level": "L1"}], "positive"),
    ([{"x": 0, "y": 0, "z": 0, "level": "L1"}], "radius"),
    ([{"x": 0, "y": 0, "z": 0, "radius": 0.1, "level": "L4"}], "level"),
    ([{"points": [(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)], "level": 1}], "volume"),
    ([{"name": "a", "x": 0, "y": 0, "z": 0, "radius": 0.1, "level": 1}] * 2, "unique"),
])
def test_bad_rocks_are_user_errors(records, fragment):
    with pytest.raises(UserInputError) as caught:
        ObstacleSet.from_rocks(records)
    assert fragment in caught.value.render()


def test_all_bad_rocks_are_reported_at_once():
    with pytest.raises(UserInputError) as caught:
        ObstacleSet.from_rocks([{"x": 0}, {"y": 0}])
    assert len(caught.value.diagnostics) == 2


@pytest.mark.parametrize("make", [
    lambda: LevelThresholds(0.2, 0.1),
    lambda: ObstacleSet((), {"L2": -0.1}),
    lambda: ObstacleSet((), [0.1, 0.2]),
    lambda: level_index("high"),
    lambda: RoverBodies(wheel_radius=0.0),
    lambda: polygon_area([(0, 0), (1, 1), (1, 0), (0, 1)], "L1", "bow-tie"),
    lambda: polygon_area([(0, 0), (1, 1)], "L1", "line"),
    lambda: steep_terrain(np.zeros((3, 3)), (0, 0), 0.1, math.radians(95), "L1"),
    lambda: steep_terrain(np.zeros(3), (0, 0), 0.1, 0.3, "L1"),
    lambda: steep_terrain(np.full((3, 3), np.nan), (0, 0), 0.1, 0.3, "L1"),
])
def test_bad_settings_are_user_errors(make):
    with pytest.raises(UserInputError):
        make()


@pytest.mark.parametrize(("change", "fragment"), [
    (lambda p: p.pop("yaw"), "lack yaw"),
    (lambda p: p.__setitem__("x", p["x"][:, :-1]), "shape"),
    (lambda p: p.__setitem__("z", p["z"] * np.nan), "NaN"),
    (lambda p: p.__setitem__("x", p["x"][0]), "(runs, samples)"),
])
def test_bad_poses_are_user_errors(drive, change, fragment):
    poses = drive(samples=11)
    change(poses)
    with pytest.raises(UserInputError) as caught:
        collision_signals(poses, ObstacleSet())
    assert fragment in caught.value.render()


def test_no_obstacles_means_no_contact_and_capped_clearance(drive):
    result = collision_signals(drive(samples=11), ObstacleSet())
    assert result.signals["collision.hits"].sum() == 0
    assert np.all(result.signals["collision.clearance"] == result.clearance_cap)
    assert result.details[0].to_dict()["hits"] == {"wheel": [], "solar_panel": [],
                                                   "chassis": []}


def test_results_are_plain_data_and_chunks_number_runs(drive):
    one = drive(samples=51)
    poses = {name: np.repeat(array, 3, axis=0) for name, array in one.items()}
    poses["y"] = poses["y"] + np.array([[0.0], [0.5], [-0.26]])
    obstacles = ObstacleSet.from_rocks([{"x": 0.8, "y": -0.26, "z": 0, "radius": 0.08,
                                         "level": 2}])
    from idefix_rules.obstacles import CheckSettings
    chunked = collision_signals(poses, obstacles, settings=CheckSettings(chunk_poses=60),
                                first_run=10)
    whole = collision_signals(poses, obstacles)
    for name, array in whole.signals.items():
        assert np.array_equal(array, chunked.signals[name]), name
    assert [d.run for d in chunked.details] == [10, 11, 12]
    summary = chunked.to_dict()
    assert summary["hits"][0][0] == [0, 1, 0]
    assert summary["details"][0]["first_contacts"][0]["obstacle"] == "rock1"
    assert chunked.signals["collision.contact"].dtype == np.int8
    assert chunked.signals["collision.hits"].dtype == np.int64


def test_rocks_of_the_fmu_terrain_are_the_same_obstacles():
    from idefix_rules.fmu.terrain import Rock, synthetic_terrain

    terrain = synthetic_terrain(size=2.0, cell=0.05, slope=0.1, seed=1,
                                rocks=[Rock(x=0.5, y=-0.26, a=0.08, b=0.06, c=0.05, level="L2"),
                                       Rock(x=-0.5, y=0.3, a=0.1, b=0.1, c=0.1)])
    obstacles = ObstacleSet.from_terrain(terrain, LevelThresholds(0.05, 0.15))
    first, second = obstacles.obstacles
    assert first.level_name == "L2"
    rock = terrain.rocks[1]
    assert second.size == pytest.approx(rock.z + rock.c - float(terrain.height_at(-0.5, 0.3)))
    assert second.pieces[0].centre.tolist() == pytest.approx([-0.5, 0.3, rock.z])


def test_quaternions_are_the_same_rotations_as_the_matrices():
    import fcl

    from idefix_rules.obstacles.bodies import quaternion_product, quaternions

    rng = np.random.default_rng(0)
    angles = rng.uniform(-3, 3, (3, 5))
    body = fcl.CollisionObject(fcl.Box(1, 1, 1), fcl.Transform())
    matrices = rotation_matrices(*angles)
    tilt = 0.4
    q = quaternion_product(quaternions(*angles), quaternions(np.array(tilt), np.array(0.0),
                                                             np.array(0.0)))
    for k in range(5):
        body.setQuatRotation(q[k])
        assert np.allclose(body.getRotation(), matrices[k] @ _axis(0, tilt))


@pytest.mark.parametrize("ground", [0.0, 100.0, -30.0])
@pytest.mark.parametrize(("centre_above", "radius", "level"), [
    (0.04, 0.06, 2),  # its top exactly 10 cm up: "L2 below 10 cm" makes it L3
    (0.039, 0.06, 1),  # 9.9 cm: L2
])
def test_a_rock_at_a_level_boundary_takes_the_level_its_numbers_give(
        ground: float, centre_above: float, radius: float, level: int) -> None:
    """The subtraction top − ground left 0.0999999999999943 m on a DEM 100 m up (and
    0.09999999999999999 for 6 cm − 2 cm embedded): L2 where the size stored and shown was 10 cm
    and the rulebook's boundary puts it in L3."""
    from idefix_rules.obstacles import LevelThresholds

    rock = {"x": 0.5, "y": 0.0, "z": ground + centre_above, "radius": radius}
    obstacles = ObstacleSet.from_rocks([rock], LevelThresholds(0.03, 0.10),
                                       ground=lambda x, y: ground)
    (obstacle,) = obstacles.obstacles
    assert obstacle.level == level
    assert obstacle.size == pytest.approx(centre_above + radius, abs=1e-12)
