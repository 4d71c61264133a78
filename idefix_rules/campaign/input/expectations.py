"""The campaign file's ``expect`` entries: what a campaign expects of its paths' outcome."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, BaseModel, BeforeValidator, Discriminator, Tag, ValidationInfo
from pydantic_core import PydanticCustomError

from idefix_rules.campaign.input.field_types import Ratio, Strict, new_run
from idefix_rules.signals import AXIS_LABELS


class PathVerdictExpectation(Strict):
    path: str
    verdict: Literal["pass", "fail", "marginal"]


class RankFirstExpectation(Strict):
    rank_first: str


def _fraction(value: float, info: ValidationInfo) -> float:
    """A risk or a chance: from 0 to 100 % (a bare number is the fraction itself: 0.3 is
    30 %, 30 is 3000 %, which no path could exceed)."""
    if new_run(info) and not 0.0 <= value <= 1.0:
        raise PydanticCustomError(
            "fraction", "expected a risk or chance from 0 to 100 %, got {got} (a bare number "
            "is a fraction: write \"30 %\" or 0.3)", {"got": f"{value * 100:g} %"})
    return value


Fraction = Annotated[Ratio, AfterValidator(_fraction)]


class MeanRiskExpectation(Strict):
    path: str
    max_mean_risk: Fraction


def _some_level(levels: dict[str, float], info: ValidationInfo) -> dict[str, float]:
    """At least one level: an empty mapping would hold with nothing checked (a campaign
    stored before this check is read back as it ran)."""
    if not levels and new_run(info):
        raise PydanticCustomError(
            "levels", "give at least one level with its largest chance, e.g. {L2: \"10 %\"} "
                      "(levels: L1, L2, L3, any)")
    return levels


class CollisionExpectation(Strict):
    path: str
    max_collision_chance: Annotated[dict[Literal["L1", "L2", "L3", "any"], Fraction],
                                    AfterValidator(_some_level)]


# Chances of a hit of any level, by their names (without one, the levels' chances bound it).
ANY_HIT_CHANCES = ("any", "collision", "hit", "collision.any", "hit_any")


def chance_level(name: str) -> str | None:
    """The obstacle level a rulebook chance counts, by the end of its name: ``hit_L2``,
    ``collision.L2``, ``collision_l2`` all count as L2 (the L2 column, the L2 expectation).

    >>> chance_level("hit_L2"), chance_level("collision_l3"), chance_level("hit_any")
    ('L2', 'L3', None)
    """
    found = None
    for level in AXIS_LABELS["level"]:
        if name.endswith(level) or name.endswith(level.lower()):
            found = level
    return found


def judged_levels(chance_names: Iterable[str]) -> set[str]:
    """The levels of ``max_collision_chance`` a rulebook with these chances can judge: each
    level it has a chance for, and ``any`` with a chance of any hit or of some level.

    >>> sorted(judged_levels(["hit_L3", "tilted"])), judged_levels(["tilted"])
    (['L3', 'any'], set())
    """
    names = list(chance_names)
    levels = {level for level in map(chance_level, names) if level is not None}
    if levels or any(name in ANY_HIT_CHANCES for name in names):
        levels.add("any")
    return levels


# An expectation's kind is the key that names it (and tags it in pydantic's union).
EXPECTATION_KINDS: dict[str, type[Strict]] = {
    "verdict": PathVerdictExpectation,
    "rank_first": RankFirstExpectation,
    "max_mean_risk": MeanRiskExpectation,
    "max_collision_chance": CollisionExpectation,
}
_EXPECTATION_KEYS = tuple(EXPECTATION_KINDS)


def _expectation_kind(value: Any) -> str | None:
    if isinstance(value, BaseModel):
        for key in _EXPECTATION_KEYS:
            if hasattr(value, key):
                return key
        return None
    if isinstance(value, dict):
        for key in _EXPECTATION_KEYS:
            if key in value:
                return key
    return None


Expectation = Annotated[
    Annotated[PathVerdictExpectation, Tag("verdict")]
    | Annotated[RankFirstExpectation, Tag("rank_first")]
    | Annotated[MeanRiskExpectation, Tag("max_mean_risk")]
    | Annotated[CollisionExpectation, Tag("max_collision_chance")],
    Discriminator(_expectation_kind, custom_error_type="expectation",
                  custom_error_message="an expectation needs one of: verdict, rank_first, "
                                       "max_mean_risk, max_collision_chance"),
]


def _one_kind(value: Any) -> Any:
    """An expectation of two kinds at once is two expectations: said as such, not as an
    unknown key of whichever kind was read first."""
    if isinstance(value, dict):
        kinds = [key for key in _EXPECTATION_KEYS if key in value]
        if len(kinds) > 1:
            raise ValueError(f"an expectation has one kind; this one gives {' and '.join(kinds)}: "
                             "write each as its own entry of expect")
    return value


ExpectationEntry = Annotated[Expectation, BeforeValidator(_one_kind)]
