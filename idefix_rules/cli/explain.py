"""``idefix-verify explain RULEBOOK``: a table of the checked rules.

One row per rule: kind, name, formula (printed by the formatter), unit of the value (SI),
threshold (the limit, with its SI value, and an index's nominal, where it is 0.5), weight and
rationale. Command rules, indices,
chances, prescreens and verdicts are all listed; a table of the constants (as written, in SI,
rationale), the settings, the obstacle levels (size limit, buffer, factors per level), the
combination and the ranking follow. ``--format json`` gives the same as data.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from idefix_rules.cli.encoding import json_text

# The rulebook and rich are imported by the functions that use them: the command line is read
# (and `explain --help` printed) without them.
if TYPE_CHECKING:
    from rich.table import Table

    from idefix_rules.rulebook.check import CheckedRulebook
    from idefix_rules.rulebook.model import Expr, VerdictRule
    from idefix_rules.units import Dimension

NAME = "explain"
HELP = ("Explain a rulebook: a table of its rules (kind, name, formula, unit, threshold, "
        "weight, rationale), its constants, settings and obstacle levels. "
        "Exit 2 when the rulebook is invalid.")

_COMPARISONS = {"<", "<=", ">", ">=", "==", "!="}
# `a op b` is `b mirrored-op a`
_MIRRORED = {"<": ">", "<=": ">=", ">": "<", ">=": "<=", "==": "==", "!=": "!="}


# The terminal width the tables need to read well (their formula and rationale columns fold).
TABLE_COLUMNS = 120


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("rulebook", type=Path, metavar="RULEBOOK", help="rulebook file (.rules)")
    parser.add_argument("--format", choices=("text", "json"), default="text",
                        help="tables (default) or the same as JSON")


def _si(value: float, dimension: Dimension | None) -> str:
    from idefix_rules.rulebook.format import format_number

    unit = "" if dimension is None or dimension.is_dimensionless else f" {dimension}"
    return f"{format_number(float(f'{value:.6g}'))}{unit}"


def _threshold(checked: CheckedRulebook, expr: Expr, dimension: Dimension | None) -> str:
    """The limit as written, with its SI value when the text is not already that."""
    from idefix_rules.rulebook.fold import NotConstant
    from idefix_rules.rulebook.format import format_expr
    from idefix_rules.rulebook.model import Number

    written = format_expr(expr)
    try:
        value = checked.value(expr)
    except (NotConstant, KeyError, ValueError, TypeError, ZeroDivisionError):
        return written
    if not isinstance(value, int | float):
        return written
    if isinstance(expr, Number) and expr.unit is None:
        return written
    return f"{written} (= {_si(float(value), dimension)})"


def _is_constant(checked: CheckedRulebook, expr: Expr) -> bool:
    """Whether ``expr`` reads constants only (no signal, index, chance or path statistic)."""
    from idefix_rules.rulebook.fold import NotConstant

    try:
        checked.value(expr)
    except NotConstant:
        return False
    except (KeyError, ValueError, TypeError, ArithmeticError):
        return True  # constant, only not computable (the checker has said so)
    return True


def _condition_threshold(checked: CheckedRulebook, condition: Expr, scope: str) -> str:
    """For ``x <= 90 deg`` the threshold is ``<= 90 deg (= 1.5708 rad)``; else empty.

    It is seen from the value the rule compares: ``90 deg >= x`` has the same threshold as
    ``x <= 90 deg``, not ``>= x``.
    """
    from idefix_rules.rulebook.infer import infer_type
    from idefix_rules.rulebook.model import Binary

    if not isinstance(condition, Binary) or condition.op not in _COMPARISONS:
        return ""
    op: str = condition.op
    limit = condition.right
    if _is_constant(checked, condition.left) and not _is_constant(checked, condition.right):
        op, limit = _MIRRORED[condition.op], condition.left
    limit_type = infer_type(limit, checked.scope(scope), [])
    dimension = limit_type.dimension if limit_type is not None else None
    return f"{op} {_threshold(checked, limit, dimension)}"


def rows(checked: CheckedRulebook) -> Iterator[tuple[str, ...]]:
    """(kind, name, formula, unit, threshold, weight, rationale) per rule, in canonical order."""
    from idefix_rules.rulebook.across import runs_reductions
    from idefix_rules.rulebook.format import format_expr, format_number

    rulebook = checked.rulebook
    for rule in rulebook.command_rules:
        yield ("command", rule.name, format_expr(rule.condition), "condition",
               _condition_threshold(checked, rule.condition, "command"), "", rule.rationale or "")
    for index in rulebook.indices:
        value_type = checked.index_types.get(index.name)
        dimension = value_type.dimension if value_type is not None else None
        formula = format_expr(index.value)
        if index.map is not None:
            formula += f"\nmap: {format_expr(index.map)}"
        if runs_reductions([index.value]):
            formula += "\npath-level: reduces over the runs of the path (the same in each run)"
        title = f"{index.name}\n{index.title}" if index.title else index.name
        threshold = _threshold(checked, index.limit, dimension)
        if index.nominal is not None:
            threshold += f"\nnominal (0.5): {_threshold(checked, index.nominal, dimension)}"
        yield ("index", title, formula, str(dimension) if dimension is not None else "",
               threshold,
               format_number(checked.weights.get(index.name, float("nan"))),
               index.rationale or "")
    for chance in rulebook.chances:
        formula = format_expr(chance.condition)
        if runs_reductions([chance.condition]):
            formula += "\npath-level: reads values over the runs of the path"
        yield ("chance", chance.name, formula, "fraction of runs", "", "",
               chance.rationale or "")
    for prescreen in rulebook.prescreens:
        yield ("prescreen", prescreen.name, format_expr(prescreen.condition), "condition",
               _condition_threshold(checked, prescreen.condition, "prescreen"), "",
               prescreen.rationale or "")
    for verdict in rulebook.verdicts:
        yield ("verdict", verdict.name, format_expr(verdict.condition), "condition",
               _condition_threshold(checked, verdict.condition, "path")
               + _margin_text(checked, verdict), "", verdict.rationale or "")


def _margin_text(checked: CheckedRulebook, verdict: VerdictRule) -> str:
    """``marginal within ± 0.5 %`` of a verdict with an indifference margin (its own or the
    ``verdict_indifference`` default), on a line of its own; else empty."""
    from idefix_rules.rulebook.format import format_expr, format_number
    from idefix_rules.rulebook.infer import infer_type

    margin = checked.verdict_margins.get(verdict.name, 0.0)
    if margin <= 0:
        return ""
    if verdict.indifference is not None:
        written = format_expr(verdict.indifference)
        limit_type = infer_type(verdict.indifference, checked.scope("constant"), [])
        dimension = limit_type.dimension if limit_type is not None else None
        si = _si(margin, dimension)
        shown = written if si == written else f"{written} (= {si})"
    else:
        shown = f"{format_number(float(f'{margin * 100:.6g}'))} % (verdict_indifference)"
    return f"\nmarginal within ± {shown}"


_ROW_KEYS = ("kind", "name", "formula", "unit", "threshold", "weight", "rationale")


def as_data(checked: CheckedRulebook) -> dict[str, Any]:
    """The JSON form: header, rules (the table's rows), constants, settings, obstacle levels,
    combination and ranking."""
    from idefix_rules.rulebook.format import format_expr
    from idefix_rules.rulebook.summary import areas, constants, obstacle_levels, settings

    rulebook = checked.rulebook
    header = rulebook.header
    rules = []
    for row in rows(checked):
        rule = dict(zip(_ROW_KEYS, row, strict=True))
        name, _, title = rule["name"].partition("\n")
        rules.append({**rule, "name": name, "title": title or None})
    combine = rulebook.combine
    return {
        "name": header.name, "version": header.version, "purpose": header.purpose,
        "rules": rules,
        "constants": [constant.to_dict() for constant in constants(checked)],
        "settings": [setting.to_dict() for setting in settings(checked)],
        "obstacle_levels": [level.to_dict() for level in obstacle_levels(checked)],
        "areas": [area.to_dict() for area in areas(checked)],
        "combine": {"run": combine.run, "path": combine.path,
                    "confidence": checked.confidence, "indifference": checked.indifference,
                    "verdict_margins": dict(checked.verdict_margins)},
        "ranking": [format_expr(key.expr) + (" desc" if key.descending else "")
                    for key in rulebook.ranking.keys],
    }


def run(args: argparse.Namespace) -> int:
    from rich.table import Table

    from idefix_rules.cli.console import interactive, make_console
    from idefix_rules.rulebook import load_checked

    checked = load_checked(args.rulebook)
    if args.format == "json":
        print(json_text(as_data(checked), indent=2))
        return 0
    rulebook = checked.rulebook
    header = rulebook.header
    console = make_console()
    table = Table(title=f"{header.name} {header.version} — {header.purpose}",
                  show_lines=True, expand=False)
    for column, style in (("kind", "cyan"), ("name", "bold")):
        table.add_column(column, style=style, no_wrap=True)
    for column, ratio in (("formula", 3), ("unit", 1), ("threshold", 2), ("weight", 1),
                          ("rationale", 3)):
        table.add_column(column, ratio=ratio, overflow="fold",
                         style="dim" if column == "rationale" else None)
    found = list(rows(checked))
    for row in found:
        table.add_row(*row)
    tables = interactive(console) and console.width >= TABLE_COLUMNS
    if tables:
        console.print(table)
        console.print(_constants_table(checked))
    else:  # a pipe or a narrow terminal: a record per rule, unfolded (the tables fold every
        # cell into slivers there, and a record a line is what grep and a log read)
        console.print(f"{header.name} {header.version} — {header.purpose}", markup=False,
                      soft_wrap=True)
        for line in _records(found, checked):
            console.print(line, markup=False, soft_wrap=True)
    for line in _footer(checked):  # records too, a line each: never cut at the width
        console.print(line, markup=False, soft_wrap=not tables)
    return 0


def _records(found: list[tuple[str, ...]], checked: CheckedRulebook) -> Iterator[str]:
    """The rules and constants as records, a field a line, where the tables would fold every
    cell into slivers: ``kind name``, then its formula, unit, threshold, weight and rationale
    (those it has), each indented."""
    from idefix_rules.rulebook.summary import constants

    fields = ("formula", "unit", "threshold", "weight", "rationale")
    for kind, name, *values in found:
        yield ""
        yield f"{kind} {name.replace(chr(10), ' — ')}"
        for label, value in zip(fields, values, strict=True):
            if value:
                yield f"  {label}: " + value.replace("\n", "\n    ")
    yield ""
    yield "constants"
    for constant in constants(checked):
        si = "" if constant.si == constant.written else f" (= {constant.si})"
        yield f"  {constant.name} = {constant.written}{si}" + (
            f"  # {constant.rationale}" if constant.rationale else "")


def _constants_table(checked: CheckedRulebook) -> Table:
    from rich.table import Table

    from idefix_rules.rulebook.summary import constants

    table = Table(title="constants", show_lines=False, expand=False)
    table.add_column("name", style="bold", no_wrap=True)
    table.add_column("value", ratio=1, overflow="fold")
    table.add_column("SI", ratio=1, overflow="fold")
    table.add_column("rationale", ratio=3, overflow="fold", style="dim")
    for constant in constants(checked):
        si = "" if constant.si == constant.written else constant.si
        table.add_row(constant.name, constant.written, si, constant.rationale or "")
    return table


def _footer(checked: CheckedRulebook) -> Iterator[str]:
    from idefix_rules.rulebook.format import format_expr, format_number
    from idefix_rules.rulebook.summary import areas, obstacle_levels, settings
    from idefix_rules.units import ANGLE, LENGTH

    rulebook = checked.rulebook
    for setting in settings(checked):
        written = setting.written if setting.written is not None else "(default)"
        si = "" if setting.si == written else f" (= {setting.si})"
        yield f"setting {setting.name} = {written}{si}"
    for level in obstacle_levels(checked):
        below = f"below {level.below} ({_si(level.below_m, LENGTH)})" \
            if level.below is not None and level.below_m is not None else "no size limit"
        factors = "".join(f", {name} {format_number(value)}"
                          for name, value in level.factors.items())
        yield (f"obstacle level {level.level}: {below}, buffer {level.buffer} "
               f"({_si(level.buffer_m, LENGTH)}){factors}")
    for area in areas(checked):
        kind = area.kind.replace("_", "-")
        if area.above is not None and area.above_rad is not None:
            kind += f" above {area.above} ({_si(area.above_rad, ANGLE)})"
        yield (f"area {area.name}: {kind}, level {area.level}, buffer {area.buffer} "
               f"({_si(area.buffer_m, LENGTH)}); runs read {', '.join(area.signals)}")
    combine = rulebook.combine
    yield (f"run risk: {combine.run} (eq. 1); path risk: {combine.path} of runs (eq. 2); "
           f"confidence {format_number(checked.confidence * 100)} %")
    if checked.indifference > 0:
        yield (f"ranks: paths whose risks differ by less than "
               f"{format_number(float(f'{checked.indifference * 100:.6g}'))} % are tied")
    keys = ", ".join(format_expr(key.expr) + (" desc" if key.descending else "")
                     for key in rulebook.ranking.keys)
    yield f"rank by {keys}"
