"""Command kinematics at the small end: a turn by a vanishing angle is still a point turn, at
the same rates, lasting a vanishing time; only a command with no motion at all is empty."""

from __future__ import annotations

import math
import sys
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from idefix_rules.commands import Command, RoverGeometry, command_kinematics, ideal_poses

ROVER = RoverGeometry()
RATE = 0.05
SMALLEST_SUBNORMAL = 5e-324
TINY_NORMAL = sys.float_info.min  # 2.2e-308


def exact_point_turn_duration(heading: float, rate: float, rover: RoverGeometry) -> float:
    """b·|Δψ| / (rate·r) in exact arithmetic, rounded once."""
    return float(Fraction(rover.half_track) * abs(Fraction(heading))
                 / (Fraction(rate) * Fraction(rover.wheel_radius)))


def test_a_command_without_motion_is_empty() -> None:
    k = command_kinematics(Command(RATE, 0.0, 0.0), ROVER)
    assert k.duration == 0.0 and k.speed == 0.0 and k.yaw_rate == 0.0
    assert k.wheel_rates == (0.0, 0.0, 0.0, 0.0)


@pytest.mark.parametrize("heading", [SMALLEST_SUBNORMAL, -SMALLEST_SUBNORMAL, 1e-320,
                                     TINY_NORMAL, -TINY_NORMAL, 1e-12, 0.5, -math.pi])
def test_a_point_turn_of_any_angle_turns_at_the_same_rates(heading: float) -> None:
    typical = command_kinematics(Command(RATE, 0.0, math.copysign(1.0, heading)), ROVER)
    k = command_kinematics(Command(RATE, 0.0, heading), ROVER)
    # the fastest wheel at the commanded rate, the sides opposite, the yaw rate r·rate/b
    assert k.wheel_rates == pytest.approx(typical.wheel_rates, rel=1e-15)
    assert max(abs(rate) for rate in k.wheel_rates) == pytest.approx(RATE, rel=1e-15)
    assert k.yaw_rate == pytest.approx(typical.yaw_rate, rel=1e-15)
    assert math.copysign(1.0, k.yaw_rate) == math.copysign(1.0, heading)
    assert k.speed == 0.0 and k.turn_radius == 0.0
    # it lasts b·|Δψ| / (rate·r): above zero, however small the angle
    assert k.duration > 0.0
    assert k.duration == pytest.approx(exact_point_turn_duration(heading, RATE, ROVER),
                                       rel=1e-15, abs=SMALLEST_SUBNORMAL)


@pytest.mark.parametrize(("rate", "distance"), [(0.04, 1e308), (1e-10, 1e300), (0.04, -1e308)])
def test_a_command_longer_than_a_double_lasts_forever_at_its_rates(rate: float,
                                                                    distance: float) -> None:
    """Its duration overflows to inf (the callers refuse it by its length), as a subnormal
    rate's does; it used to raise OverflowError from the exact rescaling."""
    k = command_kinematics(Command(rate, distance, 0.0), ROVER)
    assert k.duration == math.inf
    assert k.wheel_rates == pytest.approx((math.copysign(rate, distance),) * 4, rel=1e-15)
    assert k.speed == pytest.approx(math.copysign(rate * ROVER.wheel_radius, distance),
                                    rel=1e-15)
    nearly = command_kinematics(Command(rate, math.copysign(1e300, distance) * rate, 0.0), ROVER)
    assert math.isfinite(nearly.duration)  # just inside: still a number


@pytest.mark.parametrize("heading", [SMALLEST_SUBNORMAL, TINY_NORMAL, 1e-12])
def test_an_arc_with_a_vanishing_heading_change_drives_as_the_straight_line(
        heading: float) -> None:
    straight = command_kinematics(Command(RATE, 1.0, 0.0), ROVER)
    k = command_kinematics(Command(RATE, 1.0, heading), ROVER)
    assert k.duration == pytest.approx(straight.duration, rel=1e-9)
    assert k.speed == pytest.approx(straight.speed, rel=1e-9)
    assert k.wheel_rates == pytest.approx(straight.wheel_rates, rel=1e-9)
    assert 0.0 <= k.yaw_rate <= 1e-13


def test_the_ideal_path_of_a_vanishing_turn_stays_where_it_is() -> None:
    chain = [Command(RATE, 0.0, SMALLEST_SUBNORMAL), Command(RATE, 0.1, 0.0)]
    poses = ideal_poses(chain, ROVER, np.linspace(0.0, 30.0, 31))
    assert np.all(np.isfinite(poses))
    assert poses[-1] == pytest.approx([0.1, 0.0, SMALLEST_SUBNORMAL], abs=1e-12)


tiny_headings = st.floats(min_value=-1e-300, max_value=1e-300, allow_subnormal=True).filter(
    lambda value: value != 0.0)


@given(heading=tiny_headings, rate=st.floats(0.001, 1.0),
       position=st.one_of(st.just(0.0), st.floats(-2.0, 2.0)))
def test_a_tiny_heading_change_never_breaks_the_kinematics(heading: float, rate: float,
                                                           position: float) -> None:
    k = command_kinematics(Command(rate, position, heading), ROVER)
    values = (k.duration, k.speed, k.yaw_rate, *k.wheel_rates)
    assert all(math.isfinite(value) for value in values)
    assert not math.isnan(k.turn_radius)
    # the fastest wheel turns at the commanded rate: the definition of the command
    assert max(abs(value) for value in k.wheel_rates) == pytest.approx(rate, rel=1e-12)
    if position == 0.0:  # a point turn: positive duration, yaw rate r·rate/b in its direction
        assert k.duration > 0.0
        assert k.duration == pytest.approx(exact_point_turn_duration(heading, rate, ROVER),
                                           rel=1e-15, abs=SMALLEST_SUBNORMAL)
        assert k.yaw_rate == pytest.approx(
            math.copysign(rate * ROVER.wheel_radius / ROVER.half_track, heading), rel=1e-12)
    elif abs(position) > 1e-6:  # the heading change is nothing beside the motion: a line
        straight = command_kinematics(Command(rate, position, 0.0), ROVER)
        assert k.duration == pytest.approx(straight.duration, rel=1e-12)
        assert k.speed == pytest.approx(straight.speed, rel=1e-12)


def test_a_command_at_the_default_rulebooks_speed_limit_keeps_it() -> None:
    """0.1 rad/s on 10 cm wheels is 1 cm/s: in floating point 0.010000000000000002, which broke
    `speed <= 1 cm/s`. Worked out from the numbers as written, it keeps the limit; just above,
    it does not."""
    from pathlib import Path

    from idefix_rules.rulebook import compile_rulebook, load_rulebook
    rulebook = compile_rulebook(load_rulebook(
        Path(__file__).resolve().parents[1] / "rulebooks" / "idefix-ops.rules"))
    at_limit = rulebook.check_chain([Command(0.1, 0.2, 0.0)], ROVER)
    assert [v.rule for v in at_limit] == []
    above = rulebook.check_chain([Command(0.1000001, 0.2, 0.0)], ROVER)
    assert sorted(v.rule for v in above) == ["speed_limit", "wheel_rate_limit"]


@given(st.one_of(st.just(0.0), st.floats(1e-6, 0.3), st.floats(-0.3, -1e-6)),
       # (a subnormal's written decimal, 5e-324, is 1 % off its binary value 4.94e-324)
       st.floats(-3.0, 3.0, allow_subnormal=False), st.floats(-4.0, 4.0, allow_subnormal=False))
def test_rule_quantities_are_the_kinematics_rounded_once(rate: float, position: float,
                                                          heading: float) -> None:
    """The same quantities as the floating-point kinematics, within a few ulps, and the same
    special cases (no motion, point turn, straight)."""
    from idefix_rules.commands import forward_acceleration, rule_quantities
    command = Command(rate, position, heading)
    k = command_kinematics(command, ROVER)
    exact = rule_quantities(command, ROVER)
    floating = {"turn_radius": k.turn_radius, "duration": k.duration, "speed": k.speed,
                "yaw_rate": k.yaw_rate,
                "wheel_speed": max(abs(w) for w in k.wheel_rates) * ROVER.wheel_radius,
                "lateral_acceleration": abs(k.speed * k.yaw_rate),
                "forward_acceleration": forward_acceleration(command, ROVER)}
    for name, value in floating.items():
        if math.isinf(value) and not math.isinf(exact[name]):  # the floats overflowed
            assert abs(exact[name]) > 1e300 and math.copysign(1, exact[name]) == \
                math.copysign(1, value), name
        elif value == 0.0 or math.isinf(value):
            assert exact[name] == value, name
        else:
            assert exact[name] == pytest.approx(value, rel=1e-14), name


@pytest.mark.parametrize("rate", [SMALLEST_SUBNORMAL, TINY_NORMAL])
def test_a_subnormal_rate_breaks_neither_the_kinematics_nor_the_rules(rate: float) -> None:
    """The rim speed of a subnormal rate underflows to 0: the float kinematics last forever
    (no division by zero); the rules see the exact, vanishing speed."""
    from idefix_rules.commands import rule_quantities
    k = command_kinematics(Command(rate, 1.0, 0.0), ROVER)
    assert k.duration == math.inf or k.duration > 1e300
    exact = rule_quantities(Command(rate, 1.0, 0.0), ROVER)
    assert exact["duration"] == math.inf and 0.0 <= exact["speed"] < 1e-300
