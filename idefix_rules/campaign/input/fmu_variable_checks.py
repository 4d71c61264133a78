"""What every check of an FMU mapping shares: where the campaign says it, names, articles, units."""

from __future__ import annotations

import difflib
from collections.abc import Iterable

from idefix_rules.campaign.input.load import Campaign
from idefix_rules.campaign.input.yamlsource import format_loc
from idefix_rules.errors import Diagnostic, Span, error
from idefix_rules.fmu.description import FmuVariable
from idefix_rules.fmu.mapping import DONE_SIGNAL
from idefix_rules.units import parse_unit

Loc = tuple[str | int, ...]


def loc_span(campaign: Campaign, loc: Loc, at_key: bool = True) -> Span:
    """Where the campaign file says ``loc`` (its key, or its value with ``at_key=False``)."""
    return campaign.locations.span(loc, at_key=at_key)


def fmu_loc(campaign: Campaign) -> Loc:
    """Where the campaign names its FMU (the whole file for the built-in rover)."""
    return ("fmu", "path") if campaign.fmu is not None else ("fmu",)


def did_you_mean(name: str, known: Iterable[str]) -> str | None:
    """A hint naming the FMU variable closest to ``name``, if one is close."""
    # FMU variable names are often short ('px', 'v'): a lower cut-off than difflib's 0.6
    close = difflib.get_close_matches(name, list(known), n=1, cutoff=0.5)
    return f"did you mean {close[0]!r}?" if close else None


def article(causality: str) -> str:
    """A causality with its article: 'an input', 'a parameter'."""
    return f"an {causality}" if causality[:1] in "aeiou" else f"a {causality}"


def unit_problem(campaign: Campaign, loc: Loc, variable: FmuVariable, name: str,
                 unit: str) -> list[Diagnostic]:
    """A declared unit whose dimension is not the signal's (or set-point's) is an error, and
    so is one the tool cannot read (its values would be taken as SI: `milli-metre` as metres)."""
    if name == DONE_SIGNAL:
        return []
    if variable.si is None:
        if not variable.unit or variable.unit == "-":  # none declared: SI as the docs say
            return []
        return [error("C503", f"{format_loc(loc)}: {variable.name!r} is in "
                              f"{variable.unit!r}, which this tool cannot convert ('{name}' "
                              f"is in {unit})", loc_span(campaign, loc, at_key=False),
                      hint="declare the unit in SI symbols (mm, m/s, rad, A.s …, or a "
                           "<BaseUnit> without an offset) or map another variable")]
    expected = parse_unit(unit)
    if variable.si.dimension == expected.dimension:
        return []
    return [error("C503", f"{format_loc(loc)}: {variable.name!r} is in {variable.unit}, but "
                          f"'{name}' is in {unit}", loc_span(campaign, loc, at_key=False),
                  hint="map a variable of that dimension (values are converted to SI by the "
                       "FMU's declared unit)")]


def fmu_names(campaign: Campaign) -> dict[str, str]:
    """Our parameter name → the FMU variable it is mapped to (``fmu.parameters`` reversed: a
    name mapped from two variables is refused, C516)."""
    return {ours: theirs for theirs, ours in (campaign.model.fmu.parameters or {}).items()}
