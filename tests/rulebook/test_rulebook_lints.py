"""Lints of ``check --strict`` at their boundaries, and the default rulebooks stay clean."""

from __future__ import annotations

from pathlib import Path

import pytest

from idefix_rules.cli.check import check_file
from idefix_rules.rulebook import check_text

ROOT = Path(__file__).parents[2]
FIXTURES = ROOT / "tests" / "fixtures" / "rulebooks"  # frozen copies of released rulebooks

HEAD = '''rulebook "t" version "1.0.0"
purpose "lint boundaries"
index I_s "slip" {
  value  = max over time (max over wheels (abs(wheel.slip)))
  limit  = LIMIT
  weight = 1
}
chance moving = max over time (speed) > 1 mm/s
verdict v: require CONDITION
'''


def codes(limit: str = "70 %", condition: str = "risk <= 70 %", extra: str = "") -> list[str]:
    text = HEAD.replace("LIMIT", limit).replace("CONDITION", condition) + extra
    return [d.code for d in check_text(text, "t.rules", strict=True).diagnostics]


@pytest.mark.parametrize(("condition", "expected"), [
    ("risk < 1", []),                        # a bare 1 is 100 %: fine
    ("risk <= 1", ["W611"]),                 # … but risk never exceeds 1
    ("risk <= 1.5", ["W610", "W611"]),       # just above 1: a percentage meant
    ("risk <= 70", ["W610", "W611"]),
    ("risk <= 70 %", []),
    ("risk < 100 %", []),                    # can fail at risk = 1
    ("risk <= 100 %", ["W611"]),             # never fails
    ("chance(moving) >= 0 %", ["W611"]),
    ("chance(moving) > 0 %", []),
    ("mean(I_s) < 0.5 and max(I_s) <= 1", ["W611"]),
    ("runs >= 100", []),                      # a count, not a ratio
])
def test_ratio_and_range_lints(condition, expected):
    assert sorted(codes(condition=condition)) == expected


@pytest.mark.parametrize(("limit", "expected"), [
    ("70 %", []), ("0.7", []), ("1", []), ("1.01", ["W610"]), ("50", ["W610"])])
def test_bare_ratio_limits(limit, expected):
    assert codes(limit=limit) == expected


@pytest.mark.parametrize(("constant", "expected"), [
    ('const c = 70 % because "Slip above 70 % is critical"', []),
    ('const c = 70 % because "Slip above 0.7 is critical"', []),
    ('const c = 65 % because "Slip above 70 % is critical"', ["W612"]),
    ('const c = 5 cm because "Assumption: half the 10 cm wheel radius"', []),
    ('const c = 5 cm because "Sinkage above 6 cm digs in"', ["W612"]),
    # ordinary wording: "percent", a sentence's full stop, a version number
    ('const c = 70 % because "Slip above 70 percent is critical"', []),
    ('const c = 70 % because "Slip above 65 percent is critical"', ["W612"]),
    ('const c = 70 % because "Critical above 70 %."', []),
    ('const c = 70 % because "Critical above 65 %."', ["W612"]),
    ('const c = 70 % because "Limit 1.0.0 of the flight rules"', []),
    ('const c = 70 % because "Limit 10.0.0 of the flight rules"', []),
    ('const c = 70 % because "Slip below 2.10.1 rules"', []),
    ('const c = 5 cm because "Speeds above 6 % of the limit"', []),  # another dimension
    # a rationale rounds: to the digits it writes, in the unit it writes
    ('const c = 15 deg because "Tilt above 0.2618 rad is critical"', []),
    ('const c = 15 deg because "Tilt above 0.2617 rad is critical"', ["W612"]),  # just outside
    ('const c = 1 / 3 because "Slip above 33.3 % is critical"', []),
    ('const c = 1 / 3 because "Slip above 33.4 % is critical"', ["W612"]),
    ('const c = 0.6749 because "Slip above 67.5 % is critical"', []),
    ('const c = 75 % because "Risk above 0.7 is too high"', ["W612"]),  # 0.75 rounds to 0.8
    ('const c = 0.6744 because "Slip above 67.5 % is critical"', ["W612"]),
    ('const c = 2 / 3 because "Slip above 2/3 is critical"', []),  # a fraction, not 2
    ('const c = 60 % because "Slip above 2/3 is critical"', ["W612"]),
    # a round number says its value exactly: 2 cm is no rounding of 2.4 cm
    ('const c = 2.4 cm because "Sinkage above 2 cm digs in"', ["W612"]),
    ('const c = 70.4 % because "Slip above 70 % is critical"', ["W612"]),
    ('const c = 30.4 deg because "Tilt above 30 deg is critical"', ["W612"]),
])
def test_rationale_numbers(constant, expected):
    uses = "\nchance deep = max over time (max over wheels (wheel.sinkage)) > c\n" \
        if "cm" in constant else "\nchance tilted = max over time (abs(roll)) > c\n" \
        if "deg" in constant else "\nchance slips = max over time (wheel.slip[FL]) > c\n"
    found = codes(extra=constant + uses)
    assert [c for c in found if c != "W601"] == expected


@pytest.mark.parametrize(("literal", "expected"), [
    ("1e-300 %", []), ("1e-310 %", ["W613"]), ("0 %", []), ("1e-320", ["W613"])])
def test_underflow(literal, expected):
    assert codes(extra=f"chance tiny = max over time (wheel.slip[FL]) > {literal}\n") == \
        expected


def test_the_default_rulebook_has_no_lint():
    # the rule engineers' own check of the rulebook they edit
    report = check_file(ROOT / "rulebooks" / "idefix-ops.rules", strict=True)
    assert report.diagnostics == ()


def test_the_frozen_rulebook_has_no_lint():
    report = check_file(FIXTURES / "idefix-ops-1.1.0.rules", strict=True)
    assert report.diagnostics == ()


def test_the_old_version_kept_a_rationale_that_disagrees():
    # 0.9.0 raised acceptable_risk to 75 % but kept "mean risk above 0.7" in its rationale
    report = check_file(FIXTURES / "idefix-ops-0.9.0.rules", strict=True)
    assert [(d.code, d.span.line) for d in report.diagnostics] == [("W612", 131)]
    assert "says 0.7 but the value is 75 %" in report.diagnostics[0].message


@pytest.mark.parametrize(("rationale", "expected"), [
    ("Slip above 70 % is critical", []), ("Slip above 60 % is critical", ["W612"])])
def test_index_rationales_are_checked_against_the_limit(rationale, expected):
    text = HEAD.replace("LIMIT", "70 %").replace("CONDITION", "risk <= 70 %").replace(
        "  weight = 1\n}", f'  weight = 1\n  because "{rationale}"\n}}')
    assert [d.code for d in check_text(text, "t.rules", strict=True).diagnostics] == expected


def test_used_here_notes_are_data_too():
    text = (ROOT / "tests" / "rulebook" / "golden" /
            "constant_unit_error_used_here.rules").read_text(encoding="utf-8")
    result = check_text(text, "c.rules")
    assert [d.code for d in result.diagnostics] == ["E201"]
    related = result.diagnostics[0].to_dict()["related"]
    assert [(r["line"], r["column"]) for r in related] == [(6, 19), (9, 12), (12, 52)]


def test_a_commands_speed_is_signed_but_a_runs_is_not():
    reverse_ok = HEAD.replace("LIMIT", "70 %").replace("CONDITION", "risk <= 70 %") + \
        "command forward_only: require speed >= 0 mm/s\n"
    assert [d.code for d in check_text(reverse_ok, "t.rules", strict=True).diagnostics] == []
    never = HEAD.replace("LIMIT", "70 %").replace("CONDITION", "risk <= 70 %") + \
        "chance backwards = min over time (speed) < 0 mm/s\n"
    assert [d.code for d in check_text(never, "t.rules", strict=True).diagnostics] == ["W611"]


@pytest.mark.parametrize(("chance", "expected"), [
    ("fraction over time (stuck > 0) > 5 %", []),
    ("fraction over time (stuck > 0) > 5", ["W610", "W611"]),  # 500 %: never
    ("fraction over time (stuck > 0) >= 100 %", []),           # can hold: stuck throughout
    ("fraction over time (stuck > 0) > 100 %", ["W611"]),
    ("any over time (stuck > 0)", []),
    ("any over time (stuck > 1)", ["W611"]),                  # a flag is 0 or 1
    ("any over time (stuck >= 1)", []),
    ("any over time (chain_done > 1)", ["W611"]),
])
def test_flags_and_fractions_of_samples_have_their_ranges(chance: str, expected: list[str]
                                                         ) -> None:
    found = codes(extra=f"chance c = {chance}\nverdict cv: require chance(c) <= 5 %\n")
    assert sorted(found) == expected


@pytest.mark.parametrize(("condition", "expected"), [
    ("command_number >= 1", ["W611"]),   # commands are counted from 1
    ("command_number < 1", ["W611"]),
    ("command_number >= 2", []),
    ("command_number <= 3", []),
])
def test_a_command_number_is_counted_from_one(condition: str, expected: list[str]) -> None:
    found = codes(extra=f"command c: require {condition} or abs(delta_heading) <= 90 deg\n")
    assert sorted(found) == expected


@pytest.mark.parametrize(("parameter", "expected"), [
    ("0.95", ["W616"]),    # a fraction where 95 was meant
    ("0.001", ["W616"]),   # just above 0
    ("0.999", ["W616"]),   # just below 1
    ("1", []),             # the 1st percentile: written as meant
    ("0", []),             # the minimum
    ("95", []),
    ("99.5", []),
])
def test_a_percentile_written_as_a_fraction(parameter: str, expected: list[str]) -> None:
    found = codes(extra=f"chance c = percentile {parameter} over time (speed) > 8 mm/s\n"
                        "verdict cv: require chance(c) <= 5 %\n")
    assert sorted(found) == expected


def test_a_fraction_percentile_over_runs_is_linted_too() -> None:
    found = check_text(HEAD.replace("LIMIT", "70 %").replace("CONDITION", "risk <= 70 %")
                       + "chance c = percentile 0.5 over runs "
                         "(final over time (x - ref.x)) > 1 cm\n"
                       "verdict cv: require chance(c) <= 5 %\n", "t.rules", strict=True)
    warnings = [d for d in found.diagnostics if d.code == "W616"]
    assert len(warnings) == 1 and warnings[0].hint == "did you mean '50'?"


def test_the_editor_offers_the_percent_number_as_a_quick_fix() -> None:
    from idefix_rules.lsp.analysis import analyse
    from idefix_rules.lsp.fixes import quick_fixes

    text = HEAD.replace("LIMIT", "70 %").replace("CONDITION", "risk <= 70 %") + (
        "chance c = percentile 0.95 over time (speed) > 8 mm/s\n"
        "verdict cv: require chance(c) <= 5 %\n")
    fixes = [(f.title, f.new_text) for f in quick_fixes(analyse(text, "t.rules"))
             if f.diagnostic.code == "W616"]
    assert fixes == [("replace '0.95' with '95'", "95")]


BROKEN = [
    # (what replaces the index's value, or text appended; the error plain check reports)
    (("max over time (abs())", ""), "E106"),
    (("max over time (max over wheels (abs(wheel.slip)))",
      "verdict w: require risk <= abs()\n"), "E106"),
    (("max over time (max over wheels (abs(wheel.slip)))", "const big = 1e306 km\n"), "E003"),
    (("max over time before 1e308 h (max over wheels (abs(wheel.slip)))", ""), "E003"),
    (("max over time (max over wheels (abs(wheel.slip)))",
      "chance far = max over time (x) <= 1e308 km\n"), "E003"),
    (("max over time (max over wheels (abs(wheel.slip)))",
      'const c = 5 cm because "above 1e306 km it overflows"\n'), None),
    (("max over time (max over wheels (abs(wheel.slip)))",
      "verdict w: require mean(I_s) <= 1e308 km\n"), "E003"),
    (("max over time (max over wheels (abs(wheel.slip)))",
      "command c: require max_wheel_rate <= 1e308 km/s\n"), "E003"),
]


@pytest.mark.parametrize(("edit", "error"), BROKEN)
def test_the_lints_survive_what_plain_check_reports(edit: tuple[str, str],
                                                    error: str | None) -> None:
    """``check --strict`` (and the language server, which runs it on every edit) reports the
    errors plain ``check`` reports, lints or not: an empty call or a number a unit pushes past
    a double crashed two lints (IndexError, OverflowError)."""
    value, extra = edit
    text = HEAD.replace("LIMIT", "70 %").replace("CONDITION", "risk <= 70 %") \
        .replace("max over time (max over wheels (abs(wheel.slip)))", value) + extra
    plain = [d.code for d in check_text(text, "t.rules").diagnostics
             if d.code.startswith("E")]
    strict = [d.code for d in check_text(text, "t.rules", strict=True).diagnostics
              if d.code.startswith("E")]
    assert plain == ([error] if error else [])
    assert strict == plain


@pytest.mark.parametrize(("power", "value", "error"), [
    ("(2 cm) ^ 2", 4e-4, None),
    ("(2 cm) ^ -1", 50.0, None),         # a whole number too, written with its sign
    ("(2 cm) ^ --2", 4e-4, None),
    ("(2 cm) ^ -0.5", None, "E202"),
    ("(2 cm) ^ (1 + 1)", None, "E202"),  # written in place: no expression
])
def test_a_quantity_with_a_unit_is_raised_to_a_whole_number_written_in_place(
        power: str, value: float | None, error: str | None) -> None:
    text = HEAD.replace("LIMIT", "70 %").replace("CONDITION", "risk <= 70 %") \
        + f"const p = {power}\n"
    result = check_text(text, "t.rules")
    assert [d.code for d in result.diagnostics if d.code.startswith("E")] == \
        ([error] if error else [])
    if value is not None:
        assert result.checked is not None
        assert result.checked.constants["p"] == pytest.approx(value, rel=1e-12)


@pytest.mark.parametrize(("parameter", "words", "hint"), [
    ("95 %", "percentile needs a number from 0 to 100, written without '%': it counts in "
             "percent already", "percentile 95 over …"),
    ("95 cm", "percentile needs a number from 0 to 100, without a unit (got 95 cm)", None),
    ("150", "percentile needs a number from 0 to 100", None),
])
def test_a_percentile_parameter_out_of_place_says_what_is_wrong_with_it(
        parameter: str, words: str, hint: str | None) -> None:
    text = HEAD.replace("LIMIT", "70 %").replace("CONDITION", "risk <= 70 %").replace(
        "max over time (max over wheels", f"percentile {parameter} over time (max over wheels")
    [found] = check_text(text, "t.rules").diagnostics
    assert (found.code, found.message, found.hint) == ("E308", words, hint)


@pytest.mark.parametrize(("threshold", "expected"), [
    ("50", ["W610"]),  # 5000 % of slip: 50 % meant
    ("50 %", []), ("0.5", []), ("1", []),
])
def test_a_bare_time_above_threshold_on_a_ratio_is_a_percentage_meant(
        threshold: str, expected: list[str]) -> None:
    assert codes(extra=f"chance slow = time_above {threshold} over time (max over wheels "
                       "(wheel.slip)) > 10 s\nverdict w: require chance(slow) <= 5 %\n") \
        == expected


def test_a_constant_beyond_a_double_says_so() -> None:
    text = HEAD.replace("LIMIT", "70 %").replace("CONDITION", "risk <= 70 %") \
        + "const p = (1e200 m) ^ 2\n"
    [found] = check_text(text, "t.rules").diagnostics
    assert (found.code, found.message) == (
        "E402", "constant 'p' is beyond a double: its value is too large for a number")
