"""The rulebook language: parse → check → compile.

>>> from idefix_rules.rulebook import load_rulebook  # doctest: +SKIP
>>> rulebook = load_rulebook("rulebooks/idefix-ops.rules")  # doctest: +SKIP
"""

from __future__ import annotations

from pathlib import Path

from idefix_rules.errors import UserInputError, error
from idefix_rules.rulebook.check import CheckedRulebook, CheckResult, check
from idefix_rules.rulebook.compile import CompiledRulebook, compile_rulebook
from idefix_rules.rulebook.derived import RunContext
from idefix_rules.rulebook.model import Rulebook
from idefix_rules.rulebook.results import PathStatistics, RunEvaluation, Verdict


def read_source(path: str | Path) -> str:
    """The text of a rulebook file; a missing or unreadable file is a user error."""
    try:
        return Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UserInputError(error("E002", f"rulebook file not found: {path}")) from None
    except UnicodeDecodeError as failure:
        raise UserInputError(error("E002", f"{path}: not UTF-8 text ({failure.reason} at "
                                           f"byte {failure.start})")) from None
    except OSError as failure:
        raise UserInputError(error("E002", f"cannot read {path}: {failure.strerror}")) from None


def parse_text(text: str, path: str = "<rulebook>") -> Rulebook:
    """Parse rulebook text into the rule model (syntax errors raise ``UserInputError``)."""
    from idefix_rules.rulebook.parser import parse_rulebook

    return parse_rulebook(text, path)


def check_text(text: str, path: str = "<rulebook>", strict: bool = False) -> CheckResult:
    """Parse and check; raises ``UserInputError`` only for syntax errors."""
    return check(parse_text(text, path), strict=strict)


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
