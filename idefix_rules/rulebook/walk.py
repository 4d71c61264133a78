"""The one walk over the rule model: an expression's sub-expressions, every node of an
expression, the names it reads, and every expression a rulebook holds. The checker, the lints,
the constant cascade, rule coverage and the case runner walk expressions through these."""

from __future__ import annotations

from collections.abc import Iterator

from idefix_rules.rulebook.model import (
    Binary,
    Call,
    Expr,
    Invalid,
    Name,
    Reduce,
    Rulebook,
    Select,
    Table,
    Unary,
)


def children(expr: Expr) -> tuple[Expr, ...]:
    """The expressions directly inside ``expr`` (operands, arguments, a reduction's parameter
    and window, a table's values), in source order."""
    if isinstance(expr, Binary):
        return (expr.left, expr.right)
    if isinstance(expr, Unary | Select):
        return (expr.operand,)
    if isinstance(expr, Call):
        return tuple(expr.args)
    if isinstance(expr, Reduce):
        inner: tuple[Expr, ...] = (expr.operand,)
        if expr.parameter is not None:
            inner += (expr.parameter,)
        if expr.window is not None:
            inner += (expr.window.value,)
        return inner
    if isinstance(expr, Table):
        return tuple(value for _, value in expr.entries)
    if isinstance(expr, Invalid) and expr.written is not None:  # what it reads is still read
        return children(expr.written)
    return ()


def nodes(expr: Expr) -> Iterator[Expr]:
    """``expr`` and every expression inside it, parents before their children."""
    yield expr
    for child in children(expr):
        yield from nodes(child)


def names_in(expr: Expr) -> Iterator[Name]:
    """Every :class:`Name` read by an expression (windows and parameters included)."""
    return (node for node in nodes(expr) if isinstance(node, Name))


def windowed(rulebook: Rulebook, kind: str) -> Iterator[Reduce]:
    """Every reduction of the rulebook with a ``kind`` window (``command``, ``after``,
    ``before``), in source order."""
    for top in rulebook_expressions(rulebook):
        for node in nodes(top):
            if isinstance(node, Reduce) and node.window is not None \
                    and node.window.kind == kind:
                yield node


def rulebook_expressions(rulebook: Rulebook) -> Iterator[Expr]:
    """Every expression written in a rulebook, section by section."""
    for c in rulebook.constants:
        yield c.value
    for s in rulebook.settings:
        yield s.value
    for level in rulebook.obstacle_levels:
        if level.below is not None:
            yield level.below
        yield level.buffer
    for area in rulebook.areas:
        yield area.buffer
        if area.above is not None:
            yield area.above
    for r in rulebook.command_rules:
        yield r.condition
    for i in rulebook.indices:
        yield from (i.value, i.limit, i.weight)
        if i.nominal is not None:
            yield i.nominal
        if i.map is not None:
            yield i.map
    for ch in rulebook.chances:
        yield ch.condition
    if rulebook.combine.confidence is not None:
        yield rulebook.combine.confidence
    if rulebook.combine.indifference is not None:
        yield rulebook.combine.indifference
    if rulebook.combine.verdict_indifference is not None:
        yield rulebook.combine.verdict_indifference
    for p in rulebook.prescreens:
        yield p.condition
    for v in rulebook.verdicts:
        yield v.condition
        if v.indifference is not None:
            yield v.indifference
    for key in rulebook.ranking.keys:
        yield key.expr
