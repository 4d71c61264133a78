"""The operations rulebook's position index (its frozen 1.1.0) reads the runs' average position
(paper, eq. 3 and "exceeding when the average rover position is outside the tolerance"): the
spread of the runs around the reference run does not raise it, a common shift of their mean
does, and it is critical exactly when the mean position leaves the tolerance radius."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st

from idefix_rules.commands import Command
from idefix_rules.rulebook import compile_rulebook, load_checked
from idefix_rules.rulebook.strategies import run_batches

# the frozen copy (tests/fixtures/rulebooks), not the live one the rule engineers edit
FROZEN = Path(__file__).resolve().parents[1] / "fixtures" / "rulebooks" / "idefix-ops-1.1.0.rules"
EVALUATOR = compile_rulebook(load_checked(FROZEN))
STRAIGHT = (Command(0.05, 0.5, 0.0),)  # no turn: the tolerance radius stays at sigma


def _runs_around_reference(signals, context, offsets, shift):
    """Every run = the reference run's track + its own offset + the common ``shift``."""
    out = dict(signals)
    for axis, column in (("x", 0), ("y", 1)):
        track = np.asarray(context.reference[axis])[np.newaxis]
        out[axis] = track + offsets[:, column:column + 1] + shift[column]
    out["z"] = np.tile(np.asarray(context.reference["z"]), (offsets.shape[0], 1))
    return out


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(run_batches(max_runs=5, chain=STRAIGHT), st.data())
def test_only_the_mean_position_against_the_tolerance_makes_i_pos(batch, data):
    signals, context = batch
    runs, sigma = signals["t"].shape[0], context.initial_position_sigma
    # Each run scattered up to 3 sigma (beyond the tolerance), the scatter centred on zero.
    scatter = np.array(data.draw(st.lists(st.tuples(st.floats(-3, 3), st.floats(-3, 3)),
                                          min_size=runs, max_size=runs))) * sigma
    scatter -= scatter.mean(axis=0)
    # The common shift of the mean position, drawn around the limit (1 sigma).
    ratio = data.draw(st.one_of(st.floats(0, 2), st.sampled_from([0.99, 1.01]),
                                st.floats(0.95, 1.05)))
    assume(abs(ratio - 1.0) > 1e-9)  # exactly on the limit, rounding decides either way
    angle = data.draw(st.floats(-math.pi, math.pi))
    shift = ratio * sigma * np.array([math.cos(angle), math.sin(angle)])
    event("mean inside the tolerance" if ratio < 1 else "mean outside the tolerance")
    evaluation = EVALUATOR.evaluate(_runs_around_reference(signals, context, scatter, shift),
                                    context, per_sample=False)
    np.testing.assert_allclose(evaluation.raw["I_pos"], ratio, rtol=1e-9, atol=1e-9)
    if ratio < 1:
        assert (evaluation.values["I_pos"] < 1).all()
    else:
        assert (evaluation.values["I_pos"] == 1).all()


def test_a_spread_without_a_shift_leaves_i_pos_at_zero():
    signals, context = _flat_batch()
    scatter = np.array([[1.25, 0.0], [-1.25, 0.0], [0.0, 1.25], [0.0, -1.25]]) \
        * context.initial_position_sigma  # each run 1.25 sigma away: the per-run rule saturated
    evaluation = EVALUATOR.evaluate(_runs_around_reference(signals, context, scatter,
                                                           np.zeros(2)), context)
    np.testing.assert_allclose(evaluation.values["I_pos"], 0.0, atol=1e-12)


def _flat_batch():
    from hypothesis import find

    return find(run_batches(max_runs=4, chain=STRAIGHT), lambda b: b[0]["t"].shape[0] == 4)
