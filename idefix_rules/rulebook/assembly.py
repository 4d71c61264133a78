"""Lowered declarations assembled into the rulebook: sections held to one, comments attached."""

from __future__ import annotations

from typing import Any

from lark import Token

from idefix_rules.errors import Diagnostic, Span, error
from idefix_rules.rulebook import model
from idefix_rules.rulebook.comments import attach_comments
from idefix_rules.rulebook.lowering import Section

REPEATED_SECTION = "E004"
MISSING_HEADER = "E500"

_SECTION_NAMES = {
    model.Header: "rulebook header",
    model.Combine: "combine",
    model.Ranking: "rank by",
    "settings": "settings",
    "obstacles": "obstacles",
}


def assemble(declarations: list[Any], comments: list[Token], text: str, path: str,
             diagnostics: list[Diagnostic]) -> model.Rulebook:
    """Group declarations into the rulebook; singletons checked; comments attached."""
    singles: dict[Any, Any] = {}
    lists: dict[type, list[Any]] = {kind: [] for kind in (
        model.Constant, model.CommandRule, model.Index, model.Chance, model.Prescreen,
        model.VerdictRule)}
    settings: list[model.Setting] = []
    levels: list[model.ObstacleLevel | model.Area] = []
    blocks: list[Section] = []
    for declaration in declarations:
        key: Any = declaration.kind if isinstance(declaration, Section) else type(declaration)
        if key in _SECTION_NAMES:
            if key in singles:
                first = singles[key].span
                diagnostics.append(error(
                    REPEATED_SECTION, f"'{_SECTION_NAMES[key]}' appears twice",
                    _first_line(declaration.span),
                    f"the first is on line {first.line}; merge them into one"))
                continue
            singles[key] = declaration
        if isinstance(declaration, Section):
            blocks.append(declaration)
            (settings if declaration.kind == "settings" else levels).extend(declaration.entries)
        elif type(declaration) in lists:
            lists[type(declaration)].append(declaration)
    header = singles.get(model.Header)
    if header is None:
        diagnostics.append(error(
            MISSING_HEADER, "the rulebook has no header", Span(path, 1, 1, 1, 2),
            'start the file with: rulebook "NAME" version "1.0.0" purpose "…"'))
        header = model.Header("", "", "")
    attached = attach_comments(
        [header, *lists[model.Constant], *settings,
         *(n for n in levels if isinstance(n, model.ObstacleLevel)),
         *(n for n in levels if isinstance(n, model.Area)), *lists[model.CommandRule],
         *lists[model.Index], *lists[model.Chance], singles.get(model.Combine),
         *lists[model.Prescreen], *lists[model.VerdictRule], singles.get(model.Ranking)],
        [(block.entries[0], block.entries[-1], block.span) for block in blocks
         if block.entries], comments, text)
    rulebook = model.Rulebook(
        header=attached.get(id(header), header),
        constants=tuple(attached.get(id(node), node) for node in lists[model.Constant]),
        settings=tuple(attached.get(id(node), node) for node in settings),
        obstacle_levels=tuple(attached.get(id(node), node) for node in levels
                              if isinstance(node, model.ObstacleLevel)),
        areas=tuple(attached.get(id(node), node) for node in levels
                    if isinstance(node, model.Area)),
        command_rules=tuple(attached.get(id(node), node) for node in lists[model.CommandRule]),
        indices=tuple(attached.get(id(node), node) for node in lists[model.Index]),
        chances=tuple(attached.get(id(node), node) for node in lists[model.Chance]),
        combine=attached.get(id(singles.get(model.Combine)), singles.get(model.Combine))
        or model.Combine(),
        prescreens=tuple(attached.get(id(node), node) for node in lists[model.Prescreen]),
        verdicts=tuple(attached.get(id(node), node) for node in lists[model.VerdictRule]),
        ranking=attached.get(id(singles.get(model.Ranking)), singles.get(model.Ranking))
        or model.DEFAULT_RANKING,
        trailing_comments=tuple(attached.get("trailing", ())),
        path=path,
        source=text,
    )
    return rulebook


def _first_line(span: Span) -> Span:
    return Span(span.path, span.line, span.column, span.line, span.column + 1)
