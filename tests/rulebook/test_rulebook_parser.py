"""Parsing rulebook text into the rule model: structure, spans, comments, syntax errors."""

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from idefix_rules.errors import UserInputError
from idefix_rules.rulebook.format import format_rulebook
from idefix_rules.rulebook.grammar import grammar_text, rulebook_parser
from idefix_rules.rulebook.model import (
    Binary,
    Call,
    Name,
    Number,
    Ranking,
    RankKey,
    Reduce,
    Select,
    Table,
    Unary,
    Window,
)
from idefix_rules.rulebook.parser import parse_rulebook

HEADER = 'rulebook "t" version "1.0.0"\npurpose "test"\n'
INDEX = "index I_s { value = max over time (max over wheels (abs(wheel.slip))) " \
        "limit = 70 % weight = 1 }\n"
VERDICT = "verdict ok: require risk <= 70 %\n"


def parse(body: str = "", header: str = HEADER):
    return parse_rulebook(header + body, "t.rules")


def condition(expression: str):
    """The parsed expression of `verdict v: require EXPRESSION`."""
    return parse(f"verdict v: require {expression}\n").verdicts[0].condition


def errors(text: str) -> list:
    with pytest.raises(UserInputError) as failure:
        parse_rulebook(text, "bad.rules")
    return failure.value.diagnostics


# ----------------------------------------------------------------------------- structure

def test_the_agreed_example_parses_into_the_model():
    book = parse("""
const critical_slip = 70 % because "Slip above 70 % is critical"
const f_obs = {L1: 0.2, L2: 0.6, L3: 1.0}
settings {
  theoretical_slip = 20 %
  tolerance_growth = 5 cm/rad
}
obstacles {
  level L1 below 3 cm buffer 2 cm
  level L3 buffer 10 cm
}
command max_turn_angle: require abs(delta_heading) <= 90 deg
  because "Largest allowed turn angle per command"
index I_phi "pitch deviation" {
  value  = max over time after 5 s (abs(pitch - ref.pitch))
  limit  = 30 deg
  weight = 0.8
  map    = abs(pitch)
  because "Pitch"
}
chance hit_L2 = any over parts (collision.hits[L2] > 0)
combine { run = max_weighted path = mean confidence = 90 % indifference = 2 % }
prescreen no_hit: require I_phi < 1
verdict rare: require chance(hit_L2) <= 5 % because "rarely"
rank by risk, time desc, energy
""")
    assert book.header.name == "t" and book.header.version == "1.0.0"
    assert book.constants[0].value == Number(70.0, "%")
    assert book.constants[0].rationale == "Slip above 70 % is critical"
    assert book.constants[1].value == Table((("L1", Number(0.2)), ("L2", Number(0.6)),
                                             ("L3", Number(1.0))))
    assert [s.name for s in book.settings] == ["theoretical_slip", "tolerance_growth"]
    assert book.settings[1].value == Number(5.0, "cm/rad")
    assert book.obstacle_levels[0].below == Number(3.0, "cm")
    assert book.obstacle_levels[1].below is None
    assert book.command_rules[0].condition == Binary(
        "<=", Call("abs", (Name("delta_heading"),)), Number(90.0, "deg"))
    index = book.indices[0]
    assert index.title == "pitch deviation" and index.weight == Number(0.8)
    assert index.value == Reduce("max", "time", Call("abs", (
        Binary("-", Name("pitch"), Name("ref.pitch")),)), window=Window("after", Number(5, "s")))
    assert index.map == Call("abs", (Name("pitch"),))
    assert book.chances[0].condition == Reduce("any", "parts", Binary(
        ">", Select(Name("collision.hits"), ("L2",)), Number(0.0)))
    assert book.combine.confidence == Number(90.0, "%")
    assert book.combine.indifference == Number(2.0, "%")
    assert book.prescreens[0].name == "no_hit"
    assert book.verdicts[0].condition.left == Call("chance", (Name("hit_L2"),))
    assert book.ranking == Ranking((RankKey(Name("risk")), RankKey(Name("time"), True),
                                    RankKey(Name("energy"))))


def test_defaults_when_combine_and_rank_are_left_out():
    book = parse(INDEX + VERDICT)
    assert book.combine.run == "max_weighted" and book.combine.confidence is None
    assert [key.expr for key in book.ranking.keys] == [Name("risk"), Name("time"),
                                                       Name("energy")]


@pytest.mark.parametrize(("text", "expected"), [
    ("-2 ^ 2", Unary("-", Binary("^", Number(2), Number(2)))),
    ("2 ^ 3 ^ 2", Binary("^", Number(2), Binary("^", Number(3), Number(2)))),
    ("a - b - c", Binary("-", Binary("-", Name("a"), Name("b")), Name("c"))),
    ("a + b * c", Binary("+", Name("a"), Binary("*", Name("b"), Name("c")))),
    ("not a < b and c or d", Binary("or", Binary("and", Unary("not", Binary(
        "<", Name("a"), Name("b"))), Name("c")), Name("d"))),
    ("(a + b)[FL]", Select(Binary("+", Name("a"), Name("b")), ("FL",))),
    ("collision.hits[wheel, L2]", Select(Name("collision.hits"), ("wheel", "L2"))),
    ("max(a, b)", Call("max", (Name("a"), Name("b")))),
    ("max over time (a)", Reduce("max", "time", Name("a"))),
    ("percentile 95 over time (speed)", Reduce("percentile", "time", Name("speed"),
                                               Number(95.0))),
    ("time_above 30 deg over time (abs(pitch))", Reduce(
        "time_above", "time", Call("abs", (Name("pitch"),)), Number(30.0, "deg"))),
    ("time_above limit_x over time (x)", Reduce("time_above", "time", Name("x"),
                                                 Name("limit_x"))),
    ("mean over time during command 2 (abs(heading_error))", Reduce(
        "mean", "time", Call("abs", (Name("heading_error"),)),
        window=Window("command", Number(2.0)))),
    ("sum over time before (1 min + 5 s) (x)", Reduce(
        "sum", "time", Name("x"), window=Window("before", Binary(
            "+", Number(1.0, "min"), Number(5.0, "s"))))),
    ("0.02 m/s^2 + 648 mAs / 2 A·s", Binary("+", Number(0.02, "m/s^2"), Binary(
        "/", Number(648.0, "mAs"), Number(2.0, "A·s")))),
    ("1.5e-3 m", Number(0.0015, "m")),
    ("5cm", Number(5.0, "cm")),
    ("value + limit + time", Binary("+", Binary("+", Name("value"), Name("limit")),
                                    Name("time"))),
])
def test_expressions_parse_with_the_usual_precedence(text, expected):
    assert condition(text) == expected


def test_a_keyword_after_a_number_is_not_its_unit():
    assert condition("x > 0 and y < 1") == Binary("and", Binary(">", Name("x"), Number(0.0)),
                                                  Binary("<", Name("y"), Number(1.0)))


def test_a_unit_on_the_next_line_is_not_the_numbers_unit():
    book = parse("settings {\n  theoretical_slip = 0.2\n  tolerance_growth = 1 cm/rad\n}\n")
    assert book.settings[0].value == Number(0.2)


def test_every_node_has_a_span():
    book = parse("const a = 5 cm\n" + INDEX)
    constant = book.constants[0]
    assert (constant.span.line, constant.span.column) == (3, 1)
    assert (constant.value.span.line, constant.value.span.column,
            constant.value.span.end_column) == (3, 11, 15)
    index = book.indices[0]
    assert index.span.line == 4 and index.value.span.column > 1
    assert index.value.operand.span.path == "t.rules"


def test_windows_line_endings_tabs_and_a_byte_order_mark_are_fine():
    text = "\ufeff" + (HEADER + "const a =\t5 cm  # note\n" + INDEX + VERDICT).replace(
        "\n", "\r\n")
    book = parse_rulebook(text, "crlf.rules")
    assert book.constants[0].value == Number(5.0, "cm")
    assert book.constants[0].comments == ("@eol # note",)
    assert book == parse(INDEX + VERDICT + "const a = 5 cm\n")


def test_strings_unescape_quotes_and_backslashes():
    book = parse(r'const a = 1 because "say \"hi\" \\ now"' + "\n")
    assert book.constants[0].rationale == 'say "hi" \\ now'


# ----------------------------------------------------------------------------- comments

def test_comments_are_kept_on_their_declarations():
    book = parse_rulebook("""# top
rulebook "t" version "1.0.0"  # header line
purpose "p"
# about a
const a = 1  # inline
# before settings
settings {
  theoretical_slip = 0.1  # slip
}
index I_s "t" {  # opening
  value = max over time (speed)
  # about the limit
  limit = 1 cm/s  # why
  weight = 1
}
# the end
""", "c.rules")
    assert book.header.comments == ("# top", "@rulebook # header line")
    assert book.constants[0].comments == ("# about a", "@eol # inline")
    assert book.settings[0].comments == ("@block^ # before settings", "@eol # slip")
    assert book.indices[0].comments == ("@index # opening", "@limit^ # about the limit",
                                        "@limit # why")
    assert book.trailing_comments == ("# the end",)


def test_comments_do_not_change_the_model():
    plain = parse(INDEX + VERDICT)
    commented = parse("# a\n" + INDEX.replace("limit", "# b\nlimit") + VERDICT + "# c\n")
    assert plain == commented


# ----------------------------------------------------------------------------- errors

def test_a_syntax_error_names_place_and_expected_tokens():
    [diagnostic] = errors(HEADER + "const critical_slip 70 %\n")
    assert diagnostic.code == "E001"
    assert (diagnostic.span.path, diagnostic.span.line, diagnostic.span.column) == (
        "bad.rules", 3, 21)
    assert "expected '='" in diagnostic.message


def test_several_syntax_errors_in_one_file_are_all_reported():
    found = errors(HEADER + "const a = (1\nconst b = 2 +\nconst c = 3\nconst d = * 4\n")
    assert [d.span.line for d in found] == [4, 5, 6]


def test_equals_in_a_condition_gets_a_hint():
    [diagnostic] = errors(HEADER + "verdict v: require risk = 1\n")
    assert diagnostic.hint == "use '==' to compare"


def test_an_unclosed_block_is_reported_at_the_end():
    [diagnostic] = errors(HEADER + "index I { value = 1\n  limit = 1\n")
    assert "end of file" in diagnostic.message and "'}'" in diagnostic.message
    assert diagnostic.span.line == 4


STRUCTURAL_MISTAKES = [
    ("", "E500", "no header"),
    (HEADER + "settings { }\nsettings { }\n", "E004", "appears twice"),
    (HEADER + "index I { value = 1 weight = 1 }\n", "E006", "has no 'limit'"),
    (HEADER + "index I { value = 1 limit = 1 weight = 1 weight = 0 }\n", "E006", "twice"),
    (HEADER + "const a = max over wheel (x)\n", "E007", "unknown domain 'wheel'"),
    (HEADER + "combine { run = sum }\n", "E008", "unknown run combination"),
    (HEADER + "const a = 1e999\n", "E003", "too large"),
]


@pytest.mark.parametrize(("body", "code", "words"), STRUCTURAL_MISTAKES)
def test_structural_mistakes(body, code, words):
    found = errors(body)
    assert any(d.code == code and words in d.message for d in found), found


@pytest.mark.parametrize(("body", "code", "words"), STRUCTURAL_MISTAKES)
def test_a_structural_mistake_is_reported_with_the_rest_of_the_files_problems(body, code,
                                                                             words):
    """One structural mistake hid every other problem of the file (the checker never ran);
    each is now reported once, with the other, and the file still does not pass."""
    from idefix_rules.rulebook import check_text

    text = body + INDEX + "verdict far: require risk <= 5 cm\n"
    result = check_text(text, "bad.rules")
    found = [d.code for d in result.diagnostics]
    assert sorted(found) == sorted([code, "E201"]), result.diagnostics
    assert result.checked is None
    assert [d.code for d in errors(text)] == [code]  # parsing alone (fmt, the editor) refuses


@pytest.mark.parametrize(("literal", "column"), [
    ("1e-400", 11), ("1e-400 %", 11), ("0.5e-330 cm", 11), ("-1e-999", 12)])
def test_a_nonzero_number_a_double_reads_as_0_is_refused_at_its_column(literal, column):
    [diagnostic] = errors(HEADER + f"const a = {literal}\n")
    assert (diagnostic.code, diagnostic.span.line, diagnostic.span.column) == ("E003", 3, column)
    assert "too small for a double: it would be read as 0" in diagnostic.message


@pytest.mark.parametrize("literal", ["0e-400", "0.000e-999 %", "1e-300 %", "4.9e-324"])
def test_zero_and_small_numbers_a_double_holds_are_fine(literal):
    parse(f"const a = {literal}\n")


@pytest.mark.parametrize(("line", "column", "named", "hint"), [
    ("const a = \uff170 %", 11, "FULLWIDTH DIGIT SEVEN", "write 70"),
    ("const a = 7\uff10 %", 12, "FULLWIDTH DIGIT ZERO", "write 70"),
    ("const a = \u0663.5 m", 11, "ARABIC-INDIC DIGIT THREE", "write 3.5"),
    ("const a = 1 m^\uff12", 15, "FULLWIDTH DIGIT TWO", "write m^2"),
    ("verdict v: require risk <= 5\u0966 %", 29, "DEVANAGARI DIGIT ZERO", "write 50"),
])
def test_a_digit_of_another_script_is_refused_at_its_column(line, column, named, hint):
    [diagnostic] = errors(HEADER + line + "\n")
    assert (diagnostic.code, diagnostic.span.line, diagnostic.span.column) == ("E011", 3, column)
    assert named in diagnostic.message and "0-9" in diagnostic.message
    assert diagnostic.hint == hint


def test_unknown_domain_suggests_the_closest():
    [diagnostic] = errors(HEADER + "const a = max over wheel (x)\n")
    assert diagnostic.hint == "did you mean 'wheels'?"


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.text() | st.binary().map(lambda raw: raw.decode("latin-1")))
def test_arbitrary_text_gives_a_rulebook_error_never_another_exception(text):
    try:
        parse_rulebook(text, "fuzz.rules")
    except UserInputError as failure:
        assert failure.diagnostics
        assert all(d.span is not None and d.span.path == "fuzz.rules"
                   for d in failure.diagnostics)


SAMPLE = HEADER + """const c = 70 % because "x"
index I_s "slip" {
  value  = max over time (max over wheels (abs(wheel.slip)))
  limit  = c
  weight = 1
}
chance hit = any over parts (collision.hits[L2] > 0)
verdict ok: require risk <= 70 % and chance(hit) < 5 %
rank by risk desc
"""


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_damaged_rulebooks_give_a_rulebook_error_never_another_exception(data):
    start = data.draw(st.integers(0, len(SAMPLE)))
    end = data.draw(st.integers(start, min(len(SAMPLE), start + 12)))
    insert = data.draw(st.sampled_from(["", "(", ")", "{", "}", "over", "\"", "#", "-", "=",
                                        "max", "1e400", "\x00", "é", "\n"]))
    text = SAMPLE[:start] + insert + SAMPLE[end:]
    try:
        model = parse_rulebook(text, "damaged.rules")
    except UserInputError as failure:
        assert failure.diagnostics
        return
    # Damage that still parses: the formatter must keep its meaning and be idempotent.
    formatted = format_rulebook(model)
    assert parse_rulebook(formatted, "damaged.rules") == model
    assert format_rulebook(parse_rulebook(formatted, "damaged.rules")) == formatted


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_damaged_rulebooks_check_to_diagnostics_never_another_exception(data):
    """The checker also runs on what lowered of a file with structural mistakes: whatever
    the damage, diagnostics (or a syntax error), never a crash, never a passing file."""
    from idefix_rules.rulebook import check_text

    start = data.draw(st.integers(0, len(SAMPLE)))
    end = data.draw(st.integers(start, min(len(SAMPLE), start + 12)))
    insert = data.draw(st.sampled_from(["", "1e400", "1e-400", "over tim", "over run",
                                        "limit = 1", "weight = 1", "}", "rank by risk\n",
                                        "combine { run = sum }\n", "value = 1e999"]))
    text = SAMPLE[:start] + insert + SAMPLE[end:]
    try:
        parse_rulebook(text, "damaged.rules")
        refused = False
    except UserInputError:
        refused = True
    try:
        result = check_text(text, "damaged.rules", strict=data.draw(st.booleans()))
    except UserInputError as failure:
        assert failure.diagnostics
        return
    if refused:
        assert result.checked is None and result.errors


@pytest.mark.parametrize("expression", ["(" * 5000 + "1" + ")" * 5000, "-" * 5000 + "1",
                                        "abs(" * 3000 + "1" + ")" * 3000])
def test_deeply_nested_expressions_are_a_rulebook_error_not_a_crash(expression):
    text = HEADER + "const a = " + expression + "\n"
    try:
        parse_rulebook(text, "deep.rules")
    except UserInputError as failure:
        assert failure.diagnostics[0].code == "E001"


# ----------------------------------------------------------------------------- grammar

def test_the_grammar_is_loaded_once():
    assert rulebook_parser() is rulebook_parser()
    assert "QUANTITY" in grammar_text()


@pytest.mark.slow
def test_an_installed_wheel_contains_the_grammar(tmp_path):
    root = Path(__file__).resolve().parents[2]
    source = tmp_path / "src"
    source.mkdir()
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "build", "*.egg-info", "*.fmu")
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(root / name, source / name)
    for name in ("idefix_rules", "grammar", "fmu"):
        shutil.copytree(root / name, source / name, ignore=ignore)
    result = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", ".",
         "-w", str(tmp_path / "dist")],
        cwd=source, capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stderr[-2000:]
    [wheel] = (tmp_path / "dist").glob("*.whl")
    with zipfile.ZipFile(wheel) as archive:
        assert "idefix_rules/grammar/rulebook.lark" in archive.namelist()


@pytest.mark.parametrize(("line", "code", "says"), [
    ("chance a = mx over time (abs(roll)) > 5 deg", "E001", "'mx' is not a reducer"),
    ("chance a = 1 + maximum over time (abs(roll)) > 5 deg", "E001",
     "'maximum' is not a reducer"),
    ("chance a = percentile over time (speed) > 1 mm/s", "E106",
     "'percentile' needs a parameter before 'over'"),
    # an axis or a unit before a stray 'over' is no reducer written wrong
    ("chance a = mean over runs over time (x) > 1", "E001", "unexpected 'over'"),
    ("chance a = max over time (abs(roll)) > 5 deg over", "E001", "unexpected name 'over'"),
    # nor are the words of a comment
    ("# a percentile over\n}", "E001", "unexpected '}'"),
])
def test_a_reduction_written_wrong_is_named_where_it_is_and_only_there(
        line: str, code: str, says: str) -> None:
    text = 'rulebook "t" version "1.0.0"\npurpose "t"\n' + line + "\n"
    with pytest.raises(UserInputError) as refused:
        parse_rulebook(text, "t.rules")
    first = refused.value.diagnostics[0]
    assert (first.code, says in first.message) == (code, True), first.message


def test_an_equals_at_the_end_of_the_file_gets_the_comparison_hint() -> None:
    with pytest.raises(UserInputError) as refused:
        parse_rulebook('rulebook "t" version "1.0.0"\npurpose "t"\nverdict v: require risk =',
                       "t.rules")
    assert refused.value.diagnostics[0].hint == "use '==' to compare"
