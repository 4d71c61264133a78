"""Golden diagnostics: each ``golden/<case>.rules`` holds one kind of mistake, and
``golden/<case>.expected`` the exact output of ``idefix-verify check`` for it.

Regenerate after a deliberate change of messages with
``IDEFIX_UPDATE_GOLDEN=1 pytest tests/rulebook/test_rulebook_golden.py`` and review the diff.
Cases named ``strict_*`` are checked with ``--strict``.
"""

import os
from pathlib import Path

import pytest

from idefix_rules.cli.check import check_file, render_report

GOLDEN = Path(__file__).parent / "golden"
CASES = sorted(path.stem for path in GOLDEN.glob("*.rules"))
UPDATE = os.environ.get("IDEFIX_UPDATE_GOLDEN") == "1"


def rendered(case: str) -> tuple[str, int]:
    report = check_file(f"{case}.rules", strict=case.startswith("strict_"))
    return render_report(report) + "\n", len(report.diagnostics)


@pytest.mark.parametrize("case", CASES)
def test_golden_diagnostics(case, monkeypatch):
    monkeypatch.chdir(GOLDEN)  # paths in the output are relative: stable on every machine
    text, count = rendered(case)
    expected_path = GOLDEN / f"{case}.expected"
    if UPDATE:
        expected_path.write_text(text, encoding="utf-8")
    assert count > 0, f"golden case {case} should contain a mistake"
    assert text == expected_path.read_text(encoding="utf-8")


def test_every_expected_file_has_its_case():
    expected = {path.stem for path in GOLDEN.glob("*.expected")}
    assert expected == set(CASES)


def test_catalogue_covers_the_mistakes_the_language_promises_to_catch():
    wanted = {"syntax_missing_equals", "syntax_several_errors", "unknown_name",
              "dimension_mismatch", "weight_out_of_range", "duplicate_names",
              "reducer_over_wheels_on_time_signal", "missing_header", "missing_index",
              "missing_verdict", "bad_version", "limit_wrong_dimension", "window_on_wheels"}
    assert wanted <= set(CASES)


def test_several_syntax_errors_are_reported_in_one_run(monkeypatch):
    monkeypatch.chdir(GOLDEN)
    report = check_file("syntax_several_errors.rules")
    lines = [d.span.line for d in report.diagnostics]
    assert len(lines) >= 3 and lines == sorted(lines)
