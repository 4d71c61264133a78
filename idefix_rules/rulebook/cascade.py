"""One mistake, one message: follow-up diagnostics of a broken constant, better hints.

A constant of the wrong dimension for every place that uses it is reported once, at its
definition (:func:`fold_misfit_constants`).

A constant whose definition has an error (a unit mismatch, a division by zero …) gets no type
and no value, so every later use of it would be reported again as an unknown name — with a
misleading "did you mean". :func:`fold_cascades` drops those follow-ups and attaches their
places to the definition's error as "used here" notes. :func:`path_hints` gives the unknown-name
error of an index or chance named in a verdict the hint to use its path statistic
(``mean(I_s)``, ``chance(hit_L3)``).
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterator, Mapping
from dataclasses import replace

from idefix_rules.errors import Diagnostic, Severity, Span
from idefix_rules.rulebook.format import format_expr
from idefix_rules.rulebook.model import (
    Binary,
    Call,
    Constant,
    Expr,
    Name,
    Reduce,
    Rulebook,
    Select,
    Table,
    Unary,
)
from idefix_rules.rulebook.types import ExprType
from idefix_rules.rulebook.walk import names_in, rulebook_expressions
from idefix_rules.units import describe

_UNKNOWN = re.compile(r"^unknown name '([^']+)'")
SHOWN_USES = 3


def fold_cascades(rulebook: Rulebook, resolved: set[str],
                  diagnostics: list[Diagnostic]) -> list[Diagnostic]:
    """Drop unknown-name errors about declared constants that failed to resolve; the first
    error of each such constant's definition lists where it is used."""
    broken = {c.name: c for c in rulebook.constants if c.name not in resolved}
    if not broken:
        return diagnostics
    # A broken constant read by another broken one: the root is the one with its own error.
    reads = {name: {n.name for n in names_in(c.value) if n.name in broken}
             for name, c in broken.items()}
    uses: dict[str, list[tuple[str, Span]]] = {name: [] for name in broken}
    for constant in broken.values():
        for used in names_in(constant.value):
            if used.name in broken and used.span.line > 0:
                uses[used.name].append((f"'{used.name}' is used here", used.span))
    kept: list[Diagnostic] = []
    for diagnostic in diagnostics:
        match = _UNKNOWN.match(diagnostic.message) if diagnostic.code == "E101" else None
        if match and match.group(1) in broken and diagnostic.span is not None:
            uses[match.group(1)].append((f"'{match.group(1)}' is used here", diagnostic.span))
            continue
        kept.append(diagnostic)
    owners = {_owner(d, broken) for d in kept} - {None}
    for name in broken:  # uses of a dependent count as uses of its root
        root = _root(name, reads, owners)
        if root is not None and root != name:
            uses[root] += uses.pop(name, [])
    out: list[Diagnostic] = []
    noted: set[str] = set()
    for diagnostic in kept:
        owner = _owner(diagnostic, broken)
        if owner is not None and owner not in noted and uses.get(owner):
            noted.add(owner)
            spans = sorted(uses[owner], key=lambda item: (item[1].line, item[1].column))
            related = tuple(spans[:SHOWN_USES])
            more = len(spans) - SHOWN_USES
            hint = diagnostic.hint
            if more > 0:
                extra = f"and {more} more use{'s' if more != 1 else ''}"
                hint = f"{hint}; {extra}" if hint else extra
            diagnostic = replace(diagnostic, related=diagnostic.related + related, hint=hint)
        out.append(diagnostic)
    return out


def _root(name: str, reads: Mapping[str, set[str]], owners: set[str | None]) -> str | None:
    """The broken constant with an error of its own that ``name`` depends on."""
    seen: set[str] = set()
    pending = [name]
    while pending:
        current = pending.pop()
        if current in owners:
            return current
        if current in seen:
            continue
        seen.add(current)
        pending += sorted(reads.get(current, ()))
    return None


def _owner(diagnostic: Diagnostic, broken: Mapping[str, Constant]) -> str | None:
    """The broken constant whose definition this error is in (by line range)."""
    if diagnostic.severity is not Severity.ERROR or diagnostic.span is None:
        return None
    for name, constant in broken.items():
        span = constant.span
        end = span.end_line or span.line
        if span.line <= diagnostic.span.line <= end:
            return name
    return None


# What each context reads instead of an index or a chance (verdicts: see path_hints).
_INSTEAD = {
    "a constant expression": "a constant expression reads constants and numbers: write the "
                             "value, or declare it as a constant",
    "an index or chance": "indices and chances read signals: use the signals the other one "
                          "reads (its value is no signal)",
    "a command rule": "a command rule reads the command's max_wheel_rate, delta_position and "
                      "delta_heading",
}


def path_hints(rulebook: Rulebook, diagnostics: list[Diagnostic]) -> list[Diagnostic]:
    """An index or chance named where it cannot be read: in a verdict or rank key, point to
    its path statistic; elsewhere, say it exists but is not visible there (not "unknown"),
    and what that context reads. An unknown name closest to an index or chance: that one."""
    indices = {i.name for i in rulebook.indices}
    chances = {c.name for c in rulebook.chances}
    out = []
    for diagnostic in diagnostics:
        match = _UNKNOWN.match(diagnostic.message) if diagnostic.code == "E101" else None
        if match is None:
            out.append(diagnostic)
            continue
        name = match.group(1)
        where = diagnostic.message.split(" in ", 1)[-1]
        if name in indices or name in chances:
            kind = "index" if name in indices else "chance"
            if where.startswith("a verdict"):
                diagnostic = replace(diagnostic, message=(
                    f"{kind} '{name}' is a {'value' if kind == 'index' else 'condition'} per "
                    "run; a verdict reads path statistics"), hint=(
                    f"use mean({name}) (mean over the runs) or max({name}) (largest run)"
                    if kind == "index" else
                    f"use chance({name}) (the fraction of runs where it holds)"))
            else:
                context = next((text for key, text in _INSTEAD.items()
                                if where.startswith(key)), None)
                diagnostic = replace(diagnostic, message=(
                    f"{kind} '{name}' cannot be read in {where}"), hint=context)
        else:
            close = difflib.get_close_matches(name, sorted(indices | chances), n=1, cutoff=0.8)
            if close and not _closer_hint(name, close[0], diagnostic.hint):
                kind = "index" if close[0] in indices else "chance"
                diagnostic = replace(diagnostic, hint=(
                    f"did you mean {kind} '{close[0]}'? (" + (
                        f"a verdict reads mean({close[0]}) or max({close[0]}))"
                        if kind == "index" else f"a verdict reads chance({close[0]}))")
                    if where.startswith("a verdict") else
                    f"did you mean {kind} '{close[0]}'? It cannot be read in {where}"))
        out.append(diagnostic)
    return out



def _closer_hint(name: str, candidate: str, hint: str | None) -> bool:
    """Whether ``hint`` already suggests a visible name at least as close to ``name`` as
    ``candidate`` (an index or chance that cannot be read there)."""
    suggested = re.match(r"did you mean '([^']+)'", hint or "")
    if suggested is None:
        return False

    def ratio(other: str) -> float:
        return difflib.SequenceMatcher(None, name, other).ratio()

    return ratio(suggested.group(1)) >= ratio(candidate)

def _nodes(expr: Expr) -> Iterator[Expr]:
    yield expr
    if isinstance(expr, Binary):
        yield from _nodes(expr.left)
        yield from _nodes(expr.right)
    elif isinstance(expr, Unary | Select | Reduce):
        yield from _nodes(expr.operand)
        if isinstance(expr, Reduce):
            for extra in (expr.parameter, expr.window.value if expr.window else None):
                if extra is not None:
                    yield from _nodes(extra)
    elif isinstance(expr, Call):
        for arg in expr.args:
            yield from _nodes(arg)
    elif isinstance(expr, Table):
        for _, value in expr.entries:
            yield from _nodes(value)


def fold_misfit_constants(rulebook: Rulebook, constant_types: Mapping[str, ExprType],
                          diagnostics: list[Diagnostic]) -> list[Diagnostic]:
    """A constant whose *every* use is a dimension error (``critical_tilt = 15 cm`` used as
    the limit of two angle indices) is wrong at its definition: one error there, the uses as
    notes. When some uses fit, the misfits stay where they are (the use is the mistake)."""

    constants = {c.name: c for c in rulebook.constants}
    by_span: dict[Span, Expr] = {}
    uses: dict[str, int] = {name: 0 for name in constants}
    for expr in rulebook_expressions(rulebook):
        for node in _nodes(expr):
            by_span.setdefault(node.span, node)
            if isinstance(node, Name) and node.name in uses:
                uses[node.name] += 1
    for constant in rulebook.constants:  # uses inside other constants are not misfits here
        for node in _nodes(constant.value):
            if isinstance(node, Name) and node.name in uses:
                uses[node.name] -= 1
    misfits: dict[str, list[Diagnostic]] = {}
    for diagnostic in diagnostics:
        if diagnostic.code not in ("E201", "E204") or diagnostic.span is None:
            continue
        name = _misfit_constant(by_span.get(diagnostic.span), constants)
        if name is not None and name in constant_types:
            misfits.setdefault(name, []).append(diagnostic)
    folded = {name for name, found in misfits.items() if len(found) == uses[name] > 0}
    if not folded:
        return diagnostics
    out = [d for d in diagnostics if not any(d in misfits[name] for name in folded)]
    for name in sorted(folded):
        constant = constants[name]
        found = sorted(misfits[name], key=lambda d: (d.span.line, d.span.column)
                       if d.span else (0, 0))
        dimension = constant_types[name].dimension
        out.append(Diagnostic(
            found[0].code, Severity.ERROR,
            f"constant '{name}' is {describe(dimension)} ({format_expr(constant.value)}), but "
            f"every place that uses it needs another dimension", constant.value.span,
            "change the constant's unit (or give those places another constant)",
            tuple((d.message, d.span) for d in found if d.span is not None)))
    return out


def _misfit_constant(node: Expr | None, constants: Mapping[str, Constant]) -> str | None:
    """The constant a dimension error is about: the limit/setting itself is the constant, or a
    comparison/sum has the constant alone on one side and signals on the other."""
    if isinstance(node, Name) and node.name in constants:
        return node.name
    if isinstance(node, Binary):
        for side, other in ((node.left, node.right), (node.right, node.left)):
            if isinstance(side, Name) and side.name in constants and \
                    names_of(other) - set(constants):
                return side.name
    return None


def names_of(expr: Expr) -> set[str]:
    return {n.name for n in names_in(expr)}
