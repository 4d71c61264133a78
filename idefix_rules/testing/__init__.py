"""Testing rulebooks like code: example case files, a runner, rule coverage, mutations.

A *case file* (``rulebooks/tests/*.yaml``, format in ``docs/testing-rulebooks.md``) describes
short synthetic runs by a few keyframes with units and what the rulebook must say about them.
The pipeline is ``load_case_file → build runs → evaluate with the compiled rulebook → compare``:

>>> from idefix_rules.testing import load_case_file, run_case_file  # doctest: +SKIP
>>> outcome = run_case_file(load_case_file("rulebooks/tests/idefix-ops.yaml"))  # doctest: +SKIP
>>> outcome.passed  # doctest: +SKIP
True
"""

from __future__ import annotations

from idefix_rules.testing.case_model import Case, CaseFile
from idefix_rules.testing.casefile import discover_case_files, load_case_file
from idefix_rules.testing.runner import (
    CaseOutcome,
    FileOutcome,
    Mismatch,
    run_case,
    run_case_file,
)

__all__ = [
    "Case",
    "CaseFile",
    "CaseOutcome",
    "FileOutcome",
    "Mismatch",
    "discover_case_files",
    "load_case_file",
    "run_case",
    "run_case_file",
]
