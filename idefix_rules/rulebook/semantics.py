"""Meaning shared by both evaluators (the numpy compiler and the per-run interpreter).

Definitions that are semantics rather than implementation live here once, so the two evaluators
differ only in *how* they compute, never in *what*:

* the per-sample form of an index (every time reduction replaced by its operand, samples outside
  the reduction's window set to 0 — the result map's quantity);
* which labels belong to which axis, and axis sizes;
* the names an expression reads.

Reduction semantics (both evaluators implement exactly these; the window is the set of samples a
time reduction looks at, all samples when there is none):

====================  =========================================================  ============
reducer               value                                                      empty window
====================  =========================================================  ============
``final``/``initial``  last / first sample in the window                          0
``max``/``min``        largest / smallest                                         0
``sum``                sum                                                        0
``mean``               arithmetic mean of the samples (not time-weighted)         0
``rms``                ``sqrt(mean(x²))``                                         0
``count``              number of samples where the operand is true (non-zero)     0
``fraction``           ``count`` / number of samples in the window                 0
``any``/``all``        some / every sample true                                   false / true
``integral``           trapezoid ``Σ ½(xᵢ+xᵢ₊₁)(tᵢ₊₁-tᵢ)`` over consecutive window samples  0
``time_above T``       ``Σ (tᵢ₊₁-tᵢ)`` over window samples with ``xᵢ > T`` (last: 0)    0
``percentile P``       sorted window samples ``s``, ``r = P/100·(n-1)``,                0
                       ``s[⌊r⌋] + (s[⌈r⌉]-s[⌊r⌋])·(r-⌊r⌋)`` (numpy's ``linear``)
====================  =========================================================  ============

``rate over time (x)`` is no reduction: it keeps the time axis, its value at sample i the rate
of change of ``x`` up to that sample, ``(xᵢ - xᵢ₋₁) / (tᵢ - tᵢ₋₁)`` (backward difference, what
an on-board monitor sampling at the output interval would compute), at sample 0 the forward
difference ``(x₁ - x₀) / (t₁ - t₀)``; 0 where no time passes between two samples and for a
single sample. Its unit is x's per second. It takes no window (put the window on the reduction
around it) and only runs over time.

Over ``wheels``/``parts``/``levels`` the same reducers apply to the axis's labels in contract
order (``final`` = the last label). An operand without the reduced axis counts as constant along
it (``sum over wheels (1)`` is 4). Windows: ``during command K`` ⇔ ``command == K - 1``;
``after Q`` ⇔ ``t >= Q``; ``before Q`` ⇔ ``t < Q`` (simulation time, which starts at 0).

A run's own samples. All runs of a chain share one time grid, up to the chain's stop limit; a
run that finished its chain earlier is stored with its last sample held to the end of the grid
(the rover standing where it stopped). Its own samples are those up to the first sample, after
the one in which its chain is complete (``command`` back at -1, else ``done``), from which its
pose (``x``, ``y``, ``yaw``, those the runs give) no longer changes; without a pose, the sample
after the chain's end. A counting reducer (``mean``, ``rms``, ``sum``, ``count``, ``fraction``,
``percentile``, ``integral``, ``time_above``) over time of an operand that reads the run's own
signals counts only these samples (its window intersected with them; for ``time_above``
the last of them holds for no time, the run ending there), so that what a run
scores does not depend on how long the grid goes on after it: on the stop limit, or on how
long the other runs of the chain took. The other reducers (``final``, ``initial``, ``max``,
``min``, ``any``, ``all``) give the same value either way (the held samples repeat the last
one). Runs that give neither ``command`` nor ``done`` have no known end: every sample is
theirs. An operand that reads no signal of the run (only constants, ``ref.*`` or values over
runs) counts every sample of the grid.

Over ``runs`` (a path-level value): the same reducers (no ``final``/``initial``/``integral``/
``time_above``) apply across the runs of the evaluation, label by label of the operand's other
axes, the runs in any order; ``fraction`` is ``count / n``. The value is the same in every run,
and the per-sample form leaves it whole (:mod:`.across` has the table and the two-pass
evaluation of chunked runs).

Normalisation of an index's value *v* (run values and per-sample values alike), limit *L*
(> 0) and optional nominal *n* (0 < n < L), see :func:`normalised`:

=====================  ==============================================================
without a nominal      ``clamp(v / L, 0, 1)``
``v <= n``             ``clamp(0.5 · v / n, 0, 1)``
``v > n``              ``clamp(0.5 + 0.5 · (v - n) / (L - n), 0, 1)``
=====================  ==============================================================

Piecewise linear through (0, 0), (n, 0.5) and (L, 1): the nominal expectation scores 0.5, the
critical limit 1. Without a nominal the line through (0, 0) and (L, 1) is the same shape with
``n = L / 2``. A NaN value is 1.

Non-finite data: an index whose signals hold NaN or ±inf in a run is 1 (critical) for that run,
and so is an index whose raw value is NaN (e.g. 0/0); a chance whose signals hold non-finite
values in a run counts as holding. A path-level value that is no number (an operand NaN or
±inf in some run; a truth-valued operand whose signals are not finite in some run) makes the
indices reading it 1 and the chances reading it hold in every run. Normalised values and
per-sample values are always finite in [0, 1].
"""

from __future__ import annotations

import math
from collections.abc import Collection
from dataclasses import dataclass

from idefix_rules.rulebook.model import (
    Binary,
    Call,
    Expr,
    Name,
    Reduce,
    Select,
    Table,
    Unary,
    Window,
)
from idefix_rules.rulebook.walk import children, nodes
from idefix_rules.rulebook.walk import names_in as walk_names
from idefix_rules.signals import AXIS_LABELS

# Axes after the run axis, in the order the compiled evaluator lays arrays out.
AXES: tuple[str, ...] = ("time", "wheel", "part", "level")
LABEL_AXIS: dict[str, tuple[str, int]] = {
    label: (axis, position)
    for axis, labels in AXIS_LABELS.items()
    for position, label in enumerate(labels)
}
TIME_ONLY_REDUCERS = frozenset({"integral", "time_above", "rate"})
# Operators written like reductions that keep their axis (semantics in the module docstring).
AXIS_KEEPING_REDUCERS = frozenset({"rate"})
BOOLEAN_REDUCERS = frozenset({"any", "all"})
# Reducers whose value depends on how many samples their window holds: over time they count a
# run's own samples only (module docstring, "A run's own samples").
COUNTING_REDUCERS = frozenset({"mean", "rms", "sum", "count", "fraction", "percentile",
                               "integral", "time_above"})
# What tells where a run's own samples end (derived.DerivedSignals.own_samples): the chain's
# end ('command', else 'done') and the pose that must no longer change after it.
OWN_SAMPLES_INPUTS = frozenset({"command", "done", "x", "y", "yaw"})



def normalised(value: float, limit: float, nominal: float | None = None) -> float:
    """An index's value on its 0..1 scale: 1 at and beyond the limit, 0.5 at the nominal
    (``value / limit`` without one), NaN → 1. The reference for both evaluators.

    >>> normalised(0.2, 0.7, 0.2), normalised(0.45, 0.7, 0.2), normalised(0.35, 0.7)
    (0.5, 0.75, 0.5)
    """
    if math.isnan(value):
        return 1.0
    if nominal is None:
        ratio = value / limit
    elif value <= nominal:
        ratio = 0.5 * value / nominal
    else:
        ratio = 0.5 + 0.5 * (value - nominal) / (limit - nominal)
    return min(max(ratio, 0.0), 1.0)


@dataclass(frozen=True)
class Masked:
    """Internal node of the per-sample form: ``operand`` where ``window`` holds, 0 elsewhere."""

    operand: Expr
    window: Window


def per_sample_form(expr: Expr) -> Expr:
    """The index value with every outermost time reduction replaced by its (window-masked)
    operand: the quantity before the time reducer. Time reductions inside that operand stay
    (``max over time (pitch - mean over time (pitch))`` → ``pitch - mean over time (pitch)``).

    >>> from idefix_rules.rulebook.model import Name, Reduce
    >>> per_sample_form(Reduce("max", "time", Name("pitch")))
    Name(name='pitch')
    """
    if isinstance(expr, Reduce):
        if expr.domain == "runs":  # a path-level value: the same at every sample of every run
            return expr
        if expr.reducer in AXIS_KEEPING_REDUCERS:  # a rate is a quantity per sample already
            return expr
        if expr.domain == "time":
            operand = expr.operand
            return operand if expr.window is None else Masked(operand, expr.window)  # type: ignore[return-value]
        return Reduce(expr.reducer, expr.domain, per_sample_form(expr.operand), expr.parameter,
                      expr.window)
    if isinstance(expr, Unary):
        return Unary(expr.op, per_sample_form(expr.operand))
    if isinstance(expr, Binary):
        return Binary(expr.op, per_sample_form(expr.left), per_sample_form(expr.right))
    if isinstance(expr, Call):
        return Call(expr.function, tuple(per_sample_form(a) for a in expr.args))
    if isinstance(expr, Select):
        return Select(per_sample_form(expr.operand), expr.labels)
    return expr


def _inside(expr: Expr | Masked) -> tuple[Expr, ...]:
    """The expressions directly inside ``expr``: the rule model's walk, and a per-sample form's
    masked operand."""
    return (expr.operand,) if isinstance(expr, Masked) else children(expr)


def reads_run_signal(expr: Expr | Masked, constants: Collection[str]) -> bool:
    """Whether ``expr`` reads a signal of the run itself: a name that is not a constant, not
    the reference run's (``ref.*``), outside every reduction over runs (whose value is the
    path's, the same in every run)."""
    if isinstance(expr, Reduce) and expr.domain == "runs":
        return False
    if isinstance(expr, Name):
        return expr.name not in constants and not expr.name.startswith("ref.")
    return any(reads_run_signal(inner, constants) for inner in _inside(expr))


def counts_own_samples(expr: Reduce, constants: Collection[str]) -> bool:
    """Whether the reduction ``expr`` counts only the run's own samples: a counting reducer over
    time of an operand that reads the run's signals."""
    return (expr.domain == "time" and expr.reducer in COUNTING_REDUCERS
            and reads_run_signal(expr.operand, constants))


def any_counts_own_samples(expr: Expr | Masked, constants: Collection[str]) -> bool:
    """Whether some time reduction in ``expr`` counts only the run's own samples."""
    if isinstance(expr, Reduce) and counts_own_samples(expr, constants):
        return True
    return any(any_counts_own_samples(inner, constants) for inner in _inside(expr))


def names_in(expr: Expr | Masked) -> set[str]:
    """Every name an expression reads (signals, constants, scope names), ``chance(x)``'s
    argument included: the rule model's one walk (:func:`idefix_rules.rulebook.walk.names_in`),
    and a per-sample form's masked operands with their windows."""
    if isinstance(expr, Masked):
        return names_in(expr.operand) | names_in(expr.window.value)
    found = {name.name for name in walk_names(expr)}
    for node in nodes(expr):
        if isinstance(node, Masked):
            found |= names_in(node)
    return found


def table_axis(table: Table) -> str:
    """The axis a table's labels belong to."""
    return LABEL_AXIS[table.entries[0][0]][0]
