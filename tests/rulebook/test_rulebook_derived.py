"""Derived signals: theoretical path, errors, tolerance radius, heading error, speed."""

import math

import numpy as np
import pytest

from idefix_rules.commands import Command, RoverGeometry, command_kinematics, ideal_poses
from idefix_rules.errors import UserInputError
from idefix_rules.rulebook.derived import (
    DerivedSettings,
    DerivedSignals,
    RunContext,
    inputs_of,
    wrap_angle,
)

ROVER = RoverGeometry()


def run_of(t, command, **signals):
    out = {"t": np.atleast_2d(np.asarray(t, dtype=float)),
           "command": np.atleast_2d(np.asarray(command, dtype=float))}
    runs, samples = out["t"].shape
    for name in ("x", "y", "z", "yaw"):
        out[name] = np.zeros((runs, samples))
    for name, value in signals.items():
        out[name] = np.atleast_2d(np.asarray(value, dtype=float))
    return out


def test_theory_follows_ideal_poses_with_the_slip_scale():
    chain = (Command(0.1, 0.4, 0.0),)
    duration = command_kinematics(chain[0], ROVER).duration  # 40 s
    t = np.linspace(0.0, 60.0, 61)
    command = np.where(t < duration, 0, -1)
    source = DerivedSignals(run_of(t, command), RunContext(chain, ROVER),
                            DerivedSettings(theoretical_slip=0.25))
    expected = ideal_poses(chain, ROVER, t, scale=0.75)
    np.testing.assert_allclose(source.get("theory.x")[0], expected[:, 0], atol=1e-12)
    np.testing.assert_allclose(source.get("theory.y")[0], 0.0, atol=1e-12)
    assert source.get("theory.x")[0, -1] == pytest.approx(0.3)


def test_theory_follows_the_runs_own_command_timing():
    # The second command starts late in run 0 (at 8 s) and on time in run 1 (at 4 s).
    chain = (Command(0.1, 0.04, 0.0), Command(0.1, 0.04, 0.0))
    assert command_kinematics(chain[0], ROVER).duration == pytest.approx(4.0)
    t = np.arange(0.0, 14.0)
    late = np.where(t < 8, 0, np.where(t < 12, 1, -1))
    on_time = np.where(t < 4, 0, np.where(t < 8, 1, -1))
    source = DerivedSignals(run_of(np.tile(t, (2, 1)), np.stack([late, on_time])),
                            RunContext(chain, ROVER))
    theory = source.get("theory.x")
    # run 0 waits at the end of command 1 (0.04 m) until its second command starts at 8 s
    np.testing.assert_allclose(theory[0, 4:9], [0.04] * 5, atol=1e-12)
    assert theory[0, 10] == pytest.approx(0.06)
    assert theory[1, 6] == pytest.approx(0.06)
    np.testing.assert_allclose(theory[:, -1], [0.08, 0.08])


def test_theory_starts_at_the_reference_pose_and_local_error_is_planar_distance():
    chain = (Command(0.1, 0.2, 0.0),)
    t = np.arange(0.0, 25.0)
    command = np.where(t < 20, 0, -1)
    reference = {"x": np.full(25, 1.0), "y": np.full(25, 2.0), "yaw": np.full(25, math.pi / 2),
                 "z": np.zeros(25)}
    run = run_of(t, command, x=np.full(25, 1.0), y=np.full(25, 2.0), yaw=np.zeros(25))
    source = DerivedSignals(run, RunContext(chain, ROVER, reference=reference))
    # heading north from (1, 2): the theoretical path goes up in y
    np.testing.assert_allclose(source.get("theory.x")[0], 1.0, atol=1e-12)
    assert source.get("theory.y")[0, -1] == pytest.approx(2.2)
    # the run stands still: local error = distance travelled by the theory
    assert source.get("local_error")[0, -1] == pytest.approx(0.2)


def test_tolerance_radius_grows_only_while_turning():
    chain = (Command(0.1, 0.1, 0.0), Command(0.1, 0.0, 1.0), Command(0.1, 0.1, 0.0))
    durations = [command_kinematics(c, ROVER).duration for c in chain]
    t = np.arange(0.0, 30.0, 0.5)
    edges = np.cumsum(durations)
    command = np.select([t < edges[0], t < edges[1], t < edges[2]], [0, 1, 2], -1)
    context = RunContext(chain, ROVER, initial_position_sigma=0.02)
    source = DerivedSignals(run_of(t, command), context,
                            DerivedSettings(theoretical_slip=0.5, tolerance_growth=0.05))
    radius = source.get("tolerance_radius")[0]
    straight = t < edges[0]
    np.testing.assert_allclose(radius[straight], 0.02)
    assert np.all(np.diff(radius) >= -1e-15)
    turning = (t > edges[0]) & (t < edges[1])
    assert np.all(np.diff(radius[turning]) > 0)
    # full turn of 1 rad scaled by (1 - slip) = 0.5 rad → 0.02 + 0.05 * 0.5
    np.testing.assert_allclose(radius[t >= edges[1]], 0.045)


def test_global_error_is_the_3d_distance_to_the_reference_run():
    t = np.arange(3.0)
    reference = {"x": np.zeros(3), "y": np.zeros(3), "z": np.zeros(3)}
    run = run_of(t, [0, 0, -1], x=[0, 3, 0], y=[0, 4, 0], z=[0, 0, 2])
    source = DerivedSignals(run, RunContext((Command(0.1, 0.1, 0),), ROVER, reference=reference))
    np.testing.assert_allclose(source.get("global_error")[0], [0, 5, 2])


def test_heading_error_wraps_to_half_turns():
    t = np.arange(3.0)
    reference = {"yaw": np.array([0.0, 0.0, 3.0])}
    run = run_of(t, [0, 0, -1], yaw=[2 * math.pi + 0.1, -0.2, -3.0])
    source = DerivedSignals(run, RunContext((), ROVER, reference=reference))
    np.testing.assert_allclose(source.get("heading_error")[0],
                               [0.1, -0.2, -6.0 + 2 * math.pi], atol=1e-12)
    assert wrap_angle(np.array([math.pi]))[0] == pytest.approx(-math.pi)


def test_speed_and_acceleration_from_finite_differences():
    t = np.arange(5.0)
    x = 0.5 * t**2  # accelerating at 1 m/s² along x
    source = DerivedSignals(run_of(t, [0] * 5, x=x, y=np.zeros(5)), RunContext())
    np.testing.assert_allclose(source.get("speed")[0, 1:-1], t[1:-1])
    np.testing.assert_allclose(source.get("acceleration")[0, 2:-2], 1.0)
    single = DerivedSignals(run_of([0.0], [0]), RunContext())
    assert single.get("speed").tolist() == [[0.0]]


def test_reference_signals_are_checked():
    run = run_of(np.arange(3.0), [0, 0, -1])
    with pytest.raises(UserInputError, match="reference"):
        DerivedSignals(run, RunContext()).get("ref.pitch")
    short = RunContext(reference={"pitch": np.zeros(2)})
    with pytest.raises(UserInputError, match="samples"):
        DerivedSignals(run, short).get("ref.pitch")


def test_inputs_of_derived_signals():
    assert inputs_of("ref.pitch") == {"pitch"}
    assert inputs_of("speed") == {"t", "x", "y"}
    assert inputs_of("wheel.slip") == {"wheel.slip"}


def test_signal_shapes_are_checked():
    run = run_of(np.arange(3.0), [0, 0, -1])
    run["wheel.slip"] = np.zeros((1, 3, 3))  # three wheels
    with pytest.raises(UserInputError, match=r"wheel\.slip"):
        DerivedSignals(run, RunContext()).get("wheel.slip")


def test_the_last_sample_alone_equals_the_whole_signals_last_sample():
    # two commands, the second started late in run 0; the runs end turned and off the path
    chain = (Command(0.1, 0.04, 0.3), Command(0.1, 0.04, -0.2))
    t = np.arange(0.0, 14.0)
    late = np.where(t < 8, 0, np.where(t < 12, 1, -1))
    running = np.where(t < 4, 0, 1)  # still in its second command at the end
    reference = {"x": np.linspace(0.0, 0.1, 14), "y": np.zeros(14),
                 "yaw": np.linspace(0.0, 0.5, 14), "z": np.zeros(14)}
    run = run_of(np.tile(t, (2, 1)), np.stack([late, running]),
                 x=np.tile(np.linspace(0.0, 0.08, 14), (2, 1)),
                 y=np.tile(np.linspace(0.0, 0.01, 14), (2, 1)),
                 yaw=np.stack([np.full(14, 3.1), np.full(14, -3.1)]))
    context = RunContext(chain, ROVER, reference=reference)
    whole = DerivedSignals(run, context, DerivedSettings(theoretical_slip=0.2))
    alone = DerivedSignals(run, context, DerivedSettings(theoretical_slip=0.2))
    for name in ("local_error", "heading_error", "theory.x", "theory.y", "theory.yaw",
                 "drift"):
        np.testing.assert_array_equal(alone.last(name), whole.get(name)[:, -1], err_msg=name)
