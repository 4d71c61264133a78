"""``idefix-verify explain-error``: an explanation and a fix for every code the tool issues."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from idefix_rules.cli import main
from idefix_rules.diagnostic_codes import CODES

PACKAGE = Path(__file__).parents[2] / "idefix_rules"
_CODE = re.compile(r"""["']([CDEFHTW]\d{3})["']""")


def issued_codes() -> set[str]:
    """Every code string in the package's source (diagnostics are built with literal codes)."""
    found: set[str] = set()
    for path in PACKAGE.rglob("*.py"):
        if path.name == "diagnostic_codes.py":
            continue
        found |= set(_CODE.findall(path.read_text(encoding="utf-8")))
    return found


def test_every_issued_code_has_an_explanation():
    missing = sorted(issued_codes() - set(CODES))
    assert missing == []
    assert len(issued_codes()) >= 120


def test_every_explanation_is_complete():
    for code, entry in CODES.items():
        assert entry.code == code
        assert len(entry.explanation) > 40, code
        assert entry.example.strip() and entry.fix.strip(), code


@pytest.mark.parametrize("code", ["E201", "w610", "T005", "C002", "H011"])
def test_cli_prints_the_explanation(code, capsys):
    assert main(["explain-error", code]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{code.upper()}: ")
    assert "For example:" in out and "Fix:" in out


def test_unknown_code_exits_2_with_close_codes(capsys):
    assert main(["explain-error", "E2010"]) == 2
    err = capsys.readouterr().err
    assert "unknown diagnostic code 'E2010'" in err and "E201" in err


def test_list_names_every_code(capsys):
    assert main(["explain-error", "--list"]) == 0
    assert len(capsys.readouterr().out.strip().splitlines()) == len(CODES)


CONTEXT = '''rulebook "r" version "1.0.0"
purpose "explain-error examples"
index I_r "roll" {
  value  = max over time (abs(roll))
  limit  = 15 deg
  weight = 1
}
chance hit_L3 = any over parts (collision.hits[L3] > 0)
verdict ok: require risk <= 70 %
'''


def in_context(snippet: str) -> str | None:
    """A rulebook around an example that is a declaration or an index's item (None: the
    example is a command line, a fragment, or a campaign's)."""
    text = snippet.replace("\\n", "\n")
    if text.startswith("value"):
        return CONTEXT + 'index I_t "t" {\n  ' + text + '\n  limit = 1\n  weight = 1\n}\n'
    if text.startswith("map"):
        return (CONTEXT + 'index I_t "t" {\n  value = max over time (speed)\n  ' + text
                + '\n  limit = 1 m/s\n  weight = 1\n}\n')
    if re.match(r"(const|verdict|chance|index) ", text):
        return CONTEXT + text + "\n"
    return None


# whole files, not declarations: no header (E500), a line of 50 MB (E901)
WHOLE_FILES = {"E500", "E901"}
RULEBOOK_EXAMPLES = sorted(code for code, entry in CODES.items()
                           if code.startswith("E") and code not in WHOLE_FILES
                           and in_context(entry.example) is not None)


def rulebook_codes(text: str) -> list[str]:
    from idefix_rules.errors import UserInputError
    from idefix_rules.rulebook import check_text

    try:
        diagnostics = check_text(text, "t.rules").diagnostics
    except UserInputError as refused:  # a syntax error
        diagnostics = refused.diagnostics
    return sorted({d.code for d in diagnostics if d.code.startswith("E")})


def test_the_rulebook_examples_are_tried() -> None:
    assert len(RULEBOOK_EXAMPLES) >= 25


@pytest.mark.parametrize("code", RULEBOOK_EXAMPLES)
def test_a_rulebook_example_makes_its_own_error_and_no_other(code: str) -> None:
    """An example that drew another error too (a constant named like a signal, a typo
    in a signal's name, a wheel axis left) taught the wrong thing."""
    text = in_context(CODES[code].example)
    assert text is not None
    assert rulebook_codes(text) == [code], CODES[code].example


FIX_IN_PLACE = re.compile(r"`((?:value|map) = [^`]+|(?:const|chance) \w+ = [^`]+)`")
FIXES_IN_PLACE = sorted(code for code in RULEBOOK_EXAMPLES
                        if FIX_IN_PLACE.search(CODES[code].fix))


def test_the_fixes_in_place_are_tried() -> None:
    assert {"E801", "E802", "E800", "E307"} <= set(FIXES_IN_PLACE)


@pytest.mark.parametrize("code", FIXES_IN_PLACE)
def test_the_fix_of_a_rulebook_example_checks_clean(code: str) -> None:
    """What the catalogue's fix says to write, in the example's place, with an index limit
    of its value's dimension: no error at all (E801's and E802's fixes used to draw E302 and
    E101)."""
    found = FIX_IN_PLACE.search(CODES[code].fix)
    assert found is not None
    text = in_context(found.group(1))
    assert text is not None
    limits = ("limit = 1\n", "limit = 1 m\n", "limit = 1 m/s\n", "limit = 1 deg\n")
    assert any(rulebook_codes(text.replace("limit = 1\n", limit)) == [] for limit in limits), \
        (CODES[code].fix, rulebook_codes(text))

def test_a_misspelt_collision_signal_over_runs_is_an_unknown_name() -> None:
    """E802 is for the collision signals there are; a typo gets E101 with its did-you-mean,
    not 'collision.count cannot be reduced over runs'."""
    from idefix_rules.errors import UserInputError
    from idefix_rules.rulebook import check_text

    text = in_context("value = fraction over runs (sum over parts (sum over levels "
                      "(collision.hist)) > 0)")
    assert text is not None
    try:
        diagnostics = check_text(text, "t.rules").diagnostics
    except UserInputError as refused:
        diagnostics = refused.diagnostics
    [found] = [d for d in diagnostics if d.code.startswith("E")]
    assert (found.code, found.hint) == ("E101", "did you mean 'collision.hits'?")
    assert rulebook_codes(text.replace("collision.hist", "collision.hits")) == ["E802"]


def test_the_unknown_domain_explanation_names_every_domain() -> None:
    """E007's explanation (explain-error, the editor's hover) left out `runs`."""
    from idefix_rules.rulebook.model import DOMAIN_AXES

    assert [d for d in DOMAIN_AXES if f"`{d}`" not in CODES["E007"].explanation] == []
