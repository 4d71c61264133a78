"""Heading execution: closed loop on the gyro yaw measurement, open loop on odometry
(docs/rover-model.md, "Locomotion controller")."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import soil_model

from idefix_rules.commands import Command, RoverGeometry, ideal_poses
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


@pytest.mark.parametrize(("command", "bias"), [
    (Command(0.05, 0.0, math.radians(60)), 0.0),
    (Command(0.05, 0.3 * math.radians(60), math.radians(60)), 0.0),
    (Command(0.05, 0.0, math.radians(45)), -1e-4),  # a poor MEMS gyro, against the turn
    (Command(0.05, 0.0, math.radians(-45)), 1e-4)],
    ids=["point turn", "arc with a trim", "against a gyro bias", "right, against a bias"])
def test_a_turn_on_the_spot_brings_its_wheels_to_rest_on_the_ramp(
        rover: FmuRunner, command: Command, bias: float) -> None:
    # A turn on the spot (a point turn, or the trim after an arc) is within its tolerance once
    # the gyro heading is; from there the wheels ramp to rest at controller.wheel_acceleration
    # (0.015 rad/s^2). Done at the tolerance itself, they stopped from the ramp's
    # sqrt(2 a tol b / r) = 0.016 rad/s in one sample (0.34 rad/s^2), and a rover on two wheels,
    # pivoting about one, stopped its body in one step (the pebble field's trim-end acceleration
    # breaches); a ramp aimed at the tolerance's edge instead stalled there against a gyro bias
    # until the command timed out. The command ends well before its timeout.
    out = rover.run({**GYRO, "gyro.bias": bias}, [command], 600.0, 0.05, hold_after_chain=False)
    end = int(np.argmax(out["command"] < 0))
    assert end > 0
    # the fastest wheel's path over its rate (command_kinematics), plus the ramps' 3.3 s
    ideal = (abs(command.delta_position) + 0.26 * abs(command.delta_heading)) / (0.1 * 0.05)
    assert out["t"][end] < 0.9 * 2.0 * (ideal + 0.05 / 0.015)  # controller.timeout_factor 2
    measured = out["yaw"][end] + bias * out["t"][end]  # what the gyro saw (bias b: -b t)
    assert abs(measured - command.delta_heading) <= TOLERANCE + 1e-4
    tail = out["wheel.rate"][end - 40: end + 2]  # the last 2 s of the turn and the stop
    assert np.abs(np.diff(tail, axis=0)).max() / 0.05 < 1.01 * 0.015


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


def test_a_closed_loop_arc_moves_as_the_skid_steering_balance_of_its_wheel_rates_says(
        rover: FmuRunner) -> None:
    # The loop steers the arc with its kinematic (feed-forward) rates plus a heading correction
    # that keeps every wheel within [1/2, 3/2] of its feed-forward rate; the body then moves at
    # the (u, omega) of the forward-force and yaw-moment balance of the four wheels at those
    # rates (tests/fmu/soil_model.py), short of the mean odometry by the sides' unequal slips.
    # The command ends right: odometry equals the commanded arc length, the gyro heading the
    # commanded one, and the end pose is the commanded arc shortened by the balance's factor.
    commanded = math.radians(25.0)
    out = rover.run(GYRO, [Command(0.05, 0.3, commanded)], 200.0, 0.1)
    rates = out["wheel.rate"]
    odometry = float(np.sum(0.5 * 0.1 * (rates[:-1, 0] + rates[:-1, 1])) * 0.1)
    assert odometry == pytest.approx(0.3, abs=1e-3)  # a trim turns the sides oppositely
    assert abs(out["yaw"][-1] - commanded) <= TOLERANCE + 1e-4
    steady = 500  # 50 s into the arc, the loop's rates settled
    left, right = float(rates[steady, 0]), float(rates[steady, 1])
    kinematic = (0.3 / commanded - 0.26) / (0.3 / commanded + 0.26)
    assert 0.5 * kinematic * right - 1e-6 <= left < kinematic * right  # slowed, never stopped
    u, omega = soil_model.arc_balance(left, right)
    dx = out["x"][steady + 1] - out["x"][steady - 1]
    dy = out["y"][steady + 1] - out["y"][steady - 1]
    assert math.hypot(dx, dy) / 0.2 == pytest.approx(u, rel=0.02)
    assert (out["yaw"][steady + 1] - out["yaw"][steady - 1]) / 0.2 == pytest.approx(omega,
                                                                                   rel=0.02)
    ratio = u / (0.1 * (left + right) / 2)
    assert ratio < 0.95
    short = ideal_poses([Command(0.05, 0.3 * ratio, commanded)], RoverGeometry(),
                        np.array([1e9]))[0]
    assert math.hypot(out["x"][-1] - short[0], out["y"][-1] - short[1]) < 0.02
    full = ideal_poses([Command(0.05, 0.3, commanded)], RoverGeometry(), np.array([1e9]))[0]
    assert math.hypot(out["x"][-1] - full[0], out["y"][-1] - full[1]) > 0.02  # short of it


def test_the_smooth_detour_on_flat_ground_ends_short_by_its_arcs_balance(
        rover: FmuRunner) -> None:
    # The example's three arcs (radius 0.5 m): the body moves at the velocity the four wheels'
    # balance gives for the loop's rates, with a side's rear wheel in its front wheel's rut
    # once an arc has turned far enough (soil_model.balance_path): the end within 3 cm (1.5 cm;
    # the S-bend's ruts, the ramps and the heading trims between arcs are approximated), while
    # the commanded target is 0.1 m further on. This checks the chained arcs' kinematics, not
    # the rut's law: with a rut's whole depth as contact the end is 0.7 cm from the same
    # prediction (the sweep's arcs and the straight drive's two-axle slip tell the laws apart).
    d = math.radians
    chain = [Command(0.05, 0.2618, d(30)), Command(0.05, 0.5236, d(-60)),
             Command(0.05, 0.2618, d(30))]
    out = rover.run(GYRO, chain, 900.0, 0.1)
    assert out["command"][-1] == -1 and abs(out["yaw"][-1]) <= TOLERANCE + 1e-4
    x, y = soil_model.balance_path(out["wheel.rate"], out["yaw"], out["command"],
                                   [c.delta_heading for c in chain], 0.1)
    assert math.hypot(out["x"][-1] - x, out["y"][-1] - y) < 0.03
    assert 1.0 - out["x"][-1] > 0.1


@pytest.mark.parametrize("heading", [5e-324, -1e-300])
def test_a_vanishing_turn_is_a_point_turn_done_within_a_step(rover: FmuRunner,
                                                             heading: float) -> None:
    # the controller turns by it (b · Δψ would underflow: no NaN wheel rates), is done at the
    # end of the first step, and executes the next command
    out = rover.run(GYRO, [Command(0.05, 0.0, heading), Command(0.05, 0.1, 0.0)], 60.0, 0.1)
    assert np.all(np.isfinite(out["wheel.rate"])) and np.all(np.isfinite(out["x"]))
    assert out["command"][0] == 0 and out["command"][1] == 1 and out["x"][-1] > 0.09
