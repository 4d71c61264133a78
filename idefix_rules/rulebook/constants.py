"""Constants resolved in dependency order, and constant quantities type-checked and folded to SI."""

from __future__ import annotations

import math
from collections.abc import Mapping

from idefix_rules.errors import Diagnostic, error
from idefix_rules.rulebook.environment import CheckEnv
from idefix_rules.rulebook.fold import NotComputable, NotConstant, Value, fold
from idefix_rules.rulebook.infer import infer_type
from idefix_rules.rulebook.model import Expr
from idefix_rules.rulebook.walk import names_in
from idefix_rules.units import describe


def resolve_constants(env: CheckEnv) -> list[Diagnostic]:
    """Type and fold every constant, in dependency order; report cycles."""
    problems: list[Diagnostic] = []
    declared = {c.name: c for c in env.rulebook.constants}
    state: dict[str, str] = {}  # name -> "busy" | "done"

    def visit(name: str, chain: tuple[str, ...]) -> None:
        if state.get(name) == "done":
            return
        constant = declared[name]
        if state.get(name) == "busy":
            cycle = " -> ".join((*chain, name))
            problems.append(error("E403", f"constants depend on each other in a circle: {cycle}",
                                  constant.span))
            return
        state[name] = "busy"
        dependencies = [used.name for used in names_in(constant.value) if used.name in declared]
        for dependency in dependencies:
            visit(dependency, (*chain, name))
        state[name] = "done"
        if any(dependency not in env.constants for dependency in dependencies):
            return  # the dependency's own message says what is wrong
        scope = env.scope("constant")
        found = infer_type(constant.value, scope, problems)
        if found is None:
            return
        if found.boolean:
            problems.append(error("E304", f"constant '{name}' must be a quantity, not a "
                                  "condition", constant.value.span))
            return
        value = folded_constant(constant.value, env.constants, f"constant '{name}'", problems)
        if value is None:
            return
        env.constant_types[name] = found
        env.constants[name] = value

    for name in declared:
        visit(name, ())
    return problems


def constant_quantity(env: CheckEnv, expr: Expr, wanted: object, what: str,
                       problems: list[Diagnostic]) -> float | None:
    """Type-check ``expr`` as a constant of dimension ``wanted`` and fold it."""
    found = infer_type(expr, env.scope("constant"), problems)
    if found is None:
        return None
    if found.boolean or found.axes:
        problems.append(error("E304", f"{what} must be a single quantity", expr.span))
        return None
    if wanted is not None and found.dimension != wanted:
        problems.append(error("E204", f"{what} must be {describe(wanted)}, got "  # type: ignore[arg-type]
                              f"{describe(found.dimension)}", expr.span))
        return None
    value = folded_constant(expr, env.constants, what, problems)
    return None if value is None or isinstance(value, dict) else float(value)


def folded_constant(expr: Expr, constants: Mapping[str, Value], what: str,
                    problems: list[Diagnostic]) -> Value | None:
    """``expr``'s SI value when it is a constant with a finite value (every entry of a
    table); E402 at ``expr`` when it has none (``what`` names it in the message), None with no
    message when it is not constant (its type check says why)."""
    try:
        value = fold(expr, constants)
    except NotConstant:
        return None
    except NotComputable as failure:
        problems.append(error("E402", f"{what} {failure}", expr.span))
        return None
    values = value.values() if isinstance(value, dict) else [value]
    if not all(math.isfinite(float(v)) for v in values):
        shown = ", ".join(f"{float(v):g}" for v in values)
        problems.append(error("E402", f"{what} is not a finite number ({shown}; a division "
                                      "by zero, or a value beyond a double?)", expr.span))
        return None
    return value
