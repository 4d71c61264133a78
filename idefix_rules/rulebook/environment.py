"""What the checker's passes share: the rulebook, its resolved constants and the values the
passes collect, and the scope of names each kind of rule may read (:mod:`.check` runs the
passes; :mod:`.lints` and :mod:`.cascade` read this state without importing the checker)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from idefix_rules import signals
from idefix_rules.errors import Diagnostic
from idefix_rules.rulebook.fold import Value
from idefix_rules.rulebook.model import Rulebook
from idefix_rules.rulebook.types import (
    AREA_SIGNAL_TYPE,
    COMMAND_NAMES,
    PATH_NAMES,
    RATIO,
    ExprType,
    Scope,
)
from idefix_rules.units import DIMENSIONLESS

LEVELS = signals.AXIS_LABELS["level"]


@dataclass(frozen=True)
class ObstacleLevelSpec:
    """A level's size threshold (exclusive upper bound, m; None = no upper bound) and buffer."""

    level: str
    below: float | None
    buffer: float


@dataclass(frozen=True)
class AreaSpec:
    """A named area: its kind, obstacle level, buffer (m) and, when steep, the inclination
    (rad) it starts at. Runs read ``area.NAME.inside`` and ``area.NAME.buffer``."""

    name: str
    kind: str
    level: str
    buffer: float
    above: float | None = None

    def signal_names(self) -> tuple[str, str]:
        return (f"{signals.AREA_PREFIX}{self.name}.inside",
                f"{signals.AREA_PREFIX}{self.name}.buffer")


@dataclass
class CheckEnv:
    """What the passes share: resolved constants and collected values."""

    rulebook: Rulebook
    constant_types: dict[str, ExprType] = field(default_factory=dict)
    constants: dict[str, Value] = field(default_factory=dict)
    limits: dict[str, float] = field(default_factory=dict)
    nominals: dict[str, float] = field(default_factory=dict)
    weights: dict[str, float] = field(default_factory=dict)
    index_types: dict[str, ExprType] = field(default_factory=dict)
    settings: dict[str, float] = field(default_factory=dict)
    levels: list[ObstacleLevelSpec] = field(default_factory=list)
    areas: list[AreaSpec] = field(default_factory=list)
    confidence: float = 0.95
    indifference: float = 0.0
    verdict_indifference: float = 0.0
    verdict_margins: dict[str, float] = field(default_factory=dict)

    def scope(self, kind: str) -> Scope:
        return scope_of(kind, self.rulebook, self.constant_types)


Check = Callable[[CheckEnv], list[Diagnostic]]


def scope_of(kind: str, rulebook: Rulebook, constant_types: dict[str, ExprType]) -> Scope:
    indices = frozenset(i.name for i in rulebook.indices)
    chances = frozenset(c.name for c in rulebook.chances)
    extra: dict[str, ExprType] = {}
    if kind == "command":
        extra = dict(COMMAND_NAMES)
    elif kind == "prescreen":
        extra = {name: RATIO for name in indices}
        extra.update({name: ExprType(DIMENSIONLESS, (), True) for name in chances})
        extra["risk"] = RATIO
    elif kind == "path":
        extra = dict(PATH_NAMES)
    elif kind == "run":
        extra = {f"{signals.AREA_PREFIX}{area.name}.{part}": AREA_SIGNAL_TYPE
                 for area in rulebook.areas for part in signals.AREA_SIGNAL_PARTS}
    return Scope(kind, dict(constant_types), extra, chances, indices)  # type: ignore[arg-type]
