"""The typed rule model: what a rulebook says, as frozen dataclasses.

The parser lowers the lark tree into these nodes at once (the tree never leaves the parsing
modules); the checker, the formatter, the compiler and the interpreter all work on this model.
Every node carries a :class:`~idefix_rules.errors.Span`; spans and comments do not take part in
equality, so ``parse(format(model)) == model`` is the formatter's round-trip property.

Numbers keep the value and unit *as written* (``Number(5.0, "cm")``) so the formatter can print
them back; the checker converts them to SI.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, TypeAlias

from idefix_rules.errors import Span

NO_SPAN = Span("<generated>")


def _span() -> Span:
    return field(default=NO_SPAN, compare=False, repr=False, kw_only=True)


def _comments() -> tuple[str, ...]:
    return field(default=(), compare=False, repr=False, kw_only=True)


# ----------------------------------------------------------------------------- expressions

@dataclass(frozen=True)
class Number:
    """A literal quantity: ``70 %``, ``5 cm``, ``0.6``. ``unit`` is ``None`` for bare numbers."""

    value: float
    unit: str | None = None
    span: Span = _span()


@dataclass(frozen=True)
class Name:
    """A constant, a signal (``wheel.slip``, ``ref.x``, ``collision.hits``), a command quantity
    (``delta_heading``), an index (``I_obs``) or a path statistic (``risk``), by context."""

    name: str
    span: Span = _span()


@dataclass(frozen=True)
class Select:
    """Pick labels on named axes: ``wheel.slip[FL]``, ``collision.hits[wheel, L2]``."""

    operand: Expr
    labels: tuple[str, ...]
    span: Span = _span()


@dataclass(frozen=True)
class Table:
    """A constant indexed by an axis: ``{L1: 0.2, L2: 0.6, L3: 1.0}``."""

    entries: tuple[tuple[str, Expr], ...]
    span: Span = _span()


UnaryOp = Literal["-", "not"]
BinaryOp = Literal["+", "-", "*", "/", "^", "<", "<=", ">", ">=", "==", "!=", "and", "or"]


@dataclass(frozen=True)
class Unary:
    op: UnaryOp
    operand: Expr
    span: Span = _span()


@dataclass(frozen=True)
class Binary:
    op: BinaryOp
    left: Expr
    right: Expr
    span: Span = _span()


@dataclass(frozen=True)
class Call:
    """Element-wise functions: ``abs(x)``, ``min(a, b)``, ``max(a, b)``, ``sqrt(x)``,
    ``clamp(x, lo, hi)``; in verdicts also path statistics ``chance(hit_L2)``, ``mean(I_pos)``."""

    function: str
    args: tuple[Expr, ...]
    span: Span = _span()


WindowKind = Literal["command", "after", "before"]


@dataclass(frozen=True)
class Window:
    """Part of the drive a time reduction looks at.

    ``during command 2`` (1-based, as operators count commands), ``after 10 s``
    (settling time), ``before 60 s``. No window = the whole drive.
    """

    kind: WindowKind
    value: Expr
    span: Span = _span()


Reducer = Literal[
    "final", "initial", "max", "min", "mean", "rms", "sum", "integral",
    "percentile", "time_above", "any", "all", "count", "fraction", "rate",
]
Domain = Literal["time", "wheels", "parts", "levels", "runs"]

# Reducers that take a parameter: ``percentile 95 over time (x)``, ``time_above 30 deg over
# time (abs(pitch))``.
PARAMETRIC_REDUCERS: frozenset[str] = frozenset({"percentile", "time_above"})
# Domain word → axis name of the signal contract. ``runs`` is the run axis itself: a reduction
# over the runs of a path gives one value for the whole path (``idefix_rules.rulebook.across``).
DOMAIN_AXES: dict[str, str] = {"time": "time", "wheels": "wheel", "parts": "part",
                               "levels": "level", "runs": "run"}


@dataclass(frozen=True)
class Reduce:
    """``max over time after 5 s (abs(roll - ref.roll))``, ``any over wheels (x > 1)``,
    ``mean over runs (final over time (x - ref.x))`` (a path-level value, the same in every run)."""

    reducer: Reducer
    domain: Domain
    operand: Expr
    parameter: Expr | None = None
    window: Window | None = None
    span: Span = _span()


@dataclass(frozen=True)
class Invalid:
    """An expression the parser could not lower, its diagnostic already given: a number beyond
    a double (E003), a reduction over an unknown domain (E007, ``written`` holds it, for the
    checks of what it reads), an index item left out (E006). The checker gives it no type and
    says nothing more of it, so the rest of the file is still checked; a rulebook holding one
    never passes the check (:func:`~idefix_rules.rulebook.parser.parse_rulebook` refuses it)."""

    written: Reduce | None = None
    span: Span = _span()


Expr: TypeAlias = Number | Name | Select | Table | Unary | Binary | Call | Reduce | Invalid


# ----------------------------------------------------------------------------- declarations

@dataclass(frozen=True)
class Header:
    """``rulebook "idefix-ops" version "1.0.0"`` and ``purpose "…"``."""

    name: str
    version: str
    purpose: str
    span: Span = _span()
    comments: tuple[str, ...] = _comments()
    # the quoted strings, where their mistakes are reported (the header's span without them)
    name_span: Span = _span()
    version_span: Span = _span()
    purpose_span: Span = _span()


@dataclass(frozen=True)
class Constant:
    """``const critical_slip = 70 % because "…"``."""

    name: str
    value: Expr
    rationale: str | None = None
    span: Span = _span()
    comments: tuple[str, ...] = _comments()


@dataclass(frozen=True)
class Setting:
    """Evaluator settings in ``settings { … }``: ``theoretical_slip``, ``tolerance_growth``."""

    name: str
    value: Expr
    span: Span = _span()
    comments: tuple[str, ...] = _comments()


@dataclass(frozen=True)
class ObstacleLevel:
    """``level L2 below 10 cm buffer 5 cm``: size threshold (None for the top level) and the
    buffer-zone margin around obstacles of that level."""

    level: str
    below: Expr | None
    buffer: Expr
    span: Span = _span()
    comments: tuple[str, ...] = _comments()


AreaKind = Literal["keep_out", "unknown", "steep"]
AREA_KINDS: tuple[str, ...] = ("keep_out", "unknown", "steep")


@dataclass(frozen=True)
class Area:
    """``area crater_rim keep_out level L3 buffer 10 cm``, ``area scarp steep above 20 deg
    level L3 buffer 5 cm``: a named area to avoid, an obstacle of its level; the campaign gives
    its geometry. Runs read ``area.NAME.inside`` and ``area.NAME.buffer``."""

    name: str
    kind: AreaKind
    level: str
    buffer: Expr
    above: Expr | None = None  # the inclination a steep area starts at
    rationale: str | None = None
    span: Span = _span()
    comments: tuple[str, ...] = _comments()


@dataclass(frozen=True)
class ConditionRule:
    """A named condition with its rationale; the kinds below differ in where it is checked
    (equality includes the kind: a command rule never equals a verdict)."""

    name: str
    condition: Expr
    rationale: str | None = None
    span: Span = _span()
    comments: tuple[str, ...] = _comments()


@dataclass(frozen=True)
class CommandRule(ConditionRule):
    """``command max_turn: require abs(delta_heading) <= 90 deg because "…"``."""


@dataclass(frozen=True)
class Index:
    """A risk index, weighted in I_max. Normalised ``clamp(value / limit, 0, 1)``; with a
    ``nominal``, piecewise linear through (0, 0), (nominal, 0.5) and (limit, 1), clamped to
    [0, 1] (:func:`~idefix_rules.rulebook.semantics.normalised`)."""

    name: str
    value: Expr
    limit: Expr
    weight: Expr
    title: str | None = None
    map: Expr | None = None  # per-sample value override for the result map
    rationale: str | None = None
    nominal: Expr | None = None  # the expected value, normalised to 0.5
    span: Span = _span()
    comments: tuple[str, ...] = _comments()


@dataclass(frozen=True)
class Chance(ConditionRule):
    """``chance hit_L2 = any over parts (collision.hits[L2] > 0)``: per run a boolean; the path
    statistic is the fraction of runs where it holds."""


RunCombination = Literal["max_weighted"]
PathCombination = Literal["mean"]


@dataclass(frozen=True)
class Combine:
    """How indices combine: I_max per run (eq. 1), path risk over runs (eq. 2)."""

    run: RunCombination = "max_weighted"
    path: PathCombination = "mean"
    confidence: Expr | None = None  # e.g. 95 %; None = 95 %
    indifference: Expr | None = None  # risk difference two paths tie within; None = 0 (no ties)
    # the margin around a verdict's limit (ratio statistics) when a verdict gives none
    verdict_indifference: Expr | None = None
    span: Span = _span()
    comments: tuple[str, ...] = _comments()


@dataclass(frozen=True)
class Prescreen(ConditionRule):
    """``prescreen no_collision: require I_obs < 1 because "…"`` on the reference run."""


@dataclass(frozen=True)
class VerdictRule(ConditionRule):
    """``verdict acceptable_risk: require risk <= 70 % because "…"`` on path statistics;
    ``indifference 2 %`` after the condition: the margin around its limits (None: the
    combine block's ``verdict_indifference``)."""

    indifference: Expr | None = None


@dataclass(frozen=True)
class RankKey:
    expr: Expr
    descending: bool = False
    span: Span = _span()


@dataclass(frozen=True)
class Ranking:
    """``rank by risk, time, energy``."""

    keys: tuple[RankKey, ...]
    span: Span = _span()
    comments: tuple[str, ...] = _comments()


DEFAULT_RANKING = Ranking((RankKey(Name("risk")), RankKey(Name("time")),
                           RankKey(Name("energy"))))


@dataclass(frozen=True)
class Rulebook:
    header: Header
    constants: tuple[Constant, ...] = ()
    settings: tuple[Setting, ...] = ()
    obstacle_levels: tuple[ObstacleLevel, ...] = ()
    areas: tuple[Area, ...] = ()
    command_rules: tuple[CommandRule, ...] = ()
    indices: tuple[Index, ...] = ()
    chances: tuple[Chance, ...] = ()
    combine: Combine = Combine()
    prescreens: tuple[Prescreen, ...] = ()
    verdicts: tuple[VerdictRule, ...] = ()
    ranking: Ranking = DEFAULT_RANKING
    trailing_comments: tuple[str, ...] = _comments()
    path: str = field(default="<rulebook>", compare=False)
    source: str = field(default="", compare=False, repr=False)
