"""Positions in a document: 0-based lines and character columns, and rulebook spans as ranges.

Rulebook spans (:class:`~idefix_rules.errors.Span`) count lines and columns from 1 with an
exclusive end column; the editor counts from 0. A :class:`Range` is the editor's view, still
in characters (the server converts to the client's UTF-16 or UTF-8 units).

>>> from idefix_rules.errors import Span
>>> span_range(Span("r.rules", 3, 5, 3, 9))
Range(start=Position(line=2, character=4), end=Position(line=2, character=8))
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass

from idefix_rules.errors import Span


@dataclass(frozen=True, order=True)
class Position:
    line: int
    character: int


@dataclass(frozen=True)
class Range:
    start: Position
    end: Position

    def contains(self, position: Position) -> bool:
        """Whether ``position`` lies in the range (its end included: a cursor just after a
        word still points at the word)."""
        return self.start <= position <= self.end

    def overlaps(self, other: Range) -> bool:
        return self.start <= other.end and other.start <= self.end


def span_range(span: Span | None) -> Range:
    """The range of a span; a span without an end covers one character, a span without a line
    (a problem of the whole file) the start of the file."""
    if span is None or span.line <= 0:
        origin = Position(0, 0)
        return Range(origin, origin)
    start = Position(span.line - 1, max(span.column, 1) - 1)
    if span.end_line <= 0 or (span.end_line, span.end_column) <= (span.line, span.column):
        return Range(start, Position(start.line, start.character + 1))
    return Range(start, Position(span.end_line - 1, max(span.end_column, 1) - 1))


class LineIndex:
    """Offsets into a text ↔ positions (lines split at ``\\n`` only, as the parser does)."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.starts = [0]
        for offset, char in enumerate(text):
            if char == "\n":
                self.starts.append(offset + 1)

    def offset(self, position: Position) -> int:
        if position.line >= len(self.starts):
            return len(self.text)
        start = self.starts[position.line]
        end = self.starts[position.line + 1] - 1 if position.line + 1 < len(self.starts) \
            else len(self.text)
        return min(start + position.character, end)

    def position(self, offset: int) -> Position:
        line = bisect.bisect_right(self.starts, offset) - 1
        return Position(line, offset - self.starts[line])

    def range(self, start: int, end: int) -> Range:
        return Range(self.position(start), self.position(end))

    def line_text(self, line: int) -> str:
        if line >= len(self.starts):
            return ""
        end = self.starts[line + 1] - 1 if line + 1 < len(self.starts) else len(self.text)
        return self.text[self.starts[line]:end]
