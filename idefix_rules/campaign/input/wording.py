"""Values as a person reads them: in the units the campaign or rulebook was written in.

Everything inside the tool and in its files is SI (rad, m, Pa, A·s). Messages, tables and the
report show a value in the unit its author used: a command's ``delta_heading`` in the unit the
campaign wrote it in (``120 deg``, not ``2.0944``), a sampled parameter in the unit of its
distribution (``soil.cohesion`` in Pa, ``soil.friction_angle`` in deg), ratios of verdicts in %.
:class:`DisplayUnits` collects those units from a campaign's text; a name it does not know falls
back to the unit people use for its dimension (deg for angles, deg/s for rates, mm/s for speeds).

>>> units = DisplayUnits.from_campaign_text(
...     "paths:\\n  p:\\n    - {delta_heading: '120 deg', delta_position: '0 m'}\\n")
>>> units.show("delta_heading", 2.0943951023931953)
'120 deg'
>>> units.show("speed", 0.0123)
'12.3 mm/s'
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import yaml

from idefix_rules.campaign.input.yamlsource import yaml_data
from idefix_rules.units import UnitError, convert, parse_unit, percent_text

# Units people read when a name's own unit is not known (rules' derived command quantities).
DEFAULT_UNITS: dict[str, str] = {
    "max_wheel_rate": "rad/s",
    "delta_position": "m",
    "delta_heading": "deg",
    "turn_radius": "m",
    "duration": "s",
    "speed": "mm/s",
    "yaw_rate": "deg/s",
    "wheel_speed": "mm/s",
    "lateral_acceleration": "mm/s^2",
    "forward_acceleration": "mm/s^2",
    "command_number": "1",
    "initial.x": "cm",
    "initial.y": "cm",
    "initial.z": "cm",
    "initial.yaw": "deg",
}
# SI unit of the names above (what the stored number is in).
SI_UNITS: dict[str, str] = {
    "max_wheel_rate": "rad/s", "delta_position": "m", "delta_heading": "rad",
    "turn_radius": "m", "duration": "s", "speed": "m/s", "yaw_rate": "rad/s",
    "wheel_speed": "m/s", "lateral_acceleration": "m/s^2", "forward_acceleration": "m/s^2",
    "command_number": "1",
    "initial.x": "m", "initial.y": "m", "initial.z": "m", "initial.yaw": "rad",
}
_WRITTEN = re.compile(r"^\s*[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\s*(\S.*?)\s*$")


def number(value: float, digits: int = 3) -> str:
    """A number with ``digits`` significant digits, never in exponent form below 10^6.

    >>> number(2.0943951023931953 * 180 / math.pi), number(0.000123), number(747.04)
    ('120', '0.000123', '747')
    """
    if not math.isfinite(value):
        return "–"
    if value == 0:
        return "0"
    magnitude = math.floor(math.log10(abs(value)))
    decimals = max(0, digits - 1 - magnitude)
    if abs(value) >= 1e6 or decimals > 9:
        return f"{value:.{digits}g}"
    text = f"{value:.{decimals}f}"
    return text.rstrip("0").rstrip(".") if "." in text else text


def percent(value: float | None, decimals: int = 1) -> str:
    """A ratio as ``12.3 %``; ``–`` when unknown."""
    if value is None or not math.isfinite(value):
        return "–"
    return f"{100.0 * value:.{decimals}f} %"


def _written_unit(text: Any) -> str | None:
    if not isinstance(text, str):
        return None
    match = _WRITTEN.match(text)
    if match is None:
        return None
    try:
        parse_unit(match.group(1))
    except UnitError:
        return None
    return match.group(1)


def written_unit_at(text: str, place: tuple[str | int, ...]) -> str | None:
    """The unit of the value a campaign's text writes at ``place`` (``("environment",
    "regolith", "k_c")``), or None (no unit written, no such place, or text that is no YAML).

    >>> written_unit_at("environment: {regolith: {k_c: 1400 N/m^2}}",
    ...                 ("environment", "regolith", "k_c"))
    'N/m^2'
    """
    try:
        node: Any = yaml_data(text)
    except (yaml.YAMLError, ValueError, TypeError, ArithmeticError, LookupError,
            AttributeError):
        return None
    for key in place:
        if not isinstance(node, Mapping) or key not in node:
            return None
        node = node[key]
    return _written_unit(node)


@dataclass
class DisplayUnits:
    """Unit to show per quantity name (``delta_heading``, ``soil.cohesion`` …)."""

    units: dict[str, str] = field(default_factory=dict)

    @classmethod
    def from_campaign_text(cls, text: str) -> DisplayUnits:
        """The units a campaign's author wrote: command fields and uncertain parameters."""
        try:
            data = yaml_data(text) or {}
        except (yaml.YAMLError, ValueError, TypeError, ArithmeticError, LookupError,
                AttributeError):
            return cls()  # (load_yaml said what is wrong where it read the campaign)
        found: dict[str, str] = {}
        if not isinstance(data, Mapping):
            return cls()
        for chain in (data.get("paths") or {}).values() if isinstance(
                data.get("paths"), Mapping) else ():
            for command in chain if isinstance(chain, list) else ():
                if isinstance(command, Mapping):
                    for key, value in command.items():
                        unit = _written_unit(value)
                        if unit is not None and float(_number_of(value)) != 0.0:
                            found.setdefault(str(key), unit)
                        elif unit is not None:
                            found.setdefault(f"{key}#zero", unit)
        parameters = (data.get("uncertainty") or {}).get("parameters") \
            if isinstance(data.get("uncertainty"), Mapping) else None
        for name, spec in (parameters or {}).items() if isinstance(parameters, Mapping) else ():
            if isinstance(spec, Mapping):
                # The unit of the first non-zero value: "mean: 0 m, std: 1 cm" reads in cm.
                written = [(_number_of(str(spec.get(key))), unit) for key in
                           ("mean", "median", "low", "high", "std", "value")
                           if (unit := _written_unit(spec.get(key))) is not None]
                chosen = [unit for value, unit in written if value != 0.0] or \
                    [unit for _, unit in written]
                if chosen:
                    found.setdefault(str(name), chosen[0])
        for key in [k for k in found if k.endswith("#zero")]:
            found.setdefault(key[:-5], found.pop(key))
        return cls(found)

    def unit_of(self, name: str) -> str:
        return self.units.get(name) or DEFAULT_UNITS.get(name, "")

    def show(self, name: str, si_value: float, si_unit: str | None = None) -> str:
        """``value unit`` of a quantity given in SI, in the unit its author used."""
        unit = self.unit_of(name)
        source = si_unit or SI_UNITS.get(name)
        if unit and source and unit not in ("1",):
            try:
                value = convert(si_value, source, unit)
            except UnitError:
                return number(si_value) + (f" {source}" if source != "1" else "")
            return f"{number(value)} {unit}"
        return number(si_value) + (f" {source}" if source and source != "1" else "")


def _number_of(text: str) -> float:
    match = re.match(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)", text)
    return float(match.group(1)) if match else math.nan


def parameter_text(name: str, si_value: float, stored_unit: str, units: DisplayUnits) -> str:
    """A sampled parameter in the campaign's unit (stored values are SI, ``stored_unit``)."""
    unit = units.unit_of(name)
    if unit and stored_unit:
        try:
            return f"{number(convert(si_value, _si_spelling(stored_unit), unit))} {unit}"
        except UnitError:
            pass
    return number(si_value) + (f" {stored_unit}" if stored_unit and stored_unit != "1" else "")


_FMU_REFUSED = re.compile(r"^parameter (?P<name>\S+) = (?P<value>\S+) out of range: "
                          r"(?P<why>.*)$", re.DOTALL)
_FMU_RANGE = re.compile(r"^allowed (?P<open>[\[(])(?P<low>\S+), (?P<high>\S+)(?P<close>[\])])$")


def range_text(message: str, unit: str) -> str:
    """An FMU's "parameter N = V out of range: allowed [lo, hi]" (SI) in ``unit``, the unit
    the campaign wrote the parameter in (the value alone when the FMU says another reason);
    the message as it is when it has another shape or the unit is not one of the value's
    dimension.

    >>> range_text("parameter soil.friction_angle = 1.5271630954950384 out of range: "
    ...            "allowed [0, 1.39626]", "deg")
    'parameter soil.friction_angle = 87.5 deg out of range: allowed [0, 80 deg]'
    >>> range_text("parameter soil.cohesion = -1424.4447954825537 out of range: "
    ...            "allowed [0, 1e+06]", "kPa")
    'parameter soil.cohesion = -1.42444 kPa out of range: allowed [0, 1000 kPa]'
    """
    match = _FMU_REFUSED.match(message)
    if match is None or not unit or unit == "1":
        return message
    allowed = _FMU_RANGE.match(match["why"])
    try:
        from_si = parse_unit(unit).from_si
        # the FMU prints the value with 17 significant digits (%.17g), its limits with 6 (%g):
        # 6 of the value are plenty to compare, 5 of the limits survive a change of unit
        value = number(from_si(float(match["value"])), 6)
        why = match["why"] if allowed is None else (
            f"allowed {allowed['open']}{number(from_si(float(allowed['low'])), 5)}, "
            f"{number(from_si(float(allowed['high'])), 5)} {unit}{allowed['close']}")
    except (UnitError, ValueError, ArithmeticError):
        return message
    return f"parameter {match['name']} = {value} {unit} out of range: {why}"


def _si_spelling(unit: str) -> str:
    """Stored units are written like ``kg/(m·s^2)``; the unit parser reads ``kg/m/s^2``."""
    if "(" in unit:
        head, _, inner = unit.partition("/(")
        return head + "/" + inner.rstrip(")").replace("·", "/")
    return unit


def violation_text(violation: Any, units: DisplayUnits) -> str:
    """A command-rule violation with the command's quantities in the campaign's units."""
    values: Mapping[str, float] = getattr(violation, "values", {}) or {}
    shown = ", ".join(f"{name} = {units.show(name, float(value))}"
                      for name, value in values.items() if name != "command_number")
    text = (f"command {violation.command_number} breaks rule '{violation.rule}'"
            + (f" ({shown})" if shown else ""))
    rationale = getattr(violation, "rationale", None)
    return text + (f": {rationale}" if rationale else "")


# How a rejection names its command rule (violation_text) and an exclusion its prescreen rule
# (the compiled rulebook's finding): rule names are identifiers, never quoted inside.
_GATE_RULE = re.compile(r"(?:breaks rule|fails prescreen) '([^']+)'")


def gate_rules(reason: str) -> list[str]:
    """The command or prescreen rules a rejected or excluded path's reason names, in order,
    each once.

    >>> gate_rules("command 1 breaks rule 'wheel_rate' (max_wheel_rate = 0.5 rad/s): "
    ...            "Fastest; command 2 breaks rule 'turn_angle'; command 3 breaks rule "
    ...            "'wheel_rate'")
    ['wheel_rate', 'turn_angle']
    >>> gate_rules("the reference run fails prescreen 'not_critical' (risk = 1)")
    ['not_critical']
    """
    return list(dict.fromkeys(_GATE_RULE.findall(reason)))


def _statistic_value(statistic: str, value: float) -> str:
    if statistic in ("time",):
        return f"{number(value)} s"
    if statistic in ("energy",):
        return f"{number(value * 1000.0)} mAs"
    return f"{number(100.0 * value)} %"


def _is_shown(statistic: str | None) -> bool:
    return statistic is not None and (statistic in ("risk", "failed", "time", "energy")
                                      or statistic.startswith("chance("))


def confidence_text(confidence: float) -> str:
    """A confidence in percent: ``95 %``, ``98.8 %``, ``99.95 %`` (never rounded up to
    100 %)."""
    return percent_text(confidence)


def bounds_label(confidence: float) -> str:
    """How the console, JUnit and the report name a verdict's bounds: the rulebook's
    ``confidence`` is family-wise (every bound of every path and comparison holds at once),
    so each bound alone sits at a higher level (docs/campaign-format.md, "How α is spent").

    >>> bounds_label(0.95), bounds_label(0.9)
    ('95 % family-wise bounds', '90 % family-wise bounds')
    """
    return f"{confidence_text(confidence)} family-wise bounds"


def rule_text(rule: Mapping[str, Any], confidence: float = 0.95) -> str:
    """One verdict rule's result in words and percent, from its stored (plain) form.

    >>> rule_text({"name": "acceptable_risk", "passed": False, "decided": True,
    ...            "statistic": "risk", "value": 0.9439, "interval": [0.921, 0.9667],
    ...            "threshold": 0.7, "message": "…"})
    'acceptable_risk: risk 94.4 % (95 % family-wise bounds 92.1–96.7 %) is above the limit 70 %'
    """
    name = str(rule.get("name", ""))
    statistic = rule.get("statistic")
    value, threshold = rule.get("value"), rule.get("threshold")
    if not _is_shown(statistic) or value is None or threshold is None:
        return f"{name}: {rule.get('message', '')}"
    stat = str(statistic)
    interval = rule.get("interval")
    ci = ""
    if interval and None not in interval[:2]:
        low = _statistic_value(stat, float(interval[0])).rsplit(" ", 1)[0]
        ci = (f" ({bounds_label(confidence)} {low}–"
              f"{_statistic_value(stat, float(interval[1]))})")
    limit = _statistic_value(stat, float(threshold))
    passed, decided = bool(rule.get("passed", True)), bool(rule.get("decided", True))
    side = "above" if float(value) > float(threshold) else "below"
    if rule.get("near"):
        margin = _statistic_value(stat, float(rule.get("margin") or 0.0))
        verdict = (f"is within ± {margin} of the limit {limit}: neither shown to pass nor to "
                   "fail (the rulebook's margin)")
    elif not decided:
        verdict = f"not decided: the limit {limit} lies inside the interval"
    elif passed:
        verdict = f"within the limit {limit}"
    else:
        verdict = f"is {side} the limit {limit}"
    return f"{name}: {stat} {_statistic_value(stat, float(value))}{ci} {verdict}"


def runs_needed_text(runs: int | None) -> str:
    """``about 480 runs would decide it`` (or why there is no estimate)."""
    if runs is None:
        return "no run count up to 1,000,000 is estimated to decide it"
    return f"about {runs:,} runs would decide it"


def unfinished_text(path: str, unfinished: int, runs: int, stop_time: float) -> str:
    """The line saying how many runs of a path were stopped before their chain was done.

    >>> unfinished_text("smooth-detour", 12, 128, 1024.6)
    "smooth-detour: 12 of 128 runs were still driving at the stop limit (1025 s): their time is \
the limit, not the chain's duration"
    """
    counted = f"{unfinished} of {runs} {'run' if runs == 1 else 'runs'}"
    were, their = ("was", "its") if unfinished == 1 else ("were", "their")
    return (f"{path}: {counted} {were} still driving at the stop limit "
            f"({number(stop_time, 4)} s): {their} time is the limit, not the chain's duration")


def verdict_reasons(verdict: Mapping[str, Any] | None, confidence: float = 0.95,
                    runs_needed: Mapping[str, int | None] | None = None) -> list[str]:
    """The rules that explain a verdict: those failing decidedly, else failing or undecided
    (an undecided rule with roughly how many runs would decide it, from ``runs_needed``)."""
    return [text for _, text in verdict_reason_items(verdict, confidence, runs_needed)]


def verdict_reason_items(verdict: Mapping[str, Any] | None, confidence: float = 0.95,
                         runs_needed: Mapping[str, int | None] | None = None
                         ) -> list[tuple[bool, str]]:
    """:func:`verdict_reasons` with each rule's ``decided`` flag: ``(False, text)`` for a rule
    whose limit lies inside its interval (neither failed nor passed yet)."""
    rules = [r for r in (verdict or {}).get("rules", []) if isinstance(r, Mapping)]
    failed_for_sure = [r for r in rules if not r.get("passed", True) and r.get("decided", True)]
    shown = failed_for_sure or [r for r in rules
                                if not r.get("passed", True) or not r.get("decided", True)]
    needed = runs_needed or {}
    return [(bool(r.get("decided", True)),
             rule_text(r, confidence) + (f"; {runs_needed_text(needed[str(r.get('name'))])}"
                                         if str(r.get("name")) in needed else ""))
            for r in shown]


def joined(items: Iterable[str]) -> str:
    return "; ".join(items)
