"""The constant parts of a rulebook: a reducer's parameter and a window see constants only, a
reduction is never a constant, and every constant part (a threshold, a window, a parameter, a
limit or a constant) has a finite real value. Each was accepted by ``check`` before and then
failed in the evaluation (an internal error, exit 3) or compared with nan."""

from __future__ import annotations

import pytest

from idefix_rules.rulebook import check_text

HEAD = '''rulebook "t" version "1.0.0"
purpose "constant parts"
const f_obs = {L1: 0.2, L2: 0.6, L3: 1}
CONST
index I_s "slip" {
  value  = VALUE
  limit  = LIMIT
  weight = WEIGHT
}
chance moving = max over time (speed) > 1 mm/s
verdict v: require CONDITION
'''

SLIP = "max over wheels (abs(wheel.slip))"


def found(value: str = f"max over time ({SLIP})", limit: str = "70 %", weight: str = "1",
          condition: str = "risk <= 70 %", const: str = "") -> list[tuple[str, str]]:
    text = (HEAD.replace("VALUE", value).replace("LIMIT", limit).replace("WEIGHT", weight)
            .replace("CONDITION", condition).replace("CONST", const))
    return [(d.code, d.message) for d in check_text(text, "t.rules").diagnostics]


def test_the_template_is_valid() -> None:
    assert found() == []


@pytest.mark.parametrize("value", [
    f"max over time after (final over time (t) / 2) ({SLIP})",
    f"percentile (max over time (wheel.slip[FR]) * 100) over time ({SLIP})",
    f"max over time after (max over levels (f_obs) * 10 s) ({SLIP})",
])
def test_a_reduction_in_a_parameter_or_window_is_refused(value: str) -> None:
    assert [code for code, _ in found(value)] == ["E311"]


@pytest.mark.parametrize(("value", "message"), [
    (f"max over time after (t) ({SLIP})",
     "signal 't' cannot be used in a reducer's parameter or window (constants and numbers "
     "only)"),
    (f"time_above (speed) over time ({SLIP})",
     "signal 'speed' cannot be used in a reducer's parameter or window (constants and numbers "
     "only)"),
])
def test_a_signal_in_a_parameter_or_window_is_refused(value: str, message: str) -> None:
    assert found(value) == [("E101", message)]


def test_a_table_as_a_threshold_or_window_is_refused() -> None:
    assert found(f"time_above (f_obs) over time ({SLIP})") == [
        ("E302", "time_above needs one threshold, got one per level")]
    assert found(f"max over time after (f_obs * 1 s) ({SLIP})") == [
        ("E302", "'after' window needs one duration, got one per level")]


def test_a_constant_that_is_a_reduction_is_refused() -> None:
    assert [code for code, _ in found(const="const worst = max over levels (f_obs)")] \
        == ["E311"]


@pytest.mark.parametrize(("where", "expression", "message"), [
    ("limit", "10 ^ 400", "the limit of index 'I_s' is beyond a double: its value is too "
                          "large for a number"),
    ("limit", "sqrt(-1)", "the limit of index 'I_s' cannot be computed: sqrt(-1) is not a "
                          "real number"),
    ("weight", "0 ^ -1", "the weight of index 'I_s' cannot be computed: 0 raised to a "
                         "negative power is a division by zero"),
    ("const", "const k = (-8) ^ 0.5", "constant 'k' cannot be computed: (-8) ^ 0.5 is not a "
                                      "real number (a negative base with a fractional "
                                      "exponent)"),
    ("condition", "risk <= 0 / 0", "'0 / 0' in verdict 'v' is not a finite number (nan; a "
                                   "division by zero, or a value beyond a double?)"),
    ("condition", "risk <= sqrt(-1)", "'sqrt(-1)' in verdict 'v' cannot be computed: "
                                      "sqrt(-1) is not a real number"),
    ("value", f"percentile (10 ^ 400) over time ({SLIP})",
     "'10 ^ 400' in index 'I_s' is beyond a double: its value is too large for a number"),
    ("value", f"max over time before (0 / 0 * 1 s) ({SLIP})",
     "'0 / 0 * 1 s' in index 'I_s' is not a finite number (nan; a division by zero, or a "
     "value beyond a double?)"),
])
def test_a_constant_part_with_no_finite_value_is_e402(where: str, expression: str,
                                                      message: str) -> None:
    assert found(**{where: expression}) == [("E402", message)]


def test_just_inside_a_double_is_a_value() -> None:
    assert found(condition="risk <= 10 ^ 300 * 0") == []  # 1e300 is a double
    assert found(condition="risk <= 10 ^ 309 * 0") == [
        ("E402", "'10 ^ 309 * 0' in verdict 'v' is beyond a double: its value is too large "
                 "for a number")]


def test_a_constant_refused_once_is_not_reported_again_where_it_is_used() -> None:
    assert found(const="const bad = 1 / 0", condition="risk <= bad") == [
        ("E402", "constant 'bad' is not a finite number (inf; a division by zero, or a "
                 "value beyond a double?)")]


def test_tables_of_two_axes_in_a_rule_are_valid_as_before() -> None:
    """A product of tables on two axes is a value per pair, which the evaluators broadcast:
    folding it as one table raised KeyError (exit 3) on a rulebook that passed."""
    const = "const w = {FL: 1, FR: 1, RL: 0.5, RR: 0.5}"
    assert found("max over time (max over wheels (abs(wheel.slip) * (w * f_obs)[L3]))",
                 const=const) == []
    assert found(condition="risk <= (f_obs + w)[L1, FL] * 70 %", const=const) == []


@pytest.mark.parametrize(("condition", "code"), [
    ("risk <= f_obs[FL]", "E104"),        # a label of another axis: said by the type check
    ("risk <= 70 hits", "E205"),          # an unknown unit
])
def test_a_constant_part_the_type_check_refused_is_not_folded(condition: str,
                                                             code: str) -> None:
    assert [c for c, _ in found(condition=condition)] == [code]
