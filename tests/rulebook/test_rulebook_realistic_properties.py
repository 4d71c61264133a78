"""Properties of the operations rulebook (its frozen 1.1.0) on physically shaped runs
(``realistic_runs``), with the ready-made helpers of ``idefix_rules.testing.properties``. Inputs
are drawn relative to the limits under test, and ``event()`` records how often the limits were
reached."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from idefix_rules.rulebook import load_checked
from idefix_rules.rulebook.compile import compile_rulebook
from idefix_rules.rulebook.strategies import (
    RunRanges,
    chains_within,
    perturbed_runs,
    realistic_runs,
)
from idefix_rules.testing.properties import (
    check_bounded_risk,
    check_monotone_in_limit,
    check_monotone_in_weight,
    check_rigid_transform_invariance,
)

# the frozen operations rulebook 1.1.0 (tests/fixtures/rulebooks), not the live one
FROZEN = Path(__file__).parents[1] / "fixtures" / "rulebooks" / "idefix-ops-1.1.0.rules"
CHECKED = load_checked(FROZEN)
COMPILED = compile_rulebook(CHECKED)
MODEL = CHECKED.rulebook
SLIP_LIMIT = CHECKED.limits["I_s"]
PROPERTY = settings(max_examples=40, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def slip_ranges(fraction: float) -> RunRanges:
    """Slip up to ``fraction`` of the critical slip (so below and above it are both drawn)."""
    return RunRanges(slip=(0.0, SLIP_LIMIT * fraction))


@PROPERTY
@given(st.floats(0.3, 1.6).flatmap(lambda f: realistic_runs(slip_ranges(f))))
def test_risk_is_bounded_and_slip_is_not_saturated_by_construction(batch):
    signals, context = batch
    evaluation = check_bounded_risk(COMPILED, signals, context)
    slip = np.abs(signals["wheel.slip"]).max()
    assert slip <= SLIP_LIMIT * 1.6 + 1e-12
    saturated = bool((evaluation.values["I_s"] >= 1).any())
    event(f"I_s saturated in some run: {saturated}")


@PROPERTY
@given(realistic_runs(), st.sampled_from([i.name for i in MODEL.indices]),
       st.sampled_from([0.5, 0.8, 1.25, 2.0]))
def test_every_index_is_monotone_in_its_limit(batch, index, factor):
    signals, context = batch
    event(f"factor {'above' if factor > 1 else 'below'} 1")
    check_monotone_in_limit(MODEL, index, factor, signals, context)


@PROPERTY
@given(realistic_runs(), st.sampled_from([i.name for i in MODEL.indices]),
       st.sampled_from([0.0, 0.3, 0.7]))
def test_the_run_risk_is_monotone_in_every_weight(batch, index, weight):
    signals, context = batch
    check_monotone_in_weight(MODEL, index, weight, signals, context)


@PROPERTY
@given(realistic_runs(), st.floats(-5, 5), st.floats(-5, 5), st.floats(-3.1, 3.1))
def test_rules_are_invariant_under_rigid_transforms(batch, dx, dy, dyaw):
    signals, context = batch
    check_rigid_transform_invariance(COMPILED, signals, context, dx, dy, dyaw, tolerance=1e-7)


@PROPERTY
@given(st.sampled_from(["wheel.slip", "wheel.sinkage"]).flatmap(
    lambda signal: perturbed_runs(signal, RunRanges(slip=(0.0, SLIP_LIMIT)))))
def test_raising_one_non_negative_signal_never_lowers_its_index(runs):
    # slip and sinkage are drawn >= 0 here, so a positive bump raises their magnitude
    nominal, perturbed, context, signal = runs
    index = {"wheel.slip": "I_s", "wheel.sinkage": "I_ds"}[signal]
    before = COMPILED.evaluate(nominal, context)
    after = COMPILED.evaluate(perturbed, context)
    event(f"{index} rose: {bool((after.values[index] > before.values[index]).any())}")
    assert np.all(after.values[index] >= before.values[index] - 1e-12)
    assert np.all(after.i_max >= before.i_max - 1e-12)


@PROPERTY
@given(chains_within(COMPILED))
def test_chains_within_the_command_rules_pass_them(chain):
    assert COMPILED.check_chain(chain) == []
