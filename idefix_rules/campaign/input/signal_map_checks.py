"""The checks of a campaign's signal map: each mapped FMU output exists, is read, has its unit."""

from __future__ import annotations

from pathlib import Path

from idefix_rules.campaign.input.fmu_variable_checks import (
    Loc,
    article,
    did_you_mean,
    fmu_loc,
    loc_span,
    unit_problem,
)
from idefix_rules.campaign.input.load import Campaign
from idefix_rules.campaign.input.yamlsource import format_loc
from idefix_rules.errors import Diagnostic, UserInputError, error
from idefix_rules.fmu.archive import default_signal_map
from idefix_rules.fmu.description import FmuDescription
from idefix_rules.fmu.mapping import DONE_SIGNAL
from idefix_rules.signals import AXIS_LABELS, FMU_SIGNALS


def signal_problems(campaign: Campaign, description: FmuDescription
                    ) -> tuple[dict[str, str], list[Diagnostic]]:
    """The signal map in effect and what is wrong with it."""
    explicit = campaign.model.fmu.signals
    if explicit is None:
        try:
            mapping = default_signal_map(description, Path(description.path))
        except UserInputError as failure:  # its shipped signal_map.json: said at fmu.path
            return {}, [error("C400", f"{description.path.name}: "
                                      f"{failure.diagnostics[0].message}",
                              loc_span(campaign, fmu_loc(campaign)),
                              hint="give the campaign its own map (fmu.signals: FMU variable: "
                                   "signal)")]
        absent = [name for name in mapping if name not in description.variables]
        problems = [] if not absent else [error(
            "C401", f"the signal map shipped in {description.path.name} names "
                    f"{len(absent)} variable(s) it does not have: "
                    f"{', '.join(map(repr, absent[:6]))}{' …' if len(absent) > 6 else ''}",
            loc_span(campaign, fmu_loc(campaign)),
            hint="give the campaign its own map (fmu.signals: FMU variable: signal)")]
        return mapping, problems + [
            problem for fmu_name, target in mapping.items() if fmu_name not in absent
            for problem in _signal_entry(campaign, description, fmu_name, target,
                                         fmu_loc(campaign))]
    problems = []
    seen: dict[str, str] = {}
    for fmu_name, target in explicit.items():
        loc: Loc = ("fmu", "signals", fmu_name)
        entry = _signal_entry(campaign, description, fmu_name, target, loc)
        problems += entry
        if entry:
            continue
        if target in seen:
            problems.append(error(
                "C511", f"{format_loc(loc)}: signal '{target}' is mapped from both "
                        f"'{seen[target]}' and '{fmu_name}'", loc_span(campaign, loc),
                hint="map each signal from one FMU variable"))
        seen[target] = fmu_name
    problems += _partial_wheels(campaign, seen) + _unreachable_done(campaign, description, seen)
    return dict(explicit), problems


def _unreachable_done(campaign: Campaign, description: FmuDescription, seen: dict[str, str]
                      ) -> list[Diagnostic]:
    """``done`` from a Boolean output reads 0 or 1: a ``done_at`` above 1 is never reached
    (every run would drive to the stop limit), one at 0 or below at the first sample."""
    variable = description.variables.get(seen.get(DONE_SIGNAL, ""))
    done_at = campaign.model.fmu.done_at
    if variable is None or variable.reader != "boolean" or 0.0 < done_at <= 1.0:
        return []
    loc: Loc = ("fmu", "done_at")
    reached = "never reaches" if done_at > 1 else "is from the first sample at least"
    return [error("C502", f"{format_loc(loc)}: {variable.name!r} is a {variable.type}, read as "
                          f"0 or 1: 'done' {reached} {done_at:g}",
                  loc_span(campaign, loc, at_key=False),
                  hint="leave done_at out (1: true) for a Boolean output")]


def _partial_wheels(campaign: Campaign, seen: dict[str, str]) -> list[Diagnostic]:
    """A wheel signal is four columns: mapped for some wheels only, the others would be empty
    (not a number) and every run would fail on them."""
    problems = []
    wheels = AXIS_LABELS["wheel"]
    for base in dict.fromkeys(target.partition("[")[0] for target in seen):
        mapped = [w for w in wheels if f"{base}[{w}]" in seen]
        if mapped and len(mapped) < len(wheels):
            loc: Loc = ("fmu", "signals", seen[f"{base}[{mapped[0]}]"])
            missing = [w for w in wheels if w not in mapped]
            problems.append(error(
                "C500", f"{format_loc(loc)}: signal '{base}' is mapped for "
                        f"{', '.join(mapped)} only: a wheel signal has all four wheels",
                loc_span(campaign, loc, at_key=False),
                hint=f"map {', '.join(f'{base}[{w}]' for w in missing)} too, or none of them"))
    return problems


def _signal_entry(campaign: Campaign, description: FmuDescription, fmu_name: str,
                  target: str, loc: Loc) -> list[Diagnostic]:
    """One ``FMU variable: signal`` entry: exists, names a signal, output, readable, unit."""
    where = format_loc(loc)
    fmu_file = description.path.name
    variable = description.variables.get(fmu_name)
    whole = description.variables.get(fmu_name.partition("[")[0])
    if variable is None and whole is not None and whole.array:
        return [error("C502", f"{where}: {fmu_name!r} is an element of {whole.name!r}, a "
                              f"{whole.type}: elements of FMI 3 arrays are not read",
                      loc_span(campaign, loc), hint="map a scalar output of the FMU")]
    if variable is None:
        outputs = [v.name for v in description.variables.values() if v.causality == "output"]
        return [error("C401", f"{where}: unknown FMU variable {fmu_name!r} in {fmu_file}",
                      loc_span(campaign, loc),
                      did_you_mean(fmu_name, outputs or description.variables))]
    base, _, rest = target.partition("[")
    spec = FMU_SIGNALS.get(base)
    value_span = loc_span(campaign, loc, at_key=False)
    if spec is None:
        return [error("C500", f"{where}: {target!r} is not a signal an FMU provides",
                      value_span, did_you_mean(base, FMU_SIGNALS)
                      or f"one of {', '.join(FMU_SIGNALS)}")]
    wheels = AXIS_LABELS["wheel"]
    if "wheel" in spec.axes and rest.rstrip("]") not in wheels:
        return [error("C500", f"{where}: {target!r} needs one wheel, e.g. '{base}[FL]'",
                      value_span, hint=f"wheels are {', '.join(wheels)}")]
    if "wheel" not in spec.axes and rest:
        return [error("C500", f"{where}: {target!r}: signal '{base}' has no wheel axis",
                      value_span)]
    problems = []
    if variable.causality != "output":
        problems.append(error(
            "C501", f"{where}: {fmu_name!r} is {article(variable.causality)}; a signal must "
                    "be an output of the FMU", loc_span(campaign, loc),
            hint="`fmpy info` lists the FMU's outputs"))
    if variable.reader not in ("real", "integer", "boolean"):
        problems.append(error(
            "C502", f"{where}: {fmu_name!r} is a {variable.type}; a signal is read from a "
                    "Real/Float, Integer, Boolean or Enumeration output", loc_span(campaign, loc)))
    problems += unit_problem(campaign, loc, variable, base, spec.unit)
    return problems
