"""Graded indices: an index's optional ``nominal`` (0.5 on the index's scale), end to end.

Grammar and lowering, the checker's codes, the printer's round trip, the normalisation itself
(exact values and hypothesis properties, inputs drawn relative to the nominal and the limit),
and the two evaluators held equal on it.
"""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from idefix_rules.errors import UserInputError
from idefix_rules.rulebook import check_text
from idefix_rules.rulebook.compile import compile_rulebook
from idefix_rules.rulebook.format import format_rulebook
from idefix_rules.rulebook.interpret import interpret
from idefix_rules.rulebook.model import Name, Number
from idefix_rules.rulebook.parser import parse_rulebook
from idefix_rules.rulebook.run_values import normalise
from idefix_rules.rulebook.semantics import normalised
from idefix_rules.rulebook.strategies import rulebooks, run_batches

PROPERTY = settings(max_examples=200, deadline=None)
EVALUATORS = settings(max_examples=50, deadline=None,
                      suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

SLIP = """rulebook "graded" version "1.0.0"
purpose "Graded slip index"

const nominal_slip  = 20 %
const critical_slip = 70 %

index I_s "wheel slip ratio" {
  value   = percentile 95 over time (max over wheels (abs(wheel.slip)))  # the paper's I_s
  # 0.5 on the index's scale
  nominal = nominal_slip
  limit   = critical_slip
  weight  = 1
  because "Slip of 20 % is expected on soft soil, above 70 % is critical"
}

verdict acceptable_risk: require risk <= 70 %
"""


def checked(text: str):
    result = check_text(text, "graded.rules")
    assert result.checked is not None, [d.format() for d in result.errors]
    return result.checked


def codes(text: str, strict: bool = False) -> list[tuple[str, int, int]]:
    result = check_text(text, "graded.rules", strict=strict)
    return [(d.code, d.span.line, d.span.column) for d in result.diagnostics if d.span]


def with_nominal(nominal: str, limit: str = "70 %", value: str =
                 "max over time (max over wheels (abs(wheel.slip)))") -> str:
    return ('rulebook "t" version "1.0.0" purpose "p"\n'
            f"index I_s {{\n  value = {value}\n  nominal = {nominal}\n  limit = {limit}\n"
            "  weight = 1\n}\nverdict ok: require risk <= 70 %\n")


# ----------------------------------------------------------------------------- language

def test_nominal_is_lowered_into_the_index_with_its_span():
    index = parse_rulebook(SLIP, "graded.rules").indices[0]
    assert index.nominal == Name("nominal_slip")
    assert (index.nominal.span.line, index.nominal.span.column) == (10, 13)
    assert index.nominal.span.path == "graded.rules"


def test_an_index_without_nominal_has_none():
    text = SLIP.replace("  nominal = nominal_slip\n", "").replace("  # 0.5 on the index's scale\n",
                                                                  "")
    assert parse_rulebook(text).indices[0].nominal is None


def test_nominal_is_a_keyword_only_inside_an_index_block():
    text = with_nominal("nominal", "70 %").replace(
        'purpose "p"\n', 'purpose "p"\nconst nominal = 20 %\n')
    assert parse_rulebook(text).indices[0].nominal == Name("nominal")
    assert checked(text).nominals == {"I_s": 0.2}


def test_a_keyword_after_a_number_is_not_its_unit():
    text = ('rulebook "t" version "1.0.0" purpose "p"\n'
            "index I_s { value = max over time (max over wheels (abs(wheel.slip))) "
            "limit = 0.7 nominal = 0.2 weight = 1 }\nverdict ok: require risk <= 70 %\n")
    index = parse_rulebook(text).indices[0]
    assert index.limit == Number(0.7) and index.nominal == Number(0.2)


def test_nominal_given_twice_is_e006():
    text = with_nominal("20 %").replace("  weight = 1\n", "  weight = 1\n  nominal = 30 %\n")
    with pytest.raises(UserInputError) as failure:
        parse_rulebook(text, "t.rules")
    [problem] = failure.value.diagnostics
    assert (problem.code, problem.span.line) == ("E006", 7)
    assert problem.message == "index 'I_s' gives 'nominal' twice"


def test_the_printer_puts_nominal_after_value_and_round_trips():
    model = parse_rulebook(SLIP, "graded.rules")
    text = format_rulebook(model)
    assert text == SLIP  # already canonical: value, nominal, limit, weight, because
    assert parse_rulebook(text) == model
    assert format_rulebook(parse_rulebook(text)) == text


def test_the_printer_keeps_comments_on_the_nominal_line():
    messy = SLIP.replace("  nominal = nominal_slip\n", "  nominal = nominal_slip  # expected\n")
    text = format_rulebook(parse_rulebook(messy))
    assert "  nominal = nominal_slip  # expected\n" in text
    assert "  # 0.5 on the index's scale\n  nominal" in text


# ----------------------------------------------------------------------------- checks

def test_a_valid_nominal_is_resolved_to_si():
    rules = checked(SLIP)
    assert rules.nominals == {"I_s": pytest.approx(0.2)}
    assert rules.limits == {"I_s": pytest.approx(0.7)}


@pytest.mark.parametrize(("nominal", "limit", "expected"), [
    ("0 %", "70 %", "E407"),
    ("-5 %", "70 %", "E407"),
    ("70 %", "70 %", "E408"),
    ("80 %", "70 %", "E408"),
    ("0.71", "70 %", "E408"),
    ("5 cm", "70 %", "E204"),
    ("2 deg", "5 cm", "E204"),
])
def test_nominal_errors_name_the_nominal(nominal, limit, expected):
    value = "max over time (max over wheels (wheel.sinkage))" if limit == "5 cm" else \
        "max over time (max over wheels (abs(wheel.slip)))"
    assert codes(with_nominal(nominal, limit, value)) == [(expected, 4, 13)]


def test_nominal_errors_carry_the_values_as_written_and_in_si():
    [problem] = check_text(with_nominal("80 %"), "t.rules").diagnostics
    assert problem.message == ("the nominal of index 'I_s' must be below its limit: "
                               "80 % = 0.8 is not below 70 % = 0.7")


def test_a_nominal_that_is_not_a_constant_is_an_error():
    assert [c for c, _, _ in codes(with_nominal("max over time (x)"))] == ["E311"]  # reduction
    assert [c for c, _, _ in codes(with_nominal("x"))] == ["E101"]  # signal


def test_a_constant_used_only_as_a_nominal_is_used():
    assert not [c for c, _, _ in codes(SLIP, strict=True)]


@pytest.mark.parametrize(("nominal", "warned"), [
    ("6 %", True), ("7 %", False), ("20 %", False), ("63 %", False), ("64 %", True),
])
def test_a_nominal_within_a_tenth_of_either_end_is_nearly_a_step(nominal, warned):
    found = [c for c, _, _ in codes(with_nominal(nominal), strict=True)]
    assert found == (["W614"] if warned else [])


def test_a_bare_nominal_above_1_on_a_ratio_is_w610():
    found = [c for c, _, _ in codes(with_nominal("20", "7000 %"), strict=True)]
    assert "W610" in found


def test_a_rationale_may_name_the_nominal_instead_of_the_limit():
    text = with_nominal("20 %").replace("  weight = 1\n",
                                        '  weight = 1\n  because "Slip above 20 % is expected"\n')
    assert codes(text, strict=True) == []
    wrong = text.replace("above 20 %", "above 25 %")
    assert [c for c, _, _ in codes(wrong, strict=True)] == ["W612"]


# ----------------------------------------------------------------------------- the shape

@pytest.mark.parametrize(("value", "expected"), [
    (0.0, 0.0),
    (-0.1, 0.0),
    (0.1, 0.25),
    (0.2, 0.5),
    (0.45, 0.75),
    (0.7, 1.0),
    (0.9, 1.0),
    (math.inf, 1.0),
    (-math.inf, 0.0),
    (math.nan, 1.0),
])
def test_exact_values_with_the_papers_slip(value, expected):
    assert normalised(value, 0.7, 0.2) == expected
    assert float(normalise(np.array([value]), 0.7, 0.2)[0]) == expected


def test_just_inside_and_outside_the_nominal_and_the_limit():
    nominal, limit = 0.2, 0.7
    below, above = math.nextafter(nominal, 0.0), math.nextafter(nominal, 1.0)
    assert normalised(below, limit, nominal) < 0.5 == normalised(nominal, limit, nominal)
    assert 0.5 <= normalised(above, limit, nominal) < 0.5 + 1e-12  # 0.5 + 1e-16 rounds
    assert normalised(nominal * (1 + 1e-9), limit, nominal) > 0.5
    assert 1.0 - 1e-12 < normalised(math.nextafter(limit, 0.0), limit, nominal) < 1.0
    assert normalised(math.nextafter(limit, 1.0), limit, nominal) == 1.0
    assert normalised(limit, limit, nominal) == 1.0


def test_without_nominal_the_index_is_value_over_limit():
    for value in (0.0, 0.1, 0.35, 0.7, 1.4, -0.2):
        assert normalised(value, 0.7) == min(max(value / 0.7, 0.0), 1.0)


@st.composite
def shapes(draw):
    """(limit, nominal) with 0 < nominal < limit, from tiny to large limits."""
    limit = draw(st.floats(1e-6, 1e6, allow_nan=False, allow_infinity=False))
    share = draw(st.floats(1e-3, 1.0 - 1e-3))
    nominal = limit * share
    if not 0.0 < nominal < limit:
        nominal = limit / 2
    return limit, nominal


@st.composite
def values_around(draw, limit, nominal):
    """A value drawn relative to the nominal and the limit, naming the branch it lands in."""
    where = draw(st.sampled_from(["negative", "zero", "below nominal", "at nominal",
                                  "between", "at limit", "beyond limit"]))
    if where == "negative":
        value = -draw(st.floats(0.0, 2.0)) * limit
    elif where == "zero":
        value = 0.0
    elif where == "below nominal":
        value = nominal * draw(st.floats(0.0, 1.0, exclude_max=True))
    elif where == "at nominal":
        value = nominal
    elif where == "between":
        value = nominal + (limit - nominal) * draw(st.floats(0.0, 1.0, exclude_min=True,
                                                             exclude_max=True))
    elif where == "at limit":
        value = limit
    else:
        value = limit * (1.0 + draw(st.floats(0.0, 10.0, exclude_min=True)))
    return value


def _branch(value: float, limit: float, nominal: float) -> str:
    if value <= 0:
        return "clamped to 0"
    if value <= nominal:
        return "0 .. nominal"
    if value < limit:
        return "nominal .. limit"
    return "clamped to 1"


@PROPERTY
@given(st.data(), shapes())
def test_the_index_never_falls_as_the_value_grows(data, shape):
    limit, nominal = shape
    first = data.draw(values_around(limit, nominal))
    second = data.draw(values_around(limit, nominal))
    low, high = min(first, second), max(first, second)
    event(f"{_branch(low, limit, nominal)} → {_branch(high, limit, nominal)}")
    assert normalised(low, limit, nominal) <= normalised(high, limit, nominal)
    assert 0.0 <= normalised(low, limit, nominal) <= 1.0


@PROPERTY
@given(shapes())
def test_the_index_is_one_half_exactly_at_the_nominal(shape):
    limit, nominal = shape
    assert normalised(0.0, limit, nominal) == 0.0
    assert normalised(nominal, limit, nominal) == 0.5
    assert float(normalise(np.array([nominal]), limit, nominal)[0]) == 0.5


@PROPERTY
@given(st.data(), shapes())
def test_the_index_is_one_at_and_beyond_the_limit(data, shape):
    limit, nominal = shape
    value = limit * (1.0 + data.draw(st.floats(0.0, 1e3)))
    event("at the limit" if value == limit else "beyond the limit")
    assert normalised(value, limit, nominal) == 1.0


@PROPERTY
@given(st.data(), st.floats(1e-6, 1e6))
def test_a_nominal_at_half_the_limit_is_value_over_limit(data, limit):
    nominal = limit / 2
    value = data.draw(values_around(limit, nominal))
    event(_branch(value, limit, nominal))
    expected = min(max(value / limit, 0.0), 1.0)
    assert normalised(value, limit, nominal) == pytest.approx(expected, rel=1e-12, abs=1e-15)


@PROPERTY
@given(st.data(), shapes())
def test_the_compiler_normalises_as_the_reference(data, shape):
    limit, nominal = shape
    values = data.draw(st.lists(values_around(limit, nominal), min_size=1, max_size=8))
    event(f"branches: {sorted({_branch(v, limit, nominal) for v in values})}")
    compiled = normalise(np.array(values), limit, nominal)
    assert compiled.tolist() == [normalised(v, limit, nominal) for v in values]


# ----------------------------------------------------------------------------- evaluators

def _assert_same(compiled, slow) -> int:
    """Assert the two evaluations agree; returns the runs whose dominant index is a tie."""
    for name in compiled.index_names:
        for field in ("values", "raw", "per_sample", "weighted"):
            np.testing.assert_allclose(getattr(compiled, field)[name],
                                       getattr(slow, field)[name], rtol=1e-9, atol=1e-12,
                                       err_msg=f"{field}[{name}]")
    np.testing.assert_allclose(compiled.i_max, slow.i_max, rtol=1e-9, atol=1e-12)
    # the dominant index is the evaluators' to agree on where the largest weighted value
    # stands out by more than that tolerance: a mean of deviations from a mean (0 exactly, or
    # 2e-18 summed in another order) leaves a tie that neither order decides
    weighted = np.sort(np.stack([np.asarray(slow.weighted[name], dtype=float)
                                 for name in slow.index_names]), axis=0)
    if weighted.shape[0] > 1:
        top, second = weighted[-1], weighted[-2]
        decided = ~(np.abs(top - second) <= 1e-9 * np.abs(top) + 1e-12)
    else:
        decided = np.ones(weighted.shape[1:], dtype=bool)
    np.testing.assert_array_equal(compiled.dominant[decided], slow.dominant[decided])
    np.testing.assert_array_equal(compiled.dominant_sample[decided],
                                  slow.dominant_sample[decided])
    return int((~decided).sum())


GRADED = """rulebook "graded" version "1.0.0"
purpose "Every kind of index with a nominal"

index I_s {
  value   = max over time (max over wheels (abs(wheel.slip)))
  nominal = 20 %
  limit   = 70 %
  weight  = 1
}

index I_pitch {
  value   = max over time (abs(pitch - ref.pitch))
  nominal = 2 deg
  limit   = 15 deg
  weight  = 0.8
  map     = abs(pitch)
}

index I_spread {
  value   = final over time (global_error) - mean over runs (final over time (global_error))
  nominal = 1 mm
  limit   = 5 cm
  weight  = 1
}

verdict ok: require risk <= 70 %
"""


@EVALUATORS
@given(run_batches(non_finite=True))
def test_compiler_equals_interpreter_on_graded_indices(batch):
    rules = checked(GRADED)
    signals, context = batch
    compiled = compile_rulebook(rules).evaluate(signals, context)
    slow = interpret(rules, signals, context)
    for name in compiled.index_names:
        raw = compiled.raw[name]
        event(f"{name}: " + ", ".join(sorted({
            "NaN" if math.isnan(v) else _branch(v, rules.limits[name], rules.nominals[name])
            for v in raw.tolist()})))
    _assert_same(compiled, slow)


@EVALUATORS
@given(rulebooks(), run_batches(non_finite=True))
def test_compiler_equals_interpreter_on_generated_rulebooks_with_nominals(model, batch):
    result = check_text(format_rulebook(model), "generated.rules")
    assert result.checked is not None, [d.format() for d in result.errors]
    rules = result.checked
    event(f"indices with a nominal: {len(rules.nominals)} of {len(model.indices)}")
    ties = _assert_same(compile_rulebook(rules).evaluate(*batch), interpret(rules, *batch))
    event(f"runs whose dominant index is a tie within the tolerance: {min(ties, 2)}+"
          if ties >= 2 else f"runs whose dominant index is a tie within the tolerance: {ties}")


def _slip_batch(slips):
    """Runs whose every wheel slips ``slip`` at every sample, on a reference that does not."""
    from idefix_rules.rulebook.derived import RunContext

    runs, samples = len(slips), 4
    signals = {"t": np.tile(np.arange(samples, dtype=float), (runs, 1)),
               "wheel.slip": np.repeat(np.asarray(slips, dtype=float)[:, None, None],
                                       samples, axis=1).repeat(4, axis=2)}
    return signals, RunContext()


@EVALUATORS
@given(st.lists(values_around(0.7, 0.2), min_size=1, max_size=6))
def test_compiler_equals_interpreter_on_slips_around_nominal_and_limit(slips):
    event("branches: " + ", ".join(sorted({_branch(abs(v), 0.7, 0.2) for v in slips})))
    rules = checked(SLIP)
    signals, context = _slip_batch(slips)
    compiled = compile_rulebook(rules).evaluate(signals, context)
    _assert_same(compiled, interpret(rules, signals, context))
    expected = [normalised(abs(v), 0.7, 0.2) for v in slips]
    np.testing.assert_array_equal(compiled.values["I_s"], expected)


def test_run_values_and_per_sample_values_use_the_nominal():
    rules = checked(SLIP)
    signals, context = _slip_batch([0.0, 0.1, 0.2, 0.45, 0.7, 0.9, np.nan])
    evaluation = compile_rulebook(rules).evaluate(signals, context)
    np.testing.assert_allclose(evaluation.values["I_s"], [0, 0.25, 0.5, 0.75, 1, 1, 1])
    np.testing.assert_allclose(evaluation.per_sample["I_s"][:, 0], [0, 0.25, 0.5, 0.75, 1, 1, 1])
    assert math.isnan(evaluation.raw["I_s"][-1])
    _assert_same(evaluation, interpret(rules, signals, context))


def test_the_same_rulebook_without_nominal_scores_value_over_limit():
    plain = SLIP.replace("  nominal = nominal_slip\n", "").replace(
        "  # 0.5 on the index's scale\n", "").replace("const nominal_slip  = 20 %\n", "")
    signals, context = _slip_batch([0.0, 0.1, 0.35, 0.7, 0.9])
    evaluation = compile_rulebook(checked(plain)).evaluate(signals, context)
    np.testing.assert_allclose(evaluation.values["I_s"], [0, 0.1 / 0.7, 0.5, 1, 1])
