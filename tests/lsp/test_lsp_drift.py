"""The derived signal ``drift`` in the editor: completion, hover and highlighting."""

from __future__ import annotations

import json
import logging
from pathlib import Path

from textmate_grammar.parsers.base import LanguageParser

from idefix_rules.lsp.analysis import analyse
from idefix_rules.lsp.completion import completions
from idefix_rules.lsp.hover import hover
from idefix_rules.lsp.positions import Position

GRAMMAR = Path(__file__).resolve().parents[2] / "editors" / "rulebook.tmLanguage.json"
TEXT = ('rulebook "r" version "1.0.0" purpose "p"\n'
        "index I_d { value = final over time (drift) limit = 10 cm weight = 1 }\n"
        "verdict ok: require risk <= 70 %\n")


def test_completion_offers_drift_in_an_index_with_its_unit() -> None:
    text = TEXT.replace("(drift)", "(dr")
    line, character = 1, text.split("\n")[1].index("(dr") + 3
    [item] = [i for i in completions(text, Position(line, character)) if i.label == "drift"]
    assert item.kind == "signal" and item.detail.startswith("m [time] — what the drive adds")


def test_hover_on_drift_shows_its_contract_entry() -> None:
    analysis = analyse(TEXT, "r.rules")
    shown = hover(analysis, Position(1, TEXT.split("\n")[1].index("drift") + 2))
    assert shown is not None
    assert "**signal drift**" in shown.markdown and "- unit: `m` — a length" in shown.markdown
    assert "provided by the evaluator" in shown.markdown


def test_drift_is_highlighted_as_a_derived_signal() -> None:
    logging.getLogger("textmate_grammar").setLevel(logging.ERROR)
    parser = LanguageParser(json.loads(GRAMMAR.read_text(encoding="utf-8")))
    element = parser.parse_string(TEXT)
    assert element is not None
    scopes = {piece: scopes[-1] for _, piece, scopes in element.flatten() if piece.strip()}
    assert scopes["drift"] == "support.variable.signal.derived.rulebook"
