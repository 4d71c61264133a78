"""Diagnostics and the project's exception root.

Every user mistake (bad rulebook, bad campaign, missing FMU variable, bad terrain file) is raised
as a :class:`UserInputError` carrying :class:`Diagnostic` records. The CLI catches
:class:`IdefixError` only, prints the diagnostics and exits with the error's ``exit_code``.

>>> span = Span("r.rules", 3, 5)
>>> d = Diagnostic("E101", Severity.ERROR, "unknown name 'slp'", span)
>>> d.location()
'r.rules:3:5'
"""

from __future__ import annotations

import enum
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any


class Severity(enum.Enum):
    ERROR = "error"
    WARNING = "warning"


@dataclass(frozen=True)
class Span:
    """Where something is in a source file; lines and columns count from 1."""

    path: str
    line: int = 0
    column: int = 0
    end_line: int = 0
    end_column: int = 0

    def __str__(self) -> str:
        if self.line <= 0:
            return self.path
        return f"{self.path}:{self.line}:{self.column}"


@dataclass(frozen=True)
class Diagnostic:
    """One finding about user input, as data (rendering happens in the CLI)."""

    code: str
    severity: Severity
    message: str
    span: Span | None = None
    hint: str | None = None
    # Secondary places, each with a short label ("used here"), shown after the main caret.
    related: tuple[tuple[str, Span], ...] = ()

    def location(self) -> str:
        return str(self.span) if self.span is not None else "<input>"

    def to_dict(self) -> dict[str, Any]:
        span = self.span
        return {
            "code": self.code,
            "severity": self.severity.value,
            "message": self.message,
            "path": span.path if span else None,
            "line": span.line if span else None,
            "column": span.column if span else None,
            # end_column is exclusive (the column just after the last character), as in Span
            "end_line": span.end_line if span and span.end_line > 0 else None,
            "end_column": span.end_column if span and span.end_line > 0 else None,
            "hint": self.hint,
            **({"related": [{"label": label, "path": where.path, "line": where.line,
                             "column": where.column} for label, where in self.related]}
               if self.related else {}),
        }

    def format(self, source: str | None = None) -> str:
        """``path:line:col: severity[code]: message`` then the source line and a caret."""
        head = f"{self.location()}: {self.severity.value}[{self.code}]: {self.message}"
        lines = [head, *_caret(self.span, source)]
        for label, where in self.related:
            lines.append(f"    {where}: note: {label}")
            lines += ["  " + line for line in _caret(where, source
                                                     if self.span is None
                                                     or where.path == self.span.path
                                                     else None)]
        if self.hint:
            lines.append(f"    hint: {self.hint}")
        return "\n".join(lines)


def _caret(span: Span | None, source: str | None) -> list[str]:
    """The source line of ``span`` and a caret under it (nothing when unknown)."""
    if span is None or span.line <= 0:
        return []
    text = source if source is not None else _read_quietly(span.path)
    if text is None:
        return []
    source_lines = text.splitlines()
    if span.line > len(source_lines):
        return []
    src = source_lines[span.line - 1].expandtabs(1)
    col = max(span.column, 1)
    width = 1
    if span.end_line == span.line and span.end_column > col:
        width = span.end_column - col
    src, col, width = _clip(src, col, width)
    # columns on the terminal: a wide character (CJK) takes two, a combining mark none
    pad = _display_width(src[:col - 1])
    carets = max(1, _display_width(src[col - 1:col - 1 + width]))
    return [f"    {src}", "    " + " " * pad + "^" * carets]


def _display_width(text: str) -> int:
    """Terminal columns ``text`` takes.

    >>> _display_width("abc"), _display_width("滑り"), _display_width("e\u0301")
    (3, 4, 1)
    """
    import unicodedata

    return sum(0 if unicodedata.combining(char) else
               2 if unicodedata.east_asian_width(char) in ("W", "F") else 1 for char in text)


# Source lines longer than this are shown as a window around the caret (a generated or
# pathological line can be megabytes long).
SHOWN_LINE = 160


def _clip(line: str, column: int, width: int) -> tuple[str, int, int]:
    """``line`` cut to :data:`SHOWN_LINE` characters around ``column`` (``…`` marks cuts)."""
    if len(line) <= SHOWN_LINE:
        return line, column, width
    start = max(0, min(column - 1 - SHOWN_LINE // 4, len(line) - SHOWN_LINE))
    shown = line[start:start + SHOWN_LINE]
    prefix = "…" if start > 0 else ""
    suffix = "…" if start + SHOWN_LINE < len(line) else ""
    column = column - start + len(prefix)
    width = max(1, min(width, SHOWN_LINE - (column - 1 - len(prefix))))
    return prefix + shown + suffix, column, width


def read_user_text(path: str | Path, code: str, what: str) -> str:
    """The text of a file the user named (universal newlines, BOM kept for the caller).

    A missing file, a folder, an unreadable file or bytes that are not UTF-8 raise
    :class:`UserInputError` naming the file (and the line and column of the first bad byte).
    """
    name = str(path)
    try:
        raw = Path(path).read_bytes()
    except FileNotFoundError:
        raise UserInputError(error(code, f"{what} not found: {name}", Span(name))) from None
    except IsADirectoryError:
        raise UserInputError(error(code, f"{what} expected, but {name} is a folder",
                                   Span(name))) from None
    except OSError as failure:
        raise UserInputError(error(code, f"cannot read {what} {name}: "
                                         f"{failure.strerror or failure}", Span(name))) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as failure:
        before = raw[:failure.start]
        line = before.count(b"\n") + 1
        # columns count characters, as in every other diagnostic
        column = len(before[before.rfind(b"\n") + 1:].decode("utf-8", "replace")) + 1
        raise UserInputError(error(
            code, f"{what} is not UTF-8 text (byte 0x{raw[failure.start]:02x}: {failure.reason})",
            Span(name, line, column), hint="save the file as UTF-8")) from None
    return text.replace("\r\n", "\n").replace("\r", "\n")


def _read_quietly(path: str) -> str | None:
    try:
        return Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return None


class IdefixError(Exception):
    """Root of every error this project raises on purpose."""

    exit_code = 3

    def render(self) -> str:
        return str(self)


class UserInputError(IdefixError):
    """Invalid input or usage: exit code 2, one or more diagnostics."""

    exit_code = 2

    def __init__(self, diagnostics: Sequence[Diagnostic] | Diagnostic | str,
                 sources: dict[str, str] | None = None) -> None:
        if isinstance(diagnostics, str):
            diagnostics = [Diagnostic("E000", Severity.ERROR, diagnostics)]
        elif isinstance(diagnostics, Diagnostic):
            diagnostics = [diagnostics]
        self.diagnostics: list[Diagnostic] = list(diagnostics)
        self.sources = dict(sources or {})
        first = self.diagnostics[0] if self.diagnostics else None
        summary = f"{first.location()}: {first.message}" if first else "invalid input"
        more = len(self.diagnostics) - 1
        if more > 0:
            summary += f" (and {more} more)"
        super().__init__(summary)

    def render(self) -> str:
        return render_diagnostics(self.diagnostics, self.sources)


class VerificationFailure(IdefixError):
    """A path or expectation failed: exit code 1."""

    exit_code = 1


class InfrastructureError(IdefixError):
    """Simulation or internal infrastructure broke: exit code 3."""

    exit_code = 3


def render_diagnostics(diagnostics: Iterable[Diagnostic],
                       sources: dict[str, str] | None = None) -> str:
    sources = sources or {}
    parts = []
    for diagnostic in diagnostics:
        source = sources.get(diagnostic.span.path) if diagnostic.span else None
        parts.append(diagnostic.format(source))
    return "\n".join(parts)


def error(code: str, message: str, span: Span | None = None, hint: str | None = None) -> Diagnostic:
    return Diagnostic(code, Severity.ERROR, message, span, hint)


def warning(code: str, message: str, span: Span | None = None,
            hint: str | None = None) -> Diagnostic:
    return Diagnostic(code, Severity.WARNING, message, span, hint)


def unique_diagnostics(diagnostics: Iterable[Diagnostic]) -> list[Diagnostic]:
    """The diagnostics in their order, each (code, message, place) once."""
    seen: set[tuple[str, str, Span | None]] = set()
    unique = []
    for diagnostic in diagnostics:
        key = (diagnostic.code, diagnostic.message, diagnostic.span)
        if key not in seen:
            seen.add(key)
            unique.append(diagnostic)
    return unique
