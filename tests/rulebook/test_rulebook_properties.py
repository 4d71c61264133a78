"""Hypothesis properties of the evaluators on generated rulebooks and generated signals."""

import dataclasses
import math

import numpy as np
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from idefix_rules.rulebook.check import check
from idefix_rules.rulebook.compile import compile_rulebook
from idefix_rules.rulebook.derived import RunContext
from idefix_rules.rulebook.interpret import interpret
from idefix_rules.rulebook.model import (
    Binary,
    Call,
    Header,
    Index,
    Name,
    Number,
    Reduce,
    Rulebook,
    VerdictRule,
)
from idefix_rules.rulebook.results import RunEvaluation
from idefix_rules.rulebook.strategies import rulebooks, run_batches

PROPERTY = settings(max_examples=50, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def checked(model: Rulebook):
    result = check(model)
    assert result.checked is not None, [d.format() for d in result.errors]
    return result.checked


def assert_same(a: RunEvaluation, b: RunEvaluation) -> None:
    assert a.index_names == b.index_names
    for name in a.index_names:
        for field in ("values", "raw", "per_sample", "weighted"):
            np.testing.assert_allclose(getattr(a, field)[name], getattr(b, field)[name],
                                       rtol=1e-9, atol=1e-12, err_msg=f"{field}[{name}]")
    for name in a.chance_names:
        np.testing.assert_array_equal(a.chances[name], b.chances[name])
    for field in ("dominant", "dominant_sample"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field), err_msg=field)
    # the same rounding allowance as the indices' (a mean over runs summed in another order
    # leaves 1e-16 where the other evaluator has 0)
    for field in ("i_max", "time", "energy"):
        np.testing.assert_allclose(getattr(a, field), getattr(b, field), rtol=1e-9, atol=1e-12,
                                   err_msg=field)


@PROPERTY
@given(rulebooks(), run_batches(non_finite=True))
def test_compiled_evaluator_equals_the_per_run_interpreter(model, batch):
    rules = checked(model)
    signals, context = batch
    event(f"reductions over runs: {len(compile_rulebook(rules).runs_reductions) > 0}")
    assert_same(compile_rulebook(rules).evaluate(signals, context),
                interpret(rules, signals, context))


@PROPERTY
@given(rulebooks(), run_batches(non_finite=True))
def test_per_sample_values_alone_equal_the_evaluations(model, batch):
    evaluator = compile_rulebook(checked(model))
    signals, context = batch
    # only what the per-sample values read, with the progress signals a run holds
    wanted = evaluator.sample_signals | evaluator.sample_optional_signals | {"command"}
    alone = evaluator.per_sample_values({k: v for k, v in signals.items() if k in wanted},
                                        context)
    whole = evaluator.evaluate(signals, context).per_sample
    assert alone.keys() == whole.keys()
    for name, values in whole.items():
        np.testing.assert_array_equal(alone[name], values, err_msg=name)


@PROPERTY
@given(rulebooks(), run_batches(non_finite=True))
def test_indices_and_i_max_stay_in_the_unit_interval(model, batch):
    evaluation = compile_rulebook(checked(model)).evaluate(*batch)
    arrays = [evaluation.i_max, *evaluation.values.values(), *evaluation.per_sample.values(),
              *evaluation.weighted.values()]
    for array in arrays:
        assert np.isfinite(array).all()
        assert ((array >= 0) & (array <= 1)).all()
    assert (evaluation.dominant_sample < batch[0]["t"].shape[1]).all()


def _with_index(model: Rulebook, position: int, **changes) -> Rulebook:
    indices = list(model.indices)
    indices[position] = dataclasses.replace(indices[position], **changes)
    return dataclasses.replace(model, indices=tuple(indices))


@PROPERTY
@given(rulebooks(), run_batches(), st.data())
def test_raising_a_weight_never_lowers_i_max(model, batch, data):
    position = data.draw(st.integers(0, len(model.indices) - 1))
    old = checked(model).weights[model.indices[position].name]
    new = data.draw(st.integers(math.ceil(old * 10), 10)) / 10
    raised = _with_index(model, position, weight=Number(new))
    before = compile_rulebook(checked(model)).evaluate(*batch)
    after = compile_rulebook(checked(raised)).evaluate(*batch)
    assert (after.i_max >= before.i_max).all()


def _verdict_passes(model: Rulebook, batch) -> bool:
    evaluator = compile_rulebook(checked(model))
    return evaluator.verdict(evaluator.path_statistics(evaluator.evaluate(*batch))).passed


@PROPERTY
@given(rulebooks(), run_batches(), st.data())
def test_tightening_a_limit_never_turns_a_fail_into_a_pass(model, batch, data):
    position = data.draw(st.integers(0, len(model.indices) - 1))
    factor = data.draw(st.sampled_from([0.125, 0.25, 0.5, 0.75]))
    index = model.indices[position]
    # a nominal tightens with its limit, so it stays below it
    nominal = None if index.nominal is None else Binary("*", index.nominal, Number(factor))
    tighter = _with_index(model, position, limit=Binary("*", index.limit, Number(factor)),
                          nominal=nominal)
    before = compile_rulebook(checked(model)).evaluate(*batch)
    after = compile_rulebook(checked(tighter)).evaluate(*batch)
    assert (after.values[index.name] >= before.values[index.name]).all()
    if not _verdict_passes(model, batch):
        assert not _verdict_passes(tighter, batch)


@PROPERTY
@given(rulebooks(), run_batches(), st.integers(0, 100))
def test_tightening_a_verdict_threshold_never_turns_a_fail_into_a_pass(model, batch, percent):
    rule = model.verdicts[0]  # risk <= X %
    assert isinstance(rule.condition, Binary) and isinstance(rule.condition.right, Number)
    threshold = min(rule.condition.right.value, percent)
    tighter_rule = VerdictRule(rule.name, Binary("<=", Name("risk"), Number(threshold, "%")))
    tighter = dataclasses.replace(model, verdicts=(tighter_rule, *model.verdicts[1:]))
    if not _verdict_passes(model, batch):
        assert not _verdict_passes(tighter, batch)


# ----------------------------------------------------------------------------- invariance

_POSITION_OPERANDS = (
    Name("global_error"),
    Name("local_error"),
    Name("drift"),
    Binary("/", Name("global_error"), Name("tolerance_radius")),
    Call("abs", (Name("heading_error"),)),
    Name("speed"),
)


@st.composite
def position_rulebooks(draw):
    indices = []
    for number in range(draw(st.integers(1, 4))):
        operand = draw(st.sampled_from(_POSITION_OPERANDS))
        reducer = draw(st.sampled_from(["final", "max", "mean", "rms", "percentile"]))
        parameter = Number(float(draw(st.integers(0, 100)))) if reducer == "percentile" else None
        unit = {"global_error": "cm", "local_error": "cm", "drift": "cm", "speed": "cm/s"}.get(
            getattr(operand, "name", ""), "deg" if isinstance(operand, Call) else None)
        indices.append(Index(f"I_{number}", Reduce(reducer, "time", operand, parameter),
                             Number(float(draw(st.integers(1, 50))), unit), Number(1.0)))
    if draw(st.booleans()):  # the default rulebook's I_pos: the runs' average position
        offset = Call("hypot", (Reduce("mean", "runs", Binary("-", Name("x"), Name("ref.x"))),
                                Reduce("mean", "runs", Binary("-", Name("y"), Name("ref.y")))))
        indices.append(Index("I_pos", Reduce("final", "time", Binary(
            "/", offset, Name("tolerance_radius"))), Number(1.0), Number(1.0)))
    return Rulebook(Header("pos", "1.0.0", "position indices"), indices=tuple(indices),
                    verdicts=(VerdictRule("v", Binary("<=", Name("risk"), Number(70.0, "%"))),))


def _moved(signals, angle, dx, dy):
    out = dict(signals)
    cos, sin = math.cos(angle), math.sin(angle)
    x, y = np.asarray(signals["x"]), np.asarray(signals["y"])
    out["x"] = cos * x - sin * y + dx
    out["y"] = sin * x + cos * y + dy
    out["yaw"] = np.asarray(signals["yaw"]) + angle
    return out


@PROPERTY
@given(position_rulebooks(), run_batches(), st.floats(-math.pi, math.pi),
       st.floats(-50, 50), st.floats(-50, 50))
def test_moving_a_run_with_its_reference_leaves_position_indices_unchanged(model, batch, angle,
                                                                           dx, dy):
    signals, context = batch
    evaluator = compile_rulebook(checked(model))
    before = evaluator.evaluate(signals, context)
    moved_context = RunContext(context.chain, context.rover, context.initial_position_sigma,
                               _moved(context.reference, angle, dx, dy))
    after = evaluator.evaluate(_moved(signals, angle, dx, dy), moved_context)
    for name in before.index_names:
        np.testing.assert_allclose(after.values[name], before.values[name], atol=1e-9)
        np.testing.assert_allclose(after.per_sample[name], before.per_sample[name], atol=1e-9)


@PROPERTY
@given(rulebooks(), run_batches())
def test_chunked_evaluation_equals_one_call(model, batch):
    signals, context = batch
    evaluator = compile_rulebook(checked(model))
    whole = evaluator.evaluate(signals, context)
    runs = signals["t"].shape[0]
    chunks = [{k: v[i:i + 1] for k, v in signals.items()} for i in range(runs)]
    across = None  # path-level values: a first pass over every chunk
    for chunk in chunks:
        across = evaluator.across_runs(chunk, context, into=across)
    event(f"reductions over runs: {len(evaluator.runs_reductions) > 0}")
    parts = [evaluator.evaluate(chunk, context, across=across) for chunk in chunks]
    assert_same(RunEvaluation.concat(parts), whole)
