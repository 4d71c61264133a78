"""Path-level values: reductions over the runs of a path (``mean over runs (…)``).

The paper judges position by the runs together: I_pos exceeds "when the **average** rover
position is outside the tolerance". ``REDUCER over runs (OPERAND)`` reduces the operand across
every evaluated (complete) run of the path; the result is one value for the path, broadcast to
each run, so it takes part in every run's I_max (eq. 1) and in the per-sample map like any other
value. The operand may keep a time (or wheel/part/level) axis — ``mean over runs (x - ref.x)``
is the mean trajectory's offset at each sample — except for ``percentile``, which needs one
value per run.

Runs are evaluated chunk by chunk (memory bounded in the number of runs), so a path-level value
is computed in a first pass: :class:`AcrossRuns` accumulates, per reduction, a partial state
that merges across chunks (sums, counts, extremes; the per-run values for a percentile), and the
evaluation of every chunk then reads the finished values. With the whole path in one batch the
compiled evaluator does both steps itself.

Semantics (the interpreter implements the same with plain Python over its runs):

==============  ==========================================  =============
reducer         value over the n runs                       no runs (n=0)
==============  ==========================================  =============
``mean``        arithmetic mean                             0
``sum``         sum                                         0
``rms``         ``sqrt(mean(x²))``                          0
``max/min``     largest / smallest (NaN if any run is NaN)  0
``percentile``  numpy ``linear`` percentile                 0
``any/all``     some / every run true                       false / true
``count``       number of runs where it holds               0
``fraction``    ``count / n``                               0
==============  ==========================================  =============

>>> import numpy as np
>>> from idefix_rules.rulebook.model import Name, Reduce
>>> node = Reduce("mean", "runs", Name("x"))
>>> accumulator = RunsAccumulator(node)
>>> accumulator.add(np.array([1.0, 2.0])); accumulator.add(np.array([6.0]))
>>> accumulator.result().tolist()
[3.0]
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from typing import Any

import numpy as np

from idefix_rules.rulebook import reducers
from idefix_rules.rulebook.expressions import children
from idefix_rules.rulebook.fold import number_si
from idefix_rules.rulebook.model import Expr, Number, Reduce


def runs_reductions(expressions: Iterable[Expr]) -> tuple[Reduce, ...]:
    """The distinct ``… over runs (…)`` nodes in ``expressions``, in first-seen order."""
    found: dict[Reduce, None] = {}
    for expr in expressions:
        for node in _walk(expr):
            if isinstance(node, Reduce) and node.domain == "runs":
                found.setdefault(node, None)
    return tuple(found)


def _walk(expr: Any) -> Iterator[Any]:
    yield expr
    for child in children(expr):
        yield from _walk(child)


class RunsAccumulator:
    """Partial state of one reduction over runs; ``add`` per chunk, ``merge`` partials,
    ``result`` the value (run axis of length 1, the operand's other axes kept)."""

    def __init__(self, node: Reduce, parameter: float | None = None) -> None:
        self.node = node
        self.reducer = node.reducer
        # the percentile's P, folded by the caller when it names constants
        self.parameter = parameter if parameter is not None or node.parameter is None else \
            _parameter(node.parameter)
        self.runs = 0
        self.state: np.ndarray | None = None  # sum, sum of squares, extreme or true count
        self.values: list[np.ndarray] = []  # percentile only
        # Some run's operand read a non-finite signal or was non-finite itself: the path-level
        # value is not a number, whatever the reducer made of it (a comparison with NaN is
        # false, so `fraction over runs (x > 1)` would count that run as not holding).
        self.non_finite = False

    def add(self, values: Any, non_finite: bool = False) -> None:
        """Add the operand's values of a chunk of runs (axis 0 = run); ``non_finite``: some
        run of the chunk read a non-finite signal in the operand."""
        array = np.asarray(values)
        if array.ndim == 0:
            raise ValueError("add() needs the run axis (expressions.runs_first spells it out)")
        self.runs += array.shape[0]
        if non_finite or (array.dtype != bool and not np.isfinite(array).all()):
            self.non_finite = True
        if self.reducer == "percentile":
            self.values.append(np.asarray(array, dtype=float))
            return
        part = self._partial(array)
        self.state = part if self.state is None else self._combine(self.state, part)

    def _partial(self, array: np.ndarray) -> np.ndarray:
        if self.reducer in ("any", "all", "count", "fraction"):
            truth = array if array.dtype == bool else array != 0
            return np.asarray(truth.sum(axis=0, keepdims=True), dtype=float)
        array = np.asarray(array, dtype=float)
        if self.reducer in ("sum", "mean"):
            return np.asarray(array.sum(axis=0, keepdims=True))
        if self.reducer == "rms":
            return np.asarray((array * array).sum(axis=0, keepdims=True))
        if self.reducer == "max":
            return np.asarray(array.max(axis=0, keepdims=True))
        if self.reducer == "min":
            return np.asarray(array.min(axis=0, keepdims=True))
        raise AssertionError(f"{self.reducer} does not reduce over runs")  # checker rejects

    def _combine(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        if self.reducer == "max":
            return np.asarray(np.maximum(a, b))  # NaN propagates, like max over one batch
        if self.reducer == "min":
            return np.asarray(np.minimum(a, b))
        return np.asarray(np.add(*np.broadcast_arrays(a, b)))

    def copy(self) -> RunsAccumulator:
        """A copy to fold more chunks on (this one stays as it is)."""
        twin = RunsAccumulator(self.node, self.parameter)
        twin.runs = self.runs
        twin.non_finite = self.non_finite
        twin.state = None if self.state is None else self.state.copy()
        twin.values = list(self.values)  # arrays never changed in place
        return twin

    def merge(self, other: RunsAccumulator) -> None:
        """Fold another partial of the same reduction (e.g. another worker's chunks) in."""
        self.runs += other.runs
        self.non_finite = self.non_finite or other.non_finite
        self.values += other.values
        if other.state is not None:
            self.state = other.state if self.state is None else self._combine(self.state,
                                                                               other.state)

    def result(self) -> np.ndarray:
        """The path-level value, shaped like one run of the operand (run axis of length 1)."""
        n = self.runs
        if self.reducer == "percentile":
            if not n:
                return np.zeros(1)
            values = np.concatenate(self.values, axis=0)
            return reducers.reduce("percentile", values, 0, n, None, self.parameter)
        if self.state is None:
            return np.asarray([{"any": False, "all": True}.get(self.reducer, 0.0)])
        state = self.state
        if self.reducer == "any":
            return np.asarray(state > 0)
        if self.reducer == "all":
            return np.asarray(state == n)
        if self.reducer in ("mean", "fraction"):
            return np.asarray(state / n)
        if self.reducer == "rms":
            return np.asarray(np.sqrt(state / n))
        return np.asarray(state)  # sum, count, max, min


def _parameter(expr: Expr) -> float:
    """The percentile parameter written in place (one naming constants is folded by
    :class:`AcrossRuns`' caller, which knows them)."""
    assert isinstance(expr, Number), "a percentile naming constants needs them folded"
    return float(number_si(expr))


class AcrossRuns:
    """Accumulators of every reduction over runs of a rulebook, for one path.

    ``add`` evaluates the operands on a chunk (a callable from node to the operand's values
    with the run axis first) and folds them in; ``values`` gives the finished path-level
    values by node, which the evaluators read in place of the reductions.
    """

    def __init__(self, nodes: Iterable[Reduce],
                 parameters: Mapping[Reduce, float] | None = None) -> None:
        """``parameters``: each percentile's P where it names constants (folded)."""
        self.accumulators = {node: RunsAccumulator(node, (parameters or {}).get(node))
                             for node in nodes}

    @property
    def runs(self) -> int:
        return next(iter(self.accumulators.values())).runs if self.accumulators else 0

    def copy(self) -> AcrossRuns:
        """A copy to fold more chunks on (this one stays as it is)."""
        twin = AcrossRuns(())
        twin.accumulators = {node: a.copy() for node, a in self.accumulators.items()}
        return twin

    def merge(self, other: AcrossRuns) -> None:
        for node, accumulator in other.accumulators.items():
            self.accumulators[node].merge(accumulator)

    def values(self) -> dict[Reduce, np.ndarray]:
        return {node: accumulator.result() for node, accumulator in self.accumulators.items()}

    def non_finite(self) -> frozenset[Reduce]:
        """The reductions some run's operand of which read a non-finite value: an index or
        chance reading one is critical (holds) in every run of the path."""
        return frozenset(node for node, accumulator in self.accumulators.items()
                         if accumulator.non_finite)


def first_pass(evaluators: Sequence[Any], chunks: Callable[[set[str]], Iterable[Any]],
               context: Any, start: Sequence[AcrossRuns | None] | None = None
               ) -> list[AcrossRuns | None]:
    """The path-level values of each evaluator over every run of one path (None for an
    evaluator without reductions over runs).

    ``chunks(signal_names)`` yields the path's complete runs chunk by chunk (dicts of signals,
    axis 0 = run) with at least those signals; it is called only when some evaluator needs a
    first pass, once for all of them. ``start``: the accumulators of the runs before those
    chunks (as an earlier call returned them; copied, never changed), to fold the chunks on.
    """
    wanted = [e if getattr(e, "runs_reductions", ()) else None for e in evaluators]
    accumulators: list[AcrossRuns | None] = [
        None if e is None else e.new_across() for e in wanted] \
        if start is None else [None if a is None else a.copy() for a in start]
    needed = [e for e in wanted if e is not None]
    if not needed:
        return accumulators
    names: set[str] = set().union(*(set(e.across_signals) for e in needed))
    for signals in chunks(names):
        for evaluator, accumulator in zip(wanted, accumulators, strict=True):
            if evaluator is not None:
                evaluator.across_runs(signals, context, into=accumulator)
    return accumulators


def finished(across: AcrossRuns | Mapping[Reduce, np.ndarray]) -> Mapping[Reduce, np.ndarray]:
    """Path-level values by node, from an accumulator or already finished values."""
    return across.values() if isinstance(across, AcrossRuns) else across


def non_finite_nodes(across: AcrossRuns | Mapping[Reduce, np.ndarray] | None
                     ) -> frozenset[Reduce]:
    """The path-level values that are not numbers: an accumulator says which operands read a
    non-finite value; of finished values, those not finite."""
    if across is None:
        return frozenset()
    if isinstance(across, AcrossRuns):
        return across.non_finite()
    return frozenset(node for node, value in across.items()
                     if np.asarray(value).dtype != bool and not np.isfinite(value).all())


__all__ = ["AcrossRuns", "RunsAccumulator", "finished", "first_pass", "non_finite_nodes",
           "runs_reductions"]
