"""Checking a rulebook: small named passes over the rule model, each returning diagnostics.

``check(rulebook)`` first resolves the constants (types and SI values, in dependency order),
then runs every pass of :data:`CHECKS` (and :data:`STRICT_CHECKS` with ``strict=True``). All
problems of a file are collected; the result carries a :class:`CheckedRulebook` with every
constant value the compiler needs already in SI.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, get_args

from idefix_rules import signals
from idefix_rules.errors import Diagnostic, Severity, Span, error, unique_diagnostics, warning
from idefix_rules.rulebook.environment import AreaSpec, CheckEnv, ObstacleLevelSpec, scope_of
from idefix_rules.rulebook.fold import NotConstant, Value, fold, folded_number
from idefix_rules.rulebook.infer import did_you_mean, infer_type
from idefix_rules.rulebook.judging import MARGIN_RANGE, verdict_margins
from idefix_rules.rulebook.model import (
    Expr,
    Index,
    Number,
    Reduce,
    Reducer,
    Rulebook,
)
from idefix_rules.rulebook.types import (
    COMMAND_NAMES,
    PATH_NAMES,
    SETTINGS,
    ExprType,
    Scope,
)
from idefix_rules.rulebook.walk import names_in, nodes, rulebook_expressions, windowed
from idefix_rules.units import ANGLE, DIMENSIONLESS, LENGTH, describe

_SEMVER = re.compile(r"^(0|[1-9]\d*)\.(0|[1-9]\d*)\.(0|[1-9]\d*)(?:-[0-9A-Za-z.-]+)?"
                     r"(?:\+[0-9A-Za-z.-]+)?$")
LEVELS = signals.AXIS_LABELS["level"]


@dataclass(frozen=True)
class CheckedRulebook:
    """A rulebook that passed the checks, with every constant resolved to SI."""

    rulebook: Rulebook
    constants: dict[str, Value]
    constant_types: dict[str, ExprType]
    settings: dict[str, float]
    obstacle_levels: tuple[ObstacleLevelSpec, ...]
    limits: dict[str, float]
    weights: dict[str, float]
    index_types: dict[str, ExprType]
    confidence: float
    indifference: float = 0.0  # run-risk difference within which two paths tie (0: never)
    # per verdict, the margin around its limits (SI; 0: none): within it is "marginal"
    verdict_margins: dict[str, float] = field(default_factory=dict)
    nominals: dict[str, float] = field(default_factory=dict)  # indices that give a nominal
    areas: tuple[AreaSpec, ...] = ()

    def scope(self, kind: str) -> Scope:
        """The scope the checker used for one context (``command``, ``run``, …)."""
        return scope_of(kind, self.rulebook, self.constant_types)

    def value(self, expr: Expr) -> Value:
        """SI value of a constant expression of this rulebook (windows, thresholds …)."""
        return fold(expr, self.constants)

    def level_of_size(self, size: float) -> str:
        """Obstacle level a rock of ``size`` metres gets from the thresholds."""
        for spec in self.obstacle_levels:
            if spec.below is None or size < spec.below:
                return spec.level
        return LEVELS[-1]


@dataclass
class CheckResult:
    diagnostics: list[Diagnostic]
    checked: CheckedRulebook | None

    @property
    def errors(self) -> list[Diagnostic]:
        return [d for d in self.diagnostics if d.severity is Severity.ERROR]

    @property
    def ok(self) -> bool:
        return not self.errors


Check = Callable[[CheckEnv], list[Diagnostic]]


# ----------------------------------------------------------------------------- constants

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
        try:
            value = fold(constant.value, env.constants)
        except NotConstant:
            return
        except OverflowError:
            problems.append(error("E402", f"constant '{name}' is beyond a double: its value "
                                          "is too large for a number", constant.value.span))
            return
        except (ValueError, ZeroDivisionError) as failure:
            problems.append(error("E402", f"constant '{name}' cannot be computed: {failure}",
                                  constant.value.span))
            return
        values = value.values() if isinstance(value, dict) else [value]
        if not all(math.isfinite(float(v)) for v in values):
            problems.append(error("E402", f"constant '{name}' is not a finite number (a "
                                          "division by zero, or a value beyond a double?)",
                                  constant.value.span))
            return
        env.constant_types[name] = found
        env.constants[name] = value

    for name in declared:
        visit(name, ())
    return problems


# ----------------------------------------------------------------------------- passes

def check_header(env: CheckEnv) -> list[Diagnostic]:
    header = env.rulebook.header
    problems = []
    def at(span: Span) -> Span:  # a header built without its strings' places: the header's
        return span if span.line > 0 else header.span

    if not _SEMVER.match(header.version):
        problems.append(error("E503", f"version '{header.version}' is not a semantic version",
                              at(header.version_span),
                              "write MAJOR.MINOR.PATCH, e.g. \"1.2.0\""))
    if not header.name.strip():
        problems.append(error("E504", "the rulebook needs a name", at(header.name_span)))
    if not header.purpose.strip():
        problems.append(error("E504", "the rulebook needs a one-line purpose",
                              at(header.purpose_span)))
    return problems


def _declarations(rulebook: Rulebook) -> Iterator[tuple[str, str, object]]:
    for c in rulebook.constants:
        yield "constant", c.name, c
    for r in rulebook.command_rules:
        yield "command rule", r.name, r
    for i in rulebook.indices:
        yield "index", i.name, i
    for ch in rulebook.chances:
        yield "chance", ch.name, ch
    for p in rulebook.prescreens:
        yield "prescreen", p.name, p
    for v in rulebook.verdicts:
        yield "verdict", v.name, v


# The reduction words (`max over time (…)`): a name spelt like one starts a reduction wherever
# an expression may, so a declaration of it could never be used.
REDUCER_WORDS: frozenset[str] = frozenset(get_args(Reducer))
# the declarations whose names expressions read (`limit = c`, `chance(c)`, `mean(I)`); rules
# and verdicts are named in outputs and waivers only
READ_KINDS = frozenset({"constant", "index", "chance"})


def check_names(env: CheckEnv) -> list[Diagnostic]:
    """Duplicate declarations, and names that would hide a signal or a built-in name."""
    problems = []
    seen: dict[str, tuple[str, object]] = {}
    reserved = set(COMMAND_NAMES) | set(PATH_NAMES)

    def place(declaration: tuple[str, str, object]) -> tuple[int, int]:
        span = getattr(declaration[2], "span", None)
        return (span.line, span.column) if span is not None else (1 << 62, 0)

    # in the order of the text: the later of two declarations is the one said to repeat
    for kind, name, node in sorted(_declarations(env.rulebook), key=place):
        span = getattr(node, "span", None)
        if name in seen:
            first_kind, first = seen[name]
            first_span = getattr(first, "span", None)
            article = "an" if first_kind[0] in "aeiou" else "a"
            problems.append(error("E102", f"{kind} '{name}' is already declared as {article} "
                                  f"{first_kind}"
                                  + (f" at {first_span}" if first_span else ""), span))
            continue
        seen[name] = (kind, node)
        if signals.lookup(name) is not None or name in reserved:
            problems.append(error("E103", f"{kind} '{name}' hides the built-in name '{name}'",
                                  span, "choose another name"))
        elif name in REDUCER_WORDS and kind in READ_KINDS:  # `x > max`: a reduction begins
            problems.append(error("E103", f"{kind} '{name}' is named like the reduction "
                                  f"'{name} over …': the name could never be read",
                                  span, f"choose another name, e.g. '{name}_{kind.split()[0]}'"))
    settings_seen: set[str] = set()
    for setting in env.rulebook.settings:
        if setting.name in settings_seen:
            problems.append(error("E102", f"setting '{setting.name}' is set twice", setting.span))
        settings_seen.add(setting.name)
    return problems


def check_settings(env: CheckEnv) -> list[Diagnostic]:
    problems: list[Diagnostic] = []
    env.settings = {name: default for name, (_, default) in SETTINGS.items()}
    for setting in env.rulebook.settings:
        if setting.name not in SETTINGS:
            problems.append(error("E505", f"unknown setting '{setting.name}'", setting.span,
                                  did_you_mean(setting.name, list(SETTINGS))
                                  or f"settings are {', '.join(SETTINGS)}"))
            continue
        wanted, _ = SETTINGS[setting.name]
        value = _constant_quantity(env, setting.value, wanted, f"setting '{setting.name}'",
                                   problems)
        if value is not None:
            if value < 0:
                problems.append(error("E402", f"setting '{setting.name}' cannot be negative",
                                      setting.value.span))
            elif setting.name == "theoretical_slip" and value >= 1:
                problems.append(error("E402", "theoretical_slip must be below 100 %",
                                      setting.value.span))
            else:
                env.settings[setting.name] = value
    return problems


def _constant_quantity(env: CheckEnv, expr: Expr, wanted: object, what: str,
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
    try:
        value = fold(expr, env.constants)
    except NotConstant:
        return None
    if isinstance(value, dict):
        return None
    if not math.isfinite(float(value)):
        problems.append(error("E402", f"{what} is not a finite number ({float(value)}; a "
                                      "division by zero, or a value beyond a double?)",
                              expr.span))
        return None
    return float(value)


def check_areas(env: CheckEnv) -> list[Diagnostic]:
    """Named areas: declared once, a known level, a buffer, a steep area's inclination."""
    problems: list[Diagnostic] = []
    seen: set[str] = set()
    for area in env.rulebook.areas:
        if area.name in seen:
            problems.append(error("E409", f"area '{area.name}' is declared twice", area.span))
            continue
        seen.add(area.name)
        if area.level not in LEVELS:
            problems.append(error("E409", f"area '{area.name}': unknown obstacle level "
                                  f"'{area.level}'", area.span, f"levels are {', '.join(LEVELS)}"))
            continue
        buffer = _constant_quantity(env, area.buffer, LENGTH, f"the buffer of area '{area.name}'",
                                    problems)
        if buffer is not None and buffer < 0:
            problems.append(error("E409", "a buffer zone cannot be negative", area.buffer.span))
            continue
        above = None
        if area.above is not None:
            above = _constant_quantity(env, area.above, ANGLE,
                                       f"the inclination of area '{area.name}'", problems)
            if above is not None and not 0.0 < above < math.pi / 2:
                problems.append(error("E409", f"area '{area.name}': a steep area starts above "
                                      "0 deg and below 90 deg", area.above.span))
                continue
        if buffer is not None:
            env.areas.append(AreaSpec(area.name, area.kind, area.level, buffer, above))
    return problems


def check_obstacle_levels(env: CheckEnv) -> list[Diagnostic]:
    problems: list[Diagnostic] = []
    declared = env.rulebook.obstacle_levels
    seen: set[str] = set()
    specs = []
    for level in declared:
        if level.level not in LEVELS:
            problems.append(error("E104", f"unknown obstacle level '{level.level}'", level.span,
                                  f"levels are {', '.join(LEVELS)}"))
            continue
        if level.level in seen:
            problems.append(error("E102", f"obstacle level {level.level} is declared twice",
                                  level.span))
            continue
        seen.add(level.level)
        below = None
        if level.below is not None:
            below = _constant_quantity(env, level.below, LENGTH,
                                       f"the size threshold of {level.level}", problems)
        buffer = _constant_quantity(env, level.buffer, LENGTH, f"the buffer of {level.level}",
                                    problems)
        if buffer is not None and buffer < 0:
            problems.append(error("E402", "a buffer zone cannot be negative", level.buffer.span))
        specs.append((level, below, buffer if buffer is not None else 0.0))
    if not declared:
        # No size thresholds and no buffers: rocks must carry their level explicitly.
        env.levels = []
        return problems
    specs.sort(key=lambda item: LEVELS.index(item[0].level))
    previous = 0.0
    previous_level = ""
    for position, (level, below, _) in enumerate(specs):
        last = position == len(specs) - 1
        if level.below is None and not last:
            problems.append(error("E405", f"level {level.level} needs a size threshold "
                                  "('below …'): only the highest level may omit it", level.span))
        if level.below is not None and last and level.level == LEVELS[-1]:
            problems.append(error(
                "E405", f"level {level.level} holds every rock the levels below it do not: a "
                        "size threshold ('below …') would never be used", level.below.span,
                f"remove it: 'level {level.level} buffer …'"))
            continue
        if below is not None:
            if below <= previous:
                problems.append(error(
                    "E405", f"size thresholds must increase from L1 to L3: {level.level}'s "
                    f"({below * 100:g} cm) is not above {previous_level}'s "
                    f"({previous * 100:g} cm)" if previous_level else
                    f"{level.level}'s size threshold ({below * 100:g} cm) must be above 0 cm: "
                    f"{level.level} holds the rocks smaller than it",
                    level.below.span if level.below else level.span))
            previous, previous_level = below, level.level
    env.levels = [ObstacleLevelSpec(level.level, below, buffer)
                  for level, below, buffer in specs]
    missing = [lvl for lvl in LEVELS if lvl not in seen]
    if missing and not problems:
        problems.append(error("E405", f"obstacle levels {', '.join(missing)} are missing",
                              declared[0].span, "declare L1, L2 and L3"))
    return problems


def _condition(env: CheckEnv, expr: Expr, kind: str, what: str,
               problems: list[Diagnostic]) -> ExprType | None:
    found = infer_type(expr, env.scope(kind), problems)
    if found is None:
        return None
    if not found.boolean:
        problems.append(error("E303", f"{what} must be a condition (a comparison), got "
                              f"{describe(found.dimension)}", expr.span,
                              "for example 'abs(delta_heading) <= 90 deg'"))
        return None
    if found.axes:
        problems.append(error("E302", f"{what} must be one condition per "
                              f"{'command' if kind == 'command' else 'run'}, but it still has "
                              f"{_axes_phrase(found.axes)}", expr.span,
                              "reduce them with any/all over …"))
        return None
    return found


def _axes_phrase(axes: tuple[str, ...]) -> str:
    """``a time axis`` / ``a time and a wheel axis``."""
    return " and ".join(f"a {axis}" for axis in axes) + (" axis" if len(axes) == 1 else " axes")


def _check_conditions(kind: str, label: str,
                      rules: Callable[[Rulebook], tuple[Any, ...]]) -> Check:
    """A pass checking that each rule's ``condition`` is one boolean in scope ``kind``."""

    def check_pass(env: CheckEnv) -> list[Diagnostic]:
        problems: list[Diagnostic] = []
        for rule in rules(env.rulebook):
            _condition(env, rule.condition, kind, f"{label} '{rule.name}'", problems)
        return problems

    return check_pass


check_command_rules = _check_conditions("command", "command rule", lambda r: r.command_rules)
check_chances = _check_conditions("run", "chance", lambda r: r.chances)
check_prescreens = _check_conditions("prescreen", "prescreen", lambda r: r.prescreens)
check_verdicts = _check_conditions("path", "verdict", lambda r: r.verdicts)


def check_indices(env: CheckEnv) -> list[Diagnostic]:
    problems: list[Diagnostic] = []
    run_scope = env.scope("run")
    for index in env.rulebook.indices:
        found = infer_type(index.value, run_scope, problems)
        what = f"index '{index.name}'"
        if found is not None:
            if found.boolean:
                problems.append(error("E304", f"{what} must be a quantity, not a condition",
                                      index.value.span, "use a chance for conditions"))
                found = None
            elif found.axes:
                problems.append(error(
                    "E302", f"{what} must give one value per run, but it still has "
                    f"{_axes_phrase(found.axes)}", index.value.span,
                    "reduce them, e.g. 'max over time (…)' or 'max over wheels (…)'"))
                found = None
        if found is not None:
            env.index_types[index.name] = found
            limit = _constant_quantity(env, index.limit, found.dimension, f"the limit of {what}",
                                       problems)
            if limit is not None:
                if limit <= 0:
                    problems.append(error("E402", f"the limit of {what} must be above zero",
                                          index.limit.span))
                    limit = None
                else:
                    env.limits[index.name] = limit
            if index.nominal is not None:
                _check_nominal(env, index, found, limit, problems)
        weight = _constant_quantity(env, index.weight, DIMENSIONLESS, f"the weight of {what}",
                                    problems)
        if weight is not None:
            if not 0.0 <= weight <= 1.0:
                problems.append(error("E401", f"the weight of {what} must lie in [0, 1], got "
                                      f"{weight:g}", index.weight.span))
            else:
                env.weights[index.name] = weight
        if index.map is not None:
            mapped = infer_type(index.map, run_scope, problems)
            if mapped is not None and (mapped.boolean or mapped.axes != ("time",)):
                problems.append(error("E307", f"the map of {what} must be one quantity per "
                                      "sample (a time series)", index.map.span,
                                      "reduce wheels/parts/levels, keep time"))
            elif mapped is not None and found is not None and mapped.dimension != found.dimension:
                problems.append(error("E307", f"the map of {what} is "
                                      f"{describe(mapped.dimension)} but its value is "
                                      f"{describe(found.dimension)}", index.map.span))
    return problems


def _check_nominal(env: CheckEnv, index: Index, found: ExprType, limit: float | None,
                   problems: list[Diagnostic]) -> None:
    """An index's nominal: the value's dimension (as the limit), above zero, below the limit."""
    assert index.nominal is not None
    what = f"the nominal of index '{index.name}'"
    nominal = _constant_quantity(env, index.nominal, found.dimension, what, problems)
    if nominal is None:
        return
    from idefix_rules.rulebook.format import format_expr

    unit = "" if found.dimension.is_dimensionless else f" {found.dimension}"

    def shown(expr: Expr, si: float) -> str:
        written, in_si = format_expr(expr), f"{si:g}{unit}"
        return written if written == in_si else f"{written} = {in_si}"

    if nominal <= 0:
        problems.append(error("E407", f"{what} must be above zero, got "
                              f"{shown(index.nominal, nominal)}", index.nominal.span,
                              "the nominal is the value expected in the environment, "
                              "between 0 and the limit"))
    elif limit is not None and nominal >= limit:
        problems.append(error("E408", f"{what} must be below its limit: "
                              f"{shown(index.nominal, nominal)} is not below "
                              f"{shown(index.limit, limit)}", index.nominal.span,
                              "the index is 0.5 at the nominal and 1 at the limit"))
    else:
        env.nominals[index.name] = nominal


def check_combine(env: CheckEnv) -> list[Diagnostic]:
    problems: list[Diagnostic] = []
    combine = env.rulebook.combine
    if combine.confidence is not None:
        value = _constant_quantity(env, combine.confidence, DIMENSIONLESS, "confidence",
                                   problems)
        if value is not None:
            if not 0.5 <= value < 1.0:
                problems.append(error("E406", "confidence must lie in [50 %, 100 %)",
                                      combine.confidence.span))
            else:
                env.confidence = value
    if combine.indifference is not None:
        value = _constant_quantity(env, combine.indifference, DIMENSIONLESS, "indifference",
                                   problems)
        if value is not None:
            if not 0.0 <= value < 0.5:
                problems.append(error("E410", "indifference must lie in [0 %, 50 %)",
                                      combine.indifference.span,
                                      "a margin on the difference of two paths' mean risks, "
                                      "e.g. indifference = 2 %"))
            else:
                env.indifference = value
    if combine.verdict_indifference is not None:
        value = _constant_quantity(env, combine.verdict_indifference, DIMENSIONLESS,
                                   "verdict_indifference", problems)
        if value is not None:
            if not 0.0 <= value < 0.5:
                problems.append(error(MARGIN_RANGE, "verdict_indifference must lie in "
                                      "[0 %, 50 %)", combine.verdict_indifference.span,
                                      "a margin around the limits of verdicts on ratios, "
                                      "e.g. verdict_indifference = 0.5 %"))
            else:
                env.verdict_indifference = value
    return problems


def check_verdict_margins(env: CheckEnv) -> list[Diagnostic]:
    """Each verdict's indifference: of the dimension it compares, 0 or more."""
    problems: list[Diagnostic] = []
    env.verdict_margins = verdict_margins(env.rulebook, env.scope("path"),
                                          env.scope("constant"), env.constants,
                                          env.verdict_indifference, problems)
    return problems


def check_ranking(env: CheckEnv) -> list[Diagnostic]:
    from idefix_rules.rulebook.format import format_expr

    problems: list[Diagnostic] = []
    seen: dict[str, Any] = {}
    for key in env.rulebook.ranking.keys:
        written = format_expr(key.expr)
        if written in seen:  # a later key on the same statistic never decides anything
            problems.append(error("E413", f"rank key '{written}' is given twice: the second "
                                  "never orders what the first leaves tied", key.expr.span,
                                  "give each statistic once, in the order that breaks ties"))
            continue
        seen[written] = key
        found = infer_type(key.expr, env.scope("path"), problems)
        if found is not None and (found.boolean or found.axes):
            problems.append(error("E304", "a rank key must be a path statistic (a number)",
                                  key.expr.span))
    return problems


def check_required_sections(env: CheckEnv) -> list[Diagnostic]:
    rulebook = env.rulebook
    problems = []
    if not rulebook.indices:
        problems.append(error("E501", "the rulebook declares no index", rulebook.header.span,
                              "add at least one 'index NAME { value = … limit = … weight = … }'"))
    if not rulebook.verdicts:
        problems.append(error("E502", "the rulebook declares no verdict rule",
                              rulebook.header.span,
                              "add e.g. 'verdict acceptable_risk: require risk <= 70 %'"))
    return problems


def warn_unused_constants(env: CheckEnv) -> list[Diagnostic]:
    used: set[str] = set()
    for expr in rulebook_expressions(env.rulebook):
        used.update(name.name for name in names_in(expr))
    return [warning("W601", f"constant '{c.name}' is never used", c.span)
            for c in env.rulebook.constants if c.name not in used]


def warn_zero_weights(env: CheckEnv) -> list[Diagnostic]:
    return [warning("W602", f"index '{i.name}' has weight 0 and never affects the risk",
                    i.weight.span)
            for i in env.rulebook.indices if env.weights.get(i.name) == 0.0]


def check_command_windows(env: CheckEnv) -> list[Diagnostic]:
    """``during command K`` selects the samples of the K-th command (1-based, ``command ==
    K - 1``): K must be a whole number from 1. ``during command 0`` would select the samples
    after the chain (``command == -1``) and 1.5 the second command, both silently."""
    problems: list[Diagnostic] = []
    scope = scope_of("constant", env.rulebook, env.constant_types)
    for node in windowed(env.rulebook, "command"):
        assert node.window is not None
        found = infer_type(node.window.value, scope, [])
        if found is None or found.dimension != DIMENSIONLESS or found.axes:
            continue  # not a number: E204 says so
        number = folded_number(node.window.value, env.constants)
        if number is not None and not (math.isfinite(number) and number >= 1
                                       and number == math.floor(number)):
            problems.append(error(
                "E310", f"'during command {number:g}': commands are counted from 1, by whole "
                        "numbers", node.window.span, "the first command is 'during command 1'"))
    return problems


def check_percentiles(env: CheckEnv) -> list[Diagnostic]:
    """``percentile P`` with P naming constants: P must fold to a number from 0 to 100 (one
    written in place is checked with the types, E308 too)."""
    problems: list[Diagnostic] = []
    for expr in rulebook_expressions(env.rulebook):
        for node in nodes(expr):
            if not (isinstance(node, Reduce) and node.reducer == "percentile"
                    and node.parameter is not None and not isinstance(node.parameter, Number)):
                continue
            number = folded_number(node.parameter, env.constants)
            if number is not None and not 0 <= number <= 100:
                problems.append(error("E308", f"percentile needs a number from 0 to 100, "
                                              f"got {number:g}", node.parameter.span))
    return problems


CHECKS: tuple[Check, ...] = (
    check_header,
    check_names,
    check_settings,
    check_obstacle_levels,
    check_areas,
    check_command_rules,
    check_indices,
    check_chances,
    check_command_windows,
    check_percentiles,
    check_combine,
    check_prescreens,
    check_verdicts,
    check_verdict_margins,
    check_ranking,
    check_required_sections,
)

STRICT_CHECKS: tuple[Check, ...] = (warn_unused_constants, warn_zero_weights)


def check(rulebook: Rulebook, strict: bool = False) -> CheckResult:
    """Run every pass; all diagnostics of the file, sorted by position."""
    from idefix_rules.rulebook.cascade import fold_cascades, fold_misfit_constants, path_hints
    from idefix_rules.rulebook.lints import LINTS

    env = CheckEnv(rulebook)
    diagnostics = resolve_constants(env)
    for check_pass in CHECKS + (STRICT_CHECKS + LINTS if strict else ()):
        diagnostics.extend(check_pass(env))
    diagnostics = path_hints(rulebook, fold_cascades(rulebook, set(env.constants),
                                                     unique_diagnostics(diagnostics)))
    diagnostics = fold_misfit_constants(rulebook, env.constant_types, diagnostics)
    diagnostics.sort(key=lambda d: (d.span.line if d.span else 0,
                                    d.span.column if d.span else 0))
    checked = None
    if not any(d.severity is Severity.ERROR for d in diagnostics):
        checked = CheckedRulebook(
            rulebook=rulebook,
            constants=env.constants,
            constant_types=env.constant_types,
            settings=env.settings,
            obstacle_levels=tuple(env.levels),
            areas=tuple(env.areas),
            limits=env.limits,
            nominals=env.nominals,
            weights=env.weights,
            index_types=env.index_types,
            confidence=env.confidence,
            indifference=env.indifference,
            verdict_margins=env.verdict_margins,
        )
    return CheckResult(diagnostics, checked)
