"""Static types of rulebook expressions: dimension, named axes, boolean-ness, and scopes.

Every expression has an :class:`ExprType`. Axes are named (``time``, ``wheel``, ``part``,
``level``) and broadcast by name, so ``collision.hits * f_obs`` multiplies a (part, level)
signal by a (level,) table. Each context of the language (constants, command rules, run
indices, the reference-run prescreen, path statistics) has a :class:`Scope` with its names.

>>> from idefix_rules.units import LENGTH
>>> ExprType(LENGTH, ("wheel", "time")).axes
('time', 'wheel')
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from idefix_rules import signals
from idefix_rules.units import (
    ANGLE,
    ANGULAR_RATE,
    CHARGE,
    DIMENSIONLESS,
    LENGTH,
    TIME,
    VELOCITY,
    Dimension,
)

AXIS_ORDER: tuple[str, ...] = ("time", "wheel", "part", "level")


def canonical_axes(axes: tuple[str, ...] | set[str] | frozenset[str]) -> tuple[str, ...]:
    """Axes in the canonical order (time first, then wheel, part, level)."""
    present = set(axes)
    return tuple(axis for axis in AXIS_ORDER if axis in present)


@dataclass(frozen=True)
class ExprType:
    """What an expression evaluates to, per run."""

    dimension: Dimension = DIMENSIONLESS
    axes: tuple[str, ...] = ()
    boolean: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "axes", canonical_axes(self.axes))

    def without(self, axis: str) -> ExprType:
        return ExprType(self.dimension, tuple(a for a in self.axes if a != axis), self.boolean)


BOOLEAN = ExprType(DIMENSIONLESS, (), True)
RATIO = ExprType(DIMENSIONLESS)

ScopeKind = Literal["constant", "parameter", "command", "run", "prescreen", "path"]

SCOPE_DESCRIPTIONS: dict[str, str] = {
    "constant": "a constant expression (constants and numbers only)",
    "parameter": "a reducer's parameter or window (constants and numbers only)",
    "command": "a command rule",
    "run": "an index or chance",
    "prescreen": "a prescreen rule",
    "path": "a verdict or rank key",
}

# Quantities of one command, from idefix_rules.commands.command_kinematics.
COMMAND_NAMES: dict[str, ExprType] = {
    "max_wheel_rate": ExprType(ANGULAR_RATE),
    "delta_position": ExprType(LENGTH),
    "delta_heading": ExprType(ANGLE),
    "turn_radius": ExprType(LENGTH),
    "duration": ExprType(TIME),
    "speed": ExprType(VELOCITY),
    "yaw_rate": ExprType(ANGULAR_RATE),
    "wheel_speed": ExprType(VELOCITY),
    # centripetal acceleration of the body centre on the arc, |speed · yaw_rate|
    "lateral_acceleration": ExprType(VELOCITY / TIME),
    # body-centre acceleration while the wheel rates ramp (commands.forward_acceleration)
    "forward_acceleration": ExprType(VELOCITY / TIME),
    "command_number": ExprType(DIMENSIONLESS),
}

# Path statistics usable in verdicts and rank keys (besides chance(NAME) and mean(INDEX)).
PATH_NAMES: dict[str, ExprType] = {
    "risk": RATIO,
    "time": ExprType(TIME),
    "energy": ExprType(CHARGE),
    "failed": RATIO,
    "runs": RATIO,
}

# The verdict's own rule, added where no verdict rule reads `failed` (statistics.verdict): a
# built-in name, which no declaration may take.
FAILED_RUNS_RULE = "no_failed_runs"

# Functions of the path scope: argument kind → result.
PATH_FUNCTIONS: dict[str, str] = {"chance": "chance", "mean": "index", "max": "index"}

ELEMENTWISE_FUNCTIONS: frozenset[str] = frozenset({"abs", "min", "max", "sqrt", "clamp",
                                                 "hypot"})
# Each function's argument count, fewest and most (E106 outside them).
FUNCTION_ARITY: dict[str, tuple[int, int]] = {"abs": (1, 1), "sqrt": (1, 1), "clamp": (3, 3),
                                              "hypot": (2, 2), "min": (2, 99), "max": (2, 99)}

SETTINGS: dict[str, tuple[Dimension, float]] = {
    # name: (dimension, default in SI)
    "theoretical_slip": (DIMENSIONLESS, 0.0),
    "tolerance_growth": (LENGTH / ANGLE, 0.0),
}


# ``area.NAME.inside`` / ``area.NAME.buffer`` of a declared area: 0/1 per sample.
AREA_SIGNAL_TYPE = ExprType(DIMENSIONLESS, ("time",))


def signal_type(name: str) -> ExprType | None:
    """Type of a contract signal (``ref.*`` included), or ``None`` when unknown (an area's
    signals are typed by the rulebook that declares the area, see ``check._scope``)."""
    spec = signals.lookup(name)
    if spec is None or signals.area_signal(name) is not None:
        return None
    return ExprType(spec.dimension, spec.axes)



@dataclass
class Scope:
    """Names visible in one context of the language."""

    kind: ScopeKind
    constants: dict[str, ExprType] = field(default_factory=dict)
    extra: dict[str, ExprType] = field(default_factory=dict)
    chances: frozenset[str] = frozenset()
    indices: frozenset[str] = frozenset()

    def lookup(self, name: str) -> ExprType | None:
        if name in self.extra:
            return self.extra[name]
        if name in self.constants:
            return self.constants[name]
        if self.kind == "run":
            return signal_type(name)
        return None

    def candidates(self) -> list[str]:
        """Every name visible here, for "did you mean" hints."""
        names = [*self.extra, *self.constants]
        if self.kind == "run":
            names += list(signals.SIGNALS)
            names += [signals.REF_PREFIX + n for n in signals.FMU_SIGNALS]
        return names


def axis_of_label(label: str) -> str | None:
    """Axis a label belongs to: ``FL`` → ``wheel``, ``L2`` → ``level``."""
    for axis, labels in signals.AXIS_LABELS.items():
        if label in labels:
            return axis
    return None
