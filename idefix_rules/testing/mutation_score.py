"""Mutation testing of a rulebook's cases: run every mutant against them and score.

A mutant is *killed* when at least one case of the rulebook's case files (all of them: the
cases are the rulebook's, not one file's) fails under it; it *survives* when every case still
passes: the cases would not notice that change of the rule. The score is the share of killed
mutants among the valid ones (a mutant the checker rejects, or one equal to the rulebook, is
skipped and listed, not scored).

>>> from idefix_rules.testing import load_case_file  # doctest: +SKIP
>>> report = score_mutants([load_case_file("rulebooks/tests/idefix-ops.yaml")])  # doctest: +SKIP
>>> report.score  # doctest: +SKIP
100.0
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from idefix_rules.rulebook.check import check
from idefix_rules.rulebook.compile import CompiledRulebook, compile_rulebook
from idefix_rules.testing.case_model import Case, CaseFile
from idefix_rules.testing.mutations import NUDGE, Mutant, mutants
from idefix_rules.testing.runner import run_case


@dataclass(frozen=True)
class MutantResult:
    """What became of one mutant: ``killed_by`` names the first case that failed
    (``FILE:LINE:COL CASE``); ``skipped`` says why it was not run."""

    mutant: Mutant
    killed_by: str | None = None
    skipped: str | None = None

    @property
    def survived(self) -> bool:
        return self.killed_by is None and self.skipped is None

    def to_dict(self) -> dict[str, Any]:
        m = self.mutant
        return {"kind": m.kind, "rule": m.rule, "category": m.category, "change": m.change,
                "location": str(m.span), "line": m.span.line, "column": m.span.column,
                "killed_by": self.killed_by, "skipped": self.skipped,
                "survived": self.survived}


@dataclass(frozen=True)
class MutationReport:
    """The mutants of one rulebook run against the cases of ``files``."""

    rulebook: str
    files: tuple[str, ...]
    results: tuple[MutantResult, ...]

    @property
    def scored(self) -> list[MutantResult]:
        return [r for r in self.results if r.skipped is None]

    @property
    def killed(self) -> int:
        return sum(r.killed_by is not None for r in self.results)

    @property
    def survivors(self) -> list[MutantResult]:
        return [r for r in self.results if r.survived]

    @property
    def score(self) -> float:
        """Killed mutants in percent of the valid ones (100 when there are none)."""
        scored = len(self.scored)
        return 100.0 * self.killed / scored if scored else 100.0

    def to_dict(self) -> dict[str, Any]:
        return {"rulebook": self.rulebook, "files": list(self.files),
                "mutants": len(self.scored), "killed": self.killed,
                "survived": len(self.survivors), "score": self.score,
                "skipped": [r.to_dict() for r in self.results if r.skipped is not None],
                "survivors": [r.to_dict() for r in self.survivors]}


def _first_failure(compiled: CompiledRulebook, cases: Sequence[Case]) -> str | None:
    for case in cases:
        if not run_case(compiled, case).passed:
            return f"{case.span} {case.name}"
    return None


def score_mutants(case_files: Sequence[CaseFile], nudge: float = NUDGE) -> MutationReport:
    """Run every mutant of the rulebook the ``case_files`` name (all the same rulebook)
    against all their cases."""
    if not case_files:
        raise ValueError("mutation testing needs at least one case file")
    original = case_files[0].checked.rulebook
    cases = [case for f in case_files for case in f.cases]
    results = []
    for mutant in mutants(original, nudge):
        if mutant.rulebook == original:
            results.append(MutantResult(mutant, skipped="the same rulebook"))
            continue
        checked = check(mutant.rulebook)
        if checked.checked is None:
            reason = checked.errors[0].message if checked.errors else "invalid"
            results.append(MutantResult(mutant, skipped=f"not a valid rulebook: {reason}"))
            continue
        killer = _first_failure(compile_rulebook(checked.checked), cases)
        results.append(MutantResult(mutant, killed_by=killer))
    return MutationReport(case_files[0].rulebook_path, tuple(f.path for f in case_files),
                          tuple(results))
