"""`rate over time (x)`: the rate of change of a signal, unit inferred, both evaluators alike."""

import numpy as np
import pytest
from test_rulebook_compile import FOOTER, HEADER, batch, evaluate, rulebook

from idefix_rules.rulebook.check import check
from idefix_rules.rulebook.parser import parse_rulebook

# pitch over t = 0..5 s: backward differences 0.1, -0.4, 0.5, -0.2, 0.05 rad/s; sample 0 takes
# the forward one (0.1)
PITCH = [[0.0, 0.1, -0.3, 0.2, 0.0, 0.05], [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]]


@pytest.mark.parametrize(("value", "expected"), [
    ("max over time (rate over time (pitch))", 0.5),
    ("min over time (rate over time (pitch))", -0.4),
    ("initial over time (rate over time (pitch))", 0.1),
    ("final over time (rate over time (pitch))", 0.05),
    ("max over time after 4 s (abs(rate over time (pitch)))", 0.2),
    ("max over time during command 1 (rate over time (pitch))", 0.1),
    # the integral of a rate gives back the change (trapezoid of backward differences is not
    # exact, so compare with the hand sum): ½(0.1+0.1)+½(0.1-0.4)+½(-0.4+0.5)+½(0.5-0.2)
    # +½(-0.2+0.05)
    ("integral over time (rate over time (pitch))", 0.1 - 0.15 + 0.05 + 0.15 - 0.075),
])
def test_rate_of_a_signal(value, expected):
    limit = "10 rad" if "integral" in value else "10 rad/s"
    checked = rulebook(f"index I {{ value = {value} limit = {limit} weight = 1 }}")
    result = evaluate(checked, *batch(pitch=PITCH))
    assert result.raw["I"][0] == pytest.approx(expected, abs=1e-12)
    assert result.raw["I"][1] == 0.0  # a signal that does not change has no rate


def test_rate_per_wheel_keeps_the_wheel_axis():
    sinkage = np.zeros((2, 6, 4))
    sinkage[0, :, 2] = [0.0, 0.001, 0.003, 0.003, 0.003, 0.004]  # RL digs in at 2 mm/s
    checked = rulebook("index I { value = max over time (max over wheels (rate over time "
                       "(wheel.sinkage))) limit = 4 mm/s weight = 1 }")
    result = evaluate(checked, *batch(wheel__sinkage=sinkage))
    assert result.raw["I"][0] == pytest.approx(0.002)
    assert result.values["I"][0] == pytest.approx(0.5)


def test_rate_unit_is_the_operands_per_second():
    # m -> m/s: a limit in mm/s is accepted, one in mm is refused with the units named
    index = "index I { value = max over time (abs(pitch)) limit = 1 rad weight = 1 }\n"
    rulebook(index + "chance sinking = max over time (max over wheels (rate over time "
             "(wheel.sinkage))) > 1 mm/s")
    result = check(parse_rulebook(HEADER + index + "chance sinking = max over time (max over "
                                  "wheels (rate over time (wheel.sinkage))) > 1 mm" + FOOTER,
                                  "t.rules"))
    assert [d.code for d in result.errors] == ["E201"]
    assert "speed" in result.errors[0].message or "m/s" in result.errors[0].message


@pytest.mark.parametrize(("value", "code", "column"), [
    ("max over time (rate over wheels (wheel.sinkage))", "E309", 16),
    ("max over time (rate over time after 2 s (pitch))", "E309", 31),
    ("max over time (rate over time (pitch > 0 rad))", "E304", 32),
    ("rate over time (final over time (pitch))", "E301", 1),
    ("rate over time (pitch)", "E302", 1),  # still a time series: not one value per run
])
def test_rate_mistakes_name_their_place(value, code, column):
    text = HEADER + f"index I {{\nvalue = {value}\nlimit = 1 rad/s weight = 1 }}" + FOOTER
    result = check(parse_rulebook(text, "t.rules"))
    found = [(d.code, d.span.line, d.span.column) for d in result.errors]
    assert found and found[0][0] == code, found
    assert found[0][1] == 4
    assert found[0][2] == column + len("value = "), found


def test_rate_where_no_time_passes_is_zero():
    signals, context = batch(pitch=PITCH)
    t = signals["t"].copy()
    t[:, 3] = t[:, 2]  # a repeated sample time
    signals["t"] = t
    checked = rulebook("index I { value = max over time (abs(rate over time (pitch))) "
                       "limit = 10 rad/s weight = 1 }")
    result = evaluate(checked, signals, context)
    assert np.isfinite(result.raw["I"]).all()
