"""What a worker accepts of a run's outputs before it is stored: every value finite, and
finite in the precision it is stored in (a float32 signal beyond float32's range would read
back as infinite, and a file holding it would be refused as damaged, H004)."""

from __future__ import annotations

import numpy as np
import pytest

from idefix_rules.campaign.simulation.worker import check_outputs

LIMIT = float(np.finfo(np.float32).max)


def test_finite_outputs_in_range_are_kept_as_float64() -> None:
    checked = check_outputs({"x": np.arange(3.0), "wheel.slip": np.full((3, 4), LIMIT)}, 3)
    assert checked["wheel.slip"].dtype == np.float64 and checked["x"].tolist() == [0, 1, 2]
    # a float64 signal may hold what float32 cannot
    assert check_outputs({"x": np.full(3, 1e300)}, 3)["x"][0] == 1e300


@pytest.mark.parametrize(("values", "says"), [
    (np.array([0.0, np.nan, 1.0]), "signal 'wheel.slip' is not finite from sample 1"),
    (np.array([0.0, 1.0, LIMIT * 1.01]), "signal 'wheel.slip' exceeds the range of the float32"),
    (np.array([0.0, -LIMIT * 1.01, 1.0]), "signal 'wheel.slip' exceeds the range of the float32"),
])
def test_a_run_a_stored_file_could_not_hold_finite_is_refused(values: np.ndarray,
                                                              says: str) -> None:
    with pytest.raises(ValueError, match=says):
        check_outputs({"wheel.slip": np.repeat(values[:, None], 4, axis=1)}, 3)


def test_a_wheel_not_finite_while_the_others_are_names_its_first_sample():
    """One wheel's column NaN from sample 5 (the others finite): the run fails there, with the
    documented reason (the first bad sample was looked for where no wheel was finite: an
    IndexError)."""
    slip = np.zeros((8, 4))
    slip[5:, 2] = np.nan
    with pytest.raises(ValueError, match=r"signal 'wheel.slip' is not finite from sample 5"):
        check_outputs({"wheel.slip": slip}, 8)


def test_a_time_signal_that_does_not_increase_fails_the_run_where_it_stalls():
    """An output mapped to t that is no clock (a phase 0, 1, 1, 2) made every run's time 2 s."""
    with pytest.raises(ValueError, match=r"signal 't' does not increase at sample 2 \(1 s, then "
                                         r"1 s\)"):
        check_outputs({"t": np.array([0.0, 1.0, 1.0, 2.0])}, 4)
    assert check_outputs({"t": np.array([0.0, 0.5, 1.0])}, 3)["t"][-1] == 1.0


@pytest.mark.parametrize(("command", "outside"), [
    ([-1.0, 0.0, 1.0, -1.0], None),       # two commands, then -1
    ([-1.0, 0.0, 1.4, -1.0], None),       # rounds to 1
    ([-1.0, 0.0, 1.5, -1.0], 2),          # rounds to 2: no command of two
    ([-1.0, 0.0, 2.0, -1.0], 2),
    ([-1.4, 0.0, 1.0, -1.0], None),       # rounds to -1
    ([-1.6, 0.0, 1.0, -1.0], 0),          # rounds to -2
])
def test_command_outside_the_chains_indices_is_a_map_mistake(command: list[float],
                                                              outside: int | None) -> None:
    """A phase or 1-based counter mapped to 'command' (C520, at the map): checked against the
    chain's length, here two commands; not checked without it."""
    from idefix_rules.errors import UserInputError

    signals = {"command": np.array(command)}
    assert check_outputs(signals, 4)["command"].tolist() == command
    if outside is None:
        assert check_outputs(signals, 4, commands=2)["command"].tolist() == command
        return
    with pytest.raises(UserInputError) as raised:
        check_outputs(signals, 4, commands=2)
    [diagnostic] = raised.value.diagnostics
    assert diagnostic.code == "C520"
    assert f"reads {command[outside]:g} at sample {outside}, outside -1 … 1" \
        in diagnostic.message
