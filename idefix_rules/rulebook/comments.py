"""Keeping comments: which declaration each comment of a rulebook belongs to.

The parser collects comment tokens while lexing and calls :func:`attach_comments` once the
declarations are lowered. The result tags each comment with where it goes back (see
:mod:`~idefix_rules.rulebook.parser` for the forms); the formatter reads the tags.
"""

from __future__ import annotations

import dataclasses
import re
from typing import Any

from lark import Token

from idefix_rules.errors import Span
from idefix_rules.rulebook import model

_FIRST_WORD = re.compile(r"\s*([A-Za-z_]+|\})")
_BLOCK_ANCHORS = {
    model.Index: ("index", "value", "nominal", "limit", "weight", "map", "because", "}"),
    model.Combine: ("combine", "run", "path", "confidence", "}"),
    model.Header: ("rulebook", "purpose"),
}


def attach_comments(nodes: list[Any], blocks: list[tuple[Any, Any, Span]],
                    comments: list[Token], text: str) -> dict[Any, Any]:
    """Node id → the node with its comments; ``"trailing"`` → comments after everything.

    ``nodes`` are the commentable nodes, the header first; ``blocks`` the first and last entry
    and the span of each ``settings``/``obstacles`` block.
    """
    header = nodes[0]
    present = [node for node in nodes if node is not None and node.span.line > 0]
    present.sort(key=lambda node: (node.span.line, node.span.column))
    lines = text.split("\n")
    found: dict[int, list[str]] = {}
    trailing: list[str] = []
    for comment in comments:
        line, column = comment.line or 0, comment.column or 0
        body = str(comment).rstrip()
        own_line = not lines[line - 1][: column - 1].strip() if 0 < line <= len(lines) else True
        holder = None
        for node in present:
            span = node.span
            if (span.line, span.column) <= (line, column) and line <= span.end_line:
                holder = node
        if holder is not None:
            found.setdefault(id(holder), []).append(
                _inside_comment(holder, body, line, own_line, lines))
            continue
        closing = next((last for _, last, block_span in blocks
                        if (last.span.end_line, last.span.end_column) < (line, column)
                        and line < block_span.end_line), None)
        if closing is not None:  # after a block's last entry, before its `}`: stays inside
            found.setdefault(id(closing), []).append("@block$ " + body)
            continue
        following = next((node for node in present
                          if (node.span.line, node.span.column) > (line, column)), None)
        if present and following is present[0] and header in present:
            following = header  # comments above everything belong to the file: keep them first
        if following is None:
            trailing.append(body)
            continue
        prefix = ""
        for first_entry, _, block_span in blocks:
            if first_entry is following and (line, column) < (block_span.line,
                                                               block_span.column):
                prefix = "@block^ "
        found.setdefault(id(following), []).append(prefix + body)
    result: dict[Any, Any] = {}
    for node in present:
        if id(node) in found:
            result[id(node)] = dataclasses.replace(node, comments=tuple(found[id(node)]))
    result["trailing"] = trailing
    return result


def _inside_comment(node: Any, body: str, line: int, own_line: bool, lines: list[str]) -> str:
    """A comment within a declaration's lines, tagged with where it goes back."""
    anchors = _BLOCK_ANCHORS.get(type(node))
    if anchors is None:
        return f"@eol {body}"

    def anchor_of(number: int) -> str | None:
        line_text = lines[number - 1] if 0 < number <= len(lines) else ""
        first = _FIRST_WORD.match(line_text)
        word = first.group(1) if first else ""
        return word if word in anchors else None

    if own_line:
        for number in range(line + 1, node.span.end_line + 1):
            text = lines[number - 1].strip() if 0 < number <= len(lines) else ""
            if not text or text.startswith("#"):
                continue
            anchor = anchor_of(number)
            if anchor is not None:
                return f"@{anchor}^ {body}"
            break  # the next line goes on with an item's expression: the comment is in it
        else:
            return f"@{anchors[-1]}^ {body}"
    for number in range(line, node.span.line - 1, -1):
        anchor = anchor_of(number)
        if anchor is not None:
            return f"@{anchor} {body}"
    return f"@eol {body}"
