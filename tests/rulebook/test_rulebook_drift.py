"""The derived signal ``drift``: what the drive adds to the start offset.

``drift(t) = |Rot(-yaw[0]) · (p(t) - p[0]) - Rot(-ref.yaw[0]) · (ref.p(t) - ref.p[0])|``.
"""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from idefix_rules import signals as contract
from idefix_rules.errors import UserInputError
from idefix_rules.rulebook import check_text
from idefix_rules.rulebook.compile import compile_rulebook
from idefix_rules.rulebook.derived import DerivedSignals, RunContext
from idefix_rules.rulebook.interpret import interpret
from idefix_rules.rulebook.strategies import run_batches

PROPERTY = settings(max_examples=100, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def drift(runs: dict, reference: dict | None) -> np.ndarray:
    context = RunContext(reference=reference) if reference is not None else RunContext()
    return DerivedSignals(runs, context).get("drift")


def straight(samples: int, length: float, x0: float, y0: float, yaw0: float) -> dict:
    """A run of one sample row driving ``length`` straight ahead from (x0, y0, yaw0)."""
    along = np.linspace(0.0, length, samples)
    return {"t": np.arange(samples, dtype=float)[None],
            "x": (x0 + math.cos(yaw0) * along)[None], "y": (y0 + math.sin(yaw0) * along)[None],
            "yaw": np.full((1, samples), yaw0)}


def as_reference(run: dict) -> dict:
    return {name: values[0] for name, values in run.items()}


def moved(run: dict, angle: float, dx: float, dy: float) -> dict:
    """``run`` turned by ``angle`` about the origin, then shifted by (dx, dy): a rigid move."""
    cos, sin = math.cos(angle), math.sin(angle)
    out = dict(run)
    out["x"] = cos * run["x"] - sin * run["y"] + dx
    out["y"] = sin * run["x"] + cos * run["y"] + dy
    if "yaw" in run:
        out["yaw"] = run["yaw"] + angle
    return out


# ----------------------------------------------------------------------------- analytic cases

def test_a_straight_metre_from_a_yawed_start_drifts_nothing():
    reference = as_reference(straight(11, 1.0, 0.0, 0.0, 0.0))
    run = straight(11, 1.0, 2.0, -3.0, 0.1)
    np.testing.assert_allclose(drift(run, reference), 0.0, atol=1e-12)


def test_ending_two_centimetres_beside_the_start_frame_prediction_drifts_that():
    reference = as_reference(straight(11, 1.0, 0.0, 0.0, 0.0))
    run = straight(11, 1.0, 2.0, -3.0, 0.1)
    side = np.linspace(0.0, 0.02, 11)  # to the left of the start heading, growing to 2 cm
    run["x"] = run["x"] - math.sin(0.1) * side
    run["y"] = run["y"] + math.cos(0.1) * side
    found = drift(run, reference)[0]
    assert found[0] == 0.0
    assert found[-1] == pytest.approx(0.02, abs=1e-12)
    np.testing.assert_allclose(found, side, atol=1e-12)


def test_a_shorter_drive_drifts_by_the_missing_distance():
    reference = as_reference(straight(5, 1.0, 0.0, 0.0, 0.0))
    run = straight(5, 0.9, 0.3, 0.4, -2.0)
    assert drift(run, reference)[0, -1] == pytest.approx(0.1, abs=1e-12)


def test_drift_is_zero_at_the_first_sample_of_every_run():
    reference = as_reference(straight(4, 1.0, 0.0, 0.0, 0.0))
    runs = {k: np.concatenate([v, v + 0.5]) for k, v in straight(4, 0.7, 1.0, 1.0, 1.0).items()}
    assert (drift(runs, reference)[:, 0] == 0).all()


def test_without_yaw_the_start_yaw_is_taken_as_zero():
    reference = as_reference(straight(5, 1.0, 0.0, 0.0, 0.0))
    del reference["yaw"]
    shifted = straight(5, 1.0, 5.0, 5.0, 0.0)
    del shifted["yaw"]
    np.testing.assert_allclose(drift(shifted, reference), 0.0, atol=1e-12)
    turned = straight(5, 1.0, 5.0, 5.0, math.pi / 2)  # drives +y, but no yaw says so
    del turned["yaw"]
    assert drift(turned, reference)[0, -1] == pytest.approx(math.sqrt(2.0))


def test_without_a_reference_run_it_is_an_error_as_for_global_error():
    run = straight(3, 1.0, 0.0, 0.0, 0.0)
    for name in ("drift", "global_error"):
        with pytest.raises(UserInputError) as failure:
            DerivedSignals(run, RunContext()).get(name)
        assert failure.value.diagnostics[0].code == "E702"


def test_the_contract_declares_drift_as_a_derived_length_per_sample():
    spec = contract.lookup("drift")
    assert spec is not None
    assert (spec.unit, spec.axes, spec.kind) == ("m", ("time",), "derived")


# ----------------------------------------------------------------------------- invariance

@PROPERTY
@given(run_batches(), st.floats(-math.pi, math.pi), st.floats(-50, 50), st.floats(-50, 50))
def test_a_run_that_is_the_reference_moved_rigidly_drifts_nothing(batch, angle, dx, dy):
    _, context = batch
    assert context.reference is not None
    reference = {k: np.asarray(v)[None] for k, v in context.reference.items()}
    runs = moved(reference, angle, dx, dy)  # only its start pose differs
    event(f"turned by more than 90 deg: {abs(angle) > math.pi / 2}")
    np.testing.assert_allclose(drift(runs, context.reference), 0.0, atol=1e-9)


@PROPERTY
@given(run_batches(), st.floats(-math.pi, math.pi), st.floats(-50, 50), st.floats(-50, 50))
def test_starting_from_another_pose_leaves_drift_unchanged(batch, angle, dx, dy):
    signals, context = batch
    before = drift(signals, context.reference)
    after = drift(moved(signals, angle, dx, dy), context.reference)
    event(f"largest drift: {'> 1 m' if np.nanmax(before) > 1 else '<= 1 m'}")
    np.testing.assert_allclose(after, before, atol=1e-9)


@PROPERTY
@given(run_batches(), st.floats(-math.pi, math.pi), st.floats(-50, 50), st.floats(-50, 50))
def test_moving_the_reference_alone_leaves_drift_unchanged(batch, angle, dx, dy):
    signals, context = batch
    assert context.reference is not None
    reference = {k: np.asarray(v)[None] for k, v in context.reference.items()}
    shifted = {k: v[0] for k, v in moved(reference, angle, dx, dy).items()}
    np.testing.assert_allclose(drift(signals, shifted), drift(signals, context.reference),
                               atol=1e-9)


# ----------------------------------------------------------------------------- evaluators

DRIFT = """rulebook "drift" version "1.0.0"
purpose "What the drive adds"

index I_drift "drive spread" {
  value   = final over time (drift)
  nominal = 2 cm
  limit   = 10 cm
  weight  = 1
}

index I_drift_mean "largest mean drift" {
  value  = max over time (mean over runs (drift))
  limit  = 20 cm
  weight = 0.5
  map    = drift
}

chance drifted = max over time (drift) > 5 cm

verdict ok: require risk <= 70 % and chance(drifted) <= 50 %
"""


def checked():
    result = check_text(DRIFT, "drift.rules")
    assert result.checked is not None, [d.format() for d in result.errors]
    return result.checked


@PROPERTY
@given(run_batches(non_finite=True))
def test_compiler_equals_interpreter_on_drift(batch):
    rules = checked()
    signals, context = batch
    compiled = compile_rulebook(rules).evaluate(signals, context)
    slow = interpret(rules, signals, context)
    event(f"runs with a NaN drift value: {int(np.isnan(compiled.raw['I_drift']).sum())}")
    for name in compiled.index_names:
        for field in ("values", "raw", "per_sample", "weighted"):
            np.testing.assert_allclose(getattr(compiled, field)[name],
                                       getattr(slow, field)[name], rtol=1e-9, atol=1e-12,
                                       err_msg=f"{field}[{name}]")
    np.testing.assert_array_equal(compiled.chances["drifted"], slow.chances["drifted"])
    np.testing.assert_allclose(compiled.i_max, slow.i_max)


def test_drift_needs_x_and_y_and_reads_yaw_when_there():
    evaluator = compile_rulebook(checked())
    assert {"t", "x", "y"} <= evaluator.required_signals
    assert "yaw" not in evaluator.required_signals  # a foreign FMU may not give it
    assert evaluator.optional_signals == {"yaw"}
    assert {"x", "y", "yaw"} <= evaluator.across_signals


def test_a_rulebook_without_drift_reads_no_optional_signal():
    plain = check_text('rulebook "plain" version "1.0.0" purpose "p"\n'
                       "index I_g { value = final over time (global_error) limit = 10 cm "
                       "weight = 1 }\nverdict ok: require risk <= 70 %\n", "plain.rules").checked
    assert plain is not None
    assert compile_rulebook(plain).optional_signals == frozenset()


def test_an_evaluation_of_drift_over_a_straight_drive():
    reference = as_reference(straight(6, 1.0, 0.0, 0.0, 0.0))
    runs = straight(6, 1.0, 0.5, 0.5, 0.3)
    side = np.linspace(0.0, 0.06, 6)
    runs["x"] = runs["x"] - math.sin(0.3) * side
    runs["y"] = runs["y"] + math.cos(0.3) * side
    evaluation = compile_rulebook(checked()).evaluate(runs, RunContext(reference=reference))
    assert evaluation.raw["I_drift"][0] == pytest.approx(0.06)
    assert evaluation.values["I_drift"][0] == pytest.approx(0.5 + 0.5 * 4 / 8)
    assert bool(evaluation.chances["drifted"][0])
