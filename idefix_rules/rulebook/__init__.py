"""The rulebook language: parse → check → compile.

>>> from idefix_rules.rulebook import load_rulebook  # doctest: +SKIP
>>> rulebook = load_rulebook("rulebooks/idefix-ops.rules")  # doctest: +SKIP
"""

from __future__ import annotations

from pathlib import Path

from idefix_rules.errors import UserInputError, read_user_text
from idefix_rules.limits import MAX_RULEBOOK_BYTES, RULEBOOK_TOO_LARGE, check_file_size
from idefix_rules.rulebook.check import CheckedRulebook, CheckResult, check
from idefix_rules.rulebook.compile import CompiledRulebook, compile_rulebook
from idefix_rules.rulebook.derived import RunContext
from idefix_rules.rulebook.model import Rulebook
from idefix_rules.rulebook.results import PathStatistics, RunEvaluation, Verdict


def read_source(path: str | Path) -> str:
    """The text of a rulebook file; a missing, unreadable, non-UTF-8 or too large file is a
    user error."""
    check_file_size(path, MAX_RULEBOOK_BYTES, RULEBOOK_TOO_LARGE, "rulebook file")
    return read_user_text(path, "E002", "rulebook file")


def parse_text(text: str, path: str = "<rulebook>") -> Rulebook:
    """Parse rulebook text into the rule model (syntax errors raise ``UserInputError``)."""
    from idefix_rules.rulebook.parser import parse_rulebook

    return parse_rulebook(text, path)


def check_text(text: str, path: str = "<rulebook>", strict: bool = False) -> CheckResult:
    """Parse and check; raises ``UserInputError`` only for syntax errors. A structure problem
    (a repeated section, an index without a weight) is reported with the checker's findings on
    the rest of the file."""
    from idefix_rules.rulebook.parser import lower_rulebook

    rulebook, problems = lower_rulebook(text, path)
    return check(rulebook, strict=strict, structure=problems)


def load_checked(path: str | Path, strict: bool = False) -> CheckedRulebook:
    """Read, parse and check a rulebook file; every error of the file in one exception."""
    text = read_source(path)
    result = check_text(text, str(path), strict=strict)
    if result.checked is None:
        raise UserInputError(result.errors, {str(path): text})
    return result.checked


def load_rulebook(path: str | Path) -> Rulebook:
    """The checked rule model of a rulebook file."""
    return load_checked(path).rulebook


__all__ = [
    "CheckResult",
    "CheckedRulebook",
    "CompiledRulebook",
    "PathStatistics",
    "Rulebook",
    "RunContext",
    "RunEvaluation",
    "Verdict",
    "check",
    "check_text",
    "compile_rulebook",
    "load_checked",
    "load_rulebook",
    "parse_text",
    "read_source",
]
