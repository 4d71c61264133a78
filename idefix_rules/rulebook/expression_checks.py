"""The checker's passes over the rules' expressions: conditions, indices, windows, ranking."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from idefix_rules.errors import Diagnostic, error
from idefix_rules.rulebook.constants import constant_quantity, folded_constant
from idefix_rules.rulebook.environment import Check, CheckEnv, scope_of
from idefix_rules.rulebook.fold import NotComputable, NotConstant, fold, folded_number
from idefix_rules.rulebook.infer import infer_type
from idefix_rules.rulebook.judging import verdict_margins
from idefix_rules.rulebook.model import Expr, Index, Invalid, Number, Reduce, Rulebook
from idefix_rules.rulebook.types import ExprType
from idefix_rules.rulebook.walk import children, nodes, rulebook_expressions, windowed
from idefix_rules.units import DIMENSIONLESS, describe

# What one condition of each kind of rule is about (E302): a command rule judges each command,
# a verdict each path, the others each run.
_CONDITION_PER = {"command": "command", "path": "path"}


def _condition(env: CheckEnv, expr: Expr, kind: str, what: str,
               problems: list[Diagnostic]) -> ExprType | None:
    found = infer_type(expr, env.scope(kind), problems)
    if found is None:
        return None
    if not found.boolean:
        problems.append(error("E303", f"{what} must be a condition (a comparison), got "
                              f"{describe(found.dimension)}", expr.span,
                              "for example 'abs(delta_heading) <= 90 deg'"))
        return None
    if found.axes:
        problems.append(error("E302", f"{what} must be one condition per "
                              f"{_CONDITION_PER.get(kind, 'run')}, but it still has "
                              f"{_axes_phrase(found.axes)}", expr.span,
                              f"reduce {'it' if len(found.axes) == 1 else 'them'} with "
                              "any/all over …"))
        return None
    return found


def _axes_phrase(axes: tuple[str, ...]) -> str:
    """``a time axis`` / ``a time and a wheel axis``."""
    return " and ".join(f"a {axis}" for axis in axes) + (" axis" if len(axes) == 1 else " axes")


def _check_conditions(kind: str, label: str,
                      rules: Callable[[Rulebook], tuple[Any, ...]]) -> Check:
    """A pass checking that each rule's ``condition`` is one boolean in scope ``kind``."""

    def check_pass(env: CheckEnv) -> list[Diagnostic]:
        problems: list[Diagnostic] = []
        for rule in rules(env.rulebook):
            _condition(env, rule.condition, kind, f"{label} '{rule.name}'", problems)
        return problems

    return check_pass


check_command_rules = _check_conditions("command", "command rule", lambda r: r.command_rules)
check_chances = _check_conditions("run", "chance", lambda r: r.chances)
check_prescreens = _check_conditions("prescreen", "prescreen", lambda r: r.prescreens)
check_verdicts = _check_conditions("path", "verdict", lambda r: r.verdicts)


def check_indices(env: CheckEnv) -> list[Diagnostic]:
    problems: list[Diagnostic] = []
    run_scope = env.scope("run")
    for index in env.rulebook.indices:
        found = infer_type(index.value, run_scope, problems)
        what = f"index '{index.name}'"
        if found is not None:
            if found.boolean:
                problems.append(error("E304", f"{what} must be a quantity, not a condition",
                                      index.value.span, "use a chance for conditions"))
                found = None
            elif found.axes:
                problems.append(error(
                    "E302", f"{what} must give one value per run, but it still has "
                    f"{_axes_phrase(found.axes)}", index.value.span,
                    "reduce them, e.g. 'max over time (…)' or 'max over wheels (…)'"))
                found = None
        if found is not None:
            env.index_types[index.name] = found
            limit = constant_quantity(env, index.limit, found.dimension, f"the limit of {what}",
                                       problems)
            if limit is not None:
                if limit <= 0:
                    problems.append(error("E402", f"the limit of {what} must be above zero",
                                          index.limit.span))
                    limit = None
                else:
                    env.limits[index.name] = limit
            if index.nominal is not None:
                _check_nominal(env, index, found, limit, problems)
        else:  # the value's error is said: the limit and nominal still get their own mistakes
            for item, label in ((index.limit, "limit"), (index.nominal, "nominal")):
                if item is not None:
                    constant_quantity(env, item, None, f"the {label} of {what}", problems)
        weight = constant_quantity(env, index.weight, DIMENSIONLESS, f"the weight of {what}",
                                    problems)
        if weight is not None:
            if not 0.0 <= weight <= 1.0:
                problems.append(error("E401", f"the weight of {what} must lie in [0, 1], got "
                                      f"{weight:g}", index.weight.span))
            else:
                env.weights[index.name] = weight
        if index.map is not None:
            mapped = infer_type(index.map, run_scope, problems)
            if mapped is not None and (mapped.boolean or mapped.axes != ("time",)):
                problems.append(error("E307", f"the map of {what} must be one quantity per "
                                      "sample (a time series)", index.map.span,
                                      "reduce wheels/parts/levels, keep time"))
            elif mapped is not None and found is not None and mapped.dimension != found.dimension:
                problems.append(error("E307", f"the map of {what} is "
                                      f"{describe(mapped.dimension)} but its value is "
                                      f"{describe(found.dimension)}", index.map.span))
    return problems


def _check_nominal(env: CheckEnv, index: Index, found: ExprType, limit: float | None,
                   problems: list[Diagnostic]) -> None:
    """An index's nominal: the value's dimension (as the limit), above zero, below the limit."""
    assert index.nominal is not None
    what = f"the nominal of index '{index.name}'"
    nominal = constant_quantity(env, index.nominal, found.dimension, what, problems)
    if nominal is None:
        return
    from idefix_rules.rulebook.format import format_expr

    unit = "" if found.dimension.is_dimensionless else f" {found.dimension}"

    def shown(expr: Expr, si: float) -> str:
        written, in_si = format_expr(expr), f"{si:g}{unit}"
        return written if written == in_si else f"{written} = {in_si}"

    if nominal <= 0:
        problems.append(error("E407", f"{what} must be above zero, got "
                              f"{shown(index.nominal, nominal)}", index.nominal.span,
                              "the nominal is the value expected in the environment, "
                              "between 0 and the limit"))
    elif limit is not None and nominal >= limit:
        problems.append(error("E408", f"{what} must be below its limit: "
                              f"{shown(index.nominal, nominal)} is not below "
                              f"{shown(index.limit, limit)}", index.nominal.span,
                              "the index is 0.5 at the nominal and 1 at the limit"))
    else:
        env.nominals[index.name] = nominal


def check_verdict_margins(env: CheckEnv) -> list[Diagnostic]:
    """Each verdict's indifference: of the dimension it compares, 0 or more."""
    problems: list[Diagnostic] = []
    env.verdict_margins = verdict_margins(env.rulebook, env.scope("path"),
                                          env.scope("constant"), env.constants,
                                          env.verdict_indifference, problems)
    return problems


def check_ranking(env: CheckEnv) -> list[Diagnostic]:
    from idefix_rules.rulebook.format import format_expr

    problems: list[Diagnostic] = []
    seen: dict[str, Any] = {}
    for key in env.rulebook.ranking.keys:
        if isinstance(key.expr, Invalid):  # its number is beyond a double: said (E003)
            continue
        written = format_expr(key.expr)
        if written in seen:  # a later key on the same statistic never decides anything
            problems.append(error("E413", f"rank key '{written}' is given twice: the second "
                                  "never orders what the first leaves tied", key.expr.span,
                                  "give each statistic once, in the order that breaks ties"))
            continue
        seen[written] = key
        found = infer_type(key.expr, env.scope("path"), problems)
        if found is not None and (found.boolean or found.axes):
            problems.append(error("E304", "a rank key must be a path statistic (a number)",
                                  key.expr.span))
    return problems


def check_command_windows(env: CheckEnv) -> list[Diagnostic]:
    """``during command K`` selects the samples of the K-th command (1-based, ``command ==
    K - 1``): K must be a whole number from 1. ``during command 0`` would select the samples
    after the chain (``command == -1``) and 1.5 the second command, both silently."""
    problems: list[Diagnostic] = []
    scope = scope_of("constant", env.rulebook, env.constant_types)
    for node in windowed(env.rulebook, "command"):
        assert node.window is not None
        found = infer_type(node.window.value, scope, [])
        if found is None or found.dimension != DIMENSIONLESS or found.axes:
            continue  # not a number: E204 says so
        number = folded_number(node.window.value, env.constants)
        if number is not None and math.isfinite(number) and not (
                number >= 1 and number == math.floor(number)):  # not finite: E402
            problems.append(error(
                "E310", f"'during command {number:g}': commands are counted from 1, by whole "
                        "numbers", node.window.span, "the first command is 'during command 1'"))
    return problems


def check_percentiles(env: CheckEnv) -> list[Diagnostic]:
    """``percentile P`` with P naming constants: P must fold to a number from 0 to 100 (one
    written in place is checked with the types, E308 too)."""
    problems: list[Diagnostic] = []
    for expr in rulebook_expressions(env.rulebook):
        for node in nodes(expr):
            if not (isinstance(node, Reduce) and node.reducer == "percentile"
                    and node.parameter is not None and not isinstance(node.parameter, Number)):
                continue
            number = folded_number(node.parameter, env.constants)
            if number is not None and math.isfinite(number) and not 0 <= number <= 100:
                problems.append(error("E308", f"percentile needs a number from 0 to 100, "
                                              f"got {number:g}", node.parameter.span))
    return problems


def check_constant_parts(env: CheckEnv) -> list[Diagnostic]:
    """Every part of a rule that reads constants only (a threshold, a window, a reducer's
    parameter, ``2 * critical_slip`` inside an index) has a finite value: E402 otherwise.
    ``risk <= 0 / 0`` compared with nan and ``percentile (sqrt(-1))`` were accepted. Limits,
    weights, nominals, settings and constants have their own checks."""
    problems: list[Diagnostic] = []
    book = env.rulebook
    rules: list[tuple[str, str, Expr]] = [
        *((f"command rule '{r.name}'", "command", r.condition) for r in book.command_rules),
        *((f"index '{i.name}'", "run", i.value) for i in book.indices),
        *((f"the map of index '{i.name}'", "run", i.map) for i in book.indices
          if i.map is not None),
        *((f"chance '{c.name}'", "run", c.condition) for c in book.chances),
        *((f"prescreen '{p.name}'", "prescreen", p.condition) for p in book.prescreens),
        *((f"verdict '{v.name}'", "path", v.condition) for v in book.verdicts),
        *(("a rank key", "path", key.expr) for key in book.ranking.keys)]
    for label, kind, expr in rules:
        typed: list[Diagnostic] = []
        if infer_type(expr, env.scope(kind), typed) is not None and not typed:
            _constant_parts(expr, label, env, problems)  # else its type check says what
    return problems


def _constant_parts(expr: Expr, label: str, env: CheckEnv,
                    problems: list[Diagnostic]) -> None:
    from idefix_rules.rulebook.format import format_expr

    constant = False
    if not isinstance(expr, Number):  # a literal is finite (the parser says so)
        try:
            fold(expr, env.constants)
        except NotConstant:
            pass  # not a constant (or one refused already): its parts may be
        except NotComputable:
            constant = True
        else:
            constant = True
        if constant:
            folded_constant(expr, env.constants, f"'{format_expr(expr)}' in {label}", problems)
            return
    for child in children(expr):
        _constant_parts(child, label, env, problems)
