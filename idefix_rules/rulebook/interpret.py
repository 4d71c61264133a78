"""The reference interpreter: one run at a time, one element at a time, in plain Python.

Slow and meant to be obviously correct: a value is a dictionary from label positions (one per
axis the value has, in the order time, wheel, part, level) to a number, and every operation is
a loop over those labels. It shares only *meaning* with the compiler (:mod:`.semantics`: the
per-sample form, label positions; :mod:`.derived`: the derived signals, computed for one run at
a time) so the two evaluators check each other: the test suite runs both on every golden case
and on generated rulebooks and signals.

>>> from idefix_rules.rulebook.interpret import reduce_series
>>> float(reduce_series("integral", [0.0, 1.0, 2.0], [True, True, True], [0.0, 1.0, 2.0], None))
2.0
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from idefix_rules.rulebook.across import runs_reductions
from idefix_rules.rulebook.check import CheckedRulebook
from idefix_rules.rulebook.derived import DerivedSettings, DerivedSignals, RunContext
from idefix_rules.rulebook.fold import number_si
from idefix_rules.rulebook.model import (
    DOMAIN_AXES,
    Binary,
    Call,
    Expr,
    Name,
    Number,
    Reduce,
    Rulebook,
    Select,
    Table,
    Unary,
    Window,
)
from idefix_rules.rulebook.results import RunEvaluation
from idefix_rules.rulebook.semantics import (
    AXES,
    LABEL_AXIS,
    Masked,
    counts_own_samples,
    names_in,
    normalised,
    per_sample_form,
)
from idefix_rules.signals import AXIS_LABELS, lookup

Scalar = Any  # np.float64 or bool


@dataclass(frozen=True)
class Value:
    """A value of one run: ``data[(position per axis …)]`` for the axes in ``axes``."""

    axes: tuple[str, ...]
    data: dict[tuple[int, ...], Scalar]

    @staticmethod
    def scalar(x: Scalar) -> Value:
        return Value((), {(): x})

    def only(self) -> Scalar:
        assert not self.axes, f"expected a single value, got axes {self.axes}"
        return self.data[()]


def _nan_max(items: Sequence[Scalar]) -> Scalar:
    result = items[0]
    for item in items[1:]:
        if math.isnan(item) or item > result:
            result = item
        if math.isnan(result):
            return result
    return result


def _nan_min(items: Sequence[Scalar]) -> Scalar:
    result = items[0]
    for item in items[1:]:
        if math.isnan(item) or item < result:
            result = item
        if math.isnan(result):
            return result
    return result


def _sum(items: Sequence[Scalar]) -> np.float64:
    """Exactly rounded sum; inf/NaN follow IEEE like numpy."""
    try:
        return np.float64(math.fsum(items))
    except (OverflowError, ValueError):
        return np.float64(sum(np.float64(x) for x in items))


def reduce_series(reducer: str, xs: Sequence[Scalar], inside: Sequence[bool],
                  t: Sequence[float] | None, parameter: float | None) -> Scalar:
    """One reduction (see the table in :mod:`.semantics`) of the series ``xs``; ``inside``
    marks the window, ``t`` the sample times (time reductions only)."""
    window = [x for x, keep in zip(xs, inside, strict=True) if keep]
    if reducer == "any":
        return any(bool(x) for x in window)
    if reducer == "all":
        return all(bool(x) for x in window)
    if reducer == "count":
        return np.float64(sum(1 for x in window if x))
    if reducer == "fraction":
        return np.float64(sum(1 for x in window if x) / len(window)) if window else \
            np.float64(0.0)
    if not window:
        return np.float64(0.0)
    window = [np.float64(x) for x in window]
    if reducer == "final":
        return window[-1]
    if reducer == "initial":
        return window[0]
    if reducer == "max":
        return _nan_max(window)
    if reducer == "min":
        return _nan_min(window)
    if reducer == "sum":
        return _sum(window)
    if reducer == "mean":
        return _sum(window) / len(window)
    if reducer == "rms":
        return np.sqrt(_sum([x * x for x in window]) / len(window))
    if reducer == "percentile":
        assert parameter is not None
        if any(math.isnan(x) for x in window):
            return np.float64(math.nan)
        ordered = sorted(window)
        rank = parameter / 100.0 * (len(ordered) - 1)
        low = math.floor(rank)
        high = min(low + 1, len(ordered) - 1)
        fraction = rank - low
        if fraction == 0:
            return ordered[low]
        return ordered[low] + (ordered[high] - ordered[low]) * fraction
    assert t is not None, f"{reducer} is a time reduction"
    if reducer == "integral":
        return _sum([0.5 * (np.float64(xs[i]) + np.float64(xs[i + 1])) * (t[i + 1] - t[i])
                     for i in range(len(xs) - 1) if inside[i] and inside[i + 1]])
    if reducer == "time_above":
        assert parameter is not None
        return _sum([(t[i + 1] - t[i]) if i + 1 < len(xs) else 0.0
                     for i in range(len(xs)) if inside[i] and xs[i] > parameter])
    raise AssertionError(f"unknown reducer {reducer!r}")


class _Run:
    """Evaluation of expressions for one run."""

    def __init__(self, source: DerivedSignals, constants: Mapping[str, Value],
                 scope: Mapping[str, Scalar] | None = None) -> None:
        self.source = source
        self.constants = constants
        self.scope = scope or {}
        self.t = [float(v) for v in source.t] if source is not None else []
        # Every run of the batch (for reductions over runs) and their results, shared.
        self.peers: list[_Run] = [self]
        self.across: dict[Reduce, Value] = {}

    def size(self, axis: str) -> int:
        return len(self.t) if axis == "time" else len(AXIS_LABELS[axis])

    def signal(self, name: str) -> Value:
        spec = lookup(name)
        assert spec is not None, name
        array = np.asarray(self.source.get(name))[0]
        data = {index: (bool(array[index]) if array.dtype == bool else np.float64(array[index]))
                for index in np.ndindex(array.shape)}
        return Value(spec.axes, data)

    def window(self, window: Window) -> list[bool]:
        bound = float(constant_value(window.value, self.constants).only())
        if window.kind == "command":
            command = np.asarray(self.source.get("command"))[0]
            return [round(float(c)) == round(bound) - 1 for c in command]
        if window.kind == "after":
            return [t >= bound for t in self.t]
        return [t < bound for t in self.t]

    def evaluate(self, expr: Any) -> Value:
        if isinstance(expr, Number):
            return Value.scalar(np.float64(number_si(expr)))
        if isinstance(expr, Name):
            if expr.name in self.constants:
                return self.constants[expr.name]
            if expr.name in self.scope:
                return Value.scalar(self.scope[expr.name])
            return self.signal(expr.name)
        if isinstance(expr, Table):
            return _table(expr, self.constants)
        if isinstance(expr, Select):
            return _select(self.evaluate(expr.operand), expr.labels)
        if isinstance(expr, Unary):
            operand = self.evaluate(expr.operand)
            if expr.op == "not":
                return elementwise(lambda x: not x, [operand], self.size)
            return elementwise(lambda x: -np.float64(x), [operand], self.size)
        if isinstance(expr, Binary):
            return elementwise(BINARY[expr.op], [self.evaluate(expr.left),
                                                 self.evaluate(expr.right)], self.size)
        if isinstance(expr, Call):
            return elementwise(CALLS[expr.function], [self.evaluate(a) for a in expr.args],
                               self.size)
        if isinstance(expr, Masked):
            inside = Value(("time",), {(i,): keep for i, keep in
                                       enumerate(self.window(expr.window))})
            return elementwise(lambda x, keep: np.float64(x) if keep else np.float64(0.0),
                               [self.evaluate(expr.operand), inside], self.size)
        if isinstance(expr, Reduce):
            return self.reduce(expr)
        raise AssertionError(f"cannot interpret {type(expr).__name__}")

    def reduce(self, expr: Reduce) -> Value:
        if expr.domain == "runs":
            return self.reduce_runs(expr)
        if expr.reducer == "rate":
            return self.rate(self.evaluate(expr.operand))
        operand = self.evaluate(expr.operand)
        axis = DOMAIN_AXES[expr.domain]
        size = self.size(axis)
        parameter = (None if expr.parameter is None
                     else float(constant_value(expr.parameter, self.constants).only()))
        inside = self.window(expr.window) if expr.window is not None else [True] * size
        if counts_own_samples(expr, self.constants):
            lengths = self.source.run_lengths()
            if lengths is not None:  # the samples held after the run's end do not count
                # (the run's last own sample holds no time: time_above's hold ends with it)
                own = int(lengths[0]) - (1 if expr.reducer == "time_above" else 0)
                inside = [keep and k < own for k, keep in enumerate(inside)]
        times = self.t if axis == "time" else None
        if axis not in operand.axes:  # constant along the axis
            operand = elementwise(lambda x, _: x, [operand, _ones(axis, size)], self.size)
        position = operand.axes.index(axis)
        rest = tuple(a for a in operand.axes if a != axis)
        groups: dict[tuple[int, ...], list[Scalar]] = {}
        for key in sorted(operand.data):
            groups.setdefault(key[:position] + key[position + 1:], []).append(operand.data[key])
        return Value(rest, {key: reduce_series(expr.reducer, xs, inside, times, parameter)
                            for key, xs in groups.items()})


    def rate(self, operand: Value) -> Value:
        """Rate of change sample by sample (see :mod:`.semantics`), each series of the
        operand's other labels on its own."""
        if "time" not in operand.axes:  # constant in time
            operand = elementwise(lambda x, _: x, [operand, _ones("time", len(self.t))],
                                  self.size)
        position = operand.axes.index("time")
        data: dict[tuple[int, ...], Scalar] = {}
        for key, _x in operand.data.items():
            i = key[position]
            if len(self.t) < 2:
                data[key] = np.float64(0.0)
                continue
            j, k = (i - 1, i) if i > 0 else (0, 1)
            earlier = operand.data[(*key[:position], j, *key[position + 1:])]
            later = operand.data[(*key[:position], k, *key[position + 1:])]
            dt = self.t[k] - self.t[j]
            data[key] = (np.float64(later) - np.float64(earlier)) / dt if dt > 0 else \
                np.float64(0.0)
        return Value(operand.axes, data)

    def reduce_runs(self, expr: Reduce) -> Value:
        """The operand in every run of the batch, reduced label by label across the runs."""
        if expr not in self.across:
            values = [peer.evaluate(expr.operand) for peer in self.peers]
            parameter = (None if expr.parameter is None
                         else float(constant_value(expr.parameter, self.constants).only()))
            everyone = [True] * len(values)
            self.across[expr] = Value(values[0].axes, {
                key: reduce_series(expr.reducer, [value.data[key] for value in values],
                                   everyone, None, parameter)
                for key in values[0].data})
        return self.across[expr]


def _ones(axis: str, size: int) -> Value:
    return Value((axis,), {(i,): True for i in range(size)})


def elementwise(function: Callable[..., Scalar], values: Sequence[Value],
                size: Callable[[str], int]) -> Value:
    """Apply ``function`` label by label; axes are the union, broadcast by name."""
    axes = tuple(a for a in AXES if any(a in v.axes for v in values))
    data = {}
    for key in itertools.product(*(range(size(a)) for a in axes)):
        labels = dict(zip(axes, key, strict=True))
        args = []
        for value in values:
            args.append(value.data[tuple(labels[a] for a in value.axes)])
        data[key] = function(*args)
    return Value(axes, data)


def _select(value: Value, labels: tuple[str, ...]) -> Value:
    wanted = {LABEL_AXIS[label][0]: LABEL_AXIS[label][1] for label in labels}
    axes = tuple(a for a in value.axes if a not in wanted)
    data = {}
    for key, item in value.data.items():
        if all(key[value.axes.index(a)] == p for a, p in wanted.items() if a in value.axes):
            data[tuple(k for a, k in zip(value.axes, key, strict=True) if a not in wanted)] = item
    return Value(axes, data)


def _table(table: Table, constants: Mapping[str, Value]) -> Value:
    axis = LABEL_AXIS[table.entries[0][0]][0]
    return Value((axis,), {(LABEL_AXIS[label][1],): constant_value(entry, constants).only()
                           for label, entry in table.entries})


def constant_value(expr: Expr, constants: Mapping[str, Value]) -> Value:
    """A constant expression's value (no signals)."""
    return _Run(None, constants).evaluate(expr)  # type: ignore[arg-type]


def _f(x: Scalar) -> np.float64:
    return np.float64(x)


BINARY: dict[str, Callable[[Scalar, Scalar], Scalar]] = {
    "+": lambda a, b: _f(a) + _f(b),
    "-": lambda a, b: _f(a) - _f(b),
    "*": lambda a, b: _f(a) * _f(b),
    "/": lambda a, b: _f(a) / _f(b),
    "^": lambda a, b: _f(a) ** _f(b),
    "<": lambda a, b: bool(a < b),
    "<=": lambda a, b: bool(a <= b),
    ">": lambda a, b: bool(a > b),
    ">=": lambda a, b: bool(a >= b),
    "==": lambda a, b: bool(a == b),
    "!=": lambda a, b: bool(a != b),
    "and": lambda a, b: bool(a) and bool(b),
    "or": lambda a, b: bool(a) or bool(b),
}

CALLS: dict[str, Callable[..., Scalar]] = {
    "abs": lambda x: abs(_f(x)),
    "sqrt": lambda x: np.sqrt(_f(x)),
    "min": lambda *xs: _nan_min([_f(x) for x in xs]),
    "max": lambda *xs: _nan_max([_f(x) for x in xs]),
    "hypot": lambda a, b: np.float64(math.hypot(_f(a), _f(b))),
    "clamp": lambda x, low, high: _nan_min([_nan_max([_f(x), _f(low)]), _f(high)]),
}


def _constants(checked: CheckedRulebook) -> dict[str, Value]:
    out = {}
    for name, value in checked.constants.items():
        if isinstance(value, dict):
            axis = LABEL_AXIS[next(iter(value))][0]
            out[name] = Value((axis,), {(LABEL_AXIS[k][1],): np.float64(v)
                                        for k, v in value.items()})
        else:
            out[name] = Value.scalar(np.float64(value))
    return out


def interpret(rulebook: CheckedRulebook, signals: Mapping[str, np.ndarray],
              context: RunContext) -> RunEvaluation:
    """Evaluate every run separately; the same record ``CompiledRulebook.evaluate`` returns."""
    model: Rulebook = rulebook.rulebook
    constants = _constants(rulebook)
    settings = DerivedSettings(rulebook.settings.get("theoretical_slip", 0.0),
                               rulebook.settings.get("tolerance_growth", 0.0))
    names = tuple(i.name for i in model.indices)
    chance_names = tuple(c.name for c in model.chances)
    runs = int(np.asarray(signals["t"]).shape[0])
    rows = []
    evaluators = [_Run(DerivedSignals({k: np.asarray(v)[run:run + 1]
                                       for k, v in signals.items()}, context, settings),
                       constants)
                  for run in range(runs)]
    across: dict[Reduce, Value] = {}
    for evaluator in evaluators:  # reductions over runs see every run of the batch
        evaluator.peers, evaluator.across = evaluators, across
    for evaluator in evaluators:
        with np.errstate(all="ignore"):  # IEEE results (inf, NaN) are the semantics
            rows.append(_evaluate_run(model, rulebook, evaluator, constants, names,
                                      chance_names))
    return _stack(rows, names, chance_names)


def _non_finite(evaluator: _Run, expr: Expr, constants: Mapping[str, Value]) -> bool:
    """Whether ``expr`` reads a non-finite signal in this run, or a path-level value
    (``… over runs``) that is not a number (:func:`_operand_non_finite` in any run)."""
    if _reads_non_finite(evaluator, expr, constants):
        return True
    return any(_operand_non_finite(peer, node.operand, constants)
               for node in runs_reductions([expr]) for peer in evaluator.peers)


def _operand_non_finite(evaluator: _Run, operand: Expr, constants: Mapping[str, Value]
                        ) -> bool:
    """Whether a reduction over runs reads no number from this run: a number that is not
    finite, or a truth value computed from a signal that is not (the comparison lost its
    NaN)."""
    items = list(evaluator.evaluate(operand).data.values())
    if items and all(isinstance(item, (bool, np.bool_)) for item in items):
        return _reads_non_finite(evaluator, operand, constants)
    return not all(math.isfinite(item) for item in items)


def _reads_non_finite(evaluator: _Run, expr: Expr, constants: Mapping[str, Value]) -> bool:
    for name in sorted(names_in(expr)):
        if name in constants or lookup(name) is None:
            continue
        for item in evaluator.signal(name).data.values():
            if not isinstance(item, bool) and not math.isfinite(item):
                return True
    return False


def _evaluate_run(model: Rulebook, checked: CheckedRulebook, evaluator: _Run,
                  constants: Mapping[str, Value], names: tuple[str, ...],
                  chance_names: tuple[str, ...]) -> dict[str, Any]:
    row: dict[str, Any] = {"values": {}, "raw": {}, "per_sample": {}, "weighted": {},
                           "chances": {}}
    samples = len(evaluator.t)
    for index in model.indices:
        limit, weight = checked.limits[index.name], checked.weights[index.name]
        nominal = checked.nominals.get(index.name)
        raw = evaluator.evaluate(index.value).only()
        sample_expr = index.map if index.map is not None else per_sample_form(index.value)
        sample = evaluator.evaluate(sample_expr)
        series = ([sample.data[(i,)] for i in range(samples)] if sample.axes == ("time",)
                  else [sample.only()] * samples)
        bad = math.isnan(raw) or _non_finite(evaluator, index.value, constants) \
            or (index.map is not None and _non_finite(evaluator, index.map, constants))
        row["raw"][index.name] = math.nan if bad else float(raw)
        row["values"][index.name] = 1.0 if bad else normalised(float(raw), limit, nominal)
        row["per_sample"][index.name] = [normalised(float(x), limit, nominal) for x in series]
        row["weighted"][index.name] = weight * row["values"][index.name]
    for chance in model.chances:
        holds = bool(evaluator.evaluate(chance.condition).only())
        row["chances"][chance.name] = holds or _non_finite(evaluator, chance.condition,
                                                           constants)
    weighted = [row["weighted"][n] for n in names]
    row["i_max"] = max(weighted)
    row["dominant"] = weighted.index(row["i_max"])
    per_sample = row["per_sample"][names[row["dominant"]]]
    row["dominant_sample"] = per_sample.index(max(per_sample))
    # The run ends where the chain is complete: 'command' back at -1 after the chain started
    # (or past its last command), else a mapped 'done' set after a sample where it was not,
    # else the last sample; a chain that moves nothing is complete wherever the output says
    # so. Without 'energy' the run's energy is unknown (NaN).
    source = evaluator.source
    commands = len(source.context.chain)
    idle = all(c.delta_position == 0 and c.delta_heading == 0 for c in source.context.chain)
    ended: list[bool] = []
    if source.provides("command"):
        started = idle
        for value in np.asarray(source.get("command"))[0]:
            active = round(float(value))
            started = started or active >= 0
            ended.append(started and (active >= commands or active < 0))
    elif source.provides("done"):  # set after a sample where it was not
        clear = idle
        for value in np.asarray(source.get("done"))[0]:
            clear = clear or float(value) < 0.5
            ended.append(clear and float(value) >= 0.5)
    done = ended.index(True) if True in ended else samples - 1
    row["time"] = evaluator.t[done]
    row["energy"] = float(np.asarray(source.get("energy"))[0][done]) \
        if source.provides("energy") else math.nan
    return row


def _stack(rows: list[dict[str, Any]], names: tuple[str, ...],
           chance_names: tuple[str, ...]) -> RunEvaluation:
    def column(key: str, name: str | None = None, dtype: Any = float) -> np.ndarray:
        return np.array([row[key] if name is None else row[key][name] for row in rows],
                        dtype=dtype)

    return RunEvaluation(
        index_names=names,
        values={n: column("values", n) for n in names},
        raw={n: column("raw", n) for n in names},
        per_sample={n: column("per_sample", n) for n in names},
        weighted={n: column("weighted", n) for n in names},
        i_max=column("i_max"),
        dominant=column("dominant", dtype=int),
        dominant_sample=column("dominant_sample", dtype=int),
        chance_names=chance_names,
        chances={n: column("chances", n, bool) for n in chance_names},
        time=column("time"),
        energy=column("energy"),
    )
