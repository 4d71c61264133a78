"""The checker's passes over declarations: header, names, settings, levels, areas, combine."""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from typing import get_args

from idefix_rules import signals
from idefix_rules.errors import Diagnostic, Span, error, warning
from idefix_rules.rulebook.constants import constant_quantity
from idefix_rules.rulebook.environment import LEVELS, AreaSpec, CheckEnv, ObstacleLevelSpec
from idefix_rules.rulebook.infer import did_you_mean
from idefix_rules.rulebook.judging import MARGIN_RANGE
from idefix_rules.rulebook.model import NO_SPAN, Reducer, Rulebook
from idefix_rules.rulebook.types import COMMAND_NAMES, FAILED_RUNS_RULE, PATH_NAMES, SETTINGS
from idefix_rules.rulebook.walk import names_in, rulebook_expressions
from idefix_rules.units import ANGLE, DIMENSIONLESS, LENGTH

_SEMVER = re.compile(r"^(0|[1-9]\d*)\.(0|[1-9]\d*)\.(0|[1-9]\d*)(?:-[0-9A-Za-z.-]+)?"
                     r"(?:\+[0-9A-Za-z.-]+)?$")


def check_header(env: CheckEnv) -> list[Diagnostic]:
    header = env.rulebook.header
    problems: list[Diagnostic] = []
    if header.span == NO_SPAN and not (header.name or header.version or header.purpose):
        return problems  # no header written: the parser said so (E500)
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
# The other keyword an expression may start with (`not x`): where an expression starts
# (`limit = not`, `mean(not)`) the word is read as a negation, never as the name. The grammar's
# other keywords are read as names wherever an expression is expected.
NEGATION_WORD = "not"
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
        if name == FAILED_RUNS_RULE:  # the verdict's own rule: results would show both as one
            problems.append(error("E103", f"{kind} '{name}' takes the name of the verdict's "
                                  "own rule for failed runs", span,
                                  "choose another name; a verdict rule that reads `failed` "
                                  "(e.g. `require failed <= 10 %`) takes the place of "
                                  f"'{name}'"))
        elif signals.lookup(name) is not None or name in reserved:
            problems.append(error("E103", f"{kind} '{name}' hides the built-in name '{name}'",
                                  span, "choose another name"))
        elif name in REDUCER_WORDS and kind in READ_KINDS:  # `x > max`: a reduction begins
            problems.append(error("E103", f"{kind} '{name}' is named like the reduction "
                                  f"'{name} over …': the name could never be read",
                                  span, f"choose another name, e.g. '{name}_{kind.split()[0]}'"))
        elif name == NEGATION_WORD and kind in READ_KINDS:  # `limit = not`: a negation begins
            problems.append(error("E103", f"{kind} '{name}' is named like the keyword '{name}': "
                                  "where an expression starts it is read as a negation, so "
                                  "the name could not be read there", span,
                                  f"choose another name, e.g. '{name}_{kind.split()[0]}'"))
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
        value = constant_quantity(env, setting.value, wanted, f"setting '{setting.name}'",
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
        buffer = constant_quantity(env, area.buffer, LENGTH, f"the buffer of area '{area.name}'",
                                    problems)
        if buffer is not None and buffer < 0:
            problems.append(error("E409", "a buffer zone cannot be negative", area.buffer.span))
            continue
        above = None
        if area.above is not None:
            above = constant_quantity(env, area.above, ANGLE,
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
            below = constant_quantity(env, level.below, LENGTH,
                                       f"the size threshold of {level.level}", problems)
        buffer = constant_quantity(env, level.buffer, LENGTH, f"the buffer of {level.level}",
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


def check_combine(env: CheckEnv) -> list[Diagnostic]:
    problems: list[Diagnostic] = []
    combine = env.rulebook.combine
    if combine.confidence is not None:
        value = constant_quantity(env, combine.confidence, DIMENSIONLESS, "confidence",
                                   problems)
        if value is not None:
            if not 0.5 <= value < 1.0:
                problems.append(error("E406", "confidence must lie in [50 %, 100 %)",
                                      combine.confidence.span))
            else:
                env.confidence = value
    if combine.indifference is not None:
        value = constant_quantity(env, combine.indifference, DIMENSIONLESS, "indifference",
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
        value = constant_quantity(env, combine.verdict_indifference, DIMENSIONLESS,
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
