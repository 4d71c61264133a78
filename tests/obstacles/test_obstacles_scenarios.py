"""Collision scenarios whose answer geometry gives: rocks on and beside the wheel path, a flat rock
under the chassis, a fast drive that would jump over a small rock, buffer zones, areas."""

from __future__ import annotations

import numpy as np
import pytest

from idefix_rules.obstacles import (
    CheckSettings,
    LevelThresholds,
    ObstacleSet,
    RoverBodies,
    collision_signals,
    polygon_area,
    steep_terrain,
    unknown_terrain,
)
from idefix_rules.obstacles.reference import reference_collision_signals

FINE = CheckSettings(clearance_resolution=1e-5, clearance_relative=1e-4)
WHEEL, PANEL, CHASSIS = 0, 1, 2
L1, L2, L3 = 0, 1, 2


def rock(y: float, radius: float = 0.08, x: float = 0.8, level: str = "L2", **extra: object
         ) -> dict[str, object]:
    return {"name": "rock", "x": x, "y": y, "z": 0.0, "radius": radius, "level": level, **extra}


def test_rock_on_the_right_wheel_path_is_hit_by_the_right_wheels_only(drive):
    result = collision_signals(drive(), ObstacleSet.from_rocks([rock(-0.26)]))
    hits = result.signals["collision.hits"][0]
    assert hits.tolist() == [[0, 1, 0], [0, 0, 0], [0, 0, 0]]
    details = result.details[0]
    assert {b for b, names in details.body_hits.items() if names} == {"FR", "RR"}
    first = details.first_contacts[0]
    assert (first.part, first.level, first.body) == ("wheel", "L2", "FR")
    # The front right wheel (radius 0.1, axle 0.1 m up) first touches the sphere when the
    # centres are 0.18 m + contact tolerance apart in the x-z plane.
    contact_x = 0.8 - np.sqrt((0.18 + 0.005) ** 2 - 0.1 ** 2) - 0.2
    assert first.x == pytest.approx(contact_x, abs=0.006)
    contact = result.signals["collision.contact"][0]
    assert contact[:, WHEEL, L2].any() and not contact[:, :, [L1, L3]].any()
    assert not contact[:, [PANEL, CHASSIS]].any()


def test_rock_20_cm_aside_is_missed_with_the_clearance_geometry_gives(drive):
    obstacles = ObstacleSet.from_rocks([rock(-0.26)])
    result = collision_signals(drive(y0=0.2), obstacles, settings=FINE)
    assert result.signals["collision.hits"].sum() == 0
    assert result.signals["collision.contact"].sum() == 0
    # Right wheel's outer face at y = 0.2 - 0.26 - 0.03; rock surface at -0.26 + 0.08.
    expected = (0.2 - 0.26 - 0.03) - (-0.26 + 0.08)
    assert result.details[0].min_clearance["rock"] == pytest.approx(expected, abs=1e-4)
    assert result.signals["collision.clearance"][0, :, WHEEL].min() == pytest.approx(
        expected, abs=1e-4)
    reference = reference_collision_signals(drive(y0=0.2, samples=151), obstacles)
    assert reference.details[0].min_clearance["rock"] == pytest.approx(expected, abs=1e-3)


@pytest.mark.parametrize(("height", "chassis_hit"), [(0.10, False), (0.14, False),
                                                     (0.16, True), (0.25, True)])
def test_flat_rock_under_the_chassis_hits_it_only_when_taller_than_the_clearance(
        drive, height, chassis_hit):
    flat = {"name": "slab", "x": 0.8, "y": 0.0, "z": 0.0, "a": 0.15, "b": 0.12, "c": height,
            "level": "L3"}
    result = collision_signals(drive(), ObstacleSet.from_rocks([flat]))
    hits = result.signals["collision.hits"][0]
    assert hits[WHEEL].sum() == 0
    assert hits[CHASSIS, L3] == int(chassis_hit)
    assert RoverBodies().ground_clearance == 0.15


def test_fast_drive_does_not_jump_over_a_small_rock(drive):
    # Two samples 2 m apart: neither pose touches the 3 cm rock between them.
    poses = drive(x0=-1.0, x1=1.0, samples=2, duration=1.0)
    obstacles = ObstacleSet.from_rocks([rock(-0.26, radius=0.03, x=0.2)])
    result = collision_signals(poses, obstacles)
    assert result.signals["collision.hits"][0, WHEEL, L2] == 1
    assert result.signals["collision.contact"][0, :, WHEEL, L2].sum() >= 1
    first = result.details[0].first_contacts[0]
    assert -1.0 < first.x < 1.0 and 0.0 < first.time < 1.0
    # The sample-only check misses it: that is what the advancement between samples is for.
    assert reference_collision_signals(poses, obstacles).signals["collision.hits"].sum() == 0


def test_buffer_zone_is_entered_without_hitting(drive):
    # Rock surface 3 cm from the right wheels' outer face; L2 margin 5 cm, L3 margin 2 cm.
    near = rock(-0.26 - 0.03 - 0.03 - 0.08)
    for margins, entered in (({"L2": 0.05}, 1), ({"L2": 0.02}, 0)):
        result = collision_signals(drive(), ObstacleSet.from_rocks([near],
                                                                   buffer_margins=margins))
        assert result.signals["collision.hits"].sum() == 0
        assert result.signals["collision.buffer"][0, WHEEL, L2] == entered
        assert result.details[0].buffers["wheel"] == (("rock",) if entered else ())


def test_a_hit_rock_does_not_also_count_as_buffer_entry(drive):
    result = collision_signals(drive(), ObstacleSet.from_rocks([rock(-0.26)],
                                                              buffer_margins=[0.1, 0.1, 0.1]))
    assert result.signals["collision.hits"][0, WHEEL, L2] == 1
    assert result.signals["collision.buffer"][0, WHEEL].sum() == 0


def test_each_obstacle_counts_once_per_part_however_many_wheels_and_samples(drive):
    rocks = [rock(-0.26, name="a", x=0.6), rock(0.26, name="b", x=1.0)]
    result = collision_signals(drive(), ObstacleSet.from_rocks(rocks))
    assert result.signals["collision.hits"][0, WHEEL, L2] == 2


def test_levels_come_from_thresholds_when_rocks_have_none(drive):
    rocks = [rock(-0.26, radius=0.04, x=0.5, level=None, name="small"),
             rock(0.26, radius=0.12, x=1.0, level=None, name="big")]
    obstacles = ObstacleSet.from_rocks(rocks, thresholds=LevelThresholds(0.05, 0.10))
    assert [o.level_name for o in obstacles.obstacles] == ["L1", "L3"]
    hits = collision_signals(drive(), obstacles).signals["collision.hits"][0]
    assert hits[WHEEL].tolist() == [1, 0, 1]


def test_polygon_area_is_entered_by_the_wheels(drive):
    keep_out = polygon_area([(1.0, -1.0), (2.0, -1.0), (2.0, 1.0), (1.5, 0.0), (1.0, 1.0)],
                            "L3", "keep-out")
    result = collision_signals(drive(), ObstacleSet((keep_out,)))
    assert result.signals["collision.hits"][0].tolist() == [[0, 0, 1], [0, 0, 0], [0, 0, 0]]
    first = result.details[0].first_contacts[0]
    # Front wheels' front edge (x + 0.2 + 0.1) reaches x = 1.0 - contact tolerance.
    assert first.x == pytest.approx(1.0 - 0.3 - 0.005, abs=0.002)


def test_polygon_area_beside_the_path_is_missed(drive):
    beside = polygon_area([(0.0, 0.5), (1.0, 0.5), (1.0, 1.0), (0.0, 1.0)], "L1", "beside")
    result = collision_signals(drive(), ObstacleSet((beside,)), settings=FINE)
    assert result.signals["collision.hits"].sum() == 0
    # Left wheels' outer face at y = 0.29.
    assert result.details[0].min_clearance["beside"] == pytest.approx(0.5 - 0.29, abs=1e-4)


def test_steep_and_unknown_terrain_areas(drive):
    cell = 0.1
    ny, nx = 21, 31  # x from -0.5 to 2.5, y from -1 to 1
    heights = np.zeros((ny, nx))
    heights[:, 20:] = np.arange(nx - 20) * 0.2  # a 63 deg wall from x = 1.5 on
    steep = steep_terrain(heights, (-0.5, -1.0), cell, np.radians(30.0), "L3")
    assert len(steep) == 1
    result = collision_signals(drive(), ObstacleSet(tuple(steep)))
    assert result.signals["collision.hits"][0, WHEEL, L3] == 1
    mask = np.zeros((ny, nx), bool)
    mask[0:3, 5:10] = True  # y from -1.0 to -0.75: beside the path
    unknown = unknown_terrain(mask, (-0.5, -1.0), cell, "L2")
    result = collision_signals(drive(), ObstacleSet(tuple(unknown)))
    assert result.signals["collision.hits"].sum() == 0
    mask[8:12, 5:10] = True  # a second patch, under the path
    unknown = unknown_terrain(mask, (-0.5, -1.0), cell, "L2")
    assert len(unknown) == 2
    assert collision_signals(drive(), ObstacleSet(tuple(unknown))).signals[
        "collision.hits"][0, WHEEL, L2] == 1


def test_many_runs_match_the_exhaustive_reference():
    rng = np.random.default_rng(3)
    runs, samples = 6, 120
    t = np.linspace(0.0, 60.0, samples)
    y0 = rng.uniform(-0.4, 0.4, (runs, 1))
    yaw = rng.uniform(-0.3, 0.3, (runs, 1)) + 0.002 * t
    x = 0.02 * t * np.cos(yaw)
    poses = {"t": np.broadcast_to(t, (runs, samples)), "x": x, "y": y0 + 0.02 * t * np.sin(yaw),
             "z": 0.3 + 0.01 * np.sin(t)[None, :] + 0 * x,
             "roll": 0.05 * np.sin(0.3 * t)[None, :] + 0 * x,
             "pitch": 0.04 * np.cos(0.2 * t)[None, :] + 0 * x, "yaw": yaw + 0 * x}
    rocks = [{"name": f"r{i}", "x": float(rng.uniform(0.2, 1.2)),
              "y": float(rng.uniform(-0.8, 0.8)), "z": float(rng.uniform(-0.05, 0.05)),
              "a": float(rng.uniform(0.03, 0.12)), "b": float(rng.uniform(0.03, 0.12)),
              "c": float(rng.uniform(0.03, 0.3)), "yaw": float(rng.uniform(0, 3)),
              "level": int(rng.integers(1, 4))} for i in range(8)]
    obstacles = ObstacleSet.from_rocks(rocks, buffer_margins=[0.02, 0.05, 0.1]).extended(
        [polygon_area([(0.9, -1.0), (1.6, -1.0), (1.6, 1.0), (1.2, 0.1), (0.9, 1.0)], "L3",
                      "keep-out", parts=("wheel", "solar_panel", "chassis"))])
    settings = CheckSettings()
    fast = collision_signals(poses, obstacles, settings=settings)
    slow = reference_collision_signals(poses, obstacles, settings=settings)
    # Steps here are ≤ 1.5 cm, so a contact or buffer entry between samples would show at a
    # sample too unless it is shallower than that: compare where the reference is decisive.
    for name in ("collision.hits", "collision.buffer"):
        assert np.array_equal(fast.signals[name], slow.signals[name]), name
    exact = slow.signals["collision.clearance"]
    approx = fast.signals["collision.clearance"]
    fast_contact = fast.signals["collision.contact"].any(axis=-1)
    slow_contact = slow.signals["collision.contact"].any(axis=-1)
    # The only differences: contacts between two samples, marked on the nearer sample, where
    # the sample itself is within a step (≤ 2.5 cm here) of the obstacle.
    extra = fast_contact != slow_contact
    assert np.all(fast_contact[extra])
    assert np.all(exact[extra] <= settings.contact_tolerance + 0.025)
    bound = np.maximum(settings.clearance_resolution, settings.clearance_relative * approx)
    assert np.all((np.abs(approx - exact) <= bound + 1e-9)[~extra])
    assert fast.signals["collision.hits"].sum() > 0  # the comparison is not vacuous


def test_single_sample_and_standing_still_in_contact(drive):
    obstacles = ObstacleSet.from_rocks([rock(-0.26, x=0.2, level="L3")])
    single = collision_signals(drive(samples=1), obstacles)
    assert single.signals["collision.hits"][0, WHEEL, L3] == 1
    still = collision_signals(drive(x0=0.0, x1=0.0, samples=3001), obstacles)
    assert still.signals["collision.hits"][0, WHEEL, L3] == 1
    assert still.signals["collision.contact"][0, :, WHEEL, L3].all()
    assert np.all(still.signals["collision.clearance"][0, :, WHEEL] == 0.0)


def test_a_deep_overlap_is_not_carried_past_where_it_ends(drive):
    """A tall narrow ellipsoid under the chassis as the rover drives off it in 6 cm steps. fcl's
    penetration depth (EPA) is too large here (0.255 m where moving the chassis 0.147 m along x
    separates them); an allowance built on it carried the contact to a sample 3 cm clear.
    Every sample must agree with the exhaustive check, in contact and clearance."""
    poses = drive(x0=0.0, x1=1.6875, samples=30, duration=10.0)
    tall = {"name": "tall", "x": 0.05818965517241379, "y": 0.0, "z": 0.046875,
            "a": 0.05859375, "b": 0.1171875, "c": 0.3515625, "level": "L1"}
    obstacles = ObstacleSet.from_rocks([tall], buffer_margins=[0.02, 0.05, 0.1])
    settings = CheckSettings()
    fast = collision_signals(poses, obstacles, settings=settings)
    slow = reference_collision_signals(poses, obstacles, settings=settings)
    assert np.array_equal(fast.signals["collision.contact"], slow.signals["collision.contact"])
    approx = fast.signals["collision.clearance"][0, :, CHASSIS]
    exact = slow.signals["collision.clearance"][0, :, CHASSIS]
    assert exact[5] == 0.0 and exact[6] > 0.025  # the contact ends between samples 5 and 6
    bound = np.maximum(settings.clearance_resolution, settings.clearance_relative * approx)
    assert np.all(np.abs(approx - exact) <= bound + 1e-9)
