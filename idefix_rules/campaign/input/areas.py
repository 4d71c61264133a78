"""The campaign's geometry for the rulebook's named areas (``environment.areas``), checked.

A rulebook declares ``area NAME KIND level L buffer B``; the campaign gives a keep-out or an
unknown-surface area its polygons under ``environment.areas.NAME.polygons``. A steep area is
found in the terrain (its inclination above the rulebook's ``above``) and takes no polygons.
"""

from __future__ import annotations

import difflib
import re
from typing import Any

from idefix_rules.campaign.input.environment import declared_areas
from idefix_rules.campaign.input.load import Campaign
from idefix_rules.errors import Diagnostic, UserInputError, error, warning


def area_problems(campaign: Campaign, evaluator: Any) -> list[Diagnostic]:
    """Areas the rulebook does not declare, polygons for a steep area and polygons without
    area are errors (C209) at their line; a keep-out or unknown area the campaign gives no
    polygons (no entry, or one without ``polygons``) is a warning (C210): its signals stay 0
    in every run."""
    from idefix_rules.obstacles.areas import polygon_area

    declared = {spec.name: spec for spec in declared_areas(evaluator)}
    given = campaign.model.environment.areas
    problems: list[Diagnostic] = []
    for name, geometry in given.items():
        loc: tuple[str | int, ...] = ("environment", "areas", name)
        spec = declared.get(name)
        if spec is None:
            close = difflib.get_close_matches(name, list(declared), n=1)
            problems.append(error(
                "C209", f"environment.areas.{name}: the rulebook declares no area {name!r}"
                + (f" (it declares {', '.join(map(repr, declared))})" if declared else ""),
                campaign.locations.span(loc, at_key=True),
                f"did you mean {close[0]!r}?" if close else
                "declare it in the rulebook's obstacles block: area NAME keep_out level L3 "
                "buffer 10 cm"))
            continue
        if spec.kind == "steep" and geometry.polygons:
            problems.append(error(
                "C209", f"environment.areas.{name}: {name!r} is a steep area, found in the "
                "terrain where its inclination exceeds the rulebook's; it takes no polygons",
                campaign.locations.span(loc, at_key=True),
                "remove the entry, or declare the area keep_out in the rulebook"))
            continue
        for number, polygon in enumerate(geometry.polygons):
            try:
                polygon_area([tuple(point) for point in polygon], spec.level, name)
            except UserInputError as failure:
                problems.append(error(
                    "C209", f"environment.areas.{name}.polygons[{number}]: "
                    f"{failure.diagnostics[0].message}",
                    campaign.locations.span((*loc, "polygons", number))))
    problems += _keep_out_problems(campaign, declared) + _rock_level_problems(campaign)
    for name, spec in declared.items():
        # an entry that writes no polygons (`NAME: {}`, a template left unfilled) places the
        # area nowhere, as no entry does; `NAME: {polygons: []}` says the site has none
        written = name in given and "polygons" in given[name].model_fields_set
        if spec.kind != "steep" and not written:
            where = ("environment", "areas", name) if name in given else ("environment",)
            problems.append(warning(
                "C210", f"the rulebook declares the {spec.kind.replace('_', '-')} area "
                f"{name!r}, which this campaign gives no polygons: its signals are 0 in every "
                "run", campaign.locations.span(where, at_key=True),
                f"give its polygons under environment.areas.{name}.polygons, or `{name}: "
                "{polygons: []}` to say the site has none"))
    return problems


def unplaced_area_warnings(campaign: Campaign, evaluator: Any) -> list[Diagnostic]:
    """C210 as a run says it, for stored results scored again (``evaluate``, ``diff
    --results``): a keep-out or unknown area of the rulebook that the stored campaign gives no
    polygons (its signals are 0 in every run, so a rule reading them holds in every run). The
    stored campaign's areas the rulebook does not declare (C209 when it runs) are not read
    and change nothing here."""
    return [problem for problem in area_problems(campaign, evaluator) if problem.code == "C210"]


def _keep_out_problems(campaign: Campaign, declared: dict[str, Any]) -> list[Diagnostic]:
    """``environment.keep_out``: each polygon simple and with area, each name once and none
    another obstacle's (the campaign's rocks are rock1, rock2, … in their order; a rulebook
    area is its name, with a number when it has several parts) (E622, E613), at the line
    that says it."""
    from idefix_rules.obstacles.areas import polygon_area

    problems: list[Diagnostic] = []
    seen: dict[str, int] = {}
    rocks = len(campaign.model.environment.rocks)
    for number, area in enumerate(campaign.model.environment.keep_out):
        loc: tuple[str | int, ...] = ("environment", "keep_out", number)
        taken = _taken_by(area.name, rocks, declared)
        if area.name in seen:
            taken = f"keep_out[{seen[area.name]}]"
        if taken is not None:
            problems.append(error(
                "E613", f"environment.keep_out[{number}]: the name {area.name!r} is taken by "
                        f"{taken}; obstacle names must be unique",
                campaign.locations.span((*loc, "name")), hint="give the keep-out another name"))
        seen.setdefault(area.name, number)
        try:
            polygon_area([tuple(point) for point in area.polygon], area.level, area.name)
        except UserInputError as failure:
            problems.append(error(
                "E622", f"environment.keep_out[{number}].polygon: "
                        f"{failure.diagnostics[0].message}",
                campaign.locations.span((*loc, "polygon"))))
    return problems


def _taken_by(name: str, rocks: int, declared: dict[str, Any]) -> str | None:
    """The obstacle that already bears ``name`` (a keep-out's), or None."""
    match = re.fullmatch(r"rock([1-9]\d*)", name)
    if match is not None and int(match[1]) <= rocks:
        return f"the campaign's rock {match[1]} (environment.rocks[{int(match[1]) - 1}]: rocks " \
               "are named rock1, rock2, … in their order)"
    for area in declared:
        if re.fullmatch(re.escape(area) + r"\d*", name):
            return f"the rulebook's area {area!r} (its parts are {area}, or {area}1, {area}2, …)"
    return None


def _rock_level_problems(campaign: Campaign) -> list[Diagnostic]:
    """``environment.rock_levels``: 0 < l1_max_size <= l2_max_size (E611) at its line."""
    levels = campaign.model.environment.rock_levels
    if levels is None or 0 < levels.l1_max_size <= levels.l2_max_size:
        return []
    return [error("E611", f"environment.rock_levels: need 0 < l1_max_size <= l2_max_size, got "
                          f"{levels.l1_max_size:g} m and {levels.l2_max_size:g} m",
                  campaign.locations.span(("environment", "rock_levels")),
                  "a level-1 rock is a small one: its largest size is the smaller")]
