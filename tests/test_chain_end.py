"""Where a run's chain is complete: one reading (idefix_rules.chain_end) for the runner, which
reads it sample by sample while it steps, and the evaluator and the campaign, which read the
stored arrays."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import event, given
from hypothesis import strategies as st

from idefix_rules.campaign.evaluation.evaluate import chain_finished
from idefix_rules.chain_end import EndWatch, ended
from idefix_rules.fmu.run_end import end_sample


def test_a_minus_one_before_the_chain_started_is_no_end() -> None:
    assert end_sample(np.array([-1.0, -1.0, 0.0, 1.0, -1.0]), None) == 4
    assert end_sample(np.array([-1.0, -1.0, -1.0]), None) is None
    assert chain_finished({"command": np.array([[-1.0, -1.0], [0.0, -1.0]])}).tolist() \
        == [False, True]


def test_done_set_from_the_first_sample_counts_only_once_it_was_clear() -> None:
    assert end_sample(None, np.array([1.0, 1.0, 0.0, 0.0, 1.0])) == 4
    assert end_sample(None, np.array([1.0, 1.0, 1.0])) is None
    assert chain_finished({"done": np.array([[1.0, 1.0], [0.0, 1.0]])}).tolist() \
        == [False, True]


def test_done_at_its_threshold_is_done_and_just_below_is_not() -> None:
    assert end_sample(None, np.array([0.0, 2.0]), done_at=2.0) == 1
    assert end_sample(None, np.array([0.0, np.nextafter(2.0, 0.0)]), done_at=2.0) is None


def test_command_rounds_to_its_index() -> None:
    assert end_sample(np.array([0.4, -0.6]), None) == 1  # 0 then -1
    # -0.4 rounds to 0: the first command ran; -1.4 rounds to -1: then it ended
    assert end_sample(np.array([-0.4, -1.4]), None) == 1
    assert end_sample(np.array([-1.4, -0.6]), None) is None  # -1 throughout


samples = st.lists(st.sampled_from([-1.0, 0.0, 1.0, 2.0, 0.49, 0.51, -0.5, float("nan")]),
                   min_size=1, max_size=30)


@given(samples, st.booleans())
def test_the_runners_watch_reads_as_the_stored_arrays_are_read(values: list[float],
                                                              is_done: bool) -> None:
    watch = EndWatch(is_done, 0.5)
    stepped = [watch(value) for value in values]
    array = np.array(values)
    whole = ended(None, array) if is_done else ended(array, None)
    first = next((k for k, hit in enumerate(stepped) if hit), None)
    event(f"ends at a sample: {first is not None}")
    expected = int(np.argmax(whole)) if whole.any() else None
    event(f"a nan among the samples: {any(np.isnan(values))}")  # neither starts nor ends
    assert first == expected
    assert whole.tolist() == [first is not None and k >= first for k in range(len(values))]


@pytest.mark.parametrize("runs", [1, 3])
def test_the_stored_reading_runs_along_the_sample_axis(runs: int) -> None:
    command = np.tile(np.array([-1.0, 0.0, -1.0]), (runs, 1))
    assert ended(command, None).tolist() == [[False, False, True]] * runs


def test_an_empty_chain_is_complete_wherever_the_output_says_so() -> None:
    assert end_sample(np.array([-1.0, -1.0]), None, started=True) == 0
    assert end_sample(None, np.array([1.0, 1.0]), started=True) == 0
    watch = EndWatch(False, 0.5, started=True)
    assert watch(-1.0)
