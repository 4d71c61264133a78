"""Definitions and references of a rulebook's names, with their exact ranges.

The symbols an editor can jump between are constants, indices, chances and obstacle levels.
References are every :class:`~idefix_rules.rulebook.model.Name` that reads one (a constant in
a limit, an index in a prescreen, ``chance(hit_L3)`` in a verdict, a constant in a level's or
an area's sizes: ``steep above critical_inclination``) and, for obstacle levels, the labels of
tables (``{L1: 0.2, …}``), of selections (``collision.hits[L2]``) and the level of an area
(``area rim keep_out level L3``). The rule model keeps a span per declaration, not per declared
name, so the name is found in the source text right after the declaration's keyword.

>>> from idefix_rules.rulebook import parse_text
>>> text = '''rulebook "r" version "1.0.0" purpose "p"
... const lim = 5 cm
... index I_ds { value = max over time (max over wheels (wheel.sinkage)) limit = lim weight = 1 }
... verdict ok: require mean(I_ds) <= 0.5
... '''
>>> index = symbol_index(parse_text(text, "r.rules"), LineIndex(text))
>>> [(r.start.line, r.start.character) for r in index.symbols[("constant", "lim")].references]
[(2, 77)]
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass, field, fields, is_dataclass

from idefix_rules import signals
from idefix_rules.errors import Span
from idefix_rules.lsp.positions import LineIndex, Position, Range, span_range
from idefix_rules.rulebook.model import (
    Area,
    Chance,
    Constant,
    Expr,
    Index,
    Name,
    ObstacleLevel,
    Rulebook,
    Select,
    Table,
)
from idefix_rules.rulebook.types import ScopeKind

LEVEL_LABELS = signals.AXIS_LABELS["level"]
Declaration = Constant | Index | Chance | ObstacleLevel
_KEYWORDS = {"constant": "const", "index": "index", "chance": "chance", "level": "level"}


@dataclass
class Symbol:
    """A declared name: where it is declared and every place that reads it."""

    kind: str  # constant, index, chance, level
    name: str
    declaration: Declaration
    definition: Range
    references: list[Range] = field(default_factory=list)


@dataclass(frozen=True)
class NameUse:
    """A name read by an expression, and the context it is read in (for signals and the
    built-in names of command rules and verdicts)."""

    name: str
    range: Range
    scope: ScopeKind


@dataclass
class SymbolIndex:
    symbols: dict[tuple[str, str], Symbol] = field(default_factory=dict)
    names: list[NameUse] = field(default_factory=list)

    def symbol_at(self, position: Position) -> tuple[Symbol, Range] | None:
        """The symbol whose definition or one of whose references covers ``position``."""
        for symbol in self.symbols.values():
            for where in (symbol.definition, *symbol.references):
                if where.contains(position):
                    return symbol, where
        return None

    def name_at(self, position: Position) -> NameUse | None:
        return next((use for use in self.names if use.range.contains(position)), None)


def expressions(rulebook: Rulebook) -> Iterator[tuple[Expr, ScopeKind]]:
    """Every expression of a rulebook with the context the checker reads it in."""
    for constant in rulebook.constants:
        yield constant.value, "constant"
    for setting in rulebook.settings:
        yield setting.value, "constant"
    for level in rulebook.obstacle_levels:
        if level.below is not None:
            yield level.below, "constant"
        yield level.buffer, "constant"
    for area in rulebook.areas:
        if area.above is not None:
            yield area.above, "constant"
        yield area.buffer, "constant"
    for rule in rulebook.command_rules:
        yield rule.condition, "command"
    for index in rulebook.indices:
        yield index.value, "run"
        if index.nominal is not None:
            yield index.nominal, "constant"
        yield index.limit, "constant"
        yield index.weight, "constant"
        if index.map is not None:
            yield index.map, "run"
    for chance in rulebook.chances:
        yield chance.condition, "run"
    if rulebook.combine.confidence is not None:
        yield rulebook.combine.confidence, "constant"
    if rulebook.combine.indifference is not None:
        yield rulebook.combine.indifference, "constant"
    if rulebook.combine.verdict_indifference is not None:
        yield rulebook.combine.verdict_indifference, "constant"
    for prescreen in rulebook.prescreens:
        yield prescreen.condition, "prescreen"
    for verdict in rulebook.verdicts:
        yield verdict.condition, "path"
        if verdict.indifference is not None:
            yield verdict.indifference, "constant"
    for key in rulebook.ranking.keys:
        yield key.expr, "path"


def nodes(node: object) -> Iterator[object]:
    """``node`` and every expression node below it."""
    yield node
    if isinstance(node, tuple):
        for item in node:
            yield from nodes(item)
    elif is_dataclass(node) and not isinstance(node, type):
        for item in fields(node):
            if item.name != "span":
                yield from nodes(getattr(node, item.name))


def _declarations(rulebook: Rulebook) -> Iterator[tuple[str, Declaration]]:
    for constant in rulebook.constants:
        yield "constant", constant
    for index in rulebook.indices:
        yield "index", index
    for chance in rulebook.chances:
        yield "chance", chance
    for level in rulebook.obstacle_levels:
        yield "level", level


def _declared_name(declaration: Declaration) -> str:
    return declaration.level if isinstance(declaration, ObstacleLevel) else declaration.name


def _word(name: str) -> str:
    return rf"(?<![\w.]){re.escape(name)}(?![\w.])"


def _definition_range(kind: str, name: str, span: Span, lines: LineIndex) -> Range:
    """The declared name right after the declaration's keyword (the span starts there)."""
    whole = span_range(span)
    start = lines.offset(whole.start)
    pattern = re.compile(rf"{_KEYWORDS[kind]}\s+({_word(name)})")
    found = pattern.match(lines.text, start) or pattern.search(lines.text, start)
    if found is None or found.start(1) > lines.offset(whole.end):
        return whole
    return lines.range(found.start(1), found.end(1))


def _labels_in(text_range: Range, labels: tuple[str, ...], lines: LineIndex,
               suffix: str = "") -> Iterator[tuple[str, Range]]:
    """Ranges of the level labels written in a piece of the source (comments skipped)."""
    start, end = lines.offset(text_range.start), lines.offset(text_range.end)
    piece = re.sub(r"#[^\n]*", lambda m: " " * len(m.group()), lines.text[start:end])
    for label in labels:
        if label not in LEVEL_LABELS:
            continue
        for found in re.finditer(_word(label) + suffix, piece):
            yield label, lines.range(start + found.start(), start + found.start() + len(label))


def _area_level_range(area: Area, lines: LineIndex) -> Range | None:
    """The level label of an area (``level L3``): after its kind (and a steep area's
    inclination), before its buffer (comments skipped)."""
    after = span_range(area.above.span).end if area.above else span_range(area.span).start
    start = lines.offset(after)
    end = lines.offset(span_range(area.buffer.span).start)
    piece = re.sub(r"#[^\n]*", lambda m: " " * len(m.group()), lines.text[start:end])
    found = re.search(rf"(?<![\w.])level\s+({_word(area.level)})", piece)
    return None if found is None else lines.range(start + found.start(1), start + found.end(1))


def symbol_index(rulebook: Rulebook | None, lines: LineIndex) -> SymbolIndex:
    """Definitions, references and name uses of a parsed rulebook (empty without one)."""
    index = SymbolIndex()
    if rulebook is None:
        return index
    for kind, declaration in _declarations(rulebook):
        name = _declared_name(declaration)
        index.symbols.setdefault((kind, name), Symbol(
            kind, name, declaration, _definition_range(kind, name, declaration.span, lines)))
    by_name = {name: symbol for (kind, name), symbol in index.symbols.items() if kind != "level"}
    for expr, scope in expressions(rulebook):
        for node in nodes(expr):
            if isinstance(node, Name):
                where = span_range(node.span)
                index.names.append(NameUse(node.name, where, scope))
                if node.name in by_name:
                    by_name[node.name].references.append(where)
            elif isinstance(node, Select):
                brackets = Range(span_range(node.operand.span).end, span_range(node.span).end)
                for label, where in _labels_in(brackets, node.labels, lines):
                    if ("level", label) in index.symbols:
                        index.symbols[("level", label)].references.append(where)
            elif isinstance(node, Table):
                keys = tuple(label for label, _ in node.entries)
                for label, where in _labels_in(span_range(node.span), keys, lines, r"\s*:"):
                    if ("level", label) in index.symbols:
                        index.symbols[("level", label)].references.append(where)
    for area in rulebook.areas:
        level = index.symbols.get(("level", area.level))
        written = _area_level_range(area, lines)
        if level is not None and written is not None:
            level.references.append(written)
    for symbol in index.symbols.values():
        symbol.references.sort(key=lambda where: where.start)  # in source order
    return index
