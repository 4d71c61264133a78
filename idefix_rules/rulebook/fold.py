"""Constant folding: the SI value of an expression that reads only constants.

Limits, weights, thresholds, windows and settings are constant expressions; the compiler and
the checker both need their values. Tables fold to a ``{label: value}`` mapping.

>>> from idefix_rules.rulebook.model import Binary, Name, Number
>>> fold(Binary("*", Number(2), Name("tol0")), {"tol0": 0.05})
0.1
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

from idefix_rules.rulebook.model import Binary, Call, Expr, Name, Number, Select, Table, Unary
from idefix_rules.rulebook.types import FUNCTION_ARITY
from idefix_rules.units import parse_unit

Value = float | dict[str, float]


class NotConstant(Exception):
    """The expression reads something that is not a constant (a signal, an index …)."""


class NotComputable(ValueError):
    """A constant expression with no real value: beyond a double (``10 ^ 400``), outside a
    function's domain (``sqrt(-1)``, ``(-8) ^ 0.5``) or ``0 ^ -1``. The message says which,
    as the end of a sentence naming the expression ("… cannot be computed: …")."""


def number_si(number: Number) -> float:
    """A literal's value in SI (the unit was checked already)."""
    if number.unit is None:
        return float(number.value)
    return parse_unit(number.unit).to_si(number.value)


def fold(expr: Expr, constants: Mapping[str, Value]) -> Value:
    """SI value of a constant expression; raises :class:`NotConstant` when it is not one and
    :class:`NotComputable` when it has no real value. A division by zero gives ±inf or nan,
    which the callers refuse as not finite."""
    try:
        return _fold(expr, constants)
    except OverflowError:
        raise NotComputable("is beyond a double: its value is too large for a number") \
            from None
    except ZeroDivisionError:
        raise NotComputable("cannot be computed: 0 raised to a negative power is a division by "
                            "zero") from None


def _fold(expr: Expr, constants: Mapping[str, Value]) -> Value:
    if isinstance(expr, Number):
        return number_si(expr)
    if isinstance(expr, Name):
        if expr.name not in constants:
            raise NotConstant(expr.name)
        return constants[expr.name]
    if isinstance(expr, Table):
        out: dict[str, float] = {}
        for label, value in expr.entries:
            folded = _fold(value, constants)
            if isinstance(folded, dict):
                raise NotConstant("nested table")
            out[label] = folded
        return out
    if isinstance(expr, Select):
        base = _fold(expr.operand, constants)
        if not isinstance(base, dict) or len(expr.labels) != 1 or expr.labels[0] not in base:
            raise NotConstant("selection")  # of two axes' tables, or a label not there
        return base[expr.labels[0]]
    if isinstance(expr, Unary):
        if expr.op != "-":
            raise NotConstant("condition")
        return _map(lambda v: -v, _fold(expr.operand, constants))
    if isinstance(expr, Binary):
        return _binary(expr, constants)
    if isinstance(expr, Call):
        args = [_fold(arg, constants) for arg in expr.args]
        return _call(expr.function, args)
    raise NotConstant(type(expr).__name__)


def folded_number(expr: Expr, constants: Mapping[str, Value]) -> float | None:
    """The SI number a constant expression folds to; None when it is not constant, cannot be
    computed or is a table (its own checks say why)."""
    try:
        value = fold(expr, constants)
    except (NotConstant, NotComputable):
        return None
    return None if isinstance(value, dict) else float(value)


def _map(function: Callable[[float], float], value: Value) -> Value:
    if isinstance(value, dict):
        return {k: function(v) for k, v in value.items()}
    return function(value)


def _zip(function: Callable[[float, float], float], left: Value, right: Value) -> Value:
    if isinstance(left, dict) and isinstance(right, dict):
        if left.keys() != right.keys():  # two axes: one value per pair, folded by neither
            raise NotConstant("tables of two axes")
        return {k: function(left[k], right[k]) for k in left}
    if isinstance(left, dict):
        assert not isinstance(right, dict)
        return {k: function(v, right) for k, v in left.items()}
    if isinstance(right, dict):
        return {k: function(left, v) for k, v in right.items()}
    return function(left, right)


_OPS: dict[str, Callable[[float, float], float]] = {
    "+": lambda a, b: a + b,
    "-": lambda a, b: a - b,
    "*": lambda a, b: a * b,
    "/": lambda a, b: a / b if b != 0 else math.copysign(math.inf, a) if a else math.nan,
    "^": lambda a, b: _power(a, b),
}


def _power(base: float, exponent: float) -> float:
    result = base ** exponent
    if isinstance(result, complex):
        raise NotComputable(f"cannot be computed: ({base:g}) ^ {exponent:g} is not a real number "
                            "(a negative base with a fractional exponent)")
    return float(result)


def _sqrt(value: float) -> float:
    if value < 0:
        raise NotComputable(f"cannot be computed: sqrt({value:g}) is not a real number")
    return math.sqrt(value)


def _binary(expr: Binary, constants: Mapping[str, Value]) -> Value:
    if expr.op not in _OPS:
        raise NotConstant("condition")
    return _zip(_OPS[expr.op], _fold(expr.left, constants), _fold(expr.right, constants))


def _call(function: str, args: list[Value]) -> Value:
    # a call with another argument count is an error the checker reports (E106), not a value
    fewest, most = FUNCTION_ARITY.get(function, (1, 0))
    if not fewest <= len(args) <= most:
        raise NotConstant(function)
    if function == "abs":
        return _map(abs, args[0])
    if function == "sqrt":
        return _map(_sqrt, args[0])
    if function in ("min", "max"):
        pick: Callable[[float, float], float] = min if function == "min" else max
        result = args[0]
        for arg in args[1:]:
            result = _zip(pick, result, arg)
        return result
    if function == "hypot":
        return _zip(math.hypot, args[0], args[1])
    if function == "clamp":
        low = _zip(max, args[0], args[1])
        return _zip(min, low, args[2])
    raise NotConstant(function)
