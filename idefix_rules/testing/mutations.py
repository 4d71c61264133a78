"""Mutants of a rulebook: one rule changed in one small way, to check that cases notice.

A good set of cases fails for every mutant. The mutations of one rule:

* a comparison flipped to its negation (``<=`` → ``>``, ``<`` → ``>=``, …);
* the constant side of a comparison doubled and halved (a zero threshold is left alone: scaling
  it changes nothing);
* ``and`` ↔ ``or``; a ``not`` removed;
* a reducer swapped: ``max`` ↔ ``min``, ``final`` ↔ ``initial``, ``any`` ↔ ``all``, ``sum``,
  ``mean``, ``rms`` and ``percentile`` → ``max``, ``count`` → ``any``-like ``max``;
* for an index also its limit doubled and halved (a nominal halved with it, so it stays below
  the limit), its nominal halved, and its weight halved (when not 0).

Maps (the per-sample form of an index, only drawn in the result map) are not mutated.

>>> from idefix_rules.rulebook.model import Binary, Name, Number
>>> [d for d, _ in expression_mutations(Binary("<=", Name("speed"), Number(1, "cm/s")), set())]
['<= → >', 'threshold 1 cm/s × 2', 'threshold 1 cm/s × 0.5']
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace
from typing import Any

from idefix_rules.rulebook.format import format_expr
from idefix_rules.rulebook.model import (
    Binary,
    Call,
    ConditionRule,
    Expr,
    Index,
    Number,
    Reduce,
    Rulebook,
    Select,
    Unary,
)
from idefix_rules.rulebook.semantics import names_in

_NEGATION = {"<": ">=", "<=": ">", ">": "<=", ">=": "<", "==": "!=", "!=": "=="}
_SWAP = {"max": "min", "min": "max", "final": "initial", "initial": "final", "any": "all",
         "all": "any", "sum": "max", "mean": "max", "rms": "max", "percentile": "max",
         "count": "max"}
_SECTIONS = (("command", "command_rules"), ("index", "indices"), ("chance", "chances"),
             ("prescreen", "prescreens"), ("verdict", "verdicts"))


@dataclass(frozen=True)
class Mutant:
    """A rulebook with one rule changed: ``kind``/``rule`` name it, ``change`` says how."""

    kind: str
    rule: str
    change: str
    rulebook: Rulebook

    def __str__(self) -> str:
        return f"{self.kind} {self.rule}: {self.change}"


def _is_constant(expr: Expr, constants: set[str]) -> bool:
    return names_in(expr) <= constants and not isinstance(expr, Call)


def _is_zero(expr: Expr) -> bool:
    return isinstance(expr, Number) and expr.value == 0


def _scaled(expr: Expr, factor: float) -> Expr:
    return Binary("*", expr, Number(factor))


def expression_mutations(expr: Expr, constants: set[str]) -> Iterator[tuple[str, Expr]]:
    """``(description, mutated expression)`` for every mutation site in ``expr``."""
    yield from _local(expr, constants)
    for rebuild, child in _children(expr):
        for description, mutated in expression_mutations(child, constants):
            yield description, rebuild(mutated)


def _local(expr: Expr, constants: set[str]) -> Iterator[tuple[str, Expr]]:
    if isinstance(expr, Binary):
        if expr.op in _NEGATION:
            negated: Any = _NEGATION[expr.op]
            yield f"{expr.op} → {negated}", replace(expr, op=negated)
            for side in ("right", "left"):
                value = getattr(expr, side)
                if _is_constant(value, constants) and not _is_zero(value):
                    for factor in (2.0, 0.5):
                        changed: dict[str, Any] = {side: _scaled(value, factor)}
                        yield (f"threshold {format_expr(value)} × {factor:g}",
                               replace(expr, **changed))
                    break
        elif expr.op in ("and", "or"):
            other: Any = "or" if expr.op == "and" else "and"
            yield f"{expr.op} → {other}", replace(expr, op=other)
    elif isinstance(expr, Unary) and expr.op == "not":
        yield "not removed", expr.operand
    elif isinstance(expr, Reduce) and expr.reducer in _SWAP:
        swapped: Any = _SWAP[expr.reducer]
        yield (f"{expr.reducer} over {expr.domain} → {swapped} over {expr.domain}",
               replace(expr, reducer=swapped, parameter=None))


def _children(expr: Expr) -> Iterator[tuple[Any, Expr]]:
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


def mutants(rulebook: Rulebook) -> Iterator[Mutant]:
    """Every single-rule mutant of ``rulebook`` (see the module docstring)."""
    constants = {c.name for c in rulebook.constants}
    for kind, attribute in _SECTIONS:
        rules: tuple[Any, ...] = getattr(rulebook, attribute)
        for position, rule in enumerate(rules):
            for change, new_rule in _rule_mutations(rule, constants):
                changed = list(rules)
                changed[position] = new_rule
                fields: dict[str, Any] = {attribute: tuple(changed)}
                yield Mutant(kind, rule.name, change, replace(rulebook, **fields))


def _rule_mutations(rule: Index | ConditionRule, constants: set[str]
                    ) -> Iterator[tuple[str, Index | ConditionRule]]:
    if isinstance(rule, Index):
        for change, value in expression_mutations(rule.value, constants):
            yield change, replace(rule, value=value)
        yield "limit × 2", replace(rule, limit=_scaled(rule.limit, 2.0))
        if rule.nominal is None:
            yield "limit × 0.5", replace(rule, limit=_scaled(rule.limit, 0.5))
        else:
            yield "limit and nominal × 0.5", replace(rule, limit=_scaled(rule.limit, 0.5),
                                                     nominal=_scaled(rule.nominal, 0.5))
            yield "nominal × 0.5", replace(rule, nominal=_scaled(rule.nominal, 0.5))
        if not _is_zero(rule.weight):
            yield "weight × 0.5", replace(rule, weight=_scaled(rule.weight, 0.5))
        return
    for change, condition in expression_mutations(rule.condition, constants):
        yield change, replace(rule, condition=condition)
