"""Driving commands and their ideal kinematics.

A command is (max wheel rate, delta position, delta heading): the rover drives a circular arc of
length ``delta_position`` while its yaw changes by ``delta_heading``, the fastest wheel turning at
``max_wheel_rate``. Straight lines (``delta_heading == 0``) and point turns
(``delta_position == 0``) are special cases. The same kinematics drive the rover FMU's
controller (``fmu/idefix_rover/sources/controller.c``), the command rules of a rulebook and the
theoretical path, so they live here once.

Skid steering on unsteered wheels: each side's wheels move along the arc at lateral offset
``± half_track`` from the body centre, so for turn radius ``R`` the left and right wheel
ground speeds are ``v (R ∓ b) / R``. A point turn spins the sides at ``± yaw_rate · b``.

>>> rover = RoverGeometry()
>>> k = command_kinematics(Command(0.05, 1.0, 0.0), rover)
>>> round(k.speed, 4), round(k.duration, 1)
(0.005, 200.0)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from idefix_rules.units import written_decimal

WHEELS = ("FL", "FR", "RL", "RR")


@dataclass(frozen=True)
class Command:
    """One driving command, SI units: rad/s, m, rad."""

    max_wheel_rate: float
    delta_position: float
    delta_heading: float


@dataclass(frozen=True)
class RoverGeometry:
    """Geometry the kinematics need; defaults match the rover FMU's parameter defaults.

    The published IDEFIX figures give the 0.275 m legs and a body of about 0.41 × 0.37 m; wheel
    radius and the wheel positions in the driving pose are assumptions (docs/rover-model.md).
    """

    wheel_radius: float = 0.10
    half_track: float = 0.26
    half_wheelbase: float = 0.20
    # rad/s^2: the controller ramps the fastest wheel's rate up and down at this rate
    # (FMU parameter controller.wheel_acceleration; 0 means rate steps)
    wheel_acceleration: float = 0.015


@dataclass(frozen=True)
class CommandKinematics:
    """Ideal execution of one command (no slip)."""

    turn_radius: float  # m, signed (positive = left turn); inf for straight, 0 for point turns
    duration: float  # s
    speed: float  # m/s, body centre, signed (negative = reverse)
    yaw_rate: float  # rad/s
    wheel_rates: tuple[float, float, float, float]  # rad/s, FL FR RL RR


def command_kinematics(command: Command, rover: RoverGeometry) -> CommandKinematics:
    """Duration, speeds and wheel rates of a command executed without slip.

    Only a command with no rate or no motion at all is empty (no time, no wheel turning). Any
    other command moves its fastest wheel at ``max_wheel_rate``, however small its motion: a
    turn by a vanishing angle (even the smallest subnormal) is a point turn like any other,
    at the same wheel and yaw rates, that lasts a vanishing time.

    >>> k = command_kinematics(Command(0.05, 0.0, 5e-324), RoverGeometry())
    >>> k.wheel_rates == command_kinematics(Command(0.05, 0.0, 1.0), RoverGeometry()).wheel_rates
    True
    >>> k.duration > 0.0
    True
    """
    rate = abs(command.max_wheel_rate)
    dp, dh = command.delta_position, command.delta_heading
    b, r = rover.half_track, rover.wheel_radius
    if rate == 0.0 or (dp == 0.0 and dh == 0.0):
        return CommandKinematics(math.inf, 0.0, 0.0, 0.0, (0.0, 0.0, 0.0, 0.0))
    # The rates depend only on the command's shape (dp : dh), its size only sets the duration.
    # So the kinematics are worked out on the command scaled by a power of two (exact) that
    # brings its larger component to [0.5, 1): b·Δψ of a subnormal turn no longer underflows to
    # 0, and every result of a command of ordinary size is the same to the last bit.
    exponent = math.frexp(max(abs(dp), abs(dh)))[1]
    dp_scaled, dh_scaled = math.ldexp(dp, -exponent), math.ldexp(dh, -exponent)
    # Path length of each side: centre arc length ± b·|Δψ| (left side is inside for a left turn).
    left_path = dp_scaled - b * dh_scaled
    right_path = dp_scaled + b * dh_scaled
    fastest = max(abs(left_path), abs(right_path))
    if fastest == 0.0:  # a rover without track turning on the spot: no wheel moves
        return CommandKinematics(math.inf, 0.0, 0.0, 0.0, (0.0, 0.0, 0.0, 0.0))
    rim_speed = rate * r
    # (a subnormal rate's rim speed underflows to 0: its duration overflows instead, to inf)
    scaled_duration = fastest / rim_speed if rim_speed > 0.0 else fastest / rate / r
    left_rate = left_path / scaled_duration / r
    right_rate = right_path / scaled_duration / r
    turn_radius = math.inf if dh == 0.0 else dp / dh
    try:
        duration = math.ldexp(scaled_duration, exponent)
    except OverflowError:  # 1e308 m at 0.04 rad/s: longer than a double holds
        duration = math.inf
    return CommandKinematics(
        turn_radius=turn_radius,
        duration=duration,
        speed=dp_scaled / scaled_duration,
        yaw_rate=dh_scaled / scaled_duration,
        wheel_rates=(left_rate, right_rate, left_rate, right_rate),
    )


def forward_acceleration(command: Command, rover: RoverGeometry) -> float:
    """Commanded forward acceleration of the body centre (m/s², ≥ 0) while the wheel rates
    ramp: every wheel's rate scales with the fastest one's, which ramps at
    ``rover.wheel_acceleration``, so the centre speeds up at ``|speed| / |max_wheel_rate| ·
    wheel_acceleration``. Rate steps (``wheel_acceleration == 0``) ask for an unbounded
    acceleration (``inf``); a command that does not move (or only turns) asks for none.

    >>> round(forward_acceleration(Command(0.05, 1.0, 0.0), RoverGeometry()), 6)
    0.0015
    """
    k = command_kinematics(command, rover)
    if k.speed == 0.0:
        return 0.0
    if rover.wheel_acceleration <= 0.0:
        return math.inf
    return abs(k.speed) / abs(command.max_wheel_rate) * rover.wheel_acceleration


def rule_quantities(command: Command, rover: RoverGeometry) -> dict[str, float]:
    """What a command rule reads of a command, worked out exactly from its numbers as written
    and rounded once: the kinematics of :func:`command_kinematics` (the same special cases)
    and :func:`forward_acceleration`, with the lateral acceleration ``|speed · yaw_rate|``.

    In floating point a command at a limit can miss it: 0.1 rad/s on 10 cm wheels is
    0.010000000000000002 m/s, which breaks ``speed <= 1 cm/s``; the rulebook's numbers are
    converted as written (``units``), and so are the command's here.

    >>> rule_quantities(Command(0.1, 0.2, 0.0), RoverGeometry())["speed"]
    0.01
    """
    rate = abs(written_decimal(command.max_wheel_rate))
    dp, dh = written_decimal(command.delta_position), written_decimal(command.delta_heading)
    b, r = written_decimal(rover.half_track), written_decimal(rover.wheel_radius)
    left, right = dp - b * dh, dp + b * dh
    fastest = max(abs(left), abs(right))
    still = {"duration": 0.0, "speed": 0.0, "yaw_rate": 0.0, "wheel_speed": 0.0,
             "lateral_acceleration": 0.0, "forward_acceleration": 0.0}
    if rate == 0 or (dp == 0 and dh == 0):
        return {"turn_radius": math.inf, **still}
    turn_radius = math.inf if dh == 0 else _rounded(dp / dh)
    if fastest == 0:  # a rover without track turning on the spot: no wheel moves
        return {"turn_radius": turn_radius, **still}
    duration = fastest / (rate * r)
    speed, yaw_rate = dp / duration, dh / duration
    if speed == 0:
        forward = 0.0
    elif rover.wheel_acceleration <= 0.0:
        forward = math.inf
    else:
        forward = _rounded(abs(speed) / rate * written_decimal(rover.wheel_acceleration))
    return {"turn_radius": turn_radius, "duration": _rounded(duration),
            "speed": _rounded(speed), "yaw_rate": _rounded(yaw_rate),
            "wheel_speed": _rounded(rate * r),
            "lateral_acceleration": _rounded(abs(speed * yaw_rate)),
            "forward_acceleration": forward}


def _rounded(value: Fraction) -> float:
    """The double nearest ``value`` (±inf beyond the largest)."""
    try:
        return float(value)
    except OverflowError:
        return math.inf if value > 0 else -math.inf


def chain_duration(chain: list[Command] | tuple[Command, ...], rover: RoverGeometry) -> float:
    """Ideal total duration of a command chain, in seconds."""
    return sum(command_kinematics(c, rover).duration for c in chain)


def ideal_poses(chain: list[Command] | tuple[Command, ...], rover: RoverGeometry,
                times: np.ndarray, scale: float = 1.0,
                start: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """Planar poses (x, y, yaw) along the ideal path at ``times``, shape (len(times), 3).

    ``scale`` shrinks every command's travel (a fixed slip ``s`` gives ``scale = 1 - s``).
    Commands follow each other at their ideal durations.
    """
    x, y, yaw = start
    out = np.empty((len(times), 3))
    out[:, 0], out[:, 1], out[:, 2] = x, y, yaw
    t0 = 0.0
    for command in chain:
        k = command_kinematics(command, rover)
        if k.duration <= 0.0:
            continue
        t1 = t0 + k.duration
        # a command lasting a subnormal time overflows the fraction to ±inf: before or done
        with np.errstate(over="ignore"):
            frac = np.clip((times - t0) / k.duration, 0.0, 1.0)
        active = times >= t0
        dp = command.delta_position * scale * frac
        dh = command.delta_heading * scale * frac
        px, py, pyaw = _advance(x, y, yaw, dp, dh)
        out[active, 0], out[active, 1], out[active, 2] = px[active], py[active], pyaw[active]
        end = _advance(x, y, yaw, np.array([command.delta_position * scale]),
                       np.array([command.delta_heading * scale]))
        x, y, yaw = (float(v[0]) for v in end)
        t0 = t1
    return out


def _advance(x: float, y: float, yaw: float, dp: np.ndarray,
             dh: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pose after an arc of length ``dp`` turning by ``dh`` from (x, y, yaw)."""
    small = np.abs(dh) < 1e-12
    safe_dh = np.where(small, 1.0, dh)
    # Chord of the arc: length 2R sin(dh/2) in direction yaw + dh/2; straight limit dp.
    chord = np.where(small, dp, 2.0 * (dp / safe_dh) * np.sin(dh / 2.0))
    heading = yaw + dh / 2.0
    return x + chord * np.cos(heading), y + chord * np.sin(heading), yaw + dh
