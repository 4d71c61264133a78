"""Heading execution: closed loop on the gyro yaw measurement, open loop on odometry
(docs/rover-model.md, "Locomotion controller")."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from idefix_rules.commands import Command
from idefix_rules.fmu import FmuRunner, synthetic_terrain, write_terrain

GYRO = {"controller.heading_feedback": 1.0}
ODOMETRY = {"controller.heading_feedback": 0.0}
TOLERANCE = math.radians(0.2)  # controller.heading_tolerance default


def _final_yaw(rover: FmuRunner, parameters: dict[str, float], command: Command) -> float:
    out = rover.run(parameters, [command], 200.0, 0.1)
    assert out["command"][-1] == -1  # the command ended before the stop time (not a timeout)
    return float(out["yaw"][-1])


@pytest.mark.parametrize("degrees", [90.0, -45.0])
def test_a_point_turn_reaches_its_heading_within_the_tolerance_on_nominal_soil(
        rover: FmuRunner, degrees: float) -> None:
    commanded = math.radians(degrees)
    yaw = _final_yaw(rover, GYRO, Command(0.05, 0.0, commanded))
    assert abs(yaw - commanded) <= TOLERANCE + 1e-4
    # open loop the same turn lags by the skid-steering efficiency b²/(a²+b²) ≈ 0.6
    open_loop = _final_yaw(rover, ODOMETRY, Command(0.05, 0.0, commanded))
    assert abs(open_loop) < 0.7 * abs(commanded)


def test_a_25_degree_arc_reaches_its_heading_and_bends_the_right_way(rover: FmuRunner) -> None:
    commanded = math.radians(25.0)
    out = rover.run(GYRO, [Command(0.05, 0.3, commanded)], 200.0, 0.1)
    assert abs(out["yaw"][-1] - commanded) <= TOLERANCE + 1e-4
    # an arc to the left: forward and to the left, the heading growing along the way
    assert out["x"][-1] > 0.2 and out["y"][-1] > 0.02
    assert np.all(np.diff(out["yaw"][out["command"] == 0]) > -1e-4)
    assert abs(_final_yaw(rover, ODOMETRY, Command(0.05, 0.3, commanded))) < 0.8 * commanded


def test_a_gyro_bias_turns_the_true_heading_by_bias_times_time(rover: FmuRunner) -> None:
    # The loop holds the *measured* heading: a bias b makes the true yaw drift by -b t.
    bias = 1e-4  # rad/s, about 20 deg/h: a poor MEMS gyro
    out = rover.run({**GYRO, "gyro.bias": bias}, [Command(0.05, 0.5, 0.0)], 150.0, 0.1)
    end = int(np.argmax(out["command"] < 0))
    assert out["yaw"][end] == pytest.approx(-bias * out["t"][end], rel=0.1, abs=TOLERANCE)
    assert out["yaw"][end] < -0.5 * bias * out["t"][end]


def test_a_gyro_scale_error_scales_the_turn_by_one_over_one_plus_the_error(
        rover: FmuRunner) -> None:
    commanded = math.pi / 2
    for error in (0.05, -0.05):
        yaw = _final_yaw(rover, {**GYRO, "gyro.scale_error": error},
                         Command(0.05, 0.0, commanded))
        assert yaw == pytest.approx(commanded / (1 + error), abs=TOLERANCE / (1 - 0.05) + 1e-4)


def test_the_straight_drive_holds_its_heading_on_a_side_slope(
        rover: FmuRunner, tmp_path: Path) -> None:
    slope = write_terrain(tmp_path / "side.terrain", synthetic_terrain(
        size=5.0, cell=0.05, slope=math.radians(10), slope_direction=-math.pi / 2))
    parameters = {"terrain.file": str(slope)}
    held = rover.run({**parameters, **GYRO}, [Command(0.05, 0.5, 0.0)], 150.0, 0.1)
    assert abs(held["yaw"][-1]) <= TOLERANCE + 1e-4
