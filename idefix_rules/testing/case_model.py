"""What a case file describes, as frozen data: the case file with its checked rulebook, each
case's set-up and runs (groups of identical runs shaped by keyframes and collisions) and what it
expects of the rulebook, with the format's defaults and limits (the signals a case may shape,
the default step, σ, tolerance and settling time, the most samples and runs)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

from idefix_rules import signals
from idefix_rules.commands import Command, RoverGeometry
from idefix_rules.errors import Span
from idefix_rules.rulebook.check import CheckedRulebook

# Signals a case may shape. ``command`` follows the chain and derived/collision signals are
# computed (collisions have their own entry), so they are not keyframed.
# ('done' is read only where a run has no 'command', and a case's runs always have one: a run
# whose chain does not finish is `unfinished: true`)
SHAPEABLE = (*(name for name in signals.FMU_SIGNALS if name not in ("t", "command", "done")),
             "collision.clearance")
# Flags hold their value until the next keyframe instead of ramping.
STEP_SIGNALS = frozenset({"stuck"})
DEFAULT_STEP = 1.0  # s
DEFAULT_SIGMA = 0.01  # m: initial position σ, the starting tolerance radius
DEFAULT_TOLERANCE = 0.005  # on normalised index values and risk
DEFAULT_SETTLE = 5.0  # s of samples after the chain ends
MAX_SAMPLES = 100_000  # per run: a case is a short example, not a mission
MAX_RUNS = 10_000  # per case


@dataclass(frozen=True)
class Keyframes:
    """One shaped signal: values at times, linear in between (steps for flags), held outside.

    ``label`` picks one wheel (``wheel.slip[FL]``) or part; ``offset`` adds to the nominal run.
    """

    signal: str
    label: str | None
    times: tuple[float, ...]
    values: tuple[float, ...]
    offset: bool
    span: Span


@dataclass(frozen=True)
class Collision:
    """A contact of one body part with an obstacle of one level over ``[start, end]`` (s);
    ``buffer_only``: the part entered the level's buffer zone without hitting the obstacle."""

    part: str
    level: str
    start: float
    end: float
    buffer_only: bool
    span: Span


@dataclass(frozen=True)
class RunGroup:
    """``count`` identical runs shaped by keyframes and collisions."""

    count: int
    keyframes: tuple[Keyframes, ...]
    collisions: tuple[Collision, ...]
    unfinished: bool = False  # the runs never complete their chain (cut off at the stop limit)


ExpectKind = Literal["index", "risk", "dominant", "chance", "prescreen", "rejected", "verdict",
                     "verdict_rule", "path_risk", "decided"]


@dataclass(frozen=True)
class Expectation:
    """One expected outcome: ``kind`` and ``name`` say what, ``expected`` the value
    (a ``(low, high)`` range for numbers, a bool, a name, or ``{rule: (command numbers)}``),
    ``text`` how it reads in messages."""

    kind: ExpectKind
    name: str | None
    expected: Any
    text: str
    span: Span


@dataclass(frozen=True)
class Case:
    name: str
    description: str | None
    chain: tuple[Command, ...]
    step: float
    duration: float | None
    initial_position_sigma: float
    groups: tuple[RunGroup, ...]
    reference: tuple[Keyframes, ...]
    failed_runs: int
    expectations: tuple[Expectation, ...]
    span: Span
    # the rover's wheel-rate ramp (rad/s², controller.wheel_acceleration): what a command's
    # forward_acceleration follows
    wheel_ramp: float = RoverGeometry().wheel_acceleration

    @property
    def rover(self) -> RoverGeometry:
        """The kinematics of the case's runs and command rules."""
        return RoverGeometry(wheel_acceleration=self.wheel_ramp)

    @property
    def runs(self) -> int:
        return sum(group.count for group in self.groups)


@dataclass(frozen=True)
class CaseFile:
    path: str
    rulebook_path: str
    checked: CheckedRulebook
    cases: tuple[Case, ...]
    source: str = field(repr=False, default="")
