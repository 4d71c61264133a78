"""How a quantity moved between two rulebook versions: the sign of its move, numbers changed."""

from __future__ import annotations

import math
from typing import Any

from idefix_rules.rulebook.check import CheckedRulebook
from idefix_rules.rulebook.fold import number_si
from idefix_rules.rulebook.model import (
    Binary,
    Call,
    Expr,
    Index,
    Name,
    Number,
    Reduce,
    Select,
    Table,
    Unary,
)


def sign(old: Any, new: Any) -> int | None:
    """Sign of the move from ``old`` to ``new`` (tables: every entry the same way)."""
    if isinstance(old, dict) or isinstance(new, dict):
        if not (isinstance(old, dict) and isinstance(new, dict)) or old.keys() != new.keys():
            return None
        signs = {sign(old[k], new[k]) for k in old} - {0}
        if not signs:
            return 0
        return signs.pop() if len(signs) == 1 else None
    a, b = float(old), float(new)
    if math.isclose(a, b, rel_tol=1e-12, abs_tol=0.0):
        return 0
    return 1 if b > a else -1


def effective_nominal(checked: CheckedRulebook, name: str) -> float:
    """The index's nominal in SI; half its limit when it gives none (``value / limit`` is 0.5
    there)."""
    return checked.nominals.get(name, 0.5 * checked.limits[name])


def index_of(checked: CheckedRulebook, name: str) -> Index:
    return next(i for i in checked.rulebook.indices if i.name == name)


# A comparison that only gained or lost its equality: +1 when it now holds more often (on its
# boundary too), -1 when less. ``a <= b`` → ``a < b`` is ``b`` moved down by an infinitesimal.
_STRICTNESS = {("<", "<="): 1, ("<=", "<"): -1, (">", ">="): 1, (">=", ">"): -1}


def number_change(old: Expr, new: Expr) -> list[tuple[Expr, Expr]] | None:
    """What moved between two expressions of the same shape: pairs of numbers that differ,
    and pairs of comparisons whose operator only gained or lost its equality (``<=`` → ``<``;
    see :func:`leaf_moves`). None: the shape differs."""
    if type(old) is not type(new):
        return None
    if isinstance(old, Number) and isinstance(new, Number):
        return [] if old == new else [(old, new)]
    pairs: list[tuple[Expr, Expr]] = []
    if isinstance(old, Name) and isinstance(new, Name):
        return [] if old.name == new.name else None
    if isinstance(old, Binary) and isinstance(new, Binary):
        if old.op != new.op:
            if (old.op, new.op) not in _STRICTNESS:
                return None
            pairs.append((old, new))
        children = [(old.left, new.left), (old.right, new.right)]
    elif isinstance(old, Unary) and isinstance(new, Unary):
        if old.op != new.op:
            return None
        children = [(old.operand, new.operand)]
    elif isinstance(old, Select) and isinstance(new, Select):
        if old.labels != new.labels:
            return None
        children = [(old.operand, new.operand)]
    elif isinstance(old, Call) and isinstance(new, Call):
        if old.function != new.function or len(old.args) != len(new.args):
            return None
        children = list(zip(old.args, new.args, strict=True))
    elif isinstance(old, Reduce) and isinstance(new, Reduce):
        if (old.reducer, old.domain) != (new.reducer, new.domain) or \
                (old.parameter is None) != (new.parameter is None) or \
                (old.window is None) != (new.window is None):
            return None
        children = [(old.operand, new.operand)]
        if old.parameter is not None and new.parameter is not None:
            children.append((old.parameter, new.parameter))
        if old.window is not None and new.window is not None:
            if old.window.kind != new.window.kind:
                return None
            children.append((old.window.value, new.window.value))
    elif isinstance(old, Table) and isinstance(new, Table):
        if [k for k, _ in old.entries] != [k for k, _ in new.entries]:
            return None
        children = [(a, b) for (_, a), (_, b) in zip(old.entries, new.entries, strict=True)]
    else:
        return None
    for a, b in children:
        found = number_change(a, b)
        if found is None:
            return None
        pairs += found
    return pairs


def leaf_moves(old: Expr, new: Expr) -> list[tuple[str, int | None]] | None:
    """What moved in an expression whose shape stayed, as ``(id:N of the node in new, sign of
    its move)``: each number that moved (in SI; None when it has no SI value), and each
    comparison that gained its equality (+1: it holds on its boundary too) or lost it (-1).
    None: the shape differs."""
    pairs = number_change(old, new)
    if pairs is None:
        return None
    moves: list[tuple[str, int | None]] = []
    for before, after in pairs:
        moved: int | None
        if isinstance(before, Binary) and isinstance(after, Binary):
            moved = _STRICTNESS[(before.op, after.op)]
        else:
            assert isinstance(before, Number) and isinstance(after, Number)
            try:
                moved = sign(number_si(before), number_si(after))
            except (ValueError, KeyError):
                moved = None
        moves.append((f"id:{id(after)}", moved))
    return moves
