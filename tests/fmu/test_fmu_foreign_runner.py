"""FmuRunner on FMUs other exporters built: FMI 2.0 (pythonfmu) and FMI 3.0 (pythonfmu3),
typed outputs, declared units, and chains fed as set-points every communication step.

Runs go through ``run_in_child`` (a forked process per test, as campaign workers are): the
exporters' embedded interpreters are not built to be loaded many times in one process."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from foreign_fmus import run_in_child

from idefix_rules.commands import Command, RoverGeometry, chain_duration, ideal_poses
from idefix_rules.errors import UserInputError
from idefix_rules.fmu import FmuRunner

CHAIN = [Command(0.05, 0.2, 0.0), Command(0.05, 0.0, 0.5), Command(0.04, 0.1, -0.3)]
UNICYCLE_MAP = {"px": "x", "py": "y", "heading": "yaw", "phase": "done"}
BODY_INPUTS = {"v": "body.speed", "w": "body.yaw_rate"}
DIFF_MAP = {"pos_x": "x", "pos_y": "y", "psi": "yaw", "arrived": "done", "steps": "stuck"}
WHEEL_INPUTS = {"omega_l": "wheel.rate[FL]", "omega_r": "wheel.rate[FR]"}


def _ideal_end(chain: list[Command], scale: float = 1.0) -> np.ndarray:
    rover = RoverGeometry()
    return ideal_poses(chain, rover, np.array([chain_duration(chain, rover)]), scale=scale)[0]


def test_an_fmi2_fmu_fed_body_set_points_ends_where_the_ideal_chain_ends(
        unicycle_fmu: Path) -> None:
    # 0.7 s steps do not divide the command durations: the step means keep distances exact.
    (out,), _ = run_in_child(unicycle_fmu, {
        "signal_map": UNICYCLE_MAP, "chain_delivery": "inputs", "chain_inputs": BODY_INPUTS,
        "done_at": 2}, [({}, CHAIN, 140.0, 0.7)])
    x, y, yaw = _ideal_end(CHAIN)
    assert out["x"][-1] == pytest.approx(x, abs=2e-3)
    assert out["y"][-1] == pytest.approx(y, abs=2e-3)
    assert out["yaw"][-1] == pytest.approx(yaw, abs=1e-9)
    # the Integer 'phase' reaches 2 (done_at) at the end of the first step without motion:
    # the chain ends inside the step before it
    done = int(np.argmax(out["done"] > 0))
    assert set(np.unique(out["done"])) == {0.0, 1.0}
    assert (done - 2) * 0.7 < chain_duration(CHAIN, RoverGeometry()) <= (done - 1) * 0.7
    assert out["t"].shape == (201,)


def test_an_fmi3_fmu_fed_wheel_rates_is_read_in_si_with_its_booleans_and_integers(
        diff_drive_fmu: Path) -> None:
    (out, again, no_slip), _ = run_in_child(diff_drive_fmu, {
        "signal_map": DIFF_MAP, "chain_delivery": "inputs", "chain_inputs": WHEEL_INPUTS},
        [({"slip": 0.2}, CHAIN, 140.0, 0.5), ({"slip": 0.2}, CHAIN, 140.0, 0.5),
         ({"slip": 0.0}, CHAIN, 140.0, 0.5)])
    x, y, _ = _ideal_end(CHAIN, scale=0.8)
    # positions are declared in mm: converted to m
    assert out["x"][-1] == pytest.approx(x, abs=2e-3)
    assert out["y"][-1] == pytest.approx(y, abs=2e-3)
    assert no_slip["x"][-1] == pytest.approx(_ideal_end(CHAIN)[0], abs=2e-3)
    assert out["done"][0] == 0.0 and out["done"][-1] == 1.0  # Boolean 'arrived'
    # Int32 'steps' counts the FMU's steps: one step past the first 'arrived' sample, then
    # no fmi3DoStep at all, the counter held to the stop time
    held = int(np.argmax(out["done"] > 0)) + 1
    assert 200 < held < 280
    np.testing.assert_array_equal(out["stuck"][:held + 1], np.arange(held + 1, dtype=float))
    np.testing.assert_array_equal(out["stuck"][held:], float(held))
    np.testing.assert_array_equal(out["t"], np.arange(281) * 0.5)
    for name in DIFF_MAP.values():
        np.testing.assert_array_equal(out[name], again[name], err_msg=name)


def test_a_mapped_output_of_the_wrong_dimension_is_refused(diff_drive_fmu: Path) -> None:
    with pytest.raises(UserInputError, match=r"'pos_x' is in mm, but signal 'yaw' is in rad"):
        FmuRunner(diff_drive_fmu, signal_map={"pos_x": "yaw"})


def test_a_string_output_is_not_a_signal(unicycle_fmu: Path) -> None:
    with pytest.raises(UserInputError, match=r"'label' is a String"):
        FmuRunner(unicycle_fmu, signal_map={"label": "x"})


def test_without_chain_delivery_the_model_sees_no_chain(unicycle_fmu: Path) -> None:
    (out,), _ = run_in_child(unicycle_fmu, {"signal_map": UNICYCLE_MAP,
                                            "chain_delivery": "none"},
                             [({"x0": 0.3}, CHAIN, 20.0, 0.5)])
    np.testing.assert_array_equal(out["x"][1:], 0.3)
    np.testing.assert_array_equal(out["done"], 0.0)


def test_a_model_exchange_fmu_is_integrated_by_fmpys_solver(planar_me_fmu: Path) -> None:
    (out, again), exchange = run_in_child(planar_me_fmu, {
        "signal_map": {"px": "x", "py": "y", "psi": "yaw"}, "chain_delivery": "inputs",
        "chain_inputs": BODY_INPUTS}, [({}, CHAIN, 140.0, 0.7)] * 2)
    assert exchange
    x, y, yaw = _ideal_end(CHAIN)
    assert out["x"].shape == (201,)
    # CVode's default tolerance, not the exact step means of a co-simulation step
    assert out["x"][-1] == pytest.approx(x, abs=2e-3)
    assert out["y"][-1] == pytest.approx(y, abs=2e-3)
    assert out["yaw"][-1] == pytest.approx(yaw, abs=1e-3)
    np.testing.assert_array_equal(out["x"], again["x"])


def test_a_model_exchange_fmu_is_held_after_its_done_output_like_a_co_simulation(
        planar_me_fmu: Path) -> None:
    # 'psi' as the done output: 'done' from the sample where the heading reaches 0.45 rad,
    # inside the point turn of CHAIN
    options = {"signal_map": {"px": "x", "py": "y", "psi": "done"}, "done_at": 0.45,
               "chain_delivery": "inputs", "chain_inputs": BODY_INPUTS}
    (held_run,), _ = run_in_child(planar_me_fmu, options, [({}, CHAIN, 140.0, 0.7)])
    (full,), _ = run_in_child(planar_me_fmu, options,
                              [({}, CHAIN, 140.0, 0.7, None, False)])
    held = int(np.argmax(full["done"] > 0)) + 1
    assert 0 < held < 200 and full["y"][-1] != full["y"][held]
    for name in ("x", "y", "done"):
        np.testing.assert_array_equal(held_run[name][:held + 1], full[name][:held + 1])
        np.testing.assert_array_equal(held_run[name][held:], full[name][held])
    np.testing.assert_array_equal(held_run["t"], full["t"])


def test_an_unknown_set_point_is_refused_naming_the_known_ones(unicycle_fmu: Path) -> None:
    with pytest.raises(UserInputError, match=r"'body.velocity' is not a set-point; one of "
                                             r"wheel.rate\[FL\], .*body.speed, body.yaw_rate"):
        FmuRunner(unicycle_fmu, signal_map=UNICYCLE_MAP, chain_delivery="inputs",
                  chain_inputs={"v": "body.velocity"})


def test_a_failing_step_is_reported_with_the_fmus_own_message(unicycle_fmu: Path) -> None:
    from idefix_rules.errors import InfrastructureError

    expected = r"(?s)fmi2DoStep failed at t = 0 s .*slip 1.5 outside \[0, 1\)"
    with pytest.raises(InfrastructureError, match=expected):
        run_in_child(unicycle_fmu, {"signal_map": UNICYCLE_MAP, "chain_delivery": "inputs",
                                    "chain_inputs": BODY_INPUTS},
                     [({"slip": 1.5}, CHAIN, 10.0, 0.5)])


def test_an_fmu_that_refuses_to_be_instantiated_says_why_from_its_log(tmp_path: Path) -> None:
    """fmpy says only "Failed to instantiate model": the FMU's own reason is in its log, which
    was lost with the instance that was never made."""
    from foreign_fmus import build_refuser

    from idefix_rules.errors import InfrastructureError

    with pytest.raises(InfrastructureError) as caught:
        FmuRunner(build_refuser(tmp_path), signal_map={"px": "x"})
    said = str(caught.value)
    assert said.startswith("Refuser.fmu: cannot instantiate (Failed to instantiate model; the "
                           "FMU logged: ")
    assert "license server not reachable" in said
