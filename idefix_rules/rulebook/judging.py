"""How verdict rules judge the path statistics they read: the direction of each bound, how
many bounds a path's verdict rests on, and each rule's indifference margin.

A rule ``risk <= 70 %`` passes when the *upper* bound of ``risk`` lies below 70 % and fails
when its *lower* bound lies above: each side decides one outcome, so each is a one-sided bound
with its own error rate (:mod:`idefix_rules.campaign.statistics.budget` spends the confidence
over them).
A statistic compared with a constant under ``and``, ``or`` and ``not`` is judged in one
direction per comparison (``not`` turns it round); one used any other way (inside ``abs``,
against another statistic, with ``==``) is judged on both sides.

Only statistics estimated from the runs count: ``risk``, ``time``, ``energy``, ``failed``,
``chance(NAME)`` and ``mean(INDEX)``. ``runs`` and ``max(INDEX)`` are facts of the runs that
were simulated, not estimates, and so is a chance compared with 0 (``failed <= 0 %``: no run
failed; no number of runs bounds a chance to 0).

>>> from idefix_rules.rulebook.parser import parse_rulebook
>>> book = parse_rulebook('''
... rulebook "demo" version "0.1.0" purpose "Example"
... index I_s { value = max over time (max over wheels (abs(wheel.slip))) limit = 70 % weight = 1 }
... chance got_stuck = any over time (wheel.slip[FL] > 0.9)
... verdict ok: require risk <= 70 % and not (chance(got_stuck) > 1 %)
... verdict slow: require abs(time - 100 s) < 10 s
... ''', "demo.rules")
>>> found = judging(book)
>>> found.directions, found.units
({'risk': 'upper', 'chance(got_stuck)': 'upper', 'time': 'both'}, 4)
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Literal

from idefix_rules.errors import Diagnostic, error
from idefix_rules.rulebook.fold import NotComputable, NotConstant, Value, fold
from idefix_rules.rulebook.infer import infer_type
from idefix_rules.rulebook.model import (
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
    VerdictRule,
)
from idefix_rules.rulebook.types import Scope
from idefix_rules.rulebook.walk import names_in
from idefix_rules.units import DIMENSIONLESS, describe

Direction = Literal["upper", "lower", "both"]
ESTIMATED_NAMES = ("risk", "time", "energy", "failed")
ESTIMATED_CALLS = ("chance", "mean")
ORDER = ("<", "<=", ">", ">=")
MARGIN_DIMENSION = "E411"
MARGIN_RANGE = "E412"


def estimated_statistic(expr: Expr) -> str | None:
    """The name of the estimated path statistic ``expr`` is (``risk``, ``chance(stuck)``),
    else None."""
    if isinstance(expr, Name) and expr.name in ESTIMATED_NAMES:
        return expr.name
    if (isinstance(expr, Call) and expr.function in ESTIMATED_CALLS and len(expr.args) == 1
            and isinstance(expr.args[0], Name)):
        return f"{expr.function}({expr.args[0].name})"
    return None


def statistics_in(expr: Expr) -> Iterator[str]:
    """Every estimated statistic ``expr`` reads, once per occurrence."""
    found = estimated_statistic(expr)
    if found is not None:
        yield found
        return
    if isinstance(expr, Unary):
        yield from statistics_in(expr.operand)
    elif isinstance(expr, Binary):
        yield from statistics_in(expr.left)
        yield from statistics_in(expr.right)
    elif isinstance(expr, Call):
        for argument in expr.args:
            yield from statistics_in(argument)
    elif isinstance(expr, Reduce | Select | Table):
        return


@dataclass(frozen=True)
class Judging:
    """``directions``: per statistic the bound whose side decides a pass (``upper``: the
    statistic must stay low), ``both`` when rules judge it both ways; ``units``: the one-sided
    bounds a path's verdict can wrongly fail on (one per comparison of a statistic with a
    limit, two per statistic judged both ways)."""

    directions: dict[str, Direction] = field(default_factory=dict)
    units: int = 0

    def levels(self, statistic: str, pass_alpha: float, fail_alpha: float
               ) -> tuple[float, float]:
        """(α of the lower bound, α of the upper bound) of ``statistic``: the side that
        decides a pass at ``pass_alpha``, the side that decides a failure at ``fail_alpha``,
        both at ``fail_alpha`` when judged both ways; a statistic no rule judges gets
        ``pass_alpha`` on both sides (it is shown, and may rank, but decides no verdict)."""
        direction = self.directions.get(statistic)
        if direction == "upper":
            return fail_alpha, pass_alpha
        if direction == "lower":
            return pass_alpha, fail_alpha
        if direction == "both":
            return fail_alpha, fail_alpha
        return pass_alpha, pass_alpha


def _comparison(expr: Binary) -> tuple[str, Direction] | None:
    """``(statistic, direction)`` of ``statistic OP constant`` (either side), else None."""
    if expr.op not in ORDER:
        return None
    left, right = estimated_statistic(expr.left), estimated_statistic(expr.right)
    if left is not None and not any(statistics_in(expr.right)):
        statistic, low_passes = left, expr.op in (">", ">=")
    elif right is not None and not any(statistics_in(expr.left)):
        statistic, low_passes = right, expr.op in ("<", "<=")
    else:
        return None
    return statistic, "lower" if low_passes else "upper"


def _against_zero(expr: Binary) -> bool:
    """``failed <= 0 %``, ``chance(x) == 0``: a chance compared with a written 0, which the
    verdict reads on the runs themselves (no run failed), not on bounds."""
    for side, other in ((expr.left, expr.right), (expr.right, expr.left)):
        statistic = estimated_statistic(side)
        if statistic is not None and (statistic == "failed" or statistic.startswith("chance(")) \
                and isinstance(other, Number) and other.value == 0:
            return True
    return False


def _walk(expr: Expr, positive: bool) -> Iterator[tuple[str, Direction, int]]:
    """``(statistic, direction, units)`` per occurrence, with ``not`` turning the direction."""
    if isinstance(expr, Unary) and expr.op == "not":
        yield from _walk(expr.operand, not positive)
        return
    if isinstance(expr, Binary) and expr.op in ("and", "or"):
        yield from _walk(expr.left, positive)
        yield from _walk(expr.right, positive)
        return
    if isinstance(expr, Binary):
        if _against_zero(expr):
            return  # read on the runs themselves: no bound, nothing spent
        found = _comparison(expr)
        if found is not None:
            statistic, direction = found
            if not positive:
                direction = "upper" if direction == "lower" else "lower"
            yield statistic, direction, 1
            return
    for statistic in statistics_in(expr):
        yield statistic, "both", 2


def judging(rulebook: Rulebook) -> Judging:
    """How the rulebook's verdicts judge each statistic (see the module docstring)."""
    directions: dict[str, Direction] = {}
    units = 0
    for rule in rulebook.verdicts:
        for statistic, direction, count in _walk(rule.condition, True):
            units += count
            known = directions.get(statistic)
            directions[statistic] = direction if known in (None, direction) else "both"
    return Judging(directions, units)


# --- indifference margins ---------------------------------------------------------------------

def _compared(expr: Expr) -> Iterator[Binary]:
    """The comparisons of a condition (under and, or, not)."""
    if isinstance(expr, Unary):
        yield from _compared(expr.operand)
    elif isinstance(expr, Binary) and expr.op in ("and", "or"):
        yield from _compared(expr.left)
        yield from _compared(expr.right)
    elif isinstance(expr, Binary):
        yield expr


def compared_dimensions(rule: VerdictRule, scope: Scope) -> set[object]:
    """The dimensions of the quantities a verdict compares (mistakes are the type checker's
    to report; a comparison that does not type-check is left out)."""
    found: set[object] = set()
    for comparison in _compared(rule.condition):
        side = infer_type(comparison.left, scope, [])
        if side is not None and not side.boolean:
            found.add(side.dimension)
    return found


def verdict_margins(rulebook: Rulebook, path_scope: Scope, constant_scope: Scope,
                    constants: Mapping[str, Value], default: float,
                    problems: list[Diagnostic]) -> dict[str, float]:
    """Each verdict's margin in SI: its own ``indifference``, of the dimension it compares;
    else ``default`` (a ratio) for a verdict comparing ratios only; else 0. Mistakes are
    appended to ``problems`` (E411 dimension, E412 negative)."""
    margins: dict[str, float] = {}
    for rule in rulebook.verdicts:
        dimensions = compared_dimensions(rule, path_scope)
        if rule.indifference is None:
            margins[rule.name] = default if dimensions <= {DIMENSIONLESS} else 0.0
            continue
        margin = rule.indifference
        found = infer_type(margin, constant_scope, problems)
        if found is None:
            continue
        if found.boolean or found.axes or len(dimensions) > 1 \
                or (dimensions and found.dimension not in dimensions):
            wanted = (" or ".join(sorted(describe(d) for d in dimensions))  # type: ignore[arg-type]
                      if dimensions else "a quantity")
            problems.append(error(
                MARGIN_DIMENSION, f"the indifference of verdict '{rule.name}' must be "
                f"{wanted}, the dimension of what it compares, got "
                f"{describe(found.dimension)}", margin.span,
                "one margin per verdict: split a verdict comparing different quantities"
                if len(dimensions) > 1 else "e.g. indifference 1 % for a chance"))
            continue
        try:
            value = fold(margin, constants)
        except NotConstant:
            continue
        except NotComputable:
            value = math.nan  # refused below as not finite
        if isinstance(value, dict) or not 0.0 <= float(value) < float("inf"):
            problems.append(error(MARGIN_RANGE, f"the indifference of verdict '{rule.name}' "
                                  "must be a finite margin of 0 or more", margin.span))
            continue
        counts = any(node.name == "runs" for node in names_in(rule.condition))
        if found.dimension == DIMENSIONLESS and not counts and not float(value) < 0.5:
            # as combine's verdict_indifference: a ratio verdict with a margin of half the
            # scale or more could never be shown to pass (or to fail) across most of it (a
            # run count is no ratio: 'runs >= 100 indifference 5' is a margin of 5 runs)
            problems.append(error(MARGIN_RANGE, f"the indifference of verdict '{rule.name}' "
                                  "must lie in [0 %, 50 %), as verdict_indifference",
                                  margin.span, "e.g. indifference 1 % for a chance"))
            continue
        margins[rule.name] = float(value)
    return margins
