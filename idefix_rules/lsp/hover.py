"""What the editor shows when the pointer rests on a name or on a problem (Markdown).

* a constant: its value as written, its SI value with unit, its rationale;
* an index: its formula, nominal and limit (with SI values), weight, result-map formula and
  rationale, and how it is normalised;
* a chance, an obstacle level: the declaration and its rationale or SI sizes;
* a signal: its entry in the signal contract (unit, axes, who provides it);
* a command quantity or path statistic: what it is and its unit;
* a diagnostic's range: the code and its explanation
  (:func:`~idefix_rules.lsp.codes.code_explanation`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from idefix_rules import signals
from idefix_rules.diff.rules import si_text
from idefix_rules.errors import Severity
from idefix_rules.lsp.analysis import Analysis
from idefix_rules.lsp.codes import code_explanation
from idefix_rules.lsp.positions import Position, Range, span_range
from idefix_rules.lsp.symbols import NameUse, Symbol
from idefix_rules.rulebook.fold import NotConstant, fold
from idefix_rules.rulebook.format import format_expr
from idefix_rules.rulebook.infer import infer_type
from idefix_rules.rulebook.model import Chance, Constant, Expr, Index, ObstacleLevel
from idefix_rules.rulebook.types import COMMAND_NAMES, PATH_NAMES, ExprType, Scope
from idefix_rules.units import LENGTH, Dimension, describe

PROVIDERS = {
    "fmu": "the rover FMU (an FMU variable mapped to this name by the campaign's signal map)",
    "derived": "the evaluator (derived from the FMU signals and the reference run)",
    "collision": "the obstacle checker (collisions of the rover bodies with rocks and areas)",
}


@dataclass(frozen=True)
class Hover:
    markdown: str
    range: Range


def hover(analysis: Analysis, position: Position) -> Hover | None:
    """The hover at ``position``, or ``None`` when there is nothing to say."""
    parts: list[str] = []
    where: Range | None = None
    found = analysis.symbols.symbol_at(position)
    if found is not None:
        symbol, where = found
        parts.append(symbol_markdown(analysis, symbol))
    else:
        use = analysis.symbols.name_at(position)
        if use is not None:
            text = name_markdown(use)
            if text is not None:
                parts.append(text)
                where = use.range
    for diagnostic in analysis.diagnostics:
        covered = span_range(diagnostic.span)
        if covered.contains(position):
            parts.append(diagnostic_markdown(diagnostic.code, diagnostic.severity))
            where = where or covered
    if not parts or where is None:
        return None
    return Hover("\n\n---\n\n".join(parts), where)


def diagnostic_markdown(code: str, severity: Severity) -> str:
    explanation = code_explanation(code)
    return f"**{severity.value}[{code}]**" + (f": {explanation}" if explanation else "")


def _code(text: str) -> str:
    return f"`{text}`" if "`" not in text else f"``{text}``"


def _dimension_text(dimension: Dimension) -> str:
    return describe(dimension) + ("" if dimension.is_dimensionless else f" ({dimension})")


def _literal_si(expr: Expr) -> tuple[Any, Dimension] | None:
    """SI value and dimension of a constant expression that reads no other constant."""
    found = infer_type(expr, Scope("constant"), [])
    if found is None or found.boolean:
        return None
    try:
        return fold(expr, {}), found.dimension
    except (NotConstant, ArithmeticError, ValueError, KeyError, TypeError):
        return None


def _constant(analysis: Analysis, constant: Constant) -> list[str]:
    checked = analysis.checked
    lines = [f"**const {constant.name}** = {_code(format_expr(constant.value))}"]
    if checked is not None and constant.name in checked.constants:
        value: Any = checked.constants[constant.name]
        dimension: Dimension | None = checked.constant_types[constant.name].dimension
    else:
        literal = _literal_si(constant.value)
        value, dimension = literal if literal is not None else (None, None)
    if value is not None and dimension is not None:
        lines.append(f"SI value: {_code(si_text(value, dimension))} — "
                     f"{_dimension_text(dimension)}")
    elif analysis.checked is None:
        lines.append("SI value: shown when the rulebook has no errors")
    return lines


def _index(analysis: Analysis, index: Index) -> list[str]:
    checked = analysis.checked
    title = f" — {index.title}" if index.title else ""
    value_type: ExprType | None = checked.index_types.get(index.name) if checked else None
    lines = [f"**index {index.name}**{title}",
             f"- formula: {_code(format_expr(index.value))}"
             + (f" — {_dimension_text(value_type.dimension)}" if value_type else "")]
    if index.nominal is not None:
        nominal = f"- nominal: {_code(format_expr(index.nominal))}"
        if checked is not None and index.name in checked.nominals and value_type is not None:
            nominal += f" = {_code(si_text(checked.nominals[index.name], value_type.dimension))}"
        lines.append(nominal)
    limit = f"- limit: {_code(format_expr(index.limit))}"
    if checked is not None and index.name in checked.limits and value_type is not None:
        limit += f" = {_code(si_text(checked.limits[index.name], value_type.dimension))}"
    lines.append(limit)
    weight = f"- weight: {_code(format_expr(index.weight))}"
    if checked is not None and index.name in checked.weights:
        weight_text = si_text(checked.weights[index.name])
        if weight_text != format_expr(index.weight):
            weight += f" = {_code(weight_text)}"
    lines.append(weight)
    if index.map is not None:
        lines.append(f"- result map: {_code(format_expr(index.map))}")
    lines.append("")
    shape = ("piecewise linear through (0, 0), (nominal, 0.5) and (limit, 1), clamped to "
             "[0, 1]" if index.nominal is not None else "clamp(value / limit, 0, 1)")
    lines.append(f"I = {shape}; weighted by {format_expr(index.weight)} in the run risk I_max "
                 "(eq. 1)")
    return lines


def _level(analysis: Analysis, level: ObstacleLevel) -> list[str]:
    below = f" below {format_expr(level.below)}" if level.below is not None else ""
    lines = [f"**obstacle level {level.level}**{below} buffer {format_expr(level.buffer)}"]
    checked = analysis.checked
    spec = next((s for s in checked.obstacle_levels if s.level == level.level), None) \
        if checked is not None else None
    if spec is not None:
        size = (f"obstacles smaller than {si_text(spec.below, LENGTH)}"
                if spec.below is not None else "obstacles of any larger size")
        lines.append(f"{size}; buffer zone {si_text(spec.buffer, LENGTH)}")
    return lines


def symbol_markdown(analysis: Analysis, symbol: Symbol) -> str:
    declaration = symbol.declaration
    rationale: str | None = None
    if isinstance(declaration, Constant):
        lines = _constant(analysis, declaration)
        rationale = declaration.rationale
    elif isinstance(declaration, Index):
        lines = _index(analysis, declaration)
        rationale = declaration.rationale
    elif isinstance(declaration, Chance):
        lines = [f"**chance {declaration.name}** = {_code(format_expr(declaration.condition))}",
                 "per run a condition; the path statistic `chance("
                 f"{declaration.name})` is the fraction of runs where it holds"]
        rationale = declaration.rationale
    else:
        lines = _level(analysis, declaration)
    if rationale:
        lines.append(f"*because* {rationale}")
    return "\n\n".join(line for line in lines if line)  # Markdown paragraphs


def signal_markdown(name: str) -> str | None:
    spec = signals.lookup(name)
    if spec is None:
        return None
    axes = " × ".join(
        f"{axis} ({', '.join(signals.AXIS_LABELS[axis])})" if axis in signals.AXIS_LABELS
        else axis for axis in spec.axes)
    return "\n\n".join([
        f"**signal {name}** — {spec.description}",
        f"- unit: `{spec.unit}` — {_dimension_text(spec.dimension)}",
        f"- axes per run: {axes or 'one value'}",
        f"- provided by {PROVIDERS[spec.kind]}",
    ])


def name_markdown(use: NameUse) -> str | None:
    """A built-in name: a command quantity in command rules, a path statistic in verdicts and
    rank keys, a contract signal elsewhere."""
    if use.scope == "command" and use.name in COMMAND_NAMES:
        return (f"**command quantity {use.name}** — "
                f"{_dimension_text(COMMAND_NAMES[use.name].dimension)}, of each driving command "
                "(checked on the command chain before any simulation)")
    if use.scope == "path" and use.name in PATH_NAMES:
        return (f"**path statistic {use.name}** — "
                f"{_dimension_text(PATH_NAMES[use.name].dimension)}, over the runs of a path")
    if use.scope == "prescreen" and use.name == "risk":
        return "**risk** — the reference run's I_max (eq. 1)"
    return signal_markdown(use.name)
