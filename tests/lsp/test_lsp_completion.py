"""Completion in the obstacles block, of named areas' signals and of selected labels."""

from __future__ import annotations

import pytest

from idefix_rules.lsp.completion import completions
from idefix_rules.lsp.positions import Position

HEADER = 'rulebook "r" version "1.0.0" purpose "p"\n'
OBSTACLES = ("obstacles {\n  level L1 below 3 cm buffer 2 cm\n  level L2 below 10 cm buffer 5 cm\n"
             "  level L3 buffer 10 cm\n")


def labels_at_end(text: str) -> list[str]:
    """The completions offered at the end of ``text`` (the cursor after its last character)."""
    lines = text.split("\n")
    return [c.label for c in completions(text, Position(len(lines) - 1, len(lines[-1])))]


def test_declared_areas_offer_their_signals_in_chances() -> None:
    text = (HEADER + "obstacles {\n  area crater keep_out level L3 buffer 10 cm\n}\n"
            "chance near = any over time (ar")
    assert {"area.crater.inside", "area.crater.buffer"} <= set(labels_at_end(text))


@pytest.mark.parametrize(("written", "offered"), [
    ("", ["level", "area"]),                                       # a new item
    ("ar", ["level", "area"]),
    ("area ", []),                                                 # a new name
    ("area rim ", ["keep_out", "unknown", "steep"]),
    ("area rim ste", ["keep_out", "unknown", "steep"]),
    ("area rim steep ", ["above"]),
    ("area rim steep above steep_from ", ["level"]),
    ("area rim keep_out ", ["level"]),
    ("area rim keep_out level ", ["L1", "L2", "L3"]),
    ("area rim keep_out # the crater's\n    level L", ["L1", "L2", "L3"]),
    ("area rim unknown level L3 ", ["buffer"]),
    ("level ", ["L1", "L2", "L3"]),
    ("level L2 ", ["below", "buffer"]),
    ("level L2 below small ", ["buffer"]),
])
def test_obstacle_items_offer_what_their_grammar_puts_next(written: str,
                                                           offered: list[str]) -> None:
    assert labels_at_end(HEADER + "const steep_from = 20 deg\n" + OBSTACLES + "  "
                         + written) == offered


@pytest.mark.parametrize(("written", "keywords"), [
    ("area rim steep above 20 ", ["level"]),
    ("area rim keep_out level L3 buffer 5 c", ["because"]),
    ("level L2 below 10 ", ["buffer"]),
    ("level L2 below 10 cm buffer 5 ", []),
])
def test_a_size_in_an_obstacle_item_is_followed_by_the_items_next_keyword(
        written: str, keywords: list[str]) -> None:
    text = HEADER + OBSTACLES + "  " + written
    lines = text.split("\n")
    items = completions(text, Position(len(lines) - 1, len(lines[-1])))
    assert "cm" in {c.label for c in items if c.kind == "unit"}
    assert [c.label for c in items if c.kind == "keyword"] == keywords


@pytest.mark.parametrize(("written", "offered"), [
    ("collision.hits[", ["wheel", "solar_panel", "chassis", "L1", "L2", "L3"]),
    ("collision.hits[L3, ", ["wheel", "solar_panel", "chassis"]),
    ("collision.hits[L3", ["wheel", "solar_panel", "chassis", "L1", "L2", "L3"]),
    ("wheel.slip[", ["FL", "FR", "RL", "RR"]),
    ("ref.wheel.slip[F", ["FL", "FR", "RL", "RR"]),
    ("speed[", []),                                    # no axis to select on
])
def test_a_selection_offers_the_labels_of_the_signals_axes(written: str,
                                                           offered: list[str]) -> None:
    assert labels_at_end(HEADER + "chance c = any over time (" + written) == offered
