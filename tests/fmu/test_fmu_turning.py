"""Skid-steer turning from a point turn through arcs to a straight drive (docs/rover-model.md,
"Skid-steer turning"): the trends of skid-steering theory and experiments, and the magnitudes
of the soil equations written again in Python (tests/fmu/soil_model.py)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import soil_model
import turning_sweep
from turning_sweep import Row

from idefix_rules.fmu import FmuRunner

TOLERANCE = math.radians(0.2)  # controller.heading_tolerance default
FLOOR = 0.5  # controller.rate_floor default
ARCS = slice(1, 5)  # rows of the sweep that are arcs (R = 0.3 .. 2.4 m)


@pytest.fixture(scope="module")
def closed_loop(rover_fmu) -> list[Row]:  # type: ignore[no-untyped-def]
    with FmuRunner(rover_fmu, extra_outputs=turning_sweep.CURRENTS) as runner:
        return turning_sweep.sweep(runner)


@pytest.fixture(scope="module")
def open_loop(rover_fmu) -> list[Row]:  # type: ignore[no-untyped-def]
    with FmuRunner(rover_fmu, extra_outputs=turning_sweep.CURRENTS) as runner:
        return turning_sweep.sweep(runner, {"controller.heading_feedback": 0.0})


def _falling(values: list[float]) -> bool:
    return all(a > b for a, b in itertools.pairwise(values))


def test_every_command_of_the_sweep_ends_at_its_heading(closed_loop: list[Row]) -> None:
    for row in closed_loop:
        assert row.finished
        assert abs(row.heading - turning_sweep.command(row.radius).delta_heading) \
            <= TOLERANCE + 1e-4


def test_outer_wheels_drive_and_inner_wheels_brake_on_every_arc(closed_loop: list[Row]) -> None:
    # the signs of skid steering; the magnitudes are the balance's (the test after next)
    for row in closed_loop[ARCS]:
        assert row.outer_slip > 0 > row.inner_slip
        assert np.all(row.steady_slip[:, [1, 3]] > 0) and np.all(row.steady_slip[:, [0, 2]] < 0)


def test_the_loop_never_stops_an_inner_wheel(closed_loop: list[Row]) -> None:
    # feed-forward rates (R - b)/(R + b) of the outer; the loop keeps at least FLOOR of them
    for row in closed_loop[ARCS]:
        kinematic = (row.radius - 0.26) / (row.radius + 0.26)
        assert row.inner_rate >= FLOOR * kinematic - 1e-3
        assert row.inner_rate > 0


def test_slip_slip_angle_and_current_fall_as_the_radius_grows(closed_loop: list[Row]) -> None:
    # From the tightest arc (R = 0.3 m, just beyond the half track, where the inner wheels'
    # kinematic rate nearly vanishes) to the straight drive: Wong & Chiang's turning resistance
    # and Yu et al.'s measured power both fall with the radius.
    arcs_and_straight = closed_loop[1:]
    assert _falling([abs(r.inner_slip) for r in arcs_and_straight])
    assert _falling([r.slip_angle for r in arcs_and_straight])
    # the turning moment of the rims and the mean current, from the point turn on
    assert _falling([r.moment for r in closed_loop])
    assert _falling([r.current for r in closed_loop])


def test_the_point_turn_slip_angle_is_the_geometry_of_the_wheel_layout(
        closed_loop: list[Row]) -> None:
    # every wheel of a point turn moves perpendicular to its radius: atan(a / b)
    assert closed_loop[0].slip_angle == pytest.approx(math.atan(0.20 / 0.26), abs=math.radians(1))


def _phases(row: Row) -> list[tuple[tuple[bool, bool], np.ndarray]]:
    """The steady samples of an arc grouped by which rear wheels run in their front wheel's
    rut: on the circle the body turns on over fresh soil (u / omega of the balance at the
    loop's steady rates), a side's rear wheel reaches that rut once the body has turned by
    soil_model.rut_separation; samples within 2° of such a heading are left out (a wheel
    entering a rut overlaps it partly)."""
    inner, outer = soil_model.arc_rut_separations(*row.steady_rates)
    turned = row.steady_turned
    clear = (np.abs(turned - inner) > math.radians(2)) & (np.abs(turned - outer) > math.radians(2))
    flags = np.stack([turned > inner, turned > outer], axis=1)
    phases = []
    for ruts in ((False, False), (False, True), (True, False), (True, True)):
        members = clear & (flags[:, 0] == ruts[0]) & (flags[:, 1] == ruts[1])
        if members.sum() >= 30:
            phases.append((ruts, members))
    return phases


@pytest.mark.parametrize("position", [2, 3, 4])
def test_arc_slips_follow_the_four_wheel_force_and_moment_balance(
        closed_loop: list[Row], position: int) -> None:
    # at the loop's wheel rates, the body's (u, v, omega) from the balance of the four wheels
    # gives each side's slip ratio: on fresh soil until a rear wheel reaches the rut of the
    # front wheel ahead of it on the arc, then with that wheel in the rut (it holds less: the
    # soil carries it only below the rut's floor, with the remoulded cohesion)
    row = closed_loop[position]
    phases = _phases(row)
    assert phases
    for ruts, members in phases:
        left, right = row.steady_rate[members].mean(axis=0)
        u, omega = soil_model.arc_balance(float(left), float(right), ruts)
        ground_left, ground_right = u - omega * 0.26, u + omega * 0.26
        expected_inner = left * 0.1 / ground_left - 1 if ground_left > left * 0.1 \
            else 1 - ground_left / (left * 0.1)
        expected_outer = 1 - ground_right / (right * 0.1)
        slips = row.steady_slip[members]
        assert slips[:, [0, 2]].mean() == pytest.approx(expected_inner, abs=0.03)
        assert slips[:, [1, 3]].mean() == pytest.approx(expected_outer, abs=0.03)
    if row.radius >= 1.2:  # wide arcs run most of their turn with both rear wheels in ruts
        assert (True, True) in [ruts for ruts, _ in phases]


@pytest.mark.parametrize("radius", turning_sweep.RADII[ARCS])
def test_an_arc_ends_where_the_balance_of_its_wheel_rates_moves_the_body(
        rover_fmu, radius: float) -> None:  # type: ignore[no-untyped-def]
    # The loop's wheel rates at each sample, through the four wheels' balance (u, v) in the
    # body frame at the measured heading, on fresh soil until a side's rear wheel reaches its
    # front wheel's rut (soil_model.rut_separation) and in the rut after: the end within 2 cm.
    # A rear wheel in a rut holds less, so the body side-slips (v) and the end leaves the
    # commanded arc projected with the measured slip by 3.1-6.2 cm (the sweep's table).
    with FmuRunner(rover_fmu) as runner:
        out = runner.run({}, [turning_sweep.command(radius)], 1500.0, 0.1)
    end = int(np.argmax(out["command"] < 0))
    x, y = soil_model.balance_path(out["wheel.rate"], out["yaw"], out["command"],
                                   [turning_sweep.TURN], 0.1)
    assert math.hypot(out["x"][end] - x, out["y"][end] - y) < 0.02


@pytest.mark.parametrize("position", [0, 1, 2, 3, 4])
def test_open_loop_the_body_turns_at_the_skid_steering_efficiency_at_every_radius(
        open_loop: list[Row], position: int) -> None:
    # Kinematic wheel rates without heading feedback: the body turns at the efficiency of the
    # four wheels' force and moment balance, about the same at every radius (the instantaneous
    # centres of rotation of the sides stay outside the wheels, Mandow et al. 2007), below the
    # isotropic Coulomb bound b²/(a² + b²) = 0.63 of a point turn.
    # On an arc a side's rear wheel reaches the rut of its front wheel after the body turned
    # by soil_model.rut_separation, and holds less there: the heading reached integrates the
    # balance's efficiency over those phases (soil_model.open_loop_arc_efficiency). A point
    # turn's wheels are 75° and 105° apart on their circle: none reaches a rut in 60°.
    row = open_loop[position]
    efficiency = row.heading / turning_sweep.TURN
    coulomb = 0.26 ** 2 / (0.20 ** 2 + 0.26 ** 2)
    if row.radius == 0:
        expected = soil_model.point_turn_efficiency()
        assert 0.5 < efficiency < coulomb
    else:
        expected = soil_model.open_loop_arc_efficiency(row.radius, turning_sweep.TURN)
        ratio = (row.radius - 0.26) / (row.radius + 0.26)
        kinematic = 0.1 * 0.05 * (1 - ratio) / (2 * 0.26)
        _, omega = soil_model.arc_balance(0.05 * ratio, 0.05)
        assert 0.5 < omega / kinematic < coulomb  # fresh soil
        # where the steady part begins on fresh soil (R = 0.3, 0.6 m: before the outer rear
        # wheel reaches its rut), the FMU turns there at that efficiency, below the bound
        _, outer = soil_model.arc_rut_separations(0.05 * ratio, 0.05)
        fresh = row.steady_turned < outer - math.radians(2)
        if fresh.sum() >= 30:
            turned = row.steady_turned[fresh]
            measured = (turned[-1] - turned[0]) / (0.1 * (len(turned) - 1)) / kinematic
            assert measured == pytest.approx(omega / kinematic, rel=0.02)
            assert measured < coulomb
        else:
            assert row.radius >= 1.2
    assert efficiency == pytest.approx(expected, rel=0.03)
