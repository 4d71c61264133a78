"""The canonical printer: layout, minimal parentheses, numbers, comments, round trips."""

import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from idefix_rules.rulebook.format import format_expr, format_number, format_rulebook
from idefix_rules.rulebook.model import Binary, Call, Name, Number, Reduce, Select, Unary, Window
from idefix_rules.rulebook.parser import parse_rulebook
from idefix_rules.rulebook.strategies import rulebooks

MESSY = """# The test rulebook.
verdict ok : require risk<=70%    because "keep it low"
index I_s "slip"{value=max over time(max over wheels(abs(wheel.slip))) limit=critical_slip
weight=1.0 # full weight
because "Slip above 70 % is critical"}
const critical_slip=70 %
const f = {L1: 0.2, L2: 0.6, L3: 1.0}
rulebook "demo" version "1.0.0" purpose "Formatting"
settings {tolerance_growth = 5 cm/rad   # grows while turning
}
rank by risk , time desc
# trailing remark
"""

CANONICAL = """# The test rulebook.
rulebook "demo" version "1.0.0"
purpose "Formatting"

const critical_slip = 70 %
const f             = {L1: 0.2, L2: 0.6, L3: 1}

settings {
  tolerance_growth = 5 cm/rad  # grows while turning
}

index I_s "slip" {
  value  = max over time (max over wheels (abs(wheel.slip)))
  limit  = critical_slip
  weight = 1  # full weight
  because "Slip above 70 % is critical"
}

verdict ok: require risk <= 70 % because "keep it low"

rank by risk, time desc

# trailing remark
"""


def test_messy_text_formats_to_the_canonical_layout():
    assert format_rulebook(parse_rulebook(MESSY, "m.rules")) == CANONICAL


def test_formatting_is_idempotent_and_keeps_the_model():
    model = parse_rulebook(MESSY, "m.rules")
    once = format_rulebook(model)
    again = parse_rulebook(once, "m.rules")
    assert again == model
    assert format_rulebook(again) == once


def test_every_comment_survives_formatting():
    text = format_rulebook(parse_rulebook(MESSY, "m.rules"))
    for comment in ("# The test rulebook.", "# full weight", "# grows while turning",
                    "# trailing remark"):
        assert comment in text



def test_a_comment_inside_an_index_items_expression_stays_with_that_item():
    """Joined at the end of its item's line, as in a constant or a verdict; it used to go
    above the next item (here `limit`), where it spoke of the wrong thing."""
    text = format_rulebook(parse_rulebook(
        'rulebook "d" version "1.0.0"\npurpose "p"\nindex I_r "roll" {\n'
        '  value  = max over time (\n    # the worst roll\n    abs(roll))\n'
        '  # about the limit\n\n  limit  = 15 deg\n  weight = 1\n}\n'
        'verdict ok: require risk <= 70 %\n', "c.rules"))
    assert "  value  = max over time (abs(roll))  # the worst roll\n" in text
    assert "  # about the limit\n  limit  = 15 deg\n" in text
    assert format_rulebook(parse_rulebook(text, "c.rules")) == text

def test_a_long_rationale_moves_to_its_own_line_for_the_whole_section():
    text = format_rulebook(parse_rulebook(
        'rulebook "d" version "1.0.0" purpose "p"\n'
        'const a = 1 because "short"\n'
        f'const b = 2 because "{"long " * 25}"\n', "l.rules"))
    assert '\n  because "short"' in text
    assert all(len(line) <= 140 for line in text.splitlines())


@pytest.mark.parametrize(("expr", "text"), [
    (Binary("*", Binary("+", Name("a"), Name("b")), Name("c")), "(a + b) * c"),
    (Binary("+", Name("a"), Binary("*", Name("b"), Name("c"))), "a + b * c"),
    (Binary("-", Name("a"), Binary("-", Name("b"), Name("c"))), "a - (b - c)"),
    (Binary("-", Binary("-", Name("a"), Name("b")), Name("c")), "a - b - c"),
    (Binary("^", Name("a"), Binary("^", Name("b"), Name("c"))), "a ^ b ^ c"),
    (Binary("^", Binary("^", Name("a"), Name("b")), Name("c")), "(a ^ b) ^ c"),
    (Binary("^", Unary("-", Name("a")), Number(2)), "(-a) ^ 2"),
    (Unary("-", Binary("^", Name("a"), Number(2))), "-a ^ 2"),
    (Binary("^", Name("a"), Unary("-", Number(1))), "a ^ -1"),
    (Unary("not", Binary("<", Name("a"), Name("b"))), "not a < b"),
    (Binary("<", Binary("<", Name("a"), Name("b")), Name("c")), "(a < b) < c"),
    (Binary("and", Binary("or", Name("a"), Name("b")), Name("c")), "(a or b) and c"),
    (Select(Binary("+", Name("a"), Name("b")), ("FL",)), "(a + b)[FL]"),
    (Call("clamp", (Name("x"), Number(0), Number(1))), "clamp(x, 0, 1)"),
    (Reduce("percentile", "time", Name("x"), Number(95)), "percentile 95 over time (x)"),
    (Reduce("time_above", "time", Name("x"), Unary("-", Number(5, "deg"))),
     "time_above (-5 deg) over time (x)"),
    (Reduce("mean", "time", Name("x"), window=Window("command", Number(2))),
     "mean over time during command 2 (x)"),
    (Reduce("max", "time", Name("x"), window=Window("after", Binary(
        "+", Number(1, "min"), Number(5, "s")))), "max over time after (1 min + 5 s) (x)"),
])
def test_expressions_print_with_minimal_parentheses(expr, text):
    assert format_expr(expr) == text
    parsed = parse_rulebook(f'rulebook "d" version "1.0.0" purpose "p"\n'
                            f"verdict v: require {text}\n", "e.rules")
    assert parsed.verdicts[0].condition == expr


@pytest.mark.parametrize(("value", "text"), [
    (70.0, "70"), (0.2, "0.2"), (1e-05, "1e-05"), (0.0, "0"), (1e16, "1e+16"),
    (123.456, "123.456"),
])
def test_numbers_print_in_their_shortest_form(value, text):
    assert format_number(value) == text


@given(st.floats(min_value=0, allow_nan=False, allow_infinity=False))
def test_every_finite_number_reads_back_exactly(value):
    text = format_number(value)
    book = parse_rulebook(f'rulebook "d" version "1.0.0" purpose "p"\nconst a = {text} cm\n',
                          "n.rules")
    assert book.constants[0].value.value == value
    assert not math.isnan(book.constants[0].value.value)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(rulebooks())
def test_fmt_round_trips_generated_rulebooks(model):
    text = format_rulebook(model)
    parsed = parse_rulebook(text, "gen.rules")
    assert parsed == model
    assert format_rulebook(parsed) == text


BLOCK_END = """rulebook "demo" version "1.0.0" purpose "p"
settings {
  tolerance_growth = 5 cm/rad
  # about the settings, last in their block
}
obstacles {
  level L1 below 3 cm buffer 2 cm
  level L2 below 10 cm buffer 5 cm
  level L3 buffer 10 cm
  # last in obstacles
}
# about the index
index I_s "slip" {
  value = max over time (max over wheels (abs(wheel.slip)))
  limit = 70 %
  weight = 1
}
verdict ok: require risk <= 70 %
"""


def test_a_comment_closing_a_block_stays_in_it_and_one_above_a_declaration_stays_above_it():
    text = format_rulebook(parse_rulebook(BLOCK_END, "b.rules"))
    assert "  tolerance_growth = 5 cm/rad\n  # about the settings, last in their block\n}" in text
    assert "  level L3             buffer 10 cm\n  # last in obstacles\n}" in text
    assert "\n# about the index\nindex I_s" in text
    again = parse_rulebook(text, "b.rules")
    assert again == parse_rulebook(BLOCK_END, "b.rules") and format_rulebook(again) == text
