"""A run's own samples: the counting reducers over time (mean, percentile, fraction …) count
only the samples up to the run's end, so that the samples a finished run holds to the end of
its chain's grid (the stop limit, or the longest run) change nothing it scores
(``idefix_rules.rulebook.semantics``, "A run's own samples")."""

import numpy as np
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st

from idefix_rules.commands import Command
from idefix_rules.rulebook import check_text
from idefix_rules.rulebook.compile import compile_rulebook
from idefix_rules.rulebook.derived import DerivedSignals, RunContext
from idefix_rules.rulebook.interpret import interpret

CHAIN = (Command(0.05, 0.1, 0.0),)


def lengths(signals: dict) -> list[int] | None:
    found = DerivedSignals(signals, RunContext(chain=CHAIN)).run_lengths()
    return None if found is None else found.tolist()


def test_a_run_at_rest_after_its_chain_owns_the_samples_through_the_one_after_its_end():
    # the chain is complete at sample 3; sample 4 is the rover standing with its motors off
    signals = {"t": np.arange(8.0)[None], "command": np.array([[0, 0, 0, -1, -1, -1, -1, -1.]]),
               "x": np.array([[0, 1, 2, 3, 3, 3, 3, 3.]])}
    assert lengths(signals) == [5]


def test_a_rover_still_sliding_after_its_chain_owns_the_samples_until_it_is_at_rest():
    signals = {"t": np.arange(8.0)[None], "command": np.array([[0, 0, 0, -1, -1, -1, -1, -1.]]),
               "x": np.array([[0, 1, 2, 3, 3.5, 3.7, 3.7, 3.7]])}
    assert lengths(signals) == [6]  # at rest from sample 5 on
    signals["yaw"] = np.array([[0, 0, 0, 0, 0, 0, 0.1, 0.1]])  # still turning at sample 6
    assert lengths(signals) == [7]


def test_a_run_that_never_finishes_or_gives_no_end_owns_every_sample():
    running = {"t": np.arange(4.0)[None], "command": np.zeros((1, 4)), "x": np.zeros((1, 4))}
    assert lengths(running) == [4]
    assert lengths({"t": np.arange(4.0)[None], "x": np.zeros((1, 4))}) is None


def test_without_a_pose_the_sample_after_the_end_is_the_last_own_one():
    done = {"t": np.arange(6.0)[None], "done": np.array([[0, 0, 1, 1, 1, 1.]])}
    assert lengths(done) == [4]
    last = {"t": np.arange(4.0)[None], "done": np.array([[0, 0, 0, 1.]])}
    assert lengths(last) == [4]  # the end is the grid's last sample: nothing after it


RULEBOOK = '''rulebook "own" version "1.0.0"
purpose "counting reducers"
const small = 1 m
index I_mean "mean" {
  value  = mean over time (abs(x))
  limit  = 10 m
  weight = 1
  because "mean"
}
index I_p90 "p90" {
  value  = percentile 90 over time (max over wheels (abs(wheel.slip)))
  limit  = 1
  weight = 1
  because "percentile"
}
index I_rms "rms" {
  value  = rms over time (x)
  limit  = 10 m
  weight = 1
  because "rms"
}
index I_int "integral" {
  value  = integral over time (abs(x))
  limit  = 100 m*s
  weight = 1
  because "integral"
}
index I_final "final" {
  value  = final over time (abs(x))
  limit  = 10 m
  weight = 1
  because "final"
}
chance often_far = fraction over time (abs(x) > small) > 50 %
  because "fraction"
chance long_far = time_above 1 m over time (abs(x)) > 3 s
  because "time above"
chance many_far = count over time (abs(x) > small) > 3
  because "count"
chance sum_far = sum over time (abs(x)) > 10 m
  because "sum"
chance path_mean = mean over time (mean over runs (x)) > 1 m
  because "a path-level operand: every sample of the grid"
verdict v: require chance(often_far) <= 50 %
  because "v"
'''


@pytest.fixture(scope="module")
def model():
    result = check_text(RULEBOOK, "own.rules")
    assert result.checked is not None, [d.format() for d in result.errors]
    return result.checked


def scored(model, signals: dict) -> dict[str, list]:
    """Per-run values and chances from both evaluators (they must agree)."""
    context = RunContext(chain=CHAIN)
    compiled = compile_rulebook(model).evaluate(signals, context)
    interpreted = interpret(model, signals, context)
    out = {}
    for name in compiled.raw:
        np.testing.assert_allclose(compiled.raw[name], interpreted.raw[name], rtol=1e-9,
                                   atol=1e-12, err_msg=name)
        out[name] = compiled.raw[name].tolist()
    for name in compiled.chances:
        assert compiled.chances[name].tolist() == np.asarray(interpreted.chances[name]).tolist()
        out[name] = compiled.chances[name].tolist()
    return out


def run(xs: list[float], slips: list[float], end: int, held: int) -> dict:
    """One run whose chain is complete at sample ``end`` (the rover at rest from the sample
    after it), its last sample held ``held`` more times, ``t`` going on along the grid."""
    n = len(xs)
    x = np.array(xs + [xs[-1]] * held, dtype=float)
    slip = np.array(slips + [slips[-1]] * held, dtype=float)
    command = np.where(np.arange(n + held) >= end, -1.0, 0.0)
    return {"t": np.arange(n + held, dtype=float)[None], "x": x[None],
            "wheel.slip": np.repeat(slip[:, None], 4, axis=1)[None], "command": command[None]}


@settings(max_examples=60, deadline=None)
@given(data=st.data())
def test_samples_held_after_a_runs_end_change_nothing_it_scores(model, data):
    n = data.draw(st.integers(3, 12), label="samples")
    end = data.draw(st.integers(1, n - 2), label="end")
    # positions around the 1 m threshold the chances count against, so they flip
    xs = data.draw(st.lists(st.floats(0.0, 2.5), min_size=end + 1, max_size=end + 1), label="x")
    xs = xs + [xs[-1]] * (n - end - 1)  # at rest from the end on
    slips = data.draw(st.lists(st.floats(0.0, 1.0), min_size=n, max_size=n), label="slip")
    held = data.draw(st.integers(1, 3 * n), label="held")
    base, padded = scored(model, run(xs, slips, end, 0)), scored(model, run(xs, slips, end, held))
    for name, value in base.items():
        if name == "path_mean":  # a path-level operand counts every sample of the grid
            continue
        assert padded[name] == pytest.approx(value, rel=1e-9, abs=1e-12), name
    # without 'command' the same padding counts: the window is what keeps the values
    bare = run(xs, slips, end, held)
    del bare["command"]
    moved = scored(model, bare)["I_mean"] != pytest.approx(base["I_mean"], rel=1e-9, abs=1e-12)
    event(f"the padding would have moved the mean: {moved}")
    event(f"a chance holds: {any(base[c][0] for c in ('often_far', 'long_far', 'many_far'))}")


def test_a_path_level_operand_counts_every_sample_of_the_grid(model):
    # two runs: one finished at sample 2 and held at 3 m, the other still driving at 0.5 m
    signals = {"t": np.tile(np.arange(6.0), (2, 1)),
               "x": np.array([[1, 2, 3, 3, 3, 3.], [0.5] * 6]),
               "wheel.slip": np.zeros((2, 6, 4)),
               "command": np.array([[0, 0, -1, -1, -1, -1.], [0] * 6])}
    values = scored(model, signals)
    # mean over runs at each sample: 0.75, 1.25, 1.75, 1.75, 1.75, 1.75 -> mean 1.5 > 1 m in
    # both runs (counted over the first run's own 4 samples it would be 1.375, still > 1 m,
    # so the mean itself is checked too)
    assert values["path_mean"] == [True, True]
    assert values["I_mean"] == pytest.approx([2.25, 0.5])  # run 1: samples 0..3 own
    assert values["I_final"] == pytest.approx([3.0, 0.5])


def test_a_wheel_slipping_for_a_sixth_of_the_drive_is_judged_on_the_drive(model):
    """I_p90: 15 of a run's 100 own samples slip 80 %; 200 held samples after it (slip 0, the
    rover standing still) would have pushed them below the 90th percentile."""
    xs = [0.001 * k for k in range(99)] + [0.099]
    slips = [0.0] * 80 + [0.8] * 15 + [0.0] * 5
    finished = run(xs, slips, end=98, held=200)
    assert DerivedSignals(finished, RunContext(chain=CHAIN)).run_lengths().tolist() == [100]
    assert scored(model, finished)["I_p90"] == pytest.approx([0.8])
    del finished["command"]  # no end known: every sample counts
    assert scored(model, finished)["I_p90"] == pytest.approx([0.0])
