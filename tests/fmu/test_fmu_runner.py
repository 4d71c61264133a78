"""FmuRunner: contract-shaped outputs, reset between runs, units, maps and clear errors."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest

from idefix_rules.commands import Command, RoverGeometry, command_kinematics
from idefix_rules.errors import UserInputError
from idefix_rules.fmu import FmuRunner, Rock, extract_fmu, synthetic_terrain, write_terrain
from idefix_rules.signals import FMU_SIGNALS


def test_outputs_are_keyed_by_contract_names_with_contract_shapes(rover: FmuRunner) -> None:
    out = rover.run({}, [Command(0.05, 0.1, 0.0)], stop_time=30.0, output_interval=0.1)
    for name, spec in FMU_SIGNALS.items():
        if name == "done":  # for FMUs without 'command'; the rover reports 'command'
            continue
        assert name in out, name
        expected = (301, 4) if "wheel" in spec.axes else (301,)
        assert out[name].shape == expected, name
    np.testing.assert_allclose(out["t"], np.arange(301) * 0.1, atol=1e-9)
    assert out["wheel.FL.load"].shape == (301,)  # extra outputs keep their FMU names


def test_runs_after_reset_are_identical_and_leave_no_ruts(rover: FmuRunner) -> None:
    chain = [Command(0.05, 0.3, 0.3), Command(0.05, -0.2, 0.0)]
    first = rover.run({}, chain, 150.0, 0.1)
    rover.run({"soil.cohesion": 80.0, "initial.x": 0.05}, [Command(0.05, 0.4, -0.4)], 150.0, 0.1)
    again = rover.run({}, chain, 150.0, 0.1)
    for name in set(FMU_SIGNALS) - {"done"}:
        np.testing.assert_array_equal(first[name], again[name], err_msg=name)


def test_commanded_wheel_rates_equal_the_shared_kinematics(rover: FmuRunner) -> None:
    # open loop on odometry: the wheels turn exactly the commanded kinematics (the closed loop
    # adds a heading correction: tests/fmu/test_fmu_heading.py)
    geometry = RoverGeometry()
    odometry = {"controller.heading_feedback": 0.0}
    for command in (Command(0.05, 0.2, 0.0), Command(0.04, 0.3, 0.5), Command(0.05, 0.0, -0.8),
                    Command(0.03, -0.2, 0.3)):
        expected = command_kinematics(command, geometry)
        out = rover.run(odometry, [command], expected.duration + 5.0, 0.1)
        middle = int(expected.duration / 2 / 0.1)
        np.testing.assert_allclose(out["wheel.rate"][middle], expected.wheel_rates, rtol=1e-12)
        finished = int(np.argmax(out["command"] < 0))
        ramp = abs(command.max_wheel_rate) / 0.015  # trapezoid: ramps add rate / acceleration
        assert finished * 0.1 == pytest.approx(expected.duration + ramp, abs=0.3)
        stepped = rover.run({**odometry, "controller.wheel_acceleration": 0.0}, [command],
                            expected.duration + 5.0, 0.1)
        np.testing.assert_allclose(stepped["wheel.rate"][1], expected.wheel_rates, rtol=1e-12)
        finished = int(np.argmax(stepped["command"] < 0))
        assert finished * 0.1 == pytest.approx(expected.duration, abs=0.1 + 1e-9)


def test_parameters_accept_units_and_reject_wrong_dimensions(rover: FmuRunner) -> None:
    chain = [Command(0.05, 0.2, 0.0)]
    in_degrees = rover.run({"soil.friction_angle": "30 deg"}, chain, 50.0, 0.1)
    in_radians = rover.run({"soil.friction_angle": math.radians(30.0)}, chain, 50.0, 0.1)
    np.testing.assert_allclose(in_degrees["x"], in_radians["x"], rtol=0, atol=1e-12)
    with pytest.raises(UserInputError, match=r"soil\.cohesion"):
        rover.run({"soil.cohesion": "3 m"}, chain, 10.0, 0.1)
    with pytest.raises(UserInputError, match="no_such"):
        rover.run({"soil.no_such": 1.0}, chain, 10.0, 0.1)


def test_missing_mapped_variable_is_a_user_error_naming_variable_and_fmu(rover_fmu: Path) -> None:
    with pytest.raises(UserInputError) as caught:
        FmuRunner(rover_fmu, signal_map={"body.x": "x"})
    assert caught.value.exit_code == 2
    diagnostic = caught.value.diagnostics[0]
    assert "body.x" in diagnostic.message
    assert diagnostic.span is not None and diagnostic.span.path == str(rover_fmu)


def test_parameter_map_renames_user_names_to_fmu_variables(rover_fmu: Path) -> None:
    with FmuRunner(rover_fmu, parameter_map={"c": "soil.cohesion"}) as runner:
        soft = runner.run({"c": 50.0}, [Command(0.05, 0.3, 0.0)], 80.0, 0.1)
        firm = runner.run({"c": 600.0}, [Command(0.05, 0.3, 0.0)], 80.0, 0.1)
    assert soft["x"][-1] < firm["x"][-1]


def test_bad_terrain_file_is_a_user_error_with_its_name(rover: FmuRunner, tmp_path: Path) -> None:
    bad = tmp_path / "bad.terrain"
    bad.write_bytes(b"IDEFIX-TERRAIN 1\nnx 2\n")
    with pytest.raises(UserInputError) as caught:
        rover.run({"terrain.file": str(bad)}, [Command(0.05, 0.1, 0.0)], 10.0, 0.1)
    assert caught.value.diagnostics[0].span.path == str(bad)  # type: ignore[union-attr]
    good = write_terrain(tmp_path / "good.terrain", synthetic_terrain(size=3.0, cell=0.05))
    out = rover.run({"terrain.file": str(good)}, [Command(0.05, 0.1, 0.0)], 10.0, 0.1)
    assert np.isfinite(out["x"]).all()


def test_rover_stands_still_with_motors_off_after_the_chain(rover: FmuRunner) -> None:
    # the model itself after its chain, every sample simulated
    out = rover.run({}, [Command(0.05, 0.1, 0.0)], 60.0, 0.1, hold_after_chain=False)
    done = out["command"] < 0
    assert done[-1] and not done[0]
    after = np.argmax(done)
    assert np.all(out["wheel.rate"][after + 1:] == 0.0)
    # the body skids to a stop on its locked wheels within about a second, then stands
    coasting = out["x"][-1] - out["x"][after]
    assert 0.0 <= coasting < 0.004
    settled = after + 30
    assert np.ptp(out["x"][settled:]) == 0.0 and np.ptp(out["yaw"][settled:]) == 0.0
    assert np.ptp(out["energy"][settled:]) == 0.0  # holding still draws no current


def test_a_rewritten_terrain_file_is_read_again(rover: FmuRunner, tmp_path: Path) -> None:
    path = tmp_path / "same-name.terrain"
    results = []
    for slope in (0.0, 0.3):  # same path and size, rewritten within the same second
        write_terrain(path, synthetic_terrain(size=3.0, cell=0.05, slope=slope))
        results.append(rover.run({"terrain.file": str(path)}, [], 5.0, 0.1)["pitch"][-1])
    assert results[0] == pytest.approx(0.0, abs=1e-9)
    # the front wheels, unloaded by the slope, sink less than the rear ones: 0.3 rad within 3 mrad
    assert results[1] == pytest.approx(0.3, abs=3e-3)


def test_rock_contacts_follow_the_rocks_of_the_terrain_read(rover: FmuRunner, rover_fmu: Path,
                                                            tmp_path: Path) -> None:
    # The model keeps its recent wheel-on-rock answers (terrain.c). A runner that stood with its
    # front right wheel on a rock, or drove over it, and then reads a file with the rock 6 mm
    # higher must meet the new rock, as a runner that never saw the first one does, bit for
    # bit; and a second run the same again.
    path = tmp_path / "rock.terrain"
    runs = {"stand": ([], 3.0, (0.2, -0.26, 0.04, 0.04)),
            "drive": ([Command(0.05, 0.35, 0.0)], 60.0, (0.25, -0.26, 0.05, 0.05))}
    for chain, stop, (x, y, a, b) in runs.values():
        outs = []
        for height in (0.015, 0.021):
            write_terrain(path, synthetic_terrain(size=2.0, cell=0.02, rocks=[
                Rock(x, y, a, b, height)]))
            outs.append(rover.run({"terrain.file": str(path)}, chain, stop, 0.1))
        again = rover.run({"terrain.file": str(path)}, chain, stop, 0.1)
        with FmuRunner(rover_fmu) as fresh:
            alone = fresh.run({"terrain.file": str(path)}, chain, stop, 0.1)
        assert outs[0]["z"].max() < outs[1]["z"].max()  # the wheel is on each rock
        for name in ("x", "y", "z", "yaw", "pitch", "roll", "wheel.slip", "energy"):
            np.testing.assert_array_equal(outs[1][name], alone[name], err_msg=name)
            np.testing.assert_array_equal(again[name], alone[name], err_msg=name)


@pytest.mark.parametrize(("name", "value"), [
    ("rover.yaw_inertia", 0.0), ("rover.yaw_inertia", -1.0), ("soil.friction_angle", 1.55),
    ("soil.rut_cohesion_factor", 1.5), ("soil.multipass_factor", -0.2),
    ("rock.friction_coefficient", -0.1), ("rock.shear_K", 0.0), ("solver.step", float("nan")),
])
def test_a_parameter_out_of_range_is_a_user_error_naming_it(
        rover: FmuRunner, name: str, value: float) -> None:
    with pytest.raises(UserInputError) as caught:
        rover.run({name: value}, [Command(0.05, 0.1, 0.0)], 1.0, 0.1)
    text = str(caught.value)
    assert f"parameter {name} = " in text and "allowed" in text
    assert rover.run({}, [], 0.2, 0.1)["x"][-1] == 0.0  # the runner is still usable


def test_a_rut_grid_cell_far_finer_than_memory_allows_is_coarsened_not_out_of_memory(
        rover_fmu: Path, tmp_path: Path) -> None:
    """The rut grid counted its cells in a long: 1e-9 m cells over a 4 m terrain (5 m with its
    margins) overflowed it, and the FMU ran out of memory (exit 3). The grid coarsens instead,
    as it does for any count beyond its bound (a fresh runner: the coarsened grid is kept
    across resets)."""
    terrain = write_terrain(tmp_path / "site.terrain", synthetic_terrain(size=4.0, cell=0.05))
    with FmuRunner(rover_fmu) as runner:
        out = runner.run({"soil.grid_cell": 1e-9, "terrain.file": str(terrain)},
                         [Command(0.05, 0.1, 0.0)], 10.0, 0.1)
    assert np.isfinite(out["x"]).all() and out["x"][-1] > 0.03  # it drove


def test_a_rejected_parameter_is_named_by_its_campaign_name(rover_fmu: Path) -> None:
    with FmuRunner(rover_fmu, parameter_map={"wheel_rock_mu": "rock.friction_coefficient"}) \
            as runner, pytest.raises(UserInputError, match="'wheel_rock_mu'"):
        runner.run({"wheel_rock_mu": 3.0}, [], 1.0, 0.1)


def test_a_replaced_terrain_file_with_preserved_mtime_is_read_again(
        rover: FmuRunner, tmp_path: Path) -> None:
    # The terrain cache is keyed by the file's content: a file replaced by one of the same
    # size with its old modification time restored (e.g. `cp -p`, rsync -t) still counts.
    path = tmp_path / "replaced.terrain"
    write_terrain(path, synthetic_terrain(size=3.0, cell=0.05, slope=0.0))
    hour_ago = path.stat().st_mtime_ns - 3600 * 10**9  # an old file, not one being written
    os.utime(path, ns=(hour_ago, hour_ago))
    stamp = path.stat()
    flat = rover.run({"terrain.file": str(path)}, [], 5.0, 0.1)["pitch"][-1]
    write_terrain(path, synthetic_terrain(size=3.0, cell=0.05, slope=0.3))
    assert path.stat().st_size == stamp.st_size
    os.utime(path, ns=(stamp.st_atime_ns, stamp.st_mtime_ns))
    sloped = rover.run({"terrain.file": str(path)}, [], 5.0, 0.1)["pitch"][-1]
    assert flat == pytest.approx(0.0, abs=1e-9)
    assert sloped == pytest.approx(0.3, abs=3e-3)  # front and rear sinkage differ


def test_two_instances_in_one_process_do_not_share_state(rover_fmu: Path) -> None:
    from fmpy.fmi2 import FMU2Slave

    chain = [Command(0.05, 0.2, 0.2)]
    with FmuRunner(rover_fmu) as first:
        alone = first.run({}, chain, 60.0, 0.1)
        # a second instance of the same loaded library, stepped in between
        second = FMU2Slave(guid=first._slave.guid, unzipDirectory=str(first._unzipdir),
                           modelIdentifier="idefix_rover", instanceName="other")
        second.instantiate()
        second.setupExperiment(startTime=0.0)
        second.enterInitializationMode()
        second.setReal([first._variables["soil.cohesion"].value_reference], [40.0])
        second.exitInitializationMode()
        for k in range(100):
            second.doStep(k * 0.1, 0.1)
        again = first.run({}, chain, 60.0, 0.1)
        second.terminate()
        second.fmi2FreeInstance(second.component)
    for name in alone:
        np.testing.assert_array_equal(alone[name], again[name], err_msg=name)


def test_runners_share_a_folder_extracted_once_and_leave_it_to_its_owner(
        rover_fmu: Path, tmp_path: Path) -> None:
    folder = extract_fmu(rover_fmu, tmp_path / "unzipped")
    chain = [Command(0.05, 0.2, 0.2)]
    with FmuRunner(rover_fmu) as own:
        expected = own.run({}, chain, 30.0, 0.1)
        own_folder = own.unzipped
    assert not own_folder.exists()  # a runner removes the folder it extracted itself
    with FmuRunner(rover_fmu, unzipped=folder) as first, \
            FmuRunner(rover_fmu, unzipped=folder) as second:
        assert first.unzipped == second.unzipped == folder
        for runner in (first, second):
            out = runner.run({}, chain, 30.0, 0.1)
            for name in expected:
                np.testing.assert_array_equal(out[name], expected[name], err_msg=name)
    assert (folder / "modelDescription.xml").is_file()  # the caller's folder stays


def test_extracting_something_that_is_not_an_fmu_is_a_user_error(tmp_path: Path) -> None:
    (tmp_path / "broken.fmu").write_text("not a zip archive")
    with pytest.raises(UserInputError, match="not a readable FMU"):
        extract_fmu(tmp_path / "broken.fmu", tmp_path / "out")
    with pytest.raises(UserInputError, match="FMU file is not a file"):
        extract_fmu(tmp_path, tmp_path / "out")


class _CountingSteps:
    """fmi2DoStep of a runner, counted (the runner calls it once per communication step)."""

    def __init__(self, runner: FmuRunner) -> None:
        self.calls = 0
        self._step = runner._do_step
        runner._do_step = self

    def __call__(self, *arguments: object) -> int:
        self.calls += 1
        assert self._step is not None
        return int(self._step(*arguments))


@pytest.mark.parametrize("chain", [
    [Command(0.05, 0.1, 0.0)],  # ends on the straight's ramp down: wheels still turning at T
    [Command(0.05, 0.1, 0.3), Command(0.05, 0.0, -0.2)],  # an arc, then a point turn
])
def test_a_run_ends_one_step_after_its_chain_and_holds_that_sample(
        rover_fmu: Path, chain: list[Command]) -> None:
    with FmuRunner(rover_fmu) as runner:
        steps = _CountingSteps(runner)
        out = runner.run({}, chain, 200.0, 0.1)
        stepped = steps.calls
        full = runner.run({}, chain, 200.0, 0.1, hold_after_chain=False)
    assert steps.calls - stepped == 2000
    end = int(np.argmax(out["command"] == -1))  # the chain is complete at sample T = end
    assert 0 < end < 1000
    assert stepped == end + 1  # one step past T, none after
    for name, values in out.items():
        assert values.shape == full[name].shape, name
        if name == "t":  # t goes on along the grid as the FMU would report it
            np.testing.assert_array_equal(values, full["t"])
            continue
        np.testing.assert_array_equal(values[:end + 2], full[name][:end + 2], err_msg=name)
        np.testing.assert_array_equal(values[end + 1:], np.broadcast_to(
            values[end + 1], values[end + 1:].shape), err_msg=name)
        # the rover stands still with its motors off: the held samples are what the model
        # computes there, but for the legs' last settling (roll 2e-11 rad: below the float32
        # the results file keeps roll in)
        np.testing.assert_allclose(values, full[name], rtol=0, atol=1e-10, err_msg=name)
    assert np.all(out["wheel.rate"][end + 1:] == 0.0)


def test_a_chain_not_done_at_the_stop_time_is_simulated_to_it(rover_fmu: Path) -> None:
    with FmuRunner(rover_fmu) as runner:
        steps = _CountingSteps(runner)
        out = runner.run({}, [Command(0.05, 0.3, 0.0)], 20.0, 0.1)
        empty = runner.run({}, [], 20.0, 0.1)
    assert steps.calls == 200 + 1  # the whole unfinished run, then one step of the empty one
    assert out["command"][-1] == 0.0 and out["x"][-1] > out["x"][-2]
    assert np.all(empty["command"] == -1) and np.ptp(empty["x"]) == 0.0
