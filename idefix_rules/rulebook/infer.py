"""Type inference: the dimension, axes and boolean-ness of every expression.

:func:`infer_type` returns the type of an expression in a scope and appends a diagnostic for
every mistake it finds to ``problems``; it returns ``None`` for a sub-expression it could not
type, and its parents then stay quiet (one mistake, one message).

>>> from idefix_rules.rulebook.model import Binary, Number
>>> from idefix_rules.rulebook.types import Scope
>>> problems = []
>>> infer_type(Binary("+", Number(5, "cm"), Number(2, "deg")), Scope("constant"), problems)
>>> problems[0].code
'E201'
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Callable

from idefix_rules import signals
from idefix_rules.errors import Diagnostic, error
from idefix_rules.rulebook import semantics
from idefix_rules.rulebook.across import runs_reductions
from idefix_rules.rulebook.model import (
    DOMAIN_AXES,
    PARAMETRIC_REDUCERS,
    Binary,
    Call,
    Expr,
    Invalid,
    Name,
    Number,
    Reduce,
    Select,
    Table,
    Unary,
)
from idefix_rules.rulebook.types import (
    BOOLEAN,
    ELEMENTWISE_FUNCTIONS,
    FUNCTION_ARITY,
    PATH_FUNCTIONS,
    RATIO,
    SCOPE_DESCRIPTIONS,
    ExprType,
    Scope,
    axis_of_label,
)
from idefix_rules.units import DIMENSIONLESS, TIME, Dimension, UnitError, describe, parse_unit

Problems = list[Diagnostic]


def unit_dimension(number: Number, problems: Problems) -> Dimension | None:
    if number.unit is None:
        return DIMENSIONLESS
    try:
        unit = parse_unit(number.unit)
    except UnitError as failure:
        problems.append(error("E205", str(failure), number.span,
                              "units are listed in docs/rulebook-language.md"))
        return None
    try:
        si = unit.to_si(number.value)
    except OverflowError:
        si = math.inf
    if not math.isfinite(si):  # the number fits a double, its value in SI does not
        problems.append(error("E003", f"number {number.value:g} {number.unit} is too large: "
                                      f"in SI ({unit.dimension}) it is beyond a double",
                              number.span, "write a realistic value"))
        return None
    return unit.dimension


def did_you_mean(name: str, candidates: list[str]) -> str | None:
    close = difflib.get_close_matches(name, candidates, n=1, cutoff=0.6)
    return f"did you mean '{close[0]}'?" if close else None


def infer_type(expr: Expr, scope: Scope, problems: Problems) -> ExprType | None:
    """The type of ``expr`` in ``scope``; mistakes are appended to ``problems``."""
    handler = _HANDLERS[type(expr)]
    return handler(expr, scope, problems)


def _number(expr: Number, scope: Scope, problems: Problems) -> ExprType | None:
    dimension = unit_dimension(expr, problems)
    return None if dimension is None else ExprType(dimension)


def _name(expr: Name, scope: Scope, problems: Problems) -> ExprType | None:
    found = scope.lookup(expr.name)
    if found is not None:
        return found
    where = SCOPE_DESCRIPTIONS[scope.kind]
    hint = did_you_mean(expr.name, scope.candidates())
    if scope.kind != "run" and signals.lookup(expr.name) is not None:
        message = f"signal '{expr.name}' cannot be used in {where}"
        hint = "a reducer reads signals in its operand, e.g. 'percentile 95 over time (…)'" \
            if scope.kind == "parameter" else \
            "signals are only visible in indices, chances and maps"
    else:
        message = f"unknown name '{expr.name}' in {where}"
    problems.append(error("E101", message, expr.span, hint))
    return None


def _select(expr: Select, scope: Scope, problems: Problems) -> ExprType | None:
    base = infer_type(expr.operand, scope, problems)
    if base is None:
        return None
    axes = list(base.axes)
    selected: dict[str, str] = {}  # axis → the label that selected it
    for label in expr.labels:
        axis = axis_of_label(label)
        if axis is None:
            # the labels of the operand's own axes (every label when it has none)
            own = [axis for axis in base.axes if axis in signals.AXIS_LABELS]
            known = [lab for axis in own or signals.AXIS_LABELS
                     for lab in signals.AXIS_LABELS[axis]]
            problems.append(error("E104", f"unknown label '{label}'", expr.span,
                                  did_you_mean(label, known) or _labels_phrase(own)
                                  or f"labels are {', '.join(known)}"))
            return None
        if axis in selected:
            problems.append(error("E104", f"cannot select '{label}': it is a second {axis} "
                                  f"label for the {axis} axis, after '{selected[axis]}'; one "
                                  "label per axis", expr.span,
                                  f"write {_label_example(expr, selected[axis])} and "
                                  f"{_label_example(expr, label)} as two values, or reduce "
                                  f"over {_AXIS_PLURALS[axis]}"))
            return None
        if axis not in axes:
            left = [a for a in axes if a in signals.AXIS_LABELS]
            problems.append(error("E104", f"cannot select '{label}': the expression has no "
                                  f"{axis} axis", expr.span,
                                  _labels_phrase(left) if left else
                                  f"after [{', '.join(selected.values())}] it has no axis left"
                                  if selected else None))
            return None
        axes.remove(axis)
        selected[axis] = label
    return ExprType(base.dimension, tuple(axes), base.boolean)


_AXIS_PLURALS = {"wheel": "wheels", "part": "parts", "level": "levels"}


def _labels_phrase(axes: list[str]) -> str | None:
    """``its labels: parts wheel, solar_panel, chassis; levels L1, L2, L3``."""
    if not axes:
        return None
    return "its labels: " + "; ".join(
        f"{_AXIS_PLURALS.get(axis, axis)} {', '.join(signals.AXIS_LABELS[axis])}"
        for axis in axes)


def _label_example(expr: Select, label: str) -> str:
    """The selection written with one label (``wheel.slip[FL]``) for a hint."""
    operand = expr.operand.name if isinstance(expr.operand, Name) else "…"
    return f"{operand}[{label}]"


def _table(expr: Table, scope: Scope, problems: Problems) -> ExprType | None:
    axis_set = {axis_of_label(label) for label, _ in expr.entries}
    if None in axis_set or len(axis_set) != 1:
        problems.append(error("E306", "a table's labels must all name one axis "
                              "(wheels FL..RR, parts, or levels L1..L3)", expr.span))
        return None
    axis = axis_set.pop()
    assert axis is not None
    labels = [label for label, _ in expr.entries]
    expected = signals.AXIS_LABELS[axis]
    if sorted(labels) != sorted(expected):
        problems.append(error("E306", f"a {axis} table needs each of {', '.join(expected)} "
                              f"exactly once, got {', '.join(labels)}", expr.span))
        return None
    dimension = None
    for _, value in expr.entries:
        entry = infer_type(value, scope, problems)
        if entry is None:
            return None
        if entry.axes or entry.boolean:
            problems.append(error("E306", "table entries must be plain quantities", value.span))
            return None
        if dimension is not None and entry.dimension != dimension:
            problems.append(error("E201", f"table mixes {describe(dimension)} and "
                                  f"{describe(entry.dimension)}", value.span))
            return None
        dimension = entry.dimension
    return ExprType(dimension or DIMENSIONLESS, (axis,))


def _unary(expr: Unary, scope: Scope, problems: Problems) -> ExprType | None:
    operand = infer_type(expr.operand, scope, problems)
    if operand is None:
        return None
    if expr.op == "not":
        if not operand.boolean:
            problems.append(error("E304", "'not' needs a condition", expr.operand.span))
            return None
        return operand
    if operand.boolean:
        problems.append(error("E304", "cannot negate a condition; use 'not'", expr.span))
        return None
    return operand


_ARITHMETIC = {"+", "-", "*", "/", "^"}
_COMPARISON = {"<", "<=", ">", ">=", "==", "!="}


def _binary(expr: Binary, scope: Scope, problems: Problems) -> ExprType | None:
    left = infer_type(expr.left, scope, problems)
    right = infer_type(expr.right, scope, problems)
    if left is None or right is None:
        return None
    axes = tuple(set(left.axes) | set(right.axes))
    if expr.op in ("and", "or"):
        for side, node in ((left, expr.left), (right, expr.right)):
            if not side.boolean:
                problems.append(error("E303", f"'{expr.op}' needs conditions on both sides",
                                      node.span))
                return None
        return ExprType(DIMENSIONLESS, axes, True)
    for side, node in ((left, expr.left), (right, expr.right)):
        if side.boolean:
            problems.append(error("E304", f"a condition cannot be used with '{expr.op}'",
                                  node.span))
            return None
    if expr.op in _COMPARISON or expr.op in ("+", "-"):
        # A bare 0 is zero in any unit: `delta_position == 0`, `x - 0`.
        if _is_bare_zero(expr.right):
            right = ExprType(left.dimension, right.axes)
        elif _is_bare_zero(expr.left):
            left = ExprType(right.dimension, left.axes)
        if left.dimension != right.dimension:
            verb = "compare" if expr.op in _COMPARISON else (
                "add" if expr.op == "+" else "subtract")
            problems.append(error(
                "E201", f"cannot {verb} {describe(left.dimension)} ({left.dimension}) and "
                f"{describe(right.dimension)} ({right.dimension})", expr.span))
            return None
        return ExprType(left.dimension, axes, expr.op in _COMPARISON)
    if expr.op == "*":
        return ExprType(left.dimension * right.dimension, axes)
    if expr.op == "/":
        return ExprType(left.dimension / right.dimension, axes)
    # '^': the exponent is a dimensionless integer literal unless the base is dimensionless
    exponent = expr.right
    if right.dimension != DIMENSIONLESS or right.axes:
        problems.append(error("E202", "an exponent must be a plain number", exponent.span))
        return None
    if left.dimension.is_dimensionless:
        return ExprType(DIMENSIONLESS, axes)
    power = _whole_number(exponent)
    if power is None:
        problems.append(error("E202", "a quantity with a unit can only be raised to a whole "
                              "number written in place", exponent.span))
        return None
    return ExprType(left.dimension ** power, left.axes)


def _whole_number(expr: Expr) -> int | None:
    """The whole number written in place (``2``, ``-1``), else None."""
    sign = 1
    while isinstance(expr, Unary) and expr.op == "-":
        sign, expr = -sign, expr.operand
    if isinstance(expr, Number) and expr.unit is None and float(expr.value).is_integer():
        return sign * int(expr.value)
    return None


def _is_bare_zero(expr: Expr) -> bool:
    return isinstance(expr, Number) and expr.unit is None and expr.value == 0


def _call(expr: Call, scope: Scope, problems: Problems) -> ExprType | None:
    if scope.kind == "path" and expr.function in PATH_FUNCTIONS:
        return _path_call(expr, scope, problems)
    if expr.function not in ELEMENTWISE_FUNCTIONS:
        known = sorted(ELEMENTWISE_FUNCTIONS | (set(PATH_FUNCTIONS) if scope.kind == "path"
                                                 else set()))
        problems.append(error("E105", f"unknown function '{expr.function}'", expr.span,
                              did_you_mean(expr.function, known)
                              or f"functions are {', '.join(known)}"))
        return None
    arity = FUNCTION_ARITY
    low, high = arity[expr.function]
    if not low <= len(expr.args) <= high:
        wanted = str(low) if low == high else f"at least {low}"
        hint = None
        if expr.function in ("min", "max") and len(expr.args) == 1:
            hint = f"to reduce over time write '{expr.function} over time (…)'"
        problems.append(error("E106", f"{expr.function}() takes {wanted} argument(s), got "
                              f"{len(expr.args)}", expr.span, hint))
        return None
    types = [infer_type(arg, scope, problems) for arg in expr.args]
    if any(t is None for t in types):
        return None
    typed = [t for t in types if t is not None]
    for t, arg in zip(typed, expr.args, strict=True):
        if t.boolean:
            problems.append(error("E304", f"{expr.function}() needs quantities, not conditions",
                                  arg.span))
            return None
    first = typed[0]
    axes = tuple(set().union(*(set(t.axes) for t in typed)))
    if expr.function == "sqrt":
        exps = first.dimension.exponents()
        if any(e % 2 for e in exps):
            problems.append(error("E202", f"cannot take the square root of "
                                  f"{describe(first.dimension)}", expr.span))
            return None
        return ExprType(type(first.dimension)(*(e // 2 for e in exps)), axes)
    for t, arg in zip(typed[1:], expr.args[1:], strict=True):
        if t.dimension != first.dimension:
            problems.append(error("E201", f"{expr.function}() mixes "
                                  f"{describe(first.dimension)} and {describe(t.dimension)}",
                                  arg.span))
            return None
    return ExprType(first.dimension, axes)


def _path_call(expr: Call, scope: Scope, problems: Problems) -> ExprType | None:
    kind = PATH_FUNCTIONS[expr.function]
    if len(expr.args) != 1 or not isinstance(expr.args[0], Name):
        problems.append(error("E106", f"{expr.function}() takes the name of "
                              f"{'a chance' if kind == 'chance' else 'an index'}", expr.span))
        return None
    name = expr.args[0]
    assert isinstance(name, Name)
    known = scope.chances if kind == "chance" else scope.indices
    if name.name not in known:
        what = "chance" if kind == "chance" else "index"
        message, hint = f"unknown {what} '{name.name}'", did_you_mean(name.name, sorted(known))
        if kind == "chance" and name.name in scope.indices:
            message = f"'{name.name}' is an index, not a chance: chance() takes a chance"
            hint = f"write mean({name.name}) (or max({name.name}))"
        elif kind == "index" and name.name in scope.chances:
            message = (f"'{name.name}' is a chance, not an index: {expr.function}() takes an "
                       "index")
            hint = f"write chance({name.name})"
        problems.append(error("E101", message, name.span, hint))
        return None
    return RATIO


# Reducers that make sense across the runs of a path (run order carries no meaning, so no
# final/initial; integral and time_above are time reductions).
RUN_REDUCERS = frozenset({"mean", "max", "min", "sum", "rms", "percentile", "any", "all",
                          "count", "fraction"})


def _runs_allowed(expr: Reduce, scope: Scope, problems: Problems) -> bool:
    """Where a reduction over runs may stand and what it may read (E800-E803)."""
    if scope.kind != "run":
        hint = {"path": "verdicts read path statistics already: mean(INDEX), max(INDEX), "
                        "chance(NAME)",
                "prescreen": "a prescreen sees the reference run alone"}.get(
            scope.kind, "use it in an index value, a map or a chance")
        problems.append(error("E800", f"'{expr.reducer} over runs' cannot be used in "
                              f"{SCOPE_DESCRIPTIONS[scope.kind]}: it reduces the runs of a "
                              "path, which only indices, maps and chances see", expr.span,
                              hint))
        return False
    if expr.reducer not in RUN_REDUCERS:
        problems.append(error("E803", f"'{expr.reducer}' cannot reduce over runs", expr.span,
                              "over runs: " + ", ".join(sorted(RUN_REDUCERS))))
        return False
    if runs_reductions([expr.operand]):
        problems.append(error("E801", "a reduction over runs cannot contain another one",
                              expr.span, "reduce over runs once, outermost"))
        return False
    # a name that is no collision signal (a typo) is left to the name check (E101, with a
    # did-you-mean), not called a collision signal here
    collision = sorted(n for n in semantics.names_in(expr.operand)
                       if n in signals.COLLISION_SIGNALS)
    if collision:
        problems.append(error("E802", f"'{collision[0]}' cannot be reduced over runs",
                              expr.span, "collision signals are per run: declare a chance and "
                              "read chance(NAME) in a verdict"))
        return False
    return True


def _rate(expr: Reduce, scope: Scope, problems: Problems) -> ExprType | None:
    """``rate over time (x)``: x's rate of change, still a time series, x's unit per second."""
    if expr.domain != "time" or expr.window is not None or expr.parameter is not None:
        where = (expr.window.span if expr.window is not None else
                 expr.parameter.span if expr.parameter is not None else expr.span)
        what = (f"runs over time only, not over {expr.domain}" if expr.domain != "time" else
                "takes no window" if expr.window is not None else "takes no parameter")
        problems.append(error("E309", f"'rate' {what}: it keeps the time axis", where,
                              "reduce the rate with the window you need, e.g. "
                              "'max over time after 10 s (rate over time (x))'"))
        return None
    operand = infer_type(expr.operand, scope, problems)
    if operand is None:
        return None
    if operand.boolean:
        problems.append(error("E304", "'rate' needs a quantity, not a condition",
                              expr.operand.span))
        return None
    if "time" not in operand.axes:
        shape = ", ".join(operand.axes) if operand.axes else "a single value per run"
        problems.append(error("E301", f"'rate over time' needs a quantity with a time axis; "
                              f"this one has {shape}", expr.span))
        return None
    return ExprType(operand.dimension / TIME, operand.axes)


def _parameter_scope(scope: Scope) -> Scope:
    """A reducer's parameter or a window sees constants only, whatever the scope around it:
    a signal or a reduction there would be one value per run, which the evaluation cannot
    take."""
    return Scope("parameter", scope.constants)


def _reduce(expr: Reduce, scope: Scope, problems: Problems) -> ExprType | None:
    if scope.kind in ("constant", "parameter"):
        problems.append(error("E311", f"a reduction cannot be used in "
                              f"{SCOPE_DESCRIPTIONS[scope.kind]}", expr.span,
                              "write the value itself; signals are reduced in an index's or a "
                              "chance's value"))
        return None
    if expr.reducer == "rate":
        return _rate(expr, scope, problems)
    if expr.domain == "runs" and not _runs_allowed(expr, scope, problems):
        return None
    operand = infer_type(expr.operand, scope, problems)
    axis = DOMAIN_AXES[expr.domain]
    parameter = None
    if expr.parameter is not None:
        parameter = infer_type(expr.parameter, _parameter_scope(scope), problems)
    if expr.window is not None:
        window_type = infer_type(expr.window.value, _parameter_scope(scope), problems)
        if expr.domain != "time":
            problems.append(error("E305", f"a window only applies to reductions over time, "
                                  f"not over {expr.domain}", expr.window.span))
        elif window_type is not None:
            wanted = DIMENSIONLESS if expr.window.kind == "command" else TIME
            what = "a command number" if expr.window.kind == "command" else "a duration"
            if window_type.dimension != wanted:
                problems.append(error("E204", f"'{expr.window.kind}' window needs {what}, got "
                                      f"{describe(window_type.dimension)}", expr.window.span))
            elif window_type.axes:
                problems.append(error("E302", f"'{expr.window.kind}' window needs one {what[2:]}"
                                      f", got one per {' and '.join(window_type.axes)}",
                                      expr.window.span))
    if operand is None:
        return None
    if expr.domain == "runs":
        if expr.reducer == "percentile" and operand.axes:
            problems.append(error(
                "E804", "'percentile over runs' needs one value per run; this one still has a "
                + " and a ".join(operand.axes) + (" axis" if len(operand.axes) == 1 else " axes"),
                expr.span,
                "reduce it first, e.g. 'percentile 95 over runs (final over time (…))'"))
            return None
    elif axis not in operand.axes:
        shape = ", ".join(operand.axes) if operand.axes else "a single value per run"
        problems.append(error(
            "E301", f"'{expr.reducer} over {expr.domain}' needs a quantity with a {axis} axis; "
            f"this one has {shape}", expr.span))
        return None
    if expr.reducer in ("any", "all", "count", "fraction"):
        if not operand.boolean:
            problems.append(error("E303", f"'{expr.reducer}' needs a condition",
                                  expr.operand.span))
            return None
        result = operand.without(axis)
        if expr.reducer in ("count", "fraction"):
            return ExprType(DIMENSIONLESS, result.axes)
        return result
    if operand.boolean:
        problems.append(error("E304", f"'{expr.reducer}' needs a quantity, not a condition",
                              expr.operand.span, "use any/all/count/fraction for conditions"))
        return None
    if (expr.reducer in PARAMETRIC_REDUCERS) != (expr.parameter is not None):
        if expr.parameter is None:
            problems.append(error("E106", f"'{expr.reducer}' needs a parameter", expr.span))
        else:
            problems.append(error("E106", f"'{expr.reducer}' takes no parameter",
                                  expr.parameter.span))
        return None
    if expr.reducer in ("integral", "time_above") and expr.domain != "time":
        problems.append(error("E301", f"'{expr.reducer}' only reduces over time", expr.span))
        return None
    if expr.reducer == "percentile" and parameter is not None:
        # a number written in place is checked here; one naming constants once folded
        # (expression_checks.check_percentiles)
        value = expr.parameter
        if parameter.dimension != DIMENSIONLESS or parameter.axes or (
                isinstance(value, Number) and not (0 <= value.value <= 100
                                                   and value.unit is None)):
            message, hint = "percentile needs a number from 0 to 100", None
            if isinstance(value, Number) and value.unit == "%" and 0 <= value.value <= 100:
                message += ", written without '%': it counts in percent already"
                hint = f"percentile {value.value:g} over …"
            elif isinstance(value, Number) and value.unit is not None:
                message += f", without a unit (got {value.value:g} {value.unit})"
            problems.append(error("E308", message,
                                  expr.parameter.span if expr.parameter else expr.span, hint))
            return None
    if expr.reducer == "time_above" and parameter is not None:
        if parameter.dimension != operand.dimension:
            problems.append(error("E201", f"time_above compares {describe(operand.dimension)} "
                                  f"with a threshold that is {describe(parameter.dimension)}",
                                  expr.parameter.span if expr.parameter else expr.span))
            return None
        if parameter.axes:
            problems.append(error("E302", "time_above needs one threshold, got one per "
                                  + " and ".join(parameter.axes),
                                  expr.parameter.span if expr.parameter else expr.span))
            return None
        return ExprType(TIME, operand.without(axis).axes)
    result = operand.without(axis)
    if expr.reducer == "integral":
        return ExprType(result.dimension * TIME, result.axes)
    return result


def _invalid(expr: Invalid, scope: Scope, problems: Problems) -> ExprType | None:
    """No type: the parser said what is wrong. What a reduction over an unknown domain reads
    is checked as its reduction would (in a constant, a reduction is wrong whatever it reads)."""
    written = expr.written
    if written is not None and scope.kind not in ("constant", "parameter"):
        infer_type(written.operand, scope, problems)
        for inner in (written.parameter, written.window.value if written.window else None):
            if inner is not None:
                infer_type(inner, _parameter_scope(scope), problems)
    return None


_HANDLERS: dict[type, Callable[[Expr, Scope, Problems], ExprType | None]] = {
    Number: _number,  # type: ignore[dict-item]
    Name: _name,  # type: ignore[dict-item]
    Select: _select,  # type: ignore[dict-item]
    Table: _table,  # type: ignore[dict-item]
    Unary: _unary,  # type: ignore[dict-item]
    Binary: _binary,  # type: ignore[dict-item]
    Call: _call,  # type: ignore[dict-item]
    Reduce: _reduce,  # type: ignore[dict-item]
    Invalid: _invalid,  # type: ignore[dict-item]
}

__all__ = ["BOOLEAN", "did_you_mean", "infer_type"]
