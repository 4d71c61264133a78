"""The turning sweep of docs/rover-model.md ("Skid-steer turning"): one 60° command per
turning radius on flat nominal soil, from a point turn through arcs to a straight drive, and
what the rover does on it. ``python tests/fmu/turning_sweep.py`` prints the table."""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from idefix_rules.commands import Command, RoverGeometry, ideal_poses
from idefix_rules.fmu import FmuRunner

TURN = math.radians(60.0)
STRAIGHT = 0.5  # m, the straight row's drive
RADII = (0.0, 0.3, 0.6, 1.2, 2.4, math.inf)
CURRENTS = [f"wheel.{w}.current" for w in ("FL", "FR", "RL", "RR")]


@dataclass(frozen=True)
class Row:
    radius: float            # m; 0 point turn, inf straight
    inner_slip: float        # mean slip ratio of the inner (left) wheels, steady part
    outer_slip: float        # mean slip ratio of the outer (right) wheels, steady part
    inner_rate: float        # inner / outer wheel rate, steady part
    slip_angle: float        # 95th percentile over time of the largest wheel slip angle, rad
    moment: float            # yaw moment of the outer minus the inner wheels' rim forces, N m
    current: float           # mean motor current over the command, A
    charge_per_radian: float  # charge per radian turned, A s / rad (nan for the straight)
    heading: float           # heading reached, rad
    end_offset: float        # end position against the commanded arc projected with the slip, m
    duration: float          # s
    finished: bool           # the command ended before the stop time
    # per sample of the steady part: heading turned since the command began (rad), the left
    # and right wheel rates (rad/s) and the four wheels' slips: the phases before and after a
    # rear wheel reaches its front wheel's rut
    steady_turned: np.ndarray = field(repr=False, compare=False)
    steady_rate: np.ndarray = field(repr=False, compare=False)
    steady_slip: np.ndarray = field(repr=False, compare=False)

    @property
    def steady_rates(self) -> tuple[float, float]:
        """Left and right wheel rates over the steady part, rad/s."""
        left, right = self.steady_rate.mean(axis=0)
        return float(left), float(right)


def command(radius: float) -> Command:
    if radius == 0.0:
        return Command(0.05, 0.0, TURN)
    if math.isinf(radius):
        return Command(0.05, STRAIGHT, 0.0)
    return Command(0.05, radius * TURN, TURN)


def measure(rover: FmuRunner, radius: float, parameters: dict[str, float] | None = None) -> Row:
    """Run one command of the sweep and reduce it to a row."""
    chain = [command(radius)]
    out = rover.run(dict(parameters or {}), chain, 1500.0, 0.1)
    active = np.flatnonzero(out["command"] == 0)
    finished = bool((out["command"] < 0).any())
    end = int(np.argmax(out["command"] < 0)) if finished else len(out["t"]) - 1
    # an arc's steady part is the middle half of its drive, before a trim turns on the spot
    # (the sides' rates then have opposite signs)
    moving = active
    if 0.0 < radius < math.inf:
        rates = out["wheel.rate"][active]
        moving = active[rates[:, 0] * rates[:, 1] > 0.0]
    steady = moving[len(moving) // 4: 3 * len(moving) // 4]
    slip, rate = out["wheel.slip"][steady], out["wheel.rate"][steady]
    angle = np.abs(out["wheel.slip_angle"][active]).max(axis=1)
    # the rim (shear) force of each wheel from its current: |F| = k_T (I - I0) / r, driving
    # (along the rate) when the wheel slips, braking when it skids; the yaw moment of the
    # sides' rim forces is b (F_right - F_left)
    current = np.stack([out[name] for name in CURRENTS], axis=1)[steady]
    rim = 2.0 * np.clip(current - 0.0003, 0.0, None) / 0.1 * np.sign(rate) * np.sign(slip)
    moment = float(np.mean(0.26 * (rim[:, 1] + rim[:, 3] - rim[:, 0] - rim[:, 2])))
    energy = float(out["energy"][end])
    yaw = float(out["yaw"][end])
    # the commanded arc projected with the measured slip: the same curvature, the length the
    # body covered over ground (its path) instead of the odometry's
    path = float(np.sum(np.hypot(np.diff(out["x"][: end + 1]), np.diff(out["y"][: end + 1]))))
    projected = Command(0.05, path if chain[0].delta_position else 0.0,
                        chain[0].delta_heading if not chain[0].delta_position
                        else chain[0].delta_heading * path / chain[0].delta_position)
    pose = ideal_poses([projected], RoverGeometry(), np.array([1e9]))[0]
    offset = math.hypot(out["x"][end] - pose[0], out["y"][end] - pose[1])
    return Row(
        radius=radius, inner_slip=float(slip[:, [0, 2]].mean()),
        outer_slip=float(slip[:, [1, 3]].mean()),
        inner_rate=float(np.mean(rate[:, 0]) / np.mean(rate[:, 1])),
        slip_angle=float(np.percentile(angle, 95)), moment=moment,
        current=energy / float(out["t"][end]),
        charge_per_radian=energy / abs(yaw) if abs(yaw) > 1e-3 else math.nan,
        heading=yaw, end_offset=offset, duration=float(out["t"][end]), finished=finished,
        steady_turned=np.abs(out["yaw"][steady] - out["yaw"][active[0]]),
        steady_rate=rate[:, :2].copy(), steady_slip=slip.copy())


def sweep(rover: FmuRunner, parameters: dict[str, float] | None = None) -> list[Row]:
    return [measure(rover, radius, parameters) for radius in RADII]


def table(rows: list[Row]) -> str:
    lines = ["| R [m] | inner / outer slip | inner / outer rate | slip angle p95 [deg] | "
             "turning moment [mN m] | mean current [mA] | charge per rad [mAs] | heading [deg] "
             "| end vs projected arc [cm] |", "|" + " --- |" * 9]
    for r in rows:
        name = "point turn" if r.radius == 0 else ("straight" if math.isinf(r.radius)
                                                   else f"{r.radius:g}")
        per_radian = "–" if math.isnan(r.charge_per_radian) else f"{1e3 * r.charge_per_radian:.0f}"
        lines.append(
            f"| {name} | {r.inner_slip:+.3f} / {r.outer_slip:+.3f} | {r.inner_rate:+.3f} | "
            f"{math.degrees(r.slip_angle):.1f} | {1e3 * r.moment:.1f} | {1e3 * r.current:.2f} | "
            f"{per_radian} | {math.degrees(r.heading):.2f} | {100 * r.end_offset:.1f} |")
    return "\n".join(lines)


if __name__ == "__main__":
    from idefix_rules.fmu import build_fmu

    fmu = build_fmu(output=Path("/tmp") / "idefix_rover_sweep.fmu", force=True)
    extra = dict(arg.split("=") for arg in sys.argv[1:])
    with FmuRunner(fmu, extra_outputs=CURRENTS) as runner:
        print(table(sweep(runner, {k: float(v) for k, v in extra.items()})))
