"""Mutants of a rulebook: one rule changed in one small way, to check that cases notice.

A good set of cases fails for every mutant. The mutants are built on the lowered rule model (the
frozen dataclasses), never on source text, and each names the place it changed
(``Mutant.span``). Their categories:

* ``reducer`` — a reducer swapped: ``max`` ↔ ``min``, ``max`` → ``final`` / ``mean``,
  ``final`` → ``initial`` / ``max``, ``mean``/``rms``/``sum``/``count``/``percentile`` →
  ``max``, ``max`` → ``sum`` over wheels, parts or levels, ``any`` ↔ ``all``, and a percentile's
  value moved (``percentile 95`` → ``90`` and → ``97.5``);
* ``threshold`` — the constant side of a comparison (a command rule's limit, a verdict's limit
  …), an index's limit and its nominal nudged just past where they were, both ways: × (1 + n)
  and × (1 − n) for the nudge n (default 10 %). A zero threshold is left alone: scaling it
  changes nothing;
* ``weight`` — an index's weight halved and nudged down (when not 0);
* ``factor`` — one entry of a table constant (the obstacle factors ``f_obs``) nudged both ways;
* ``drop`` — one term dropped: an operand of ``+``/``-`` (``a - b`` → ``a``), of ``and``/``or``,
  of ``max(…)``/``min(…)``/``hypot(…)``;
* ``operator`` — a comparison flipped to its negation (``<=`` → ``>``), ``and`` ↔ ``or``, a
  ``not`` removed.

Maps (the per-sample form of an index, only drawn in the result map) are not mutated. A mutant
can be an invalid rulebook (a nominal nudged above its limit, a term dropped that leaves the
wrong unit): :mod:`idefix_rules.testing.mutation_score` checks each and skips those.

>>> from idefix_rules.rulebook.model import Binary, Name, Number
>>> [m.change for m in expression_mutations(Binary("<=", Name("speed"), Number(1, "cm/s")),
...                                         set(), 0.1)]
['<= → >', 'threshold 1 cm/s → 1.1 cm/s', 'threshold 1 cm/s → 0.9 cm/s']
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from typing import Any

from idefix_rules.errors import Span
from idefix_rules.rulebook.format import format_expr, format_number
from idefix_rules.rulebook.model import (
    NO_SPAN,
    Binary,
    Call,
    ConditionRule,
    Constant,
    Expr,
    Index,
    Number,
    Reduce,
    Rulebook,
    Select,
    Table,
    Unary,
)
from idefix_rules.rulebook.semantics import names_in

NUDGE = 0.1  # default relative nudge of a threshold, limit, nominal or factor
CATEGORIES = ("reducer", "threshold", "weight", "factor", "drop", "operator")
_NEGATION = {"<": ">=", "<=": ">", ">": "<=", ">=": "<", "==": "!=", "!=": "=="}
_SWAPS: dict[str, tuple[str, ...]] = {
    "max": ("min", "final", "mean"), "min": ("max",), "final": ("initial", "max"),
    "initial": ("final",), "mean": ("max",), "rms": ("max",), "sum": ("max",),
    "percentile": ("max",), "count": ("max",), "any": ("all",), "all": ("any",)}
_DROPPABLE_CALLS = ("max", "min", "hypot")
_SECTIONS = (("command", "command_rules"), ("index", "indices"), ("chance", "chances"),
             ("prescreen", "prescreens"), ("verdict", "verdicts"))


@dataclass(frozen=True)
class Mutant:
    """A rulebook with one thing changed: ``kind``/``rule`` name the declaration, ``change``
    says what changed, ``category`` which kind of mutation it is, ``span`` where."""

    kind: str
    rule: str
    change: str
    rulebook: Rulebook
    category: str = "operator"
    span: Span = NO_SPAN

    def __str__(self) -> str:
        return f"{self.kind} {self.rule}: {self.change}"


@dataclass(frozen=True)
class Mutation:
    """One change of an expression: its category, what changed, where, and the result."""

    category: str
    change: str
    span: Span
    expr: Expr


def _is_constant(expr: Expr, constants: set[str]) -> bool:
    return names_in(expr) <= constants and not isinstance(expr, Call)


def _is_zero(expr: Expr) -> bool:
    return isinstance(expr, Number) and expr.value == 0


def _scaled(expr: Expr, factor: float) -> Expr:
    if isinstance(expr, Number):
        return replace(expr, value=round(expr.value * factor, 12))
    return Binary("*", expr, Number(round(factor, 12)))


def nudged(expr: Expr, nudge: float) -> Iterator[tuple[str, Expr]]:
    """``expr`` × (1 + nudge) and × (1 − nudge), each with its text (``70 % → 77 %``)."""
    for factor in (1 + nudge, 1 - nudge):
        moved = _scaled(expr, factor)
        yield f"{format_expr(expr)} → {format_expr(moved)}", moved


def expression_mutations(expr: Expr, constants: set[str], nudge: float = NUDGE
                         ) -> Iterator[Mutation]:
    """Every mutation of ``expr`` (see the module docstring), sites depth first."""
    for category, change, mutated in _local(expr, constants, nudge):
        yield Mutation(category, change, expr.span, mutated)
    for rebuild, child in _children(expr):
        for found in expression_mutations(child, constants, nudge):
            yield replace(found, expr=rebuild(found.expr))


def _local(expr: Expr, constants: set[str], nudge: float) -> Iterator[tuple[str, str, Expr]]:
    if isinstance(expr, Binary):
        yield from _binary(expr, constants, nudge)
    elif isinstance(expr, Unary) and expr.op == "not":
        yield "operator", "not removed", expr.operand
    elif isinstance(expr, Reduce):
        yield from _reducer_swaps(expr)
    elif isinstance(expr, Call) and expr.function in _DROPPABLE_CALLS and len(expr.args) > 1:
        for position, arg in enumerate(expr.args):
            rest = expr.args[:position] + expr.args[position + 1:]
            kept: Expr = replace(expr, args=rest)
            if len(rest) == 1:
                kept = rest[0] if expr.function != "hypot" else Call("abs", rest)
            yield ("drop", f"dropped {format_expr(arg)} from {expr.function}(…)", kept)


def _binary(expr: Binary, constants: set[str], nudge: float) -> Iterator[tuple[str, str, Expr]]:
    if expr.op in _NEGATION:
        negated: Any = _NEGATION[expr.op]
        yield "operator", f"{expr.op} → {negated}", replace(expr, op=negated)
        for side in ("right", "left"):
            value = getattr(expr, side)
            if _is_constant(value, constants) and not _is_zero(value):
                for change, moved in nudged(value, nudge):
                    changed: dict[str, Any] = {side: moved}
                    yield "threshold", f"threshold {change}", replace(expr, **changed)
                break
    elif expr.op in ("and", "or"):
        other: Any = "or" if expr.op == "and" else "and"
        yield "operator", f"{expr.op} → {other}", replace(expr, op=other)
        yield "drop", f"dropped {expr.op} {format_expr(expr.right)}", expr.left
        yield "drop", f"dropped {format_expr(expr.left)} {expr.op}", expr.right
    elif expr.op in ("+", "-"):
        yield "drop", f"dropped {expr.op} {format_expr(expr.right)}", expr.left
        if expr.op == "+":
            yield "drop", f"dropped {format_expr(expr.left)} +", expr.right


def _reducer_swaps(expr: Reduce) -> Iterator[tuple[str, str, Expr]]:
    old = _reducer_text(expr)
    swaps = list(_SWAPS.get(expr.reducer, ()))
    if expr.reducer == "max" and expr.domain in ("wheels", "parts", "levels"):
        swaps.append("sum")
    for reducer in swaps:
        if reducer in ("final", "initial") and expr.domain != "time":
            continue  # the first or last wheel, part or level means nothing
        swapped = replace(expr, reducer=reducer, parameter=None)  # type: ignore[arg-type]
        yield "reducer", f"{old} → {_reducer_text(swapped)}", swapped
    if expr.reducer == "percentile" and isinstance(expr.parameter, Number):
        p = expr.parameter.value
        for value in (max(p - 5, p / 2), min(p + 5, (p + 100) / 2)):
            moved = replace(expr, parameter=replace(expr.parameter, value=value))
            yield "reducer", f"{old} → {_reducer_text(moved)}", moved


def _reducer_text(expr: Reduce) -> str:
    parameter = f" {format_expr(expr.parameter)}" if expr.parameter is not None else ""
    return f"{expr.reducer}{parameter} over {expr.domain}"


def _children(expr: Expr) -> Iterator[tuple[Callable[[Expr], Expr], Expr]]:
    if isinstance(expr, Binary):
        yield (lambda new: replace(expr, left=new)), expr.left
        yield (lambda new: replace(expr, right=new)), expr.right
    elif isinstance(expr, Unary | Select | Reduce):
        yield (lambda new: replace(expr, operand=new)), expr.operand
    elif isinstance(expr, Call):
        for position, arg in enumerate(expr.args):
            def rebuild(new: Expr, position: int = position) -> Expr:
                args = list(expr.args)
                args[position] = new
                return replace(expr, args=tuple(args))
            yield rebuild, arg


def mutants(rulebook: Rulebook, nudge: float = NUDGE) -> Iterator[Mutant]:
    """Every single-change mutant of ``rulebook`` (see the module docstring)."""
    constants = {c.name for c in rulebook.constants}
    for position, constant in enumerate(rulebook.constants):
        for change, span, value in _factor_mutations(constant, nudge):
            changed_constants = list(rulebook.constants)
            changed_constants[position] = replace(constant, value=value)
            yield Mutant("constant", constant.name, change,
                         replace(rulebook, constants=tuple(changed_constants)), "factor",
                         _where(span, constant.span))
    for kind, attribute in _SECTIONS:
        rules: tuple[Any, ...] = getattr(rulebook, attribute)
        for position, rule in enumerate(rules):
            for found, new_rule in _rule_mutations(rule, constants, nudge):
                changed = list(rules)
                changed[position] = new_rule
                fields: dict[str, Any] = {attribute: tuple(changed)}
                yield Mutant(kind, rule.name, found.change, replace(rulebook, **fields),
                             found.category, _where(found.span, rule.span))


def _where(span: Span, fallback: Span) -> Span:
    return span if span.line > 0 else fallback


def _factor_mutations(constant: Constant, nudge: float) -> Iterator[tuple[str, Span, Expr]]:
    if not isinstance(constant.value, Table):
        return
    entries = constant.value.entries
    for position, (label, value) in enumerate(entries):
        if _is_zero(value):
            continue
        for change, moved in nudged(value, nudge):
            new_entries = list(entries)
            new_entries[position] = (label, moved)
            yield (f"factor {constant.name}[{label}] {change}", value.span,
                   replace(constant.value, entries=tuple(new_entries)))


def _rule_mutations(rule: Index | ConditionRule, constants: set[str], nudge: float
                    ) -> Iterator[tuple[Mutation, Index | ConditionRule]]:
    if not isinstance(rule, Index):
        for found in expression_mutations(rule.condition, constants, nudge):
            yield found, replace(rule, condition=found.expr)
        return
    for found in expression_mutations(rule.value, constants, nudge):
        yield found, replace(rule, value=found.expr)
    down = 1 - nudge
    for change, limit in nudged(rule.limit, nudge):
        yield Mutation("threshold", f"limit {change}", rule.limit.span, limit), \
            replace(rule, limit=limit)
    if rule.nominal is not None:
        both = replace(rule, limit=_scaled(rule.limit, down), nominal=_scaled(rule.nominal, down))
        yield Mutation("threshold", f"limit and nominal × {format_number(down)}",
                       rule.limit.span, both.limit), both
        for change, nominal in nudged(rule.nominal, nudge):
            yield Mutation("threshold", f"nominal {change}", rule.nominal.span, nominal), \
                replace(rule, nominal=nominal)
    if not _is_zero(rule.weight):
        for factor in (0.5, down):
            weight = _scaled(rule.weight, factor)
            yield Mutation("weight", f"weight {format_expr(rule.weight)} → "
                           f"{format_expr(weight)}", rule.weight.span, weight), \
                replace(rule, weight=weight)
