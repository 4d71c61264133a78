"""What a checked rulebook declares besides its rules: constants, settings, obstacle levels.

``idefix-verify explain`` prints these below its table of rules and in its JSON form. Each value
is given as written (printed by the formatter) and in SI, so a changed obstacle factor or a
threshold written in another unit can be read at a glance.

>>> from idefix_rules.rulebook import check_text
>>> checked = check_text(TEXT).checked  # doctest: +SKIP
>>> [(c.name, c.written, c.si) for c in constants(checked)]  # doctest: +SKIP
[('critical_slip', '70 %', '0.7')]
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from idefix_rules.rulebook.check import CheckedRulebook
from idefix_rules.rulebook.format import format_expr, format_number
from idefix_rules.rulebook.types import SETTINGS
from idefix_rules.units import Dimension


def si_text(value: Any, dimension: Dimension | None) -> str:
    """``0.7``, ``0.05 m/rad``, ``{L1: 0.2, L2: 0.6, L3: 1}``: 6 significant digits."""
    if isinstance(value, dict):
        return "{" + ", ".join(f"{key}: {si_text(entry, dimension)}"
                               for key, entry in value.items()) + "}"
    number = format_number(float(f"{float(value):.6g}"))
    if dimension is None or dimension.is_dimensionless:
        return number
    return f"{number} {dimension}"


def _plain(value: Any) -> float | dict[str, float]:
    if isinstance(value, dict):
        return {key: float(entry) for key, entry in value.items()}
    return float(value)


def _unit(dimension: Dimension | None) -> str:
    return "" if dimension is None or dimension.is_dimensionless else str(dimension)


@dataclass(frozen=True)
class ConstantSummary:
    """``const critical_slip = 70 %``: as written, in SI (text and ``value``), its SI unit
    ("" = a ratio or count), the axis it is indexed by (``level`` for a factor per obstacle
    level) and its rationale."""

    name: str
    written: str
    si: str
    unit: str
    axes: tuple[str, ...]
    rationale: str | None
    value: float | dict[str, float]

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "axes": list(self.axes)}


@dataclass(frozen=True)
class SettingSummary:
    """An evaluator setting; ``written`` is ``None`` when the rulebook leaves the default."""

    name: str
    written: str | None
    si: str
    unit: str
    value: float

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class LevelSummary:
    """An obstacle level: its size limit (``None`` for the top level) and buffer as written and
    in metres, and the factors per level that constants give it (``{"f_obs": 0.2}``)."""

    level: str
    below: str | None
    below_m: float | None
    buffer: str
    buffer_m: float
    factors: dict[str, float]

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class AreaSummary:
    """A named area: kind, the inclination a steep one starts at (as written and in rad),
    obstacle level, buffer (as written and in m), the signals runs read, the rationale."""

    name: str
    kind: str
    above: str | None
    above_rad: float | None
    level: str
    buffer: str
    buffer_m: float
    signals: tuple[str, ...]
    rationale: str | None

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def areas(checked: CheckedRulebook) -> list[AreaSummary]:
    """Every named area, in the rulebook's order."""
    specs = {spec.name: spec for spec in checked.areas}
    found = []
    for area in checked.rulebook.areas:
        spec = specs[area.name]
        found.append(AreaSummary(
            area.name, area.kind, format_expr(area.above) if area.above is not None else None,
            spec.above, area.level, format_expr(area.buffer), spec.buffer, spec.signal_names(),
            area.rationale))
    return found


def constants(checked: CheckedRulebook) -> list[ConstantSummary]:
    """Every constant, in the rulebook's order."""
    found = []
    for constant in checked.rulebook.constants:
        constant_type = checked.constant_types.get(constant.name)
        dimension = constant_type.dimension if constant_type is not None else None
        found.append(ConstantSummary(
            constant.name, format_expr(constant.value),
            si_text(checked.constants[constant.name], dimension), _unit(dimension),
            tuple(constant_type.axes) if constant_type is not None else (),
            constant.rationale, _plain(checked.constants[constant.name])))
    return found


def settings(checked: CheckedRulebook) -> list[SettingSummary]:
    """Every setting the evaluator uses, written or left at its default."""
    written = {setting.name: format_expr(setting.value) for setting in checked.rulebook.settings}
    found = []
    for name, value in sorted(checked.settings.items()):
        dimension = SETTINGS[name][0] if name in SETTINGS else None
        found.append(SettingSummary(name, written.get(name), si_text(value, dimension),
                                    _unit(dimension), float(value)))
    return found


def obstacle_levels(checked: CheckedRulebook) -> list[LevelSummary]:
    """Every declared obstacle level, in the rulebook's order, with the level factors of the
    constants (none without an ``obstacles`` section)."""
    specs = {spec.level: spec for spec in checked.obstacle_levels}
    tables = {name: value for name, value in checked.constants.items()
              if isinstance(value, dict) and name in checked.constant_types
              and checked.constant_types[name].axes == ("level",)}
    found = []
    for level in checked.rulebook.obstacle_levels:
        spec = specs[level.level]
        found.append(LevelSummary(
            level.level, format_expr(level.below) if level.below is not None else None,
            spec.below, format_expr(level.buffer), spec.buffer,
            {name: float(table[level.level]) for name, table in tables.items()
             if level.level in table}))
    return found
