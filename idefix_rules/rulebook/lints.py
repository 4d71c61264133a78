"""Lints of ``check --strict``: rules that are valid but almost certainly not what was meant.

* **W610** a ratio written as a bare number above 1 where a percentage is meant:
  ``require risk <= 70`` (7000 %), ``const critical_slip = 50`` as the limit of a slip index.
* **W611** a comparison that is always true or always false over the declared range of what it
  compares: ``risk <= 150 %`` (risk lies in [0, 1]), ``abs(delta_heading) >= 0 deg``,
  ``I_obs <= 1`` in a prescreen.
* **W612** a number in a ``because`` that disagrees with the value it explains, rounded to the
  digits it writes: ``const critical_slip = 65 % because "Slip above 70 % is critical"``.
* **W613** a literal that is a denormal or 0 in SI once its unit's scale is applied: ``1e-320``,
  ``5e-324 mm`` (one a double cannot hold at all, ``1e-400 %``, is refused by the parser: E003).
* **W614** an index's nominal within 10 % of the limit from 0 or from the limit: half of the
  index's range is crossed in a tenth of the value's, so the index is nearly a step.
* **W615** ``before Q`` with Q at or below 0 s: a window that holds no sample.
* **W616** ``percentile P`` with P strictly between 0 and 1: a percentile near the minimum,
  almost certainly a fraction written where the percent number was meant (``percentile 0.95``
  for ``percentile 95``).

Each lint is a pass of the checker (same shape as :data:`~.check.STRICT_CHECKS`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any

from idefix_rules.errors import Diagnostic, Span, warning
from idefix_rules.rulebook.fold import NotConstant, fold, folded_number, number_si
from idefix_rules.rulebook.model import (
    Binary,
    Call,
    Expr,
    Name,
    Number,
    Reduce,
    Rulebook,
    Select,
)
from idefix_rules.rulebook.walk import nodes, rulebook_expressions, windowed
from idefix_rules.signals import area_signal
from idefix_rules.units import DIMENSIONLESS, Dimension, UnitError, parse_quantity, parse_unit

if TYPE_CHECKING:
    from idefix_rules.rulebook.environment import CheckEnv

# Quantities that are fractions (0..1, shown as %): where a bare 70 means 7000 %.
RATIO_SIGNALS = frozenset({"wheel.slip", "ref.wheel.slip"})
RATIO_PATH_NAMES = frozenset({"risk", "failed"})
NON_NEGATIVE = frozenset({
    "collision.hits", "collision.buffer", "collision.contact", "collision.clearance",
    "wheel.sinkage", "global_error", "local_error", "drift", "tolerance_radius", "energy",
    "stuck", "t", "duration", "wheel_speed", "lateral_acceleration", "forward_acceleration",
    "command_number",
    "time", "runs", "failed", "risk"})
# Flags: 0 or 1 in every sample (stuck, a chain done, inside a named area or its buffer).
FLAG_SIGNALS = frozenset({"stuck", "chain_done", "done"})
# Counted from 1: the number of a command in its chain.
FROM_ONE = frozenset({"command_number"})
# Non-negative in runs only: the planar speed of a run (a command's speed is signed).
RUN_NON_NEGATIVE = frozenset({"speed"})
_COMPARISONS = {"<", "<=", ">", ">="}
_TRIGGER = re.compile(
    r"(?:above|below|over|under|beyond|exceed\w*|than|at most|at least|up to|limit(?:ed)?"
    r"(?: of| to| is| at)?|maximum|minimum|[<>≤≥]=?)\s+(-?\d+(?:\.\d+)?(?:[eE]-?\d+)?)"
    r"(?![\d.]*\.\d)"  # a version (1.0.0, 10.2.1) is no number
    r"(?:\s*([^\s,;:)]+))?", re.IGNORECASE)


def _conditions(rulebook: Rulebook) -> Iterator[tuple[str, str, Expr]]:
    for kind, rules in (("command rule", rulebook.command_rules),
                        ("chance", rulebook.chances), ("prescreen", rulebook.prescreens),
                        ("verdict", rulebook.verdicts)):
        for rule in rules:
            yield kind, rule.name, rule.condition


# ----------------------------------------------------------------------------- W610

def _is_ratio(expr: Expr, rulebook: Rulebook) -> bool:
    """A fraction the rules speak of in %: risk, failed, chance(X), mean/max(I), an index in a
    prescreen, a slip signal (possibly inside abs, reductions, selections)."""
    indices = {i.name for i in rulebook.indices}
    if isinstance(expr, Name):
        return expr.name in RATIO_SIGNALS | RATIO_PATH_NAMES or expr.name in indices
    if isinstance(expr, Call):
        single = len(expr.args) == 1 and isinstance(expr.args[0], Name)
        if single and expr.function in ("chance", "mean", "max") and (
                expr.function == "chance" or expr.args[0].name in indices):  # type: ignore[union-attr]
            return True
        return expr.function == "abs" and len(expr.args) == 1 \
            and _is_ratio(expr.args[0], rulebook)
    if isinstance(expr, Select):
        return _is_ratio(expr.operand, rulebook)
    if isinstance(expr, Reduce) and expr.reducer == "fraction":  # of the samples, runs …
        return True
    if isinstance(expr, Reduce) and expr.reducer not in ("count", "integral", "time_above",
                                                         "sum", "rate", "any", "all"):
        return _is_ratio(expr.operand, rulebook)
    return False


def _bare_number(expr: Expr, rulebook: Rulebook) -> tuple[float, Span, str | None] | None:
    """A bare number above 1, written directly or as a constant: (value, span, constant)."""
    if isinstance(expr, Number) and expr.unit is None and expr.value > 1:
        return expr.value, expr.span, None
    if isinstance(expr, Name):
        constant = next((c for c in rulebook.constants if c.name == expr.name), None)
        if constant is not None and isinstance(constant.value, Number) and \
                constant.value.unit is None and constant.value.value > 1:
            return constant.value.value, constant.value.span, constant.name
    return None


def lint_bare_ratios(env: CheckEnv) -> list[Diagnostic]:
    rulebook = env.rulebook
    found: list[Diagnostic] = []
    seen: set[tuple[int, int]] = set()

    def report(value: float, span: Span, constant: str | None, what: str, used: Span) -> None:
        key = (span.line, span.column)
        if key in seen:
            return
        seen.add(key)
        written = f"{value:g}"
        subject = f"constant '{constant}' = {written}" if constant else written
        message = (f"{subject} is a ratio of {value * 100:g} % where {what} is a fraction "
                   f"(0 to 1)")
        related = ((f"'{constant}' is used here", used),) if constant else ()
        found.append(_with_related(warning(
            "W610", message, span, f"write {written} % for {written} percent, or "
            f"{value / 100:g} as a plain ratio"), related))

    for _, _, condition in _conditions(rulebook):
        for node in nodes(condition):
            if isinstance(node, Binary) and node.op in _COMPARISONS | {"==", "!="}:
                for ratio, other in ((node.left, node.right), (node.right, node.left)):
                    bare = _bare_number(other, rulebook)
                    if bare is not None and _is_ratio(ratio, rulebook):
                        from idefix_rules.rulebook.format import format_expr
                        report(*bare, f"'{format_expr(ratio)}'", node.span)
    for top in _every_expression(rulebook):  # time_above's threshold is compared too
        for node in nodes(top):
            if isinstance(node, Reduce) and node.reducer == "time_above" and \
                    node.parameter is not None and _is_ratio(node.operand, rulebook):
                bare = _bare_number(node.parameter, rulebook)
                if bare is not None:
                    from idefix_rules.rulebook.format import format_expr
                    report(*bare, f"the threshold of 'time_above' over "
                           f"'{format_expr(node.operand)}'", node.span)
    for index in rulebook.indices:
        if not (_is_ratio(index.value, rulebook) and
                env.index_types.get(index.name, None) is not None and
                env.index_types[index.name].dimension == DIMENSIONLESS):
            continue
        for item, expr in (("limit", index.limit), ("nominal", index.nominal)):
            bare = _bare_number(expr, rulebook) if expr is not None else None
            if bare is not None and expr is not None:
                report(*bare, f"the {item} of index '{index.name}'", expr.span)
    return found


def _with_related(diagnostic: Diagnostic, related: tuple[tuple[str, Span], ...]) -> Diagnostic:
    from dataclasses import replace
    return replace(diagnostic, related=related)


# ----------------------------------------------------------------------------- W611

Range = tuple[float, float]


def _range(expr: Expr, rulebook: Rulebook, run: bool = True) -> Range | None:
    """Declared range of a quantity, when the language fixes one (``run``: in an index,
    chance or map, where ``speed`` is a run's planar speed)."""
    # risk, failed, chance(X), mean(I), max(I), an index in a prescreen: fractions in [0, 1]
    # (slip itself is a ratio but not bounded: a spinning wheel slips 100 %, a sliding one more)
    if _is_ratio(expr, rulebook) and isinstance(expr, Name | Call) and not (
            isinstance(expr, Name) and expr.name in RATIO_SIGNALS) and not (
            isinstance(expr, Call) and expr.function == "abs"):
        return (0.0, 1.0)
    if isinstance(expr, Reduce) and expr.reducer == "fraction":
        return (0.0, 1.0)
    if isinstance(expr, Name) and (expr.name in FLAG_SIGNALS or area_signal(expr.name)):
        return (0.0, 1.0)
    if isinstance(expr, Name) and expr.name in FROM_ONE:
        return (1.0, math.inf)
    if isinstance(expr, Call) and expr.function in ("abs", "sqrt"):
        return (0.0, math.inf)
    if isinstance(expr, Name) and (expr.name in NON_NEGATIVE
                                   or (run and expr.name in RUN_NON_NEGATIVE)):
        return (0.0, 1.0) if expr.name in RATIO_PATH_NAMES else (0.0, math.inf)
    if isinstance(expr, Reduce):
        if expr.reducer == "rate":  # a non-negative quantity still falls
            return None
        if expr.reducer in ("count", "time_above"):
            return (0.0, math.inf)
        inner = _range(expr.operand, rulebook, run)
        if inner is not None and expr.reducer not in ("sum", "integral"):
            return inner
        if inner is not None and inner[0] >= 0:
            return (0.0, math.inf)
    if isinstance(expr, Select):
        return _range(expr.operand, rulebook, run)
    return None


def _always(op: str, low: float, high: float, threshold: float) -> bool | None:
    """True / False when ``x op threshold`` holds for every / no x in [low, high]."""
    if op == "<=":
        return True if high <= threshold else False if low > threshold else None
    if op == "<":
        return True if high < threshold else False if low >= threshold else None
    if op == ">=":
        return True if low >= threshold else False if high < threshold else None
    if op == ">":
        return True if low > threshold else False if high <= threshold else None
    return None


_FLIP = {"<": ">", "<=": ">=", ">": "<", ">=": "<="}


def lint_constant_comparisons(env: CheckEnv) -> list[Diagnostic]:
    from idefix_rules.rulebook.format import format_expr

    found: list[Diagnostic] = []
    for kind, name, condition in _conditions(env.rulebook):
        for node in nodes(condition):
            if not (isinstance(node, Binary) and node.op in _COMPARISONS):
                continue
            for quantity, other, op in ((node.left, node.right, node.op),
                                        (node.right, node.left, _FLIP[node.op])):
                declared = _range(quantity, env.rulebook, run=kind != "command rule")
                if declared is None:
                    continue
                try:
                    threshold = fold(other, env.constants)
                except (NotConstant, KeyError, ValueError, ArithmeticError, TypeError):
                    continue
                if isinstance(threshold, dict):
                    continue
                verdict = _always(op, declared[0], declared[1], float(threshold))
                if verdict is None:
                    continue
                low = f"{declared[0]:g}"
                high = "∞)" if math.isinf(declared[1]) else f"{declared[1]:g}]"
                found.append(warning(
                    "W611", f"'{format_expr(node)}' in {kind} '{name}' is always "
                    f"{'true' if verdict else 'false'}: '{format_expr(quantity)}' lies in "
                    f"[{low}, {high}", node.span,
                    "the rule never decides anything; check the threshold and its unit"))
                break
    return found


# ----------------------------------------------------------------------------- W612

def _quantities(text: str) -> Iterator[tuple[float, Dimension, str, float]]:
    """Numbers after a comparison word in a rationale: (SI value, dimension, as written, half
    the place of its last digit in SI: how far a value rounded to the digits written may lie
    from it). A fraction (``2/3``) is no number of a unit and is left out."""
    for match in _TRIGGER.finditer(text):
        number, unit = match.group(1), match.group(2)
        if unit is not None:
            unit = unit.rstrip(".") or None  # "above 70 %." ends a sentence
        if unit is not None and unit.lower() in ("percent", "pct"):  # "above 70 percent"
            unit = "%"
        fraction = re.match(r"\s*/\s*(\d+)\b", text[match.end(1):])
        if fraction is not None:  # "above 2/3": the ratio, exactly
            if float(fraction.group(1)) != 0.0:
                yield (float(number) / float(fraction.group(1)), DIMENSIONLESS,
                       f"{number}/{fraction.group(1)}", 0.0)
            continue
        candidates = [f"{number} {unit}"] if unit else []
        candidates.append(number)
        for candidate in candidates:
            try:
                if candidate != number:
                    parse_unit(str(unit))
                found = parse_quantity(candidate)
                half = abs(found.value / float(number)) * 0.5 * _place(number) \
                    if float(number) != 0.0 else 0.0
            except (UnitError, ValueError, ZeroDivisionError, OverflowError):
                continue
            yield found.value, found.dimension, candidate, half
            break


def _place(number: str) -> float:
    """Half the rounding a written number may carry: the place of its last digit when it
    writes three significant digits or more (``0.2618`` → 1e-4, ``33.3`` → 0.1), else 0 (a
    round number, ``70``, ``2``, ``0.7``, ``1e3``, says its value exactly).

    >>> _place("0.2618"), _place("33.3"), _place("70"), _place("0.7"), _place("1e3")
    (0.0001, 0.1, 0.0, 0.0, 0.0)
    """
    mantissa, _, exponent = number.lower().lstrip("+-").partition("e")
    digits = mantissa.replace(".", "").lstrip("0")
    if "." not in mantissa:
        digits = digits.rstrip("0")  # 100: one significant digit
    if len(digits) < 3:
        return 0.0
    decimals = len(mantissa.partition(".")[2])
    return float(f"1e{int(exponent or 0) - decimals}")


def lint_rationale_numbers(env: CheckEnv) -> list[Diagnostic]:
    """Constants, index limits, and rules whose condition compares with one constant."""
    from idefix_rules.rulebook.format import format_expr

    found: list[Diagnostic] = []

    def compare(name: str, rationale: str | None, value: Any, dimension: Dimension | None,
                written: Expr, span: Span, also: float | None = None) -> None:
        """``also``: a second value the rationale may name instead (an index's nominal)."""
        if rationale is None or value is None or dimension is None or isinstance(value, dict):
            return
        mentioned = [(v, text, half) for v, found_dimension, text, half
                     in _quantities(rationale) if found_dimension == dimension]
        explained = [float(value)] + ([also] if also is not None else [])
        # a rationale rounds: 0.2618 rad says 15 deg (0.261799 rad), 33.3 % says 1 / 3
        if mentioned and not any(math.isclose(v, e, rel_tol=1e-6, abs_tol=1e-15)
                                 or abs(v - e) < half * (1.0 - 1e-9)
                                 for v, _, half in mentioned for e in explained):
            said = ", ".join(text for _, text, _ in mentioned)
            shown = format_expr(written)
            si = f"{float(value):g}"
            found.append(warning(
                "W612", f"the rationale of '{name}' says {said} but the value is {shown}"
                + (f" (= {si})" if si != shown else ""), span,
                "update the value or its rationale so they agree"))

    for constant in env.rulebook.constants:
        kind = env.constant_types.get(constant.name)
        compare(constant.name, constant.rationale, env.constants.get(constant.name),
                kind.dimension if kind else None, constant.value, constant.span)
    for index in env.rulebook.indices:
        kind = env.index_types.get(index.name)
        compare(index.name, index.rationale, env.limits.get(index.name),
                kind.dimension if kind else None, index.limit, index.span,
                also=env.nominals.get(index.name))
    for rule in (*env.rulebook.command_rules, *env.rulebook.prescreens,
                 *env.rulebook.verdicts):
        condition = rule.condition
        if not (isinstance(condition, Binary) and condition.op in _COMPARISONS):
            continue
        try:
            threshold = fold(condition.right, env.constants)
        except (NotConstant, KeyError, ValueError, ArithmeticError, TypeError):
            continue
        dimension = _dimension_of(condition.right, env)
        compare(rule.name, rule.rationale, threshold, dimension, condition.right, rule.span)
    return found


def _dimension_of(expr: Expr, env: CheckEnv) -> Dimension | None:
    from idefix_rules.rulebook.infer import infer_type

    found = infer_type(expr, env.scope("constant"), [])
    return found.dimension if found is not None else None


# ----------------------------------------------------------------------------- W613

def lint_underflow(env: CheckEnv) -> list[Diagnostic]:
    source = env.rulebook.source.splitlines()
    found: list[Diagnostic] = []
    for expr in _every_expression(env.rulebook):
        for node in nodes(expr):
            if not isinstance(node, Number):
                continue
            try:
                si = number_si(node)
            except (UnitError, ValueError, OverflowError):  # too large: E003 says so
                continue
            written = _written(node.span, source)
            nonzero = any(ch in "123456789" for ch in written.split("e")[0].split("E")[0])
            if (si == 0 and nonzero) or (si != 0 and abs(si) < 2.2250738585072014e-308):
                found.append(warning(
                    "W613", f"'{written or node.value}' is "
                    + ("0 in SI: the number is too small for a double" if si == 0 else
                       "a denormal in SI: too small for a double's full precision"), node.span,
                    "write 0 if zero is meant, or a larger unit"))
    return found


def _written(span: Span, lines: list[str]) -> str:
    if span.line <= 0 or span.line > len(lines):
        return ""
    line = lines[span.line - 1]
    end = span.end_column if span.end_line == span.line and span.end_column > span.column \
        else len(line) + 1
    return line[span.column - 1:end - 1].strip()


def _every_expression(rulebook: Rulebook) -> Iterator[Expr]:

    yield from rulebook_expressions(rulebook)


# ----------------------------------------------------------------------------- W614

# A nominal closer than this share of the limit to 0 or to the limit makes the index nearly a
# step: half of its range (0 → 0.5 or 0.5 → 1) is crossed within a tenth of the limit.
STEP_SHARE = 0.1


def lint_step_nominal(env: CheckEnv) -> list[Diagnostic]:
    found: list[Diagnostic] = []
    for index in env.rulebook.indices:
        nominal, limit = env.nominals.get(index.name), env.limits.get(index.name)
        if index.nominal is None or nominal is None or limit is None:
            continue
        share = nominal / limit
        if STEP_SHARE <= share <= 1.0 - STEP_SHARE:
            continue
        low = share < STEP_SHARE
        width = share if low else 1.0 - share
        where = "first" if low else "last"
        found.append(warning(
            "W614", f"the nominal of index '{index.name}' is {share * 100:.3g} % of its limit: "
            f"the index climbs from {'0 to 0.5' if low else '0.5 to 1'} over the {where} "
            f"{width * 100:.3g} % of the limit, nearly a step", index.nominal.span,
            "put the nominal where the value is expected (0.5 on the index's scale), or leave "
            "it out for value / limit"))
    return found


# ----------------------------------------------------------------------------- W615

def lint_empty_windows(env: CheckEnv) -> list[Diagnostic]:
    """``before Q`` with Q at or below 0 s holds no sample (a run's time starts at 0): its
    reduction reads its empty-window value (0) in every run."""
    found: list[Diagnostic] = []
    for node in windowed(env.rulebook, "before"):
        assert node.window is not None
        bound = folded_number(node.window.value, env.constants)
        if bound is not None and bound <= 0.0:
            found.append(warning(
                "W615", f"'before {bound:g} s' holds no sample (a run's time starts at 0 s): "
                "the reduction gives its empty-window value in every run", node.window.span,
                "give a time after the start, e.g. 'before 30 s'"))
    return found


# ----------------------------------------------------------------------------- W616

def lint_fraction_percentiles(env: CheckEnv) -> list[Diagnostic]:
    """``percentile P`` with 0 < P < 1: the parameter counts in percent (0 to 100), so
    ``percentile 0.95`` is a value just above the minimum, not the 95th percentile."""
    found: list[Diagnostic] = []
    for top in rulebook_expressions(env.rulebook):
        for node in nodes(top):
            if not (isinstance(node, Reduce) and node.reducer == "percentile"
                    and isinstance(node.parameter, Number) and node.parameter.unit is None):
                continue
            value = node.parameter.value
            if 0.0 < value < 1.0:
                found.append(warning(
                    "W616", f"percentile '{value:g}' is the {value:g}th percentile, a value "
                    "just above the smallest: the parameter counts in percent, from 0 to 100",
                    node.parameter.span, f"did you mean '{value * 100:g}'?"))
    return found


LINTS: tuple[Callable[[CheckEnv], list[Diagnostic]], ...] = (
    lint_bare_ratios, lint_constant_comparisons, lint_rationale_numbers, lint_underflow,
    lint_step_nominal, lint_empty_windows, lint_fraction_percentiles)
