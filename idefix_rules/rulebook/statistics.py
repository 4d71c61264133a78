"""Path statistics, the verdict and the ranking.

* Path risk (eq. 2): mean of I_max over the evaluated runs, with a Student-t interval at the
  rulebook's ``confidence`` (``mean ± t · s / √n``, clipped to [0, 1]; with one run the interval
  is the whole [0, 1]). Index means get the same interval; mean time and energy a Student-t
  interval (unclipped; a single run gives (-inf, inf)).
* Chances: the fraction of runs where the condition holds, with a Wilson score interval.
* Verdict rules are evaluated twice: on the point estimates (pass/fail) and on the intervals
  (three-valued: a comparison is *decided* when it holds, or fails, for every value in the
  intervals of the statistics it reads). A rule whose threshold lies strictly inside its
  statistic's interval is "not decided at this number of runs". The verdict is decided when every
  rule is, or when at least one rule fails decidedly (the path fails whatever the others say).
* Failed runs: unless a verdict rule reads ``failed`` itself, the verdict carries an extra rule
  ``no_failed_runs`` that fails when any run of the path failed, so a path with failed
  simulations never passes silently.
* Ranking: paths that pass come first, then the rest; within each group by the rulebook's keys
  (``rank by risk, time, energy`` by default; ``desc`` reverses a key), then by path name.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from idefix_rules.rulebook.fold import NotConstant, fold
from idefix_rules.rulebook.model import (
    Binary,
    Call,
    Expr,
    Name,
    Number,
    Rulebook,
    Select,
    Table,
    Unary,
)
from idefix_rules.rulebook.results import (
    Estimate,
    PathStatistics,
    RuleResult,
    RunEvaluation,
    Verdict,
)
from idefix_rules.rulebook.semantics import names_in
from idefix_rules.rulebook.types import FAILED_RUNS_RULE
from idefix_rules.units import percent_text

Interval = tuple[float, float]


def sample_mean(values: np.ndarray) -> float:
    """The mean, summed as deviations from the first value: n equal values average to that
    value exactly (``numpy.mean`` of seven runs at 0.7 is 0.7000000000000001, of three
    0.6999999999999998, so a verdict ``risk <= 70 %`` on runs exactly at the limit depended
    on the number of runs), and the sum of deviations loses fewer digits otherwise.

    >>> sample_mean(np.full(7, 0.7)), float(np.full(7, 0.7).mean())
    (0.7, 0.7000000000000001)
    """
    x = np.asarray(values, dtype=np.float64).ravel()
    if x.size == 0:
        return math.nan
    first = x[0]
    if not math.isfinite(first):
        return float(x.mean())
    return float(first + (x - first).mean())


def sample_std(values: np.ndarray, mean: float | None = None) -> float:
    """The sample standard deviation (n − 1) about :func:`sample_mean`: 0 for equal values."""
    x = np.asarray(values, dtype=np.float64).ravel()
    if x.size < 2:
        return 0.0
    centre = sample_mean(x) if mean is None else mean
    deviations = x - centre
    return float(math.sqrt(float(np.dot(deviations, deviations)) / (x.size - 1)))


def student_interval(samples: np.ndarray, confidence: float, bounds: Interval | None = None
                     ) -> Estimate:
    """Mean with a Student-t interval; ``bounds`` clips it (and stands in when n < 2)."""
    n = samples.size
    if n == 0:
        low, high = bounds or (-math.inf, math.inf)
        return Estimate(math.nan, low, high)
    mean = sample_mean(samples)
    if n < 2:
        low, high = bounds or (-math.inf, math.inf)
        return Estimate(mean, low, high)
    # Student's t quantile (what scipy.stats.t.ppf computes, without importing scipy.stats,
    # which takes a second; scipy.special takes a third of it)
    from scipy.special import stdtrit

    half = float(stdtrit(n - 1, 0.5 + confidence / 2) * sample_std(samples, mean) /
                 math.sqrt(n))
    low, high = mean - half, mean + half
    if bounds is not None:
        low, high = max(low, bounds[0]), min(high, bounds[1])
    return Estimate(mean, low, high)


def wilson_interval(successes: int, n: int, confidence: float) -> Estimate:
    """Fraction with its Wilson score interval; (nan, 0, 1) when there are no runs."""
    if n == 0:
        return Estimate(math.nan, 0.0, 1.0)
    from scipy.special import ndtri  # the normal quantile (scipy.stats.norm.ppf)

    z = float(ndtri(0.5 + confidence / 2))
    p = successes / n
    denominator = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denominator
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denominator
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == n else min(1.0, centre + half)
    return Estimate(p, low, high)


def path_statistics(evaluation: RunEvaluation, confidence: float,
                    failed_runs: int = 0) -> PathStatistics:
    """Statistics of one path from the evaluation of its Monte Carlo runs."""
    n = evaluation.runs
    unit = (0.0, 1.0)
    names = evaluation.index_names
    counts = np.bincount(evaluation.dominant.astype(int), minlength=len(names)) if n else \
        np.zeros(len(names), dtype=int)
    return PathStatistics(
        runs=n,
        failed_runs=int(failed_runs),
        confidence=confidence,
        risk=student_interval(evaluation.i_max, confidence, unit),
        risk_std=sample_std(evaluation.i_max),
        index_mean={k: student_interval(evaluation.values[k], confidence, unit) for k in names},
        index_max={k: float(evaluation.values[k].max()) if n else math.nan for k in names},
        chances={k: wilson_interval(int(evaluation.chances[k].sum()), n, confidence)
                 for k in evaluation.chance_names},
        time=student_interval(evaluation.time, confidence),
        energy=student_interval(evaluation.energy, confidence),
        dominant_counts={k: int(c) for k, c in zip(names, counts, strict=True)},
    )


# ----------------------------------------------------------------------------- path scope

def _statistic(expr: Expr, stats: PathStatistics) -> tuple[str, Estimate] | None:
    """The path statistic an expression names, with its interval (None: not a statistic)."""
    if isinstance(expr, Name):
        if expr.name == "risk":
            return "risk", stats.risk
        if expr.name == "time":
            return "time", stats.time
        if expr.name == "energy":
            return "energy", stats.energy
        if expr.name == "failed":
            if stats.failed is not None:
                return "failed", stats.failed
            f = stats.failed_fraction
            return "failed", Estimate(f, f, f)
        if expr.name == "runs":
            return "runs", Estimate(stats.runs, stats.runs, stats.runs)
        return None
    if isinstance(expr, Call) and len(expr.args) == 1 and isinstance(expr.args[0], Name):
        arg = expr.args[0].name
        if expr.function == "chance" and arg in stats.chances:
            return f"chance({arg})", stats.chances[arg]
        if expr.function == "mean" and arg in stats.index_mean:
            return f"mean({arg})", stats.index_mean[arg]
        if expr.function == "max" and arg in stats.index_max:
            value = stats.index_max[arg]
            return f"max({arg})", Estimate(value, value, value)
    return None


_Value = Any  # float, bool, Interval, or bool | None | NEAR
NEAR = "near"  # the fourth value of a condition on intervals: within the margin of a limit


def _evaluate(expr: Expr, stats: PathStatistics, constants: Mapping[str, Any],
              interval: bool, margin: float = 0.0) -> _Value:
    """Point (``interval=False``) or interval evaluation of a path expression. On intervals a
    condition is True or False when decided, None when not, and :data:`NEAR` when a
    comparison's two sides are confidently within ``margin`` of each other (and no other part
    decides it)."""
    found = _statistic(expr, stats)
    if found is not None:
        estimate = found[1]
        return (estimate.low, estimate.high) if interval else estimate.value
    if isinstance(expr, Number | Name | Select | Table):  # constants
        value = float(fold(expr, constants))  # type: ignore[arg-type]
        return (value, value) if interval else value
    def recurse(e: Expr) -> _Value:
        return _evaluate(e, stats, constants, interval, margin)
    if isinstance(expr, Unary):
        operand = recurse(expr.operand)
        if expr.op == "not":
            return operand if operand is None or operand is NEAR else not operand
        return (-operand[1], -operand[0]) if interval else -operand
    if isinstance(expr, Call):
        args = [recurse(a) for a in expr.args]
        return _call(expr.function, args, interval)
    if isinstance(expr, Binary):
        left, right = recurse(expr.left), recurse(expr.right)
        if interval and expr.op in _COMPARISONS:
            left, right = _against_zero(expr, stats, constants, left, right)
        return _binary(expr.op, left, right, interval, margin)
    raise ValueError(f"cannot evaluate {type(expr).__name__} on path statistics")


_COMPARISONS = ("<", "<=", ">", ">=", "==", "!=")


def _against_zero(expr: Binary, stats: PathStatistics, constants: Mapping[str, Any],
                  left: _Value, right: _Value) -> tuple[_Value, _Value]:
    """A chance (``chance(NAME)``, ``failed``) compared with exactly 0 is read on the runs
    themselves (``failed <= 0 %``: no run failed): no number of runs bounds a chance to 0,
    so on its bounds such a rule could never pass."""
    for side, other in ((expr.left, expr.right), (expr.right, expr.left)):
        found = _statistic(side, stats)
        if found is None or not (found[0] == "failed" or found[0].startswith("chance(")) \
                or _statistic(other, stats) is not None:
            continue
        try:
            limit = float(fold(other, constants))  # type: ignore[arg-type]
        except (NotConstant, TypeError, ValueError):
            continue
        if limit == 0.0:
            value = found[1].value
            exact = (value, value)
            return (exact, right) if side is expr.left else (left, exact)
    return left, right


def _call(function: str, args: list[_Value], interval: bool) -> _Value:
    if not interval:
        if function == "abs":
            return abs(args[0])
        if function == "sqrt":
            return math.sqrt(args[0]) if args[0] >= 0 else math.nan
        if function == "min":
            return min(args)
        if function == "max":
            return max(args)
        if function == "hypot":
            return math.hypot(args[0], args[1])
        if function == "clamp":
            return min(max(args[0], args[1]), args[2])
    else:
        lows, highs = [a[0] for a in args], [a[1] for a in args]
        if function == "abs":
            low, high = args[0]
            return (0.0 if low <= 0 <= high else min(abs(low), abs(high)),
                    max(abs(low), abs(high)))
        if function == "sqrt":
            return (math.sqrt(max(lows[0], 0.0)), math.sqrt(max(highs[0], 0.0)))
        if function == "min":
            return (min(lows), min(highs))
        if function == "max":
            return (max(lows), max(highs))
        if function == "clamp":
            return (min(max(lows[0], lows[1]), lows[2]), min(max(highs[0], highs[1]), highs[2]))
        if function == "hypot":  # grows with |a| and |b|: the corners nearest and farthest
            near = [0.0 if low <= 0 <= high else min(abs(low), abs(high))
                    for low, high in args]
            far = [max(abs(low), abs(high)) for low, high in args]
            return (math.hypot(*near), math.hypot(*far))
    raise ValueError(f"unknown function {function}")


def _binary(op: str, left: _Value, right: _Value, interval: bool,
            margin: float = 0.0) -> _Value:
    if op == "and":
        if not interval:
            return bool(left) and bool(right)
        if left is False or right is False:
            return False
        if left is None or right is None:
            return None
        return NEAR if NEAR in (left, right) else True
    if op == "or":
        if not interval:
            return bool(left) or bool(right)
        if left is True or right is True:
            return True
        if left is None or right is None:
            return None
        return NEAR if NEAR in (left, right) else False
    if not interval:
        return _POINT[op](left, right)
    (a, b), (c, d) = left, right
    if op == "+":
        return (a + c, b + d)
    if op == "-":
        return (a - d, b - c)
    if op in ("*", "/", "^"):
        corners = [_POINT[op](x, y) for x in (a, b) for y in (c, d)]
        corners = [v for v in corners if not math.isnan(v)] or [math.nan]
        if op == "/" and c <= 0 <= d and c != d:
            return (-math.inf, math.inf)
        return (min(corners), max(corners))
    # comparisons: decided when every value of the intervals gives the same answer
    decided = _compare(op, a, b, c, d)
    if decided is None and margin > 0 and op in ("<", "<=", ">", ">=") \
            and a - d > -margin and b - c < margin:
        return NEAR  # the two sides differ by less than the margin, whatever they are
    return decided


def _compare(op: str, a: float, b: float, c: float, d: float) -> bool | None:
    """A comparison of the intervals (a, b) and (c, d): True or False when every value of
    them gives that answer, else None."""
    always = _POINT[op](b, c) if op in ("<", "<=") else _POINT[op](a, d)
    never_op = {"<": ">=", "<=": ">", ">": "<=", ">=": "<"}.get(op)
    if never_op is not None:
        never = _POINT[never_op](a, d) if op in ("<", "<=") else _POINT[never_op](b, c)
        if always:
            return True
        return False if never else None
    if op == "==":
        if a == b == c == d:
            return True
        return False if (b < c or d < a) else None
    if a == b == c == d:
        return False
    return True if (b < c or d < a) else None


def _divide(a: float, b: float) -> float:
    if b == 0:
        return math.copysign(math.inf, a) if a else math.nan
    return a / b


def _power(a: float, b: float) -> float:
    try:
        return float(a ** b) if not (a < 0 and not float(b).is_integer()) else math.nan
    except (OverflowError, ZeroDivisionError):
        return math.inf


_POINT: dict[str, Callable[[float, float], Any]] = {
    "+": lambda a, b: a + b, "-": lambda a, b: a - b, "*": lambda a, b: a * b,
    "/": _divide, "^": _power,
    "<": lambda a, b: a < b, "<=": lambda a, b: a <= b, ">": lambda a, b: a > b,
    ">=": lambda a, b: a >= b, "==": lambda a, b: a == b, "!=": lambda a, b: a != b,
}


def _explain(expr: Expr, stats: PathStatistics, constants: Mapping[str, Any]
             ) -> tuple[str | None, float | None, Interval | None, float | None]:
    """For ``statistic OP threshold`` (either side): names and numbers for the report."""
    if isinstance(expr, Binary) and expr.op in ("<", "<=", ">", ">=", "==", "!="):
        for side, other in ((expr.left, expr.right), (expr.right, expr.left)):
            found = _statistic(side, stats)
            if found is not None and _statistic(other, stats) is None:
                name, estimate = found
                threshold = _evaluate(other, stats, constants, interval=False)
                return name, estimate.value, (estimate.low, estimate.high), float(threshold)
    return None, None, None, None


def verdict(rulebook: Rulebook, constants: Mapping[str, Any], stats: PathStatistics,
            margins: Mapping[str, float] | None = None) -> Verdict:
    """Every verdict rule on one path's statistics (plus ``no_failed_runs``, see module doc).
    ``margins``: each rule's indifference margin (SI); a rule whose statistic lies
    confidently within it of the limit, and is not decided otherwise, is *near* the limit:
    neither passed nor failed, and the path does not pass."""
    results = []
    for rule in rulebook.verdicts:
        margin = float((margins or {}).get(rule.name, 0.0))
        passed = bool(_evaluate(rule.condition, stats, constants, interval=False))
        judged = _evaluate(rule.condition, stats, constants, interval=True, margin=margin)
        near = judged is NEAR
        decided = judged is not None
        passed = passed and not near
        name, value, interval, threshold = _explain(rule.condition, stats, constants)
        state = "is within the margin of its limit" if near else \
            f"is not decided at {stats.runs} runs" if not decided else \
            "passes" if passed else "fails"
        message = f"verdict '{rule.name}' {state}"
        if name is not None and value is not None:
            message += f": {name} = {value:.4g}"
            if interval is not None:
                message += f" [{interval[0]:.4g}, {interval[1]:.4g}]"
            message += f", threshold {threshold:.4g}"
            if near:
                message += f" ± {margin:.4g}"
        if not decided:  # the bounds at the rulebook's confidence, family-wise (budget.py)
            message += f" (the threshold lies between the {percent_text(stats.confidence)} " \
                       "family-wise bounds)"
        results.append(RuleResult(rule.name, passed, decided, name, value, interval, threshold,
                                  rule.rationale, message, rule.condition.span, near, margin))
    reads_failed = any("failed" in names_in(rule.condition) for rule in rulebook.verdicts)
    if not reads_failed:
        passed = stats.failed_runs == 0
        results.append(RuleResult(
            FAILED_RUNS_RULE, passed, True, "failed", stats.failed_fraction, None, 0.0,
            "A path whose simulations failed cannot pass without the rulebook saying so",
            f"{stats.failed_runs} of {stats.runs + stats.failed_runs} runs failed"
            if not passed else "no run failed"))
    return Verdict(passed=all(r.passed for r in results), decided=verdict_decided(results),
                   rules=tuple(results))


def verdict_decided(rules: Sequence[RuleResult]) -> bool:
    """A verdict is decided when it passes with every rule decided, or when at least one rule
    fails decidedly or is near its limit (then the path does not pass)."""
    if any(not rule.passed and rule.decided for rule in rules):
        return True
    return all(rule.decided for rule in rules)


def rank(rulebook: Rulebook, constants: Mapping[str, Any],
         stats_by_path: Mapping[str, PathStatistics],
         margins: Mapping[str, float] | None = None) -> list[str]:
    """Path names, best first: passing paths, then the others; each by the rank keys."""
    def key(path: str) -> tuple[Any, ...]:
        stats = stats_by_path[path]
        values = []
        for rank_key in rulebook.ranking.keys:
            value = float(_evaluate(rank_key.expr, stats, constants, interval=False))
            if math.isnan(value):
                values.append(math.inf)  # unknown statistics rank last either way
            else:
                values.append(-value if rank_key.descending else value)
        passed = verdict(rulebook, constants, stats, margins).passed
        return (0 if passed else 1, *values, path)

    return sorted(stats_by_path, key=key)


def rank_key_intervals(rulebook: Rulebook, constants: Mapping[str, Any],
                       stats: PathStatistics) -> list[Interval]:
    """Each rank key's interval on one path's statistics, oriented so that lower ranks first
    (a ``desc`` key is negated): two paths' order by a key is settled when these are apart."""
    intervals = []
    for rank_key in rulebook.ranking.keys:
        low, high = _evaluate(rank_key.expr, stats, constants, interval=True)
        intervals.append((-high, -low) if rank_key.descending else (float(low), float(high)))
    return intervals
