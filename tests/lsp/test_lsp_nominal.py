"""An index's ``nominal`` in the editor: completion, hover, references and highlighting."""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

import pytest
from textmate_grammar.parsers.base import LanguageParser

from idefix_rules.lsp.analysis import analyse
from idefix_rules.lsp.completion import completions
from idefix_rules.lsp.hover import hover
from idefix_rules.lsp.positions import Position

GRAMMAR = Path(__file__).resolve().parents[2] / "editors" / "rulebook.tmLanguage.json"

TEXT = """rulebook "r" version "1.0.0" purpose "p"
const nominal_slip = 20 %
const critical_slip = 70 %
index I_s "wheel slip ratio" {
  value   = max over time (max over wheels (abs(wheel.slip)))
  nominal = nominal_slip
  limit   = critical_slip
  weight  = 1
}
verdict ok: require risk <= 70 %
"""


def position(text: str, needle: str, offset: int = 0) -> Position:
    start = text.index(needle) + offset
    line = text.count("\n", 0, start)
    return Position(line, start - (text.rfind("\n", 0, start) + 1))


def labels(text: str, needle: str, offset: int = 0) -> set[str]:
    return {item.label for item in completions(text, position(text, needle, offset))}


def test_completion_offers_nominal_among_the_index_items() -> None:
    text = TEXT.replace("  nominal = nominal_slip\n", "  nom\n")
    assert "nominal" in labels(text, "  nom", 5)


def test_after_nominal_only_constants_and_functions_are_offered() -> None:
    text = TEXT.replace("nominal = nominal_slip", "nominal = ")
    offered = labels(text, "nominal = ", 10)
    assert {"nominal_slip", "critical_slip"} <= offered
    assert "wheel.slip" not in offered and "percentile" not in offered  # no signals, reducers


def test_hover_on_the_index_shows_nominal_limit_and_shape() -> None:
    analysis = analyse(TEXT, "r.rules")
    shown = hover(analysis, position(TEXT, "I_s", 1))
    assert shown is not None
    assert "- nominal: `nominal_slip` = `0.2`" in shown.markdown
    assert "- limit: `critical_slip` = `0.7`" in shown.markdown
    assert "(nominal, 0.5) and (limit, 1)" in shown.markdown


def test_hover_without_nominal_keeps_value_over_limit() -> None:
    text = TEXT.replace("  nominal = nominal_slip\n", "").replace("const nominal_slip = 20 %\n",
                                                                  "")
    shown = hover(analyse(text, "r.rules"), position(text, "I_s", 1))
    assert shown is not None and "clamp(value / limit, 0, 1)" in shown.markdown
    assert "nominal" not in shown.markdown


def test_a_constant_read_by_a_nominal_is_referenced_and_hovered() -> None:
    analysis = analyse(TEXT, "r.rules")
    assert len(analysis.symbols.symbols[("constant", "nominal_slip")].references) == 1
    shown = hover(analysis, position(TEXT, "= nominal_slip", 3))
    assert shown is not None and "const nominal_slip" in shown.markdown


def test_a_nominal_error_is_a_diagnostic_with_its_code() -> None:
    text = TEXT.replace("const nominal_slip = 20 %", "const nominal_slip = 80 %")
    analysis = analyse(text, "r.rules")
    assert [d.code for d in analysis.diagnostics] == ["E408"]
    shown = hover(analysis, position(text, "= nominal_slip", 3))
    assert shown is not None and "error[E408]" in shown.markdown


@pytest.fixture(scope="module")
def tokenize() -> Any:
    logging.getLogger("textmate_grammar").setLevel(logging.ERROR)
    parser = LanguageParser(json.loads(GRAMMAR.read_text(encoding="utf-8")))

    def scopes(text: str) -> dict[str, str]:
        element = parser.parse_string(text)
        assert element is not None
        return {piece: scopes[-1] for _, piece, scopes in element.flatten() if piece.strip()}

    return scopes


def test_nominal_is_highlighted_as_an_index_item(tokenize: Any) -> None:
    scoped = tokenize("index I { value = max over time (x) nominal = 1 cm limit = 2 cm "
                      "weight = 1 }\n")
    assert scoped["nominal"] == "variable.other.item.rulebook"
    assert scoped["cm"] == "keyword.other.unit.rulebook"


def test_nominal_after_a_number_is_not_its_unit(tokenize: Any) -> None:
    scoped = tokenize("index I { value = max over time (x) limit = 2 nominal = 1 weight = 1 }\n")
    assert scoped["nominal"] == "variable.other.item.rulebook"
    assert scoped["2"] == "constant.numeric.rulebook"
