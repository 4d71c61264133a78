"""Rule coverage: did the cases bring each rule across its limit, near it, or never touch it?

For every command rule, index, chance, prescreen and verdict of the rulebook:

* ``across`` — the cases put the rule on both sides of its limit: an index below its limit in
  some run and at or beyond it in another; a condition true in some case and false in another.
  A change to that limit will show in at least one case.
* ``near`` — one side only, but some case came within a factor of 2 of the limit (an index
  between 50 % and 200 % of its limit; a comparison inside the condition whose two sides were
  within a factor of 2 of each other). A large change of the limit would show; a small one may
  not.
* ``untouched`` — no case came within a factor of 2: the cases say nothing about this limit.

Indices count the raw value against the limit in every run of every case; command rules every
command of every chain; chances every run; prescreens each case's first run (as the reference
run); verdicts each case's path statistics.

Coverage belongs to a rulebook, not to a case file: :func:`coverage_of_files` sums the cases of
every case file that names the same rulebook (one file may hold the calm cases, another the
edge cases), and :func:`by_rulebook` groups case files that way.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from idefix_rules.rulebook.across import finished
from idefix_rules.rulebook.compile import compile_rulebook
from idefix_rules.rulebook.expressions import ExpressionCompiler, Frame, signal_closure
from idefix_rules.rulebook.model import Binary, Expr, Reduce, Select, Unary
from idefix_rules.rulebook.named_values import (
    command_quantities,
    scope_closure,  # the compiler's own reader of named values
)
from idefix_rules.testing.runner import CaseOutcome, FileOutcome
from idefix_rules.testing.synthetic import build_runs

NEAR = 2.0  # within this factor of the limit counts as near
_COMPARISONS = ("<", "<=", ">", ">=")
_LABELS = {"across": "across", "near": "near only", "untouched": "never touched"}


@dataclass
class RuleCoverage:
    kind: str
    name: str
    state: str = "untouched"
    detail: str = ""
    cases: list[str] = field(default_factory=list)
    seen: set[bool] = field(default_factory=set)
    closest: float = float("inf")  # best |log2(ratio)| of a comparison or index, 0 = at limit

    @property
    def label(self) -> str:
        return _LABELS[self.state]

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "name": self.name, "state": self.state,
                "detail": self.detail, "cases": list(self.cases)}

    def note(self, case: str, outcomes: Iterable[bool], ratios: Iterable[float]) -> None:
        outcomes = list(outcomes)
        new = set(outcomes) - self.seen
        self.seen |= set(outcomes)
        closest = min((abs(float(np.log2(r))) for r in ratios if np.isfinite(r) and r > 0),
                      default=float("inf"))
        crossed = bool(new) and self.seen == {True, False}
        if (crossed or closest <= 1.0) and case not in self.cases:
            self.cases.append(case)
        self.closest = min(self.closest, closest)

    def finish(self) -> None:
        if self.seen == {True, False}:
            self.state = "across"
        elif self.closest <= np.log2(NEAR):
            self.state = "near"
        else:
            self.state = "untouched"
        if self.closest < float("inf"):
            self.detail = f"closest: {2 ** -self.closest:.2f}× or {2 ** self.closest:.2f}× " \
                          "the limit" if self.closest else "a case sat at the limit"
        outcomes = {True: "held", False: "did not hold"}
        if self.kind == "index":
            outcomes = {True: "reached", False: "stayed below"}
        if self.seen:
            self.detail = "; ".join(
                [", ".join(outcomes[o] for o in sorted(self.seen, reverse=True))] +
                ([self.detail] if self.detail else []))


def coverage_percent(items: Iterable[RuleCoverage]) -> float:
    """Share of rules brought across their limit, in percent (100 when there are none)."""
    items = list(items)
    return 100.0 * sum(i.state == "across" for i in items) / len(items) if items else 100.0


def _leaves(expr: Expr) -> Iterator[Binary]:
    """Comparisons inside a condition (not those nested in another comparison's side)."""
    if isinstance(expr, Binary):
        if expr.op in _COMPARISONS:
            yield expr
            return
        yield from _leaves(expr.left)
        yield from _leaves(expr.right)
    elif isinstance(expr, Unary | Select | Reduce):
        yield from _leaves(expr.operand)


def _ratios(left: Any, right: Any) -> list[float]:
    a, b = np.broadcast_arrays(np.abs(np.asarray(left, dtype=float)),
                               np.abs(np.asarray(right, dtype=float)))
    with np.errstate(all="ignore"):
        ratio = np.divide(a, b)
    keep = np.isfinite(ratio) & (ratio > 0)
    return [float(r) for r in ratio[keep].ravel()]


def by_rulebook(outcomes: Iterable[FileOutcome]) -> list[list[FileOutcome]]:
    """Case file outcomes grouped by the rulebook they name (the same file reached by two
    relative paths is one rulebook), in the order the rulebooks first appear."""
    groups: dict[str, list[FileOutcome]] = {}
    for outcome in outcomes:
        key = os.path.realpath(outcome.case_file.rulebook_path)
        groups.setdefault(key, []).append(outcome)
    return list(groups.values())


def coverage_of(outcome: FileOutcome) -> list[RuleCoverage]:
    """Coverage of every rule of a case file's rulebook by its cases alone."""
    return coverage_of_files([outcome])


def coverage_of_files(outcomes: Sequence[FileOutcome]) -> list[RuleCoverage]:
    """Coverage of every rule of one rulebook by the cases of all ``outcomes`` (case files that
    name that rulebook): a rule one file brings below its limit and another beyond it is
    **across**. With several files a case is named ``FILE:CASE`` (the file's name)."""
    if not outcomes:
        raise ValueError("coverage needs at least one case file")
    several = len(outcomes) > 1
    compiled = compile_rulebook(outcomes[0].case_file.checked)
    model = compiled.rulebook
    constants = compiled.constants
    scoped = ExpressionCompiler(constants, scope_closure)
    run_compiler = ExpressionCompiler(constants, signal_closure)
    items: dict[tuple[str, str], RuleCoverage] = {}
    for kind, rules in (("command", model.command_rules), ("index", model.indices),
                        ("chance", model.chances), ("prescreen", model.prescreens),
                        ("verdict", model.verdicts)):
        for rule in rules:
            items[(kind, rule.name)] = RuleCoverage(kind, rule.name)

    def leaf_ratios(condition: Expr, compiler: ExpressionCompiler, frame: Frame
                    ) -> list[float]:
        ratios: list[float] = []
        for leaf in _leaves(condition):
            ratios += _ratios(compiler.compile(leaf.left)(frame),
                              compiler.compile(leaf.right)(frame))
        return ratios

    cases = [(f"{Path(o.case_file.path).name}:{c.case.name}" if several else c.case.name, c)
             for o in outcomes for c in o.outcomes]
    for name, case_outcome in cases:
        _cover_commands(items, name, case_outcome, compiled, scoped, leaf_ratios)
        for index in model.indices:
            raw = case_outcome.evaluation.raw[index.name]
            limit = compiled.checked.limits[index.name]
            ratio = np.where(np.isnan(raw), np.inf, raw / limit)
            items[("index", index.name)].note(name, (ratio >= 1).tolist(),
                                              [float(r) for r in ratio])
        batch, context = build_runs(case_outcome.case, areas=compiled.area_signals)
        source = compiled.derived_signals(batch, context)
        # a chance may read path-level values (reductions over runs): computed first, over the
        # case's runs, as the evaluation does
        across = compiled.across_runs(batch, context, source=source) \
            if compiled.runs_reductions else None
        frame = Frame(source=source, across=finished(across) if across is not None else {})
        for chance in model.chances:
            items[("chance", chance.name)].note(
                name, case_outcome.evaluation.chances[chance.name].tolist(),
                leaf_ratios(chance.condition, run_compiler, frame))
        first = case_outcome.first
        scope: dict[str, Any] = {"risk": first.i_max, **first.values, **first.chances}
        failed = {f.rule for f in case_outcome.findings}
        for prescreen in model.prescreens:
            items[("prescreen", prescreen.name)].note(
                name, [prescreen.name not in failed],
                leaf_ratios(prescreen.condition, scoped, Frame(scope=scope)))
        results = {r.name: r for r in case_outcome.verdict.rules}
        for verdict in model.verdicts:
            result = results[verdict.name]
            ratios = []
            if result.value is not None and result.threshold:
                ratios = _ratios(result.value, result.threshold)
            items[("verdict", verdict.name)].note(name, [result.passed], ratios)
    for item in items.values():
        item.finish()
    return list(items.values())


def _cover_commands(items: Mapping[tuple[str, str], RuleCoverage], name: str,
                    case_outcome: CaseOutcome, compiled: Any, scoped: ExpressionCompiler,
                    leaf_ratios: Any) -> None:
    broken = {(v.rule, v.command_number) for v in case_outcome.violations}
    rover = build_runs(case_outcome.case)[1].rover
    for number, command in enumerate(case_outcome.case.chain, start=1):
        frame = Frame(scope=command_quantities(command, number, rover))
        for rule in compiled.rulebook.command_rules:
            items[("command", rule.name)].note(
                name, [(rule.name, number) not in broken],
                leaf_ratios(rule.condition, scoped, frame))
