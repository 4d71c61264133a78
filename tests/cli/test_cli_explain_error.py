"""``idefix-verify explain-error``: an explanation and a fix for every code the tool issues."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from idefix_rules.cli import main
from idefix_rules.diagnostic_codes import CODES

PACKAGE = Path(__file__).parents[2] / "idefix_rules"
_CODE = re.compile(r"""["']([CDEFHTW]\d{3})["']""")


def issued_codes() -> set[str]:
    """Every code string in the package's source (diagnostics are built with literal codes)."""
    found: set[str] = set()
    for path in PACKAGE.rglob("*.py"):
        if path.name == "diagnostic_codes.py":
            continue
        found |= set(_CODE.findall(path.read_text(encoding="utf-8")))
    return found


def test_every_issued_code_has_an_explanation():
    missing = sorted(issued_codes() - set(CODES))
    assert missing == []
    assert len(issued_codes()) >= 120


def test_every_explanation_is_complete():
    for code, entry in CODES.items():
        assert entry.code == code
        assert len(entry.explanation) > 40, code
        assert entry.example.strip() and entry.fix.strip(), code


@pytest.mark.parametrize("code", ["E201", "w610", "T005", "C002", "H011"])
def test_cli_prints_the_explanation(code, capsys):
    assert main(["explain-error", code]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{code.upper()}: ")
    assert "For example:" in out and "Fix:" in out


def test_unknown_code_exits_2_with_close_codes(capsys):
    assert main(["explain-error", "E2010"]) == 2
    err = capsys.readouterr().err
    assert "unknown diagnostic code 'E2010'" in err and "E201" in err


def test_list_names_every_code(capsys):
    assert main(["explain-error", "--list"]) == 0
    assert len(capsys.readouterr().out.strip().splitlines()) == len(CODES)
