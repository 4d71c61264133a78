"""Running cases: evaluate each case's runs with the compiled rulebook and compare.

Per-run expectations (``indices``, ``risk``, ``dominant``, ``chances``, ``prescreens``) read the
case's *first* run (prescreens treat it as a reference run); ``rejected`` reads the chain;
``verdict``, ``verdicts``, ``path_risk`` and ``decided`` read the path statistics of all the
case's runs. A mismatch says what was expected, what came out, the rule's text (with its place
in the rulebook) and where in the run the value came from.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from idefix_rules.rulebook.compile import CompiledRulebook, compile_rulebook
from idefix_rules.rulebook.expressions import (
    ExpressionCompiler,
    Frame,
    InternalError,
    per_run_sample,
    signal_closure,
)
from idefix_rules.rulebook.format import format_expr
from idefix_rules.rulebook.model import Binary, Call, Expr, Reduce, Select, Unary
from idefix_rules.rulebook.results import (
    CommandViolation,
    PathStatistics,
    PrescreenFinding,
    RunEvaluation,
    Verdict,
)
from idefix_rules.testing.case_model import Case, CaseFile, Expectation
from idefix_rules.testing.synthetic import build_runs


@dataclass(frozen=True)
class Mismatch:
    """One expectation that did not hold."""

    expectation: Expectation
    what: str
    expected: str
    actual: str
    rule: str | None = None
    where: str | None = None

    def render(self) -> str:
        lines = [f"{self.expectation.span}: {self.what}: expected {self.expected}, "
                 f"got {self.actual}"]
        if self.rule:
            lines.append(f"    rule: {self.rule}")
        if self.where:
            lines.append(f"    from: {self.where}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        return {"what": self.what, "expected": self.expected, "actual": self.actual,
                "rule": self.rule, "where": self.where, "location": str(self.expectation.span)}


@dataclass(frozen=True)
class CaseOutcome:
    """A case's results: the evaluation of its runs and the expectations that failed."""

    case: Case
    evaluation: RunEvaluation
    first: RunEvaluation
    t: np.ndarray
    violations: tuple[CommandViolation, ...]
    findings: tuple[PrescreenFinding, ...]
    statistics: PathStatistics
    verdict: Verdict
    mismatches: tuple[Mismatch, ...] = field(default=())

    @property
    def passed(self) -> bool:
        return not self.mismatches

    def to_dict(self) -> dict[str, Any]:
        return {"case": self.case.name, "location": str(self.case.span), "passed": self.passed,
                "mismatches": [m.to_dict() for m in self.mismatches]}


@dataclass(frozen=True)
class FileOutcome:
    case_file: CaseFile
    outcomes: tuple[CaseOutcome, ...]

    @property
    def passed(self) -> bool:
        return all(o.passed for o in self.outcomes)


def first_run(evaluation: RunEvaluation) -> RunEvaluation:
    """The first run of an evaluation, as an evaluation of one run."""
    def cut(mapping: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return {k: v[:1] for k, v in mapping.items()}

    e = evaluation
    return RunEvaluation(e.index_names, cut(e.values), cut(e.raw), cut(e.per_sample),
                         cut(e.weighted), e.i_max[:1], e.dominant[:1], e.dominant_sample[:1],
                         e.chance_names, cut(e.chances), e.time[:1], e.energy[:1])


def run_case(compiled: CompiledRulebook, case: Case) -> CaseOutcome:
    """Evaluate one case and compare every expectation."""
    batch, context = build_runs(case, areas=compiled.area_signals)
    evaluation = compiled.evaluate(batch, context)
    first = first_run(evaluation)
    violations = tuple(compiled.check_chain(case.chain, context.rover))
    findings = tuple(compiled.prescreen(first))
    stats = compiled.path_statistics(evaluation, case.failed_runs)
    verdict = compiled.verdict(stats)
    outcome = CaseOutcome(case, evaluation, first, np.asarray(batch["t"][0]), violations,
                          findings, stats, verdict)
    mismatches = []
    for expectation in case.expectations:
        found = _COMPARE[expectation.kind](compiled, outcome, expectation)
        if found is not None:
            mismatches.append(found)
    return CaseOutcome(case, evaluation, first, outcome.t, violations, findings, stats,
                       verdict, tuple(mismatches))


def run_case_file(case_file: CaseFile,
                  compiled: CompiledRulebook | None = None) -> FileOutcome:
    """Every case of a file (the rulebook compiled once)."""
    compiled = compiled or compile_rulebook(case_file.checked)
    return FileOutcome(case_file, tuple(run_case(compiled, case) for case in case_file.cases))


# ----------------------------------------------------------------------------- rule texts

def _located(compiled: CompiledRulebook, span: Any) -> str:
    line = getattr(span, "line", 0)
    return f"  ({compiled.rulebook.path}:{line})" if line else ""


def index_text(compiled: CompiledRulebook, name: str) -> str:
    """``I_s = percentile 95 over time (…) / critical_slip (0.7)``, with its place."""
    index = next(i for i in compiled.rulebook.indices if i.name == name)
    limit = compiled.checked.limits[name]
    nominal = compiled.checked.nominals.get(name)
    nominal_text = "" if index.nominal is None or nominal is None else \
        f"nominal = {format_expr(index.nominal)} (= {nominal:.6g} SI); "
    return (f"index {name}: value = {format_expr(index.value)}; {nominal_text}limit = "
            f"{format_expr(index.limit)} (= {limit:.6g} SI); weight = "
            f"{compiled.checked.weights[name]:g}{_located(compiled, index.span)}")


def condition_text(compiled: CompiledRulebook, kind: str, name: str) -> str:
    model = compiled.rulebook
    groups = {"command": model.command_rules, "chance": model.chances,
              "prescreen": model.prescreens, "verdict": model.verdicts}
    rule = next((r for r in groups[kind] if r.name == name), None)
    if rule is None:
        return f"{kind} {name} (added by the evaluator)"
    return f"{kind} {name}: {format_expr(rule.condition)}{_located(compiled, rule.span)}"


def _time(outcome: CaseOutcome, sample: int) -> str:
    return f"t = {float(outcome.t[sample]):g} s (sample {sample})"


def _index_where(compiled: CompiledRulebook, outcome: CaseOutcome, name: str) -> str:
    first = outcome.first
    raw = float(first.raw[name][0])
    found = compiled.checked.index_types.get(name)
    unit = "" if found is None or found.dimension.is_dimensionless else f" {found.dimension}"
    limit = compiled.checked.limits[name]
    nominal = compiled.checked.nominals.get(name)
    against = f"the limit {limit:.6g}{unit}" if nominal is None else \
        f"the nominal {nominal:.6g}{unit} (0.5) and the limit {limit:.6g}{unit} (1)"
    text = f"run 1: raw value {raw:.6g}{unit} against {against}" \
        if np.isfinite(raw) else \
        "run 1: its signals hold NaN or inf (the index counts as 1)"
    per_sample = first.per_sample[name]
    if per_sample.shape[1]:
        sample = int(np.argmax(per_sample[0]))
        scale = "of the limit" if nominal is None else "on the index's 0..1 scale"
        text += f"; per-sample value peaks at {_time(outcome, sample)}: " \
                f"{float(per_sample[0, sample]):.4g} {scale}"
    return text


# ----------------------------------------------------------------------------- comparisons

def _in(value: float, expected: tuple[float, float]) -> bool:
    low, high = expected
    return bool(low - 1e-12 <= value <= high + 1e-12)


def _index(compiled: CompiledRulebook, outcome: CaseOutcome, e: Expectation) -> Mismatch | None:
    assert e.name is not None
    value = float(outcome.first.values[e.name][0])
    if _in(value, e.expected):
        return None
    return Mismatch(e, f"index {e.name}", e.text, f"{value:.6g}", index_text(compiled, e.name),
                    _index_where(compiled, outcome, e.name))


def _dominant_where(compiled: CompiledRulebook, outcome: CaseOutcome) -> str:
    first = outcome.first
    name = first.index_names[int(first.dominant[0])]
    weighted = ", ".join(f"{n} {float(first.weighted[n][0]):.3g}" for n in first.index_names)
    return (f"run 1: I_max = {float(first.i_max[0]):.4g} from {name} at "
            f"{_time(outcome, int(first.dominant_sample[0]))}; weighted indices: {weighted}")


def _risk(compiled: CompiledRulebook, outcome: CaseOutcome, e: Expectation) -> Mismatch | None:
    value = float(outcome.first.i_max[0])
    if _in(value, e.expected):
        return None
    return Mismatch(e, "run risk I_max", e.text, f"{value:.6g}",
                    "I_max = max over indices of weight × index (eq. 1)",
                    _dominant_where(compiled, outcome))


def _dominant(compiled: CompiledRulebook, outcome: CaseOutcome,
              e: Expectation) -> Mismatch | None:
    first = outcome.first
    name = first.index_names[int(first.dominant[0])]
    if name == e.expected:
        return None
    return Mismatch(e, "dominant index", e.text, name, index_text(compiled, e.expected),
                    _dominant_where(compiled, outcome))


def _chance(compiled: CompiledRulebook, outcome: CaseOutcome, e: Expectation) -> Mismatch | None:
    assert e.name is not None
    held = bool(outcome.first.chances[e.name][0])
    if held == e.expected:
        return None
    return Mismatch(e, f"chance {e.name}", e.text, "holds" if held else "does not hold",
                    condition_text(compiled, "chance", e.name),
                    _chance_where(compiled, outcome, e.name))


def _time_reduction(expr: Expr) -> Reduce | None:
    """The first reduction over time inside a condition (depth first)."""
    if isinstance(expr, Reduce) and expr.domain == "time":
        return expr
    children: tuple[Expr, ...] = ()
    if isinstance(expr, Binary):
        children = (expr.left, expr.right)
    elif isinstance(expr, Unary | Select | Reduce):
        children = (expr.operand,)
    elif isinstance(expr, Call):
        children = expr.args
    for child in children:
        found = _time_reduction(child)
        if found is not None:
            return found
    return None


def _chance_where(compiled: CompiledRulebook, outcome: CaseOutcome, name: str) -> str:
    """Run 1, and where the chance's time reduction found its value: the sample where its
    operand peaks (or first holds, for a condition)."""
    chance = next(c for c in compiled.rulebook.chances if c.name == name)
    reduction = _time_reduction(chance.condition)
    if reduction is None:
        return "run 1"
    batch, context = build_runs(outcome.case, areas=compiled.area_signals)
    frame = Frame(source=compiled.derived_signals(batch, context))
    compiler = ExpressionCompiler(compiled.constants, signal_closure)
    try:
        series = per_run_sample(compiler.compile(reduction.operand)(frame), outcome.case.runs,
                                len(outcome.t))[0]
    except InternalError:  # the operand still has wheel/part axes: no single series
        return "run 1"
    operand = format_expr(reduction.operand)
    if reduction.reducer in ("any", "all", "count"):
        true = np.flatnonzero(series > 0)
        if not true.size:
            return f"run 1: {operand} never holds"
        return f"run 1: {operand} first holds at {_time(outcome, int(true[0]))}"
    pick = int(np.argmin(series)) if reduction.reducer == "min" else int(np.argmax(series))
    word = "lowest" if reduction.reducer == "min" else "highest"
    return (f"run 1: {operand} is {word} at {_time(outcome, pick)}: "
            f"{float(series[pick]):.6g} (SI)")


def _prescreen(compiled: CompiledRulebook, outcome: CaseOutcome,
               e: Expectation) -> Mismatch | None:
    found = next((f for f in outcome.findings if f.rule == e.name), None)
    passed = found is None
    if passed == e.expected:
        return None
    first = outcome.first
    values = ", ".join(f"{n} {float(first.values[n][0]):.3g}" for n in first.index_names)
    where = found.message if found is not None else \
        f"run 1 as the reference run: risk {float(first.i_max[0]):.3g}; {values}"
    assert e.name is not None
    return Mismatch(e, f"prescreen {e.name}", e.text, "pass" if passed else "fail",
                    condition_text(compiled, "prescreen", e.name), where)


def _rejected(compiled: CompiledRulebook, outcome: CaseOutcome,
              e: Expectation) -> Mismatch | None:
    got: dict[str, list[int]] = {}
    for violation in outcome.violations:
        got.setdefault(violation.rule, []).append(violation.command_number)
    expected: dict[str, tuple[int, ...]] = e.expected
    same = set(got) == set(expected) and all(
        not numbers or tuple(got[rule]) == numbers for rule, numbers in expected.items())
    if same:
        return None
    actual = ", ".join(f"{rule} (command {', '.join(map(str, numbers))})"
                       for rule, numbers in got.items()) or "none"
    rules = sorted(set(got) ^ set(expected)) or sorted(expected)
    text = "; ".join(condition_text(compiled, "command", rule) for rule in rules)
    where = "; ".join(v.message for v in outcome.violations) or \
        "every command of the chain satisfies every command rule"
    return Mismatch(e, "command rules rejecting the chain", e.text, actual, text, where)


def _verdict(compiled: CompiledRulebook, outcome: CaseOutcome,
             e: Expectation) -> Mismatch | None:
    passed = outcome.verdict.passed
    if passed == e.expected:
        return None
    rules = outcome.verdict.failed_rules if not passed else outcome.verdict.rules
    return Mismatch(e, "verdict", e.text, "pass" if passed else "fail",
                    "; ".join(condition_text(compiled, "verdict", r.name) for r in rules),
                    f"{outcome.statistics.runs} runs: " + "; ".join(r.message for r in rules))


def _verdict_rule(compiled: CompiledRulebook, outcome: CaseOutcome,
                  e: Expectation) -> Mismatch | None:
    rule = next((r for r in outcome.verdict.rules if r.name == e.name), None)
    assert e.name is not None
    if rule is None:
        return Mismatch(e, f"verdict rule {e.name}", e.text, "not evaluated")
    if rule.passed == e.expected:
        return None
    return Mismatch(e, f"verdict rule {e.name}", e.text, "pass" if rule.passed else "fail",
                    condition_text(compiled, "verdict", e.name),
                    f"{outcome.statistics.runs} runs: {rule.message}")


def _path_risk(compiled: CompiledRulebook, outcome: CaseOutcome,
               e: Expectation) -> Mismatch | None:
    risk = outcome.statistics.risk
    if _in(risk.value, e.expected):
        return None
    return Mismatch(e, "path risk (mean I_max)", e.text, f"{risk.value:.6g}",
                    "path risk = mean of I_max over the runs (eq. 2)",
                    f"{outcome.statistics.runs} runs, interval [{risk.low:.4g}, {risk.high:.4g}]")


def _decided(compiled: CompiledRulebook, outcome: CaseOutcome,
             e: Expectation) -> Mismatch | None:
    decided = outcome.verdict.decided
    if decided == e.expected:
        return None
    undecided = [r.message for r in outcome.verdict.rules if not r.decided]
    return Mismatch(e, "verdict decided", e.text, "decided" if decided else "not decided",
                    None, "; ".join(undecided) or f"{outcome.statistics.runs} runs")


_COMPARE: dict[str, Callable[[CompiledRulebook, CaseOutcome, Expectation], Mismatch | None]] = {
    "index": _index, "risk": _risk, "dominant": _dominant, "chance": _chance,
    "prescreen": _prescreen, "rejected": _rejected, "verdict": _verdict,
    "verdict_rule": _verdict_rule, "path_risk": _path_risk, "decided": _decided,
}
