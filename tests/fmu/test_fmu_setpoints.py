"""Set-points fed to FMUs that take wheel or body commands: step means keep the ideal
distances and headings whatever the step, and the active command follows the ideal timing."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import event, given
from hypothesis import strategies as st

from idefix_rules.commands import Command, RoverGeometry, chain_duration, command_kinematics
from idefix_rules.fmu.setpoints import chain_setpoints

commands = st.builds(
    Command,
    max_wheel_rate=st.floats(0.01, 0.1),
    delta_position=st.one_of(st.just(0.0), st.floats(-0.5, 0.5)),
    delta_heading=st.one_of(st.just(0.0), st.floats(-1.0, 1.0)))


@given(chain=st.lists(commands, min_size=1, max_size=4),
       steps_per_command=st.floats(0.3, 40.0), extra=st.integers(1, 5))
def test_step_means_integrate_to_the_commanded_travel(chain: list[Command],
                                                      steps_per_command: float,
                                                      extra: int) -> None:
    rover = RoverGeometry()
    duration = chain_duration(chain, rover)
    if duration == 0.0:
        event("chain without motion")
        interval = 1.0
    else:
        # the step relative to a command's length: from several commands per step to many
        # steps per command, rarely a divisor of the durations
        interval = duration / len(chain) / steps_per_command
        event("steps longer than commands" if steps_per_command < 1 else "commands span steps")
    steps = math.ceil(duration / interval) + extra
    values = chain_setpoints(chain, rover, interval, steps)
    travel = sum(c.delta_position for c in chain if command_kinematics(c, rover).duration > 0)
    turn = sum(c.delta_heading for c in chain if command_kinematics(c, rover).duration > 0)
    assert math.isclose(float(np.sum(values["body.speed"]) * interval), travel, abs_tol=1e-9)
    assert math.isclose(float(np.sum(values["body.yaw_rate"]) * interval), turn, abs_tol=1e-9)
    left = sum(command_kinematics(c, rover).wheel_rates[0] * command_kinematics(c, rover).duration
               for c in chain)
    assert math.isclose(float(np.sum(values["wheel.rate[FL]"]) * interval), left, abs_tol=1e-9)
    np.testing.assert_array_equal(values["wheel.rate[FL]"], values["wheel.rate[RL]"])
    assert values["command"][-1] == -1.0  # after the chain
    for name, series in values.items():
        assert series.shape == (steps,), name


def test_the_active_command_follows_the_ideal_timing() -> None:
    rover = RoverGeometry()
    chain = [Command(0.05, 0.1, 0.0), Command(0.05, 0.0, 0.0), Command(0.05, 0.0, 0.4)]
    first = command_kinematics(chain[0], rover).duration  # 20 s; the second takes no time
    values = chain_setpoints(chain, rover, 0.5, 120)
    starts = np.arange(120) * 0.5
    np.testing.assert_array_equal(values["command"][starts < first], 0.0)
    active = values["command"][starts >= first]
    assert set(active[active >= 0]) == {2.0}  # the command without motion is skipped
    assert active[0] == 2.0 and active[-1] == -1.0


@pytest.mark.parametrize("heading", [5e-324, -5e-324, 1e-300])
def test_a_vanishing_turn_before_a_drive_leaves_its_set_points_as_they_were(
        heading: float) -> None:
    # a point turn by a vanishing angle is a command lasting a vanishing time (a random
    # hypothesis seed found the division by zero a subnormal angle used to be): no step sees it
    rover = RoverGeometry()
    drive = Command(0.0625, 0.1, 0.0)
    alone = chain_setpoints([drive], rover, 0.5, 60)
    values = chain_setpoints([Command(0.0625, 0.0, heading), drive], rover, 0.5, 60)
    for name, series in alone.items():
        assert np.all(np.isfinite(values[name])), name
        if name != "command":
            np.testing.assert_allclose(values[name], series, rtol=0.0, atol=1e-12)
    np.testing.assert_array_equal(values["command"], np.where(alone["command"] >= 0, 1.0, -1.0))
