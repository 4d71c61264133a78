"""Named areas on the ground: contact points, polygons, masks, steep terrain, buffers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from idefix_rules.commands import RoverGeometry
from idefix_rules.obstacles.named import AreaGeometry, area_signals, contact_points, steep_area

ROVER = RoverGeometry()  # wheels at (±0.20, ±0.26) m
SQUARE = np.array([[1.0, -1.0], [2.0, -1.0], [2.0, 1.0], [1.0, 1.0]])


def signals_at(area: AreaGeometry, x: float, y: float = 0.0, yaw: float = 0.0):
    inside, near = area_signals(area, np.array([[x]]), np.array([[y]]), np.array([[yaw]]), ROVER)
    return float(inside[0, 0]), float(near[0, 0])


def test_contact_points_turn_with_the_yaw():
    px, py = contact_points(np.array([1.0]), np.array([2.0]), np.array([math.pi / 2]), ROVER)
    # front-left wheel (0.20 ahead, 0.26 left) of a rover facing +y: at (1 - 0.26, 2 + 0.20)
    assert px[0, 0] == pytest.approx(0.74) and py[0, 0] == pytest.approx(2.20)
    assert px[0, 3] == pytest.approx(1.26) and py[0, 3] == pytest.approx(1.80)  # rear right


@pytest.mark.parametrize(("centre_x", "inside", "near"), [
    (0.79, 0.0, 1.0),   # front wheels at 0.99: 1 cm out, inside the 10 cm buffer
    (0.81, 1.0, 1.0),   # 1 cm in
    (0.69, 0.0, 0.0),   # 11 cm out: beyond the buffer
    (0.71, 0.0, 1.0),   # 9 cm out
    (2.25, 0.0, 1.0),   # rear wheels at 2.05: 5 cm beyond the far edge
    (2.31, 0.0, 0.0),   # rear wheels at 2.11: 11 cm beyond it
])
def test_polygon_inside_and_buffer_boundaries(centre_x, inside, near):
    area = AreaGeometry("crater", "L3", 0.10, polygons=(SQUARE,))
    assert signals_at(area, centre_x) == (inside, near)


def test_concave_polygon_uses_the_even_odd_rule():
    notch = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [1.0, 1.0], [0.0, 2.0]])
    area = AreaGeometry("notch", "L2", 0.0, polygons=(notch,))
    inside, _ = area_signals(area, np.array([[0.8]]), np.array([[1.2]]), np.array([[0.0]]),
                             RoverGeometry(half_track=0.0, half_wheelbase=0.0))
    assert inside[0, 0] == 0.0  # (0.8, 1.2) lies in the notch
    inside, _ = area_signals(area, np.array([[0.3]]), np.array([[1.2]]), np.array([[0.0]]),
                             RoverGeometry(half_track=0.0, half_wheelbase=0.0))
    assert inside[0, 0] == 1.0


def test_mask_is_read_at_the_nearest_node_and_grown_by_the_buffer():
    mask = np.zeros((11, 11), bool)
    mask[5, 8] = True  # the node at (0.8, 0.5) on a 10 cm grid from the origin
    point = RoverGeometry(half_track=0.0, half_wheelbase=0.0)
    area = AreaGeometry("dark", "L2", 0.2, mask=mask, origin=(0.0, 0.0), cell=0.1)

    def at(x: float) -> tuple[float, float]:
        inside, near = area_signals(area, np.array([[x]]), np.array([[0.5]]),
                                    np.array([[0.0]]), point)
        return float(inside[0, 0]), float(near[0, 0])

    assert at(0.76) == (1.0, 1.0)  # nearest node 0.8
    assert at(0.74) == (0.0, 1.0)  # nearest node 0.7: 10 cm from the flagged one
    assert at(0.61) == (0.0, 1.0)  # node 0.6: 20 cm, the buffer's edge
    assert at(0.54) == (0.0, 0.0)  # node 0.5: 30 cm
    assert at(-5.0) == (0.0, 0.0)  # off the grid


def test_steep_area_is_where_the_terrain_is_steeper_than_the_threshold():
    # a ramp rising along x at 25 deg between x = 1 m and 2 m, flat elsewhere
    x = np.arange(0.0, 3.01, 0.05)
    heights = np.tile(np.clip(x - 1.0, 0.0, 1.0) * math.tan(math.radians(25)), (21, 1))
    steep = steep_area("scarp", "L3", 0.0, math.radians(20), heights, (0.0, -0.5), 0.05)
    gentle = steep_area("scarp", "L3", 0.0, math.radians(30), heights, (0.0, -0.5), 0.05)
    point = RoverGeometry(half_track=0.0, half_wheelbase=0.0)
    on_ramp = area_signals(steep, np.array([[1.5]]), np.array([[0.0]]), np.array([[0.0]]),
                           point)[0]
    flat = area_signals(steep, np.array([[0.5]]), np.array([[0.0]]), np.array([[0.0]]), point)[0]
    assert on_ramp[0, 0] == 1.0 and flat[0, 0] == 0.0
    assert not gentle.mask.any()  # 25 deg is not above 30 deg


def test_poses_after_a_run_ended_stay_missing():
    area = AreaGeometry("crater", "L3", 0.1, polygons=(SQUARE,))
    inside, near = area_signals(area, np.array([[0.9, np.nan]]), np.zeros((1, 2)),
                                np.zeros((1, 2)), ROVER)
    assert inside[0, 0] == 1.0 and math.isnan(inside[0, 1]) and math.isnan(near[0, 1])


def test_an_area_with_no_ground_reads_0_and_keeps_missing_samples():
    flat = AreaGeometry("scarp", "L3", 0.05, mask=np.zeros((5, 5), bool), origin=(0.0, 0.0),
                        cell=0.1, kind="steep")
    assert flat.empty and flat.obstacles() == []
    inside, near = area_signals(flat, np.array([[0.2, np.nan]]), np.zeros((1, 2)),
                                np.zeros((1, 2)), ROVER)
    assert inside[0, 0] == 0.0 and near[0, 0] == 0.0
    assert math.isnan(inside[0, 1]) and math.isnan(near[0, 1])
