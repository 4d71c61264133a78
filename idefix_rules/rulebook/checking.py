"""Checking rulebook text as a file or an open editor buffer: every diagnostic, never an
exception for a user mistake (``idefix-verify check`` prints these reports, the language server
publishes them)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from idefix_rules.errors import Diagnostic, Severity, UserInputError
from idefix_rules.rulebook import check_text, read_source


@dataclass(frozen=True)
class FileReport:
    """The outcome of checking one file: its diagnostics and its text (for carets)."""

    path: str
    diagnostics: tuple[Diagnostic, ...]
    source: str

    @property
    def errors(self) -> int:
        return sum(d.severity is Severity.ERROR for d in self.diagnostics)

    @property
    def warnings(self) -> int:
        return sum(d.severity is Severity.WARNING for d in self.diagnostics)


def check_file(path: str | Path, strict: bool = False) -> FileReport:
    """Read, parse and check one rulebook; never raises for a user mistake."""
    name = str(path)
    try:
        source = read_source(path)
    except UserInputError as failure:
        return FileReport(name, tuple(failure.diagnostics), "")
    return check_source(source, name, strict)


def check_source(source: str, name: str, strict: bool = False) -> FileReport:
    """Parse and check rulebook text read from ``name`` (an open editor buffer, a file)."""
    try:
        result = check_text(source, name, strict=strict)
    except UserInputError as failure:
        return FileReport(name, tuple(failure.diagnostics), source)
    return FileReport(name, tuple(result.diagnostics), source)
