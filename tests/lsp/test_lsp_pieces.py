"""The language server's pieces without the protocol: symbols, hover, completion, quick fixes,
code explanations, and the ``lsp`` command itself."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

from idefix_rules.cli import main
from idefix_rules.errors import Span
from idefix_rules.limits import MAX_RULEBOOK_BYTES
from idefix_rules.lsp.analysis import analyse
from idefix_rules.lsp.codes import code_explanation
from idefix_rules.lsp.completion import completions
from idefix_rules.lsp.fixes import quick_fixes
from idefix_rules.lsp.hover import hover
from idefix_rules.lsp.positions import Position, Range, span_range
from idefix_rules.lsp.symbols import expressions
from idefix_rules.rulebook import parse_text
from idefix_rules.rulebook.checking import check_file
from idefix_rules.rulebook.walk import rulebook_expressions

REPOSITORY = Path(__file__).resolve().parents[2]
# the frozen operations rulebook 1.1.0: the tests name its declarations and texts
DEFAULT_TEXT = (REPOSITORY / "tests" / "fixtures" / "rulebooks" / "idefix-ops-1.1.0.rules"
                ).read_text(encoding="utf-8")

HEADER = 'rulebook "r" version "1.0.0" purpose "p"\n'
INDEX = ("index I_s { value = max over time (max over wheels (abs(wheel.slip))) limit = 1 "
         "weight = 1 }\n")
VERDICT = "verdict ok: require risk <= 0.7\n"


def position(text: str, needle: str, offset: int = 0) -> Position:
    start = text.index(needle) + offset
    line = text.count("\n", 0, start)
    return Position(line, start - (text.rfind("\n", 0, start) + 1))


def labels(text: str, needle: str, offset: int = 0) -> set[str]:
    return {item.label for item in completions(text, position(text, needle, offset))}


# ----------------------------------------------------------------------------- symbols

def test_every_declared_name_of_the_default_rulebook_is_a_definition() -> None:
    analysis = analyse(DEFAULT_TEXT, "idefix-ops.rules")
    symbols = analysis.symbols.symbols
    assert {kind for kind, _ in symbols} == {"constant", "index", "chance", "level"}
    assert len(symbols) == 14 + 8 + 6 + 3
    for (_, name), symbol in symbols.items():
        start, end = (analysis.lines.offset(symbol.definition.start),
                      analysis.lines.offset(symbol.definition.end))
        assert DEFAULT_TEXT[start:end] == name
    # f_obs is read twice (value and map of I_obs); critical_slip_angle once
    assert len(symbols[("constant", "f_obs")].references) == 2
    assert len(symbols[("constant", "critical_slip_angle")].references) == 1
    assert len(symbols[("index", "I_pos")].references) == 0


def test_a_rulebook_that_does_not_parse_has_diagnostics_but_no_symbols() -> None:
    analysis = analyse(HEADER + "const a = (5 cm\n", "r.rules")
    assert [d.code for d in analysis.diagnostics] == ["E001"]
    assert analysis.rulebook is None and analysis.symbols.symbols == {}
    problem = span_range(analysis.diagnostics[0].span)
    shown = hover(analysis, problem.start)  # the problem itself is explained
    assert shown is not None and shown.markdown.startswith("**error[E001]**: syntax error")


@pytest.mark.parametrize("path", ["rulebooks/idefix-ops.rules",
                                  "rulebooks/examples/site-areas.rules"])
def test_the_symbols_walk_every_expression_the_rule_model_walks(path: str) -> None:
    rulebook = parse_text((REPOSITORY / path).read_text(encoding="utf-8"), path)
    walked = sorted(id(expr) for expr in rulebook_expressions(rulebook))
    assert sorted(id(expr) for expr, _ in expressions(rulebook)) == walked


def test_the_sizes_and_levels_of_obstacles_and_areas_are_references() -> None:
    text = (HEADER + "const small = 3 cm\nconst margin = 2 cm\nconst steep_from = 20 deg\n"
            "obstacles {\n  level L1 below small buffer margin\n"
            "  level L2 below 10 cm buffer 5 cm\n  level L3 buffer 10 cm\n"
            "  area rim steep above steep_from level L3 buffer margin  # level L1 in a comment\n"
            "  area pit keep_out # level L1\n    level L3 buffer 5 cm\n}\n" + INDEX + VERDICT)
    analysis = analyse(text, "r.rules")
    assert analysis.diagnostics == ()
    symbols = analysis.symbols.symbols

    def used(kind: str, name: str) -> list[Position]:
        return [where.start for where in symbols[(kind, name)].references]

    assert used("constant", "small") == [position(text, "small buffer")]
    assert used("constant", "margin") == [position(text, "margin\n  level L2"),
                                          position(text, "margin  #")]
    assert used("constant", "steep_from") == [position(text, "steep_from level")]
    assert used("level", "L3") == [position(text, "L3 buffer margin"),
                                   position(text, "L3 buffer 5 cm")]
    assert used("level", "L1") == []
    shown = hover(analysis, position(text, "steep_from level", 2))
    assert shown is not None and shown.markdown.startswith("**const steep_from** = `20 deg`")
    found = analysis.symbols.symbol_at(position(text, "L3 buffer 5 cm", 1))
    assert found is not None and found[0].definition.start == position(text, "L3 buffer 10 cm")


# ----------------------------------------------------------------------------- size limit

@pytest.mark.parametrize("extra_bytes", [0, 1])
def test_a_buffer_is_over_the_size_limit_exactly_when_its_file_is(
        tmp_path: Path, extra_bytes: int) -> None:
    # `°` is one character and two bytes: under the limit in characters, over it in bytes
    line = "# " + "°" * 999 + "\n"
    lines = (MAX_RULEBOOK_BYTES - len(HEADER) - len(VERDICT)) // len(line.encode())
    text = HEADER + line * lines + VERDICT
    text += "#" * (MAX_RULEBOOK_BYTES - len(text.encode()) - 1 + extra_bytes) + "\n"
    (tmp_path / "big.rules").write_text(text, encoding="utf-8")
    assert (tmp_path / "big.rules").stat().st_size == MAX_RULEBOOK_BYTES + extra_bytes
    assert len(text) < MAX_RULEBOOK_BYTES * 3 // 4
    from_file = check_file(tmp_path / "big.rules").diagnostics
    assert analyse(text, str(tmp_path / "big.rules")).diagnostics == from_file
    if extra_bytes:
        [problem] = from_file
        assert problem.code == "E900"
        assert problem.message == (f"rulebook file {tmp_path / 'big.rules'} is 131073 bytes; "
                                   "at most 128 KiB (131072 bytes) is accepted")
    else:
        assert "E900" not in {d.code for d in from_file}


# ----------------------------------------------------------------------------- hover

def test_hover_on_a_rulebook_with_errors_still_gives_what_it_can() -> None:
    text = HEADER + "const a = 5 cm\nconst b = a * 2\n" + INDEX.replace("limit = 1",
                                                                        "limit = b") + VERDICT
    analysis = analyse(text, "r.rules")
    assert analysis.checked is None  # I_s's limit is a length, its value a ratio: E204
    literal = hover(analysis, position(text, "const a", 6))
    assert literal is not None and "SI value: `0.05 m` — a length (m)" in literal.markdown
    # the unit error of b is reported once, at its definition (its use is a note)
    derived = hover(analysis, position(text, "const b", 6))
    assert derived is not None and "shown when the rulebook has no errors" in derived.markdown
    problem = hover(analysis, position(text, "a * 2", 4))
    assert problem is not None and "error[E204]" in problem.markdown
    limit = hover(analysis, position(text, "limit = b", 8))
    assert limit is not None and "const b" in limit.markdown
    assert "error[E204]" not in limit.markdown


def test_hover_of_path_statistics_and_levels() -> None:
    analysis = analyse(DEFAULT_TEXT, "idefix-ops.rules")
    risk = hover(analysis, position(DEFAULT_TEXT, "risk <= 70 %"))
    assert risk is not None and "path statistic risk" in risk.markdown
    level = hover(analysis, position(DEFAULT_TEXT, "level L2", 6))
    assert level is not None and "below 10 cm buffer 5 cm" in level.markdown
    assert "obstacles smaller than 0.1 m; buffer zone 0.05 m" in level.markdown


# ----------------------------------------------------------------------------- completion

def test_completion_offers_what_fits_the_context() -> None:
    text = DEFAULT_TEXT
    assert "theoretical_slip" in labels(text, "  theoretical_slip", 2)
    assert {"value", "nominal", "limit", "weight", "map", "because"} == labels(text,
                                                                               "  limit  = 1", 2)
    prescreen = labels(text, "require I_obs", 8)
    assert {"I_obs", "I_pos", "got_stuck", "risk", "critical_tilt"} <= prescreen
    assert "wheel.slip" not in prescreen and "delta_heading" not in prescreen
    assert labels(text, "Slip above 70") == set()           # inside a string
    assert labels(text, "eq. 1", 2) == set()                # inside a comment
    after_parameter = HEADER + "chance c = percentile 95 "
    assert "over" in labels(after_parameter, "95 ", 3)
    declaration = labels(HEADER + "\n", "\n", 1)
    assert {"const", "index", "chance", "verdict", "rank"} <= declaration


def test_completion_replaces_the_dotted_word_being_typed() -> None:
    text = HEADER + "index I { value = max over time (ref.ro"
    [item] = [i for i in completions(text, position(text, "ref.ro", 6)) if i.label == "ref.roll"]
    assert item.range == Range(position(text, "ref.ro"), position(text, "ref.ro", 6))


# ----------------------------------------------------------------------------- quick fixes

FIXABLE = (HEADER + "settings {\n  theoretical_slip = 20 %\n}\n"
           + "index I_s {\n  value  = max over time (max over wheels (abs(wheel.slip)))\n"
           + "  limit  = 1\n  weight = 1\n}\n" + VERDICT)


@pytest.mark.parametrize(("right", "wrong"), [
    ("abs(wheel.slip)", "abs(wheel.slp)"),             # E101 unknown name
    ("abs(wheel.slip)", "ab(wheel.slip)"),             # E105 unknown function
    ("max over wheels", "max over wheel"),             # E007 unknown domain
    ("theoretical_slip", "theoretical_slp"),           # E505 unknown setting
    ("limit  = 1", "limt  = 1"),                       # E001 misspelt keyword
])
def test_quick_fix_replaces_the_misspelt_word(right: str, wrong: str) -> None:
    text = FIXABLE.replace(right, wrong)
    assert analyse(FIXABLE, "r.rules").diagnostics == ()
    analysis = analyse(text, "r.rules")
    [fix] = quick_fixes(analysis)
    start, end = analysis.lines.offset(fix.range.start), analysis.lines.offset(fix.range.end)
    assert text[:start] + fix.new_text + text[end:] == FIXABLE
    assert fix.title == f"replace '{text[start:end]}' with '{fix.new_text}'"


def test_no_quick_fix_for_a_hint_that_is_not_a_replacement() -> None:
    text = HEADER + INDEX + "verdict ok: require wheel.slip <= 0.7\n"
    analysis = analyse(text, "r.rules")
    assert [d.code for d in analysis.diagnostics] == ["E101"]  # signals are not seen here
    assert quick_fixes(analysis) == []


# ----------------------------------------------------------------------------- pieces

def test_a_problem_of_the_whole_file_sits_at_its_start() -> None:
    assert span_range(Span("r.rules")) == Range(Position(0, 0), Position(0, 0))
    assert span_range(Span("r.rules", 2, 3)) == Range(Position(1, 2), Position(1, 3))


def test_every_code_the_checker_can_give_has_an_explanation() -> None:
    # every module of the rulebook package: a new one is read without being listed here
    sources = sorted((REPOSITORY / "idefix_rules" / "rulebook").glob("*.py"))
    codes = {code for path in sources
             for code in re.findall(r"\"([EW]\d{3})\"", path.read_text(encoding="utf-8"))}
    assert {"E001", "E101", "E204", "W601"} <= codes
    assert {code for code in codes if code_explanation(code) is None} == set()
    assert code_explanation("E999") is None


def test_lsp_command_has_help(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["lsp", "--help"]) == 0
    assert "language server" in capsys.readouterr().out


def test_lsp_command_without_the_extra_says_how_to_install_it(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setitem(sys.modules, "idefix_rules.lsp.server", None)  # as if pygls were absent
    assert main(["lsp"]) == 3
    err = capsys.readouterr().err
    assert "pip install 'idefix-rules[lsp]'" in err and "Traceback" not in err


def test_unit_completions_say_what_each_unit_is_in_si() -> None:
    text = HEADER + "const a = 5 "
    details = {item.label: item.detail for item in completions(text, position(text, "5 ", 2))}
    assert details["cm"] == "a length: 1 cm = 0.01 m"
    assert details["%"] == "a ratio: 1 % = 0.01"
    assert details["km"] == "a length: 1 km = 1000 m"
    assert details["deg"] == "an angle: 1 deg = 0.0174533 rad"
    assert "1" not in details  # a unit a rulebook cannot write


@pytest.mark.parametrize("value", ["-1", "nan", "inf", "soon"])
def test_lsp_debounce_must_be_seconds(value: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["lsp", "--debounce", value]) == 2  # a usage error; the server never starts
    assert "--debounce" in capsys.readouterr().err
