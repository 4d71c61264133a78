"""The derived signal ``chain_done``: 1 from the sample the chain is complete, as a run's time
reads it, so a rulebook can count runs still executing their chain at the stop limit."""

import numpy as np

from idefix_rules.commands import Command
from idefix_rules.rulebook import check_text
from idefix_rules.rulebook.compile import compile_rulebook
from idefix_rules.rulebook.derived import DerivedSignals, RunContext
from idefix_rules.rulebook.interpret import interpret

CHAIN = (Command(0.05, 0.1, 0.0), Command(0.05, 0.0, 0.5))


def done(signals: dict, chain: tuple = CHAIN) -> np.ndarray:
    return DerivedSignals(signals, RunContext(chain=chain)).get("chain_done")


def test_it_turns_one_where_command_returns_to_minus_one_and_stays():
    t = np.arange(6, dtype=float)[None]
    finished = {"t": t, "command": np.array([[0, 0, 1, 1, -1, -1]], dtype=float)}
    running = {"t": t, "command": np.array([[0, 0, 1, 1, 1, 1]], dtype=float)}
    assert done(finished).tolist() == [[0, 0, 0, 0, 1, 1]]
    assert done(running).tolist() == [[0, 0, 0, 0, 0, 0]]


def test_a_mapped_done_output_is_used_without_command():
    signals = {"t": np.arange(4, dtype=float)[None], "done": np.array([[0, 0, 1, 0]], float)}
    assert done(signals).tolist() == [[0, 0, 1, 1]]  # complete once, complete for good


def test_without_either_the_ideal_schedule_decides():
    # 0.1 m at 0.05 rad/s on 0.1 m wheels: 20 s; the point turn 0.5 rad * 0.26 m: 26 s
    signals = {"t": np.array([[0.0, 19.0, 45.0, 47.0]])}
    assert done(signals).tolist() == [[0, 0, 0, 1]]


def test_an_empty_chain_is_complete_from_the_start():
    signals = {"t": np.arange(3, dtype=float)[None], "command": np.full((1, 3), -1.0)}
    assert done(signals, chain=()).tolist() == [[1, 1, 1]]


RULEBOOK = '''rulebook "done" version "1.0.0"
purpose "chains that finish"
index I_x "x" {
  value  = final over time (x)
  limit  = 1 m
  weight = 1
  because "x"
}
chance unfinished = final over time (chain_done) < 1
  because "still executing its chain at the stop limit"
verdict finish: require chance(unfinished) <= 5 %
  because "chains finish"
'''


def test_a_chance_counts_the_runs_still_executing_in_both_evaluators():
    result = check_text(RULEBOOK, "done.rules")
    assert result.checked is not None, [d.format() for d in result.errors]
    model = result.checked
    t = np.arange(5, dtype=float)
    signals = {"t": np.broadcast_to(t, (3, 5)).copy(),
               "x": np.zeros((3, 5)),
               "command": np.array([[0, 1, -1, -1, -1], [0, 1, 1, 1, 1], [0, 0, 1, -1, -1]],
                                   dtype=float)}
    context = RunContext(chain=CHAIN)
    compiled = compile_rulebook(model).evaluate(signals, context)
    assert compiled.chances["unfinished"].tolist() == [False, True, False]
    interpreted = interpret(model, signals, context)
    assert np.asarray(interpreted.chances["unfinished"]).tolist() == [False, True, False]


def test_a_runs_time_and_energy_are_read_where_chain_done_turns_one_in_both_evaluators():
    """A -1 before the chain started is no end: the time is read where the chain is complete
    (it was read at the first -1, t = 0, energy 0)."""
    result = check_text(RULEBOOK, "done.rules")
    assert result.checked is not None
    t = np.arange(8, dtype=float)
    signals = {"t": np.broadcast_to(t, (2, 8)).copy(), "x": np.zeros((2, 8)),
               "energy": np.broadcast_to(0.1 * t, (2, 8)).copy(),
               "command": np.array([[-1, -1, 0, 0, 1, -1, -1, -1],
                                    [0, 1, -1, -1, -1, -1, -1, -1]], dtype=float)}
    context = RunContext(chain=CHAIN)
    for evaluation in (compile_rulebook(result.checked).evaluate(signals, context),
                       interpret(result.checked, signals, context)):
        assert np.asarray(evaluation.time).tolist() == [5.0, 2.0]
        np.testing.assert_allclose(evaluation.energy, [0.5, 0.2])
    assert done(signals).tolist()[0] == [0, 0, 0, 0, 0, 1, 1, 1]
