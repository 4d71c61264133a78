"""Compile rule-model expressions to Python closures over numpy arrays.

A closure takes a :class:`Frame` (the signals of one evaluation call, or a scope of named
values) and returns an array laid out (runs, time, wheel, part, level) — size 1 along every axis
the value does not vary on — or a plain float for constants. Nothing from the rulebook text is
ever executed: every node maps to a fixed numpy operation.

Sub-expressions that appear more than once (e.g. the operand of a time reduction, which the
index value and its per-sample form share) are computed once per call: :meth:`ExpressionCompiler
.share` marks them before compiling.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from idefix_rules.rulebook import reducers
from idefix_rules.rulebook.derived import DerivedSignals
from idefix_rules.rulebook.fold import number_si
from idefix_rules.rulebook.model import (
    DOMAIN_AXES,
    Binary,
    Call,
    Expr,
    Name,
    Number,
    Reduce,
    Select,
    Table,
    Unary,
    Window,
)
from idefix_rules.rulebook.semantics import (
    AXES,
    LABEL_AXIS,
    Masked,
    counts_own_samples,
)
from idefix_rules.signals import AXIS_LABELS, lookup

Closure = Callable[["Frame"], Any]
_NDIM = 1 + len(AXES)


@dataclass
class Frame:
    """Inputs of one evaluation: signals (index/chance scope) or named values (other scopes)."""

    source: DerivedSignals | None = None
    scope: Mapping[str, Any] = field(default_factory=dict)
    memo: dict[int, Any] = field(default_factory=dict)
    # Path-level values of the reductions over runs, by node (idefix_rules.rulebook.across).
    across: Mapping[Any, Any] = field(default_factory=dict)

    @property
    def samples(self) -> int:
        return self.source.samples if self.source is not None else 1


class InternalError(AssertionError):
    """The checked model holds something the checker should have rejected."""


def layout(array: np.ndarray, axes: tuple[str, ...]) -> np.ndarray:
    """Reshape a (runs, *axes) array into the (runs, time, wheel, part, level) layout."""
    shape = [array.shape[0]]
    position = 1
    for axis in AXES:
        if axis in axes:
            shape.append(array.shape[position])
            position += 1
        else:
            shape.append(1)
    return array.reshape(shape)


def axis_size(axis: str, frame: Frame) -> int:
    return frame.samples if axis == "time" else len(AXIS_LABELS[axis])


def per_run(value: Any, runs: int) -> np.ndarray:
    """A per-run scalar value (every other axis reduced) as an array (runs,)."""
    array = np.asarray(value, dtype=float)
    if array.ndim == 0:
        return np.full(runs, float(array))
    flat = array.reshape(array.shape[0], -1)
    if flat.shape[1] != 1:
        raise InternalError(f"expected one value per run, got shape {array.shape}")
    return np.broadcast_to(flat[:, 0], (runs,))


def per_run_sample(value: Any, runs: int, samples: int) -> np.ndarray:
    """A per-sample value (only the time axis left) as an array (runs, samples)."""
    array = np.asarray(value, dtype=float)
    if array.ndim == 0:
        return np.full((runs, samples), float(array))
    if array.ndim != _NDIM or any(n != 1 for n in array.shape[2:]):
        raise InternalError(f"expected a per-sample value, got shape {array.shape}")
    return np.broadcast_to(array[:, :, 0, 0, 0], (runs, samples))


def _float(x: Any) -> Any:
    return x.astype(float) if isinstance(x, np.ndarray) and x.dtype == bool else x


_ARITHMETIC: dict[str, Callable[[Any, Any], Any]] = {
    "+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide, "^": np.power,
}
_COMPARISON: dict[str, Callable[[Any, Any], Any]] = {
    "<": np.less, "<=": np.less_equal, ">": np.greater, ">=": np.greater_equal,
    "==": np.equal, "!=": np.not_equal,
}


class ExpressionCompiler:
    """Turns expressions into closures.

    ``constants`` maps constant names to SI floats or table arrays (already in the layout);
    ``resolve`` maps any other name to a closure (signals, scope names) or None (unknown).
    """

    def __init__(self, constants: Mapping[str, Any],
                 resolve: Callable[[str], Closure | None]) -> None:
        self.constants = constants
        self.resolve = resolve
        self._compiled: dict[Any, Closure] = {}
        self._uses: dict[Any, int] = {}

    # ------------------------------------------------------------------ sharing
    def share(self, expressions: Iterable[Any]) -> None:
        """Count how often each distinct sub-expression is used, so shared ones are memoised."""
        for expr in expressions:
            self._count(expr)

    def _count(self, expr: Any) -> None:
        self._uses[expr] = self._uses.get(expr, 0) + 1
        if self._uses[expr] > 1:
            return
        for child in children(expr):
            self._count(child)

    # ------------------------------------------------------------------ compiling
    def compile(self, expr: Any) -> Closure:
        closure = self._compiled.get(expr)
        if closure is None:
            closure = self._build(expr)
            if self._uses.get(expr, 0) > 1 and not isinstance(expr, Number):
                closure = _memoised(closure)
            self._compiled[expr] = closure
        return closure

    def constant(self, expr: Expr) -> Any:
        """Value of a constant expression (no signals)."""
        return self.compile(expr)(Frame())

    def _build(self, expr: Any) -> Closure:
        if isinstance(expr, Number):
            value = number_si(expr)
            return lambda frame: value
        if isinstance(expr, Name):
            return self._name(expr.name)
        if isinstance(expr, Table):
            return self._table(expr)
        if isinstance(expr, Select):
            return self._select(expr)
        if isinstance(expr, Unary):
            operand = self.compile(expr.operand)
            if expr.op == "-":
                return lambda frame: np.negative(_float(operand(frame)))
            return lambda frame: np.logical_not(operand(frame))
        if isinstance(expr, Binary):
            return self._binary(expr)
        if isinstance(expr, Call):
            return self._call(expr)
        if isinstance(expr, Reduce):
            return self._reduce(expr)
        if isinstance(expr, Masked):
            operand = self.compile(expr.operand)
            window = self._window(expr.window)
            return lambda frame: np.where(window(frame), _float(operand(frame)), 0.0)
        raise InternalError(f"cannot compile {type(expr).__name__}")

    def _name(self, name: str) -> Closure:
        if name in self.constants:
            value = self.constants[name]
            return lambda frame: value
        closure = self.resolve(name)
        if closure is None:
            raise InternalError(f"unknown name {name!r}")
        return closure

    def _table(self, table: Table) -> Closure:
        axis = LABEL_AXIS[table.entries[0][0]][0]
        values = np.zeros(len(AXIS_LABELS[axis]))
        for label, entry in table.entries:
            values[LABEL_AXIS[label][1]] = float(self.constant(entry))
        shape = [1] * _NDIM
        shape[1 + AXES.index(axis)] = values.size
        array = values.reshape(shape)
        return lambda frame: array

    def _select(self, select: Select) -> Closure:
        operand = self.compile(select.operand)
        index: list[Any] = [slice(None)] * _NDIM
        for label in select.labels:
            axis, position = LABEL_AXIS[label]
            index[1 + AXES.index(axis)] = slice(position, position + 1)
        key = tuple(index)

        def run(frame: Frame) -> Any:
            value = np.asarray(operand(frame))
            if value.ndim != _NDIM:
                raise InternalError("selection on a value without axes")
            # A value constant along the axis (size 1) has the same value at every label.
            return value[tuple(k if value.shape[i] > 1 else slice(None)
                               for i, k in enumerate(key))]

        return run

    def _binary(self, expr: Binary) -> Closure:
        left, right = self.compile(expr.left), self.compile(expr.right)
        op = expr.op
        if op in _ARITHMETIC:
            function = _ARITHMETIC[op]
            return lambda frame: function(_float(left(frame)), _float(right(frame)))
        if op in _COMPARISON:
            function = _COMPARISON[op]
            return lambda frame: function(left(frame), right(frame))
        if op == "and":
            return lambda frame: np.logical_and(left(frame), right(frame))
        if op == "or":
            return lambda frame: np.logical_or(left(frame), right(frame))
        raise InternalError(f"unknown operator {op!r}")

    def _call(self, expr: Call) -> Closure:
        args = [self.compile(a) for a in expr.args]
        name = expr.function
        if name == "abs" and len(args) == 1:
            return lambda frame: np.abs(_float(args[0](frame)))
        if name == "sqrt" and len(args) == 1:
            return lambda frame: np.sqrt(_float(args[0](frame)))
        if name in ("min", "max") and args:
            function = np.minimum if name == "min" else np.maximum

            def extreme(frame: Frame) -> Any:
                result = _float(args[0](frame))
                for arg in args[1:]:
                    result = function(result, _float(arg(frame)))
                return result

            return extreme
        if name == "hypot" and len(args) == 2:
            return lambda frame: np.hypot(_float(args[0](frame)), _float(args[1](frame)))
        if name == "clamp" and len(args) == 3:
            return lambda frame: np.minimum(np.maximum(_float(args[0](frame)),
                                                       _float(args[1](frame))),
                                            _float(args[2](frame)))
        raise InternalError(f"unknown function {name}/{len(args)}")

    def _window(self, window: Window | None) -> Closure:
        if window is None:
            return lambda frame: None
        value = self.constant(window.value)
        if window.kind == "command":
            wanted = round(float(value)) - 1

            def during(frame: Frame) -> np.ndarray:
                assert frame.source is not None
                command = np.rint(frame.source.get("command"))
                return layout(np.asarray(command == wanted), ("time",))

            return _memoised(during)
        if window.kind == "after":
            return _memoised(lambda frame: layout(_time(frame) >= value, ("time",)))
        return _memoised(lambda frame: layout(_time(frame) < value, ("time",)))

    def _reduce(self, expr: Reduce) -> Closure:
        if expr.domain == "runs":
            return self._across(expr)
        operand = self.compile(expr.operand)
        axis_name = DOMAIN_AXES[expr.domain]
        axis = 1 + AXES.index(axis_name)
        window = self._window(expr.window)
        parameter = (None if expr.parameter is None else self.constant(expr.parameter))
        reducer = expr.reducer
        if reducer == "rate":
            def rate(frame: Frame) -> Any:
                value = np.asarray(operand(frame))
                if value.ndim == 0:
                    value = value.reshape((1,) * _NDIM)
                assert frame.source is not None
                return reducers.rate(_float(value), frame.source.t)

            return rate

        own = counts_own_samples(expr, self.constants)

        def run(frame: Frame) -> Any:
            value = np.asarray(operand(frame))
            if value.ndim == 0:
                value = value.reshape((1,) * _NDIM)
            t = frame.source.t if frame.source is not None and axis_name == "time" else None
            mask = window(frame)
            if own and frame.source is not None:
                samples = frame.source.own_samples()
                if samples is not None:
                    if reducer == "time_above":  # the run's last own sample holds no time
                        samples = np.concatenate(
                            [samples[:, 1:], np.zeros((samples.shape[0], 1), bool)], axis=1)
                    samples = layout(samples, ("time",))
                    mask = samples if mask is None else mask & samples
            return reducers.reduce(reducer, value, axis, axis_size(axis_name, frame), mask,
                                   parameter, t)

        return run


    def _across(self, expr: Reduce) -> Closure:
        """A reduction over runs reads its path-level value, computed beforehand over every
        run of the path (:class:`~idefix_rules.rulebook.across.AcrossRuns`)."""

        def run(frame: Frame) -> Any:
            try:
                return frame.across[expr]
            except KeyError:
                raise InternalError("a reduction over runs was evaluated before its "
                                    "path-level value was computed") from None

        return run


def runs_first(value: Any, runs: int) -> np.ndarray:
    """A compiled value with its run axis spelled out: (runs, time, wheel, part, level)."""
    array = np.asarray(value)
    if array.ndim == 0:
        array = array.reshape((1,) * _NDIM)
    return np.broadcast_to(array, (runs, *array.shape[1:]))


def _time(frame: Frame) -> np.ndarray:
    assert frame.source is not None
    return frame.source.t[np.newaxis]


def _memoised(closure: Closure) -> Closure:
    key = id(closure)

    def run(frame: Frame) -> Any:
        try:
            return frame.memo[key]
        except KeyError:
            value = frame.memo[key] = closure(frame)
            return value

    return run


def children(expr: Any) -> tuple[Any, ...]:
    """The sub-expressions an expression node evaluates (its operands and arguments)."""
    if isinstance(expr, Unary | Select | Masked):
        return (expr.operand,)
    if isinstance(expr, Binary):
        return (expr.left, expr.right)
    if isinstance(expr, Call):
        return tuple(expr.args)
    if isinstance(expr, Reduce):
        return (expr.operand,)
    return ()


def signal_closure(name: str) -> Closure | None:
    """Closure reading a contract signal (incl. ``ref.*`` and derived) in the layout."""
    spec = lookup(name)
    if spec is None:
        return None
    axes = spec.axes

    def run(frame: Frame) -> Any:
        if frame.source is None:
            raise InternalError(f"signal {name!r} read outside a run")
        return layout(frame.source.get(name), axes)

    return _memoised(run)
