"""Where a run's chain is complete: one reading (idefix_rules.chain_end) for the runner, which
reads it sample by sample while it steps, and the evaluator and the campaign, which read the
stored arrays."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import event, given
from hypothesis import strategies as st

from idefix_rules.campaign.evaluation.evaluate import chain_finished
from idefix_rules.chain_end import EndWatch, ended, nothing_to_execute
from idefix_rules.commands import Command
from idefix_rules.fmu.run_end import end_sample
from idefix_rules.rulebook import check_text
from idefix_rules.rulebook.interpret import interpret


def test_a_minus_one_before_the_chain_started_is_no_end() -> None:
    assert end_sample(np.array([-1.0, -1.0, 0.0, 1.0, -1.0]), None) == 4
    assert end_sample(np.array([-1.0, -1.0, -1.0]), None) is None
    assert chain_finished({"command": np.array([[-1.0, -1.0], [0.0, -1.0]])},
                          (MOVE,)).tolist() == [False, True]


def test_done_set_from_the_first_sample_counts_only_once_it_was_clear() -> None:
    assert end_sample(None, np.array([1.0, 1.0, 0.0, 0.0, 1.0])) == 4
    assert end_sample(None, np.array([1.0, 1.0, 1.0])) is None
    assert chain_finished({"done": np.array([[1.0, 1.0], [0.0, 1.0]])}, (MOVE,)).tolist() \
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


STILL = Command(0.05, 0.0, 0.0)
MOVE = Command(0.05, 0.1, 0.0)


def test_a_chain_that_moves_nothing_has_nothing_to_execute() -> None:
    assert nothing_to_execute(()) and nothing_to_execute((STILL, STILL))
    assert not nothing_to_execute((STILL, MOVE))
    assert not nothing_to_execute((Command(0.05, 0.0, 0.1),))  # a turn on the spot


def test_past_the_last_command_or_below_minus_one_is_the_end() -> None:
    """As the evaluator reads 'command' (C520 refuses such runs now; results stored before
    are read the same way everywhere)."""
    for command in ([0.0, 1.0, 1.0, 1.0], [0.0, -2.0, -2.0, -2.0]):
        assert end_sample(np.array(command), None, commands=1) == 1
        assert chain_finished({"command": np.array([command])}, (MOVE,)).tolist() == [True]


@pytest.mark.parametrize("chain", [(), (STILL,), (STILL, STILL)])
def test_a_chain_with_nothing_to_execute_is_complete_from_the_start(
        chain: tuple[Command, ...]) -> None:
    assert chain_finished({"done": np.ones((1, 4))}, chain).tolist() == [True]
    assert chain_finished({"command": -np.ones((1, 4))}, chain).tolist() == [True]


_CHECKED = check_text('''rulebook "t" version "1.0.0"
purpose "a run's time"
index I_x "x" {
  value  = max over time (abs(x))
  limit  = 1 m
  weight = 1
}
verdict v: require risk <= 50 %
''', "t.rules").checked


def _first(flags: np.ndarray) -> int | None:
    return int(np.argmax(flags)) if flags.any() else None


@given(st.lists(st.sampled_from([-2.0, -1.0, 0.0, 1.0, 2.0, 0.6]), min_size=2, max_size=12),
       st.lists(st.sampled_from([STILL, MOVE]), min_size=0, max_size=3), st.booleans())
def test_the_runner_the_evaluators_and_the_campaign_end_a_chain_at_one_sample(
        values: list[float], chain: list[Command], as_done: bool) -> None:
    """Where each reads a run's chain as complete: the runner sample by sample, the compiled
    evaluator's chain_done and run time, the interpreter's run time (written apart) and the
    campaign's count of unfinished runs."""
    from idefix_rules.rulebook.derived import DerivedSignals, RunContext
    from idefix_rules.rulebook.run_values import time_energy

    name = "done" if as_done else "command"
    given_values = np.array(values if not as_done else [float(v > 0.5) for v in values])
    samples = len(values)
    context = RunContext(chain=tuple(chain))
    watch = EndWatch(as_done, 0.5, nothing_to_execute(chain), len(chain))
    stepped = next((k for k, v in enumerate(given_values) if watch(float(v))), None)
    source = DerivedSignals({"t": np.arange(float(samples))[None], name: given_values[None]},
                            context)
    done = _first(source.get("chain_done")[0] > 0)
    time, _ = time_energy(source, 1)
    finished = chain_finished({name: given_values[None]}, chain)
    signals = {"t": np.arange(float(samples))[None], "x": np.zeros((1, samples)),
               "y": np.zeros((1, samples)), name: given_values[None]}
    interpreted = interpret(_CHECKED, signals, context)
    event(f"ends: {stepped is not None}; nothing to execute: {nothing_to_execute(chain)}")
    assert stepped == done
    assert time[0] == (samples - 1 if done is None else done)
    assert interpreted.time.tolist() == time.tolist()
    assert finished is not None and finished.tolist() == [done is not None]
