"""Completion of the signals of a rulebook's named areas."""

from idefix_rules.lsp.completion import completions
from idefix_rules.lsp.positions import Position


def test_declared_areas_offer_their_signals_in_chances():
    text = ('rulebook "r" version "1.0.0" purpose "p"\n'
            "obstacles {\n  area crater keep_out level L3 buffer 10 cm\n}\n"
            "chance near = any over time (ar")
    lines = text.splitlines()
    names = {c.label for c in completions(text, Position(len(lines) - 1, len(lines[-1])))}
    assert {"area.crater.inside", "area.crater.buffer"} <= names
