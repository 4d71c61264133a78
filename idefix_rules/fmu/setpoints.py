"""Time-varying set-points computed from a command chain, for FMUs that take wheel or body
commands instead of whole chains (``fmu.chain.delivery: inputs``).

The chain is executed along its ideal kinematics (:func:`idefix_rules.commands.command_kinematics`):
commands follow each other at their ideal durations, then every rate is zero. Each
communication step ``[t_k, t_k + h)`` receives the *mean* of a rate over the step, so the
distance and heading a kinematic model integrates equal the ideal ones even when a command ends
inside a step; ``command`` (the active command's index, -1 after the chain) is its value at
``t_k``.

>>> from idefix_rules.commands import Command, RoverGeometry
>>> values = chain_setpoints([Command(0.05, 0.1, 0.0)], RoverGeometry(), 10.0, 30)
>>> round(float(values["body.speed"][0]), 6), float(values["command"][-1])
(0.005, -1.0)
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from idefix_rules.commands import WHEELS, Command, RoverGeometry, command_kinematics

# Set-point name → SI unit (the FMU input's declared unit, when it has one, is converted to).
SETPOINTS: dict[str, str] = {
    **{f"wheel.rate[{wheel}]": "rad/s" for wheel in WHEELS},
    "body.speed": "m/s",
    "body.yaw_rate": "rad/s",
    "command": "1",
}


def chain_setpoints(chain: Sequence[Command], rover: RoverGeometry, interval: float,
                    steps: int) -> dict[str, np.ndarray]:
    """Every set-point for the ``steps`` communication steps of length ``interval``."""
    kinematics = [command_kinematics(command, rover) for command in chain]
    durations = np.array([k.duration for k in kinematics])
    starts = np.concatenate([[0.0], np.cumsum(durations)])
    edges = np.arange(steps + 1) * interval

    def mean_over_steps(values: Sequence[float]) -> np.ndarray:
        # Integral of the piecewise-constant rate up to each edge, differenced per step.
        rates = np.asarray(values, dtype=float)
        covered = np.clip(edges[:, np.newaxis] - starts[np.newaxis, :-1], 0.0, durations)
        integral = covered @ rates if len(rates) else np.zeros_like(edges)
        return np.asarray(np.diff(integral) / interval)

    values = {f"wheel.rate[{wheel}]": mean_over_steps([k.wheel_rates[i] for k in kinematics])
              for i, wheel in enumerate(WHEELS)}
    values["body.speed"] = mean_over_steps([k.speed for k in kinematics])
    values["body.yaw_rate"] = mean_over_steps([k.yaw_rate for k in kinematics])
    # a step starting within rounding of a command's end (the durations are sums of floats)
    # starts after it
    active = np.searchsorted(starts, edges[:-1] + 1e-9 * interval, side="right") - 1
    running = (active < len(chain)) & (durations[np.minimum(active, len(chain) - 1)] > 0) \
        if len(chain) else np.zeros(steps, dtype=bool)
    values["command"] = np.where(running, active, -1).astype(float)
    return values
