"""``expect:`` entries that could never be judged, refused before anything is simulated.

An expectation is judged from the statistics of a path's runs (``campaign/outcome/
expectation_checks.py``). Two kinds of entry would only ever read "n/a", and both are known from
the campaign and the rulebook alone (C220 at the entry):

* a ``max_collision_chance`` level the rulebook has no chance for (a chance whose name ends in
  the level, e.g. ``chance hit_L2 = …``; for ``any`` a chance of any hit or of some level):
  without one, the level's chance is never computed, whatever the runs;
* a ``max_mean_risk`` or ``max_collision_chance`` of a path whose chain breaks a command rule
  (not waived): the path is rejected and never simulated.

A verdict or ``rank_first`` is always judged (a rejected path fails, and ranks nowhere); so is
a path a prescreen excludes, which only its reference run shows.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from idefix_rules.campaign.input import waivers
from idefix_rules.campaign.input.expectations import (
    CollisionExpectation,
    MeanRiskExpectation,
    judged_levels,
)
from idefix_rules.errors import Diagnostic, error

if TYPE_CHECKING:
    from idefix_rules.campaign.input.load import Campaign


def expectation_problems(campaign: Campaign, evaluator: Any) -> list[Diagnostic]:
    """C220 for every ``expect:`` entry the rulebook (``evaluator``, compiled) could never
    judge on this campaign's paths."""
    from idefix_rules.campaign.input.campaign_values import rover_geometry

    rulebook = f"rulebook {evaluator.name} {evaluator.version}"
    levels = judged_levels(evaluator.chance_names)
    chains = {spec.name: spec.chain for spec in campaign.paths}
    rover = rover_geometry(campaign)
    problems = []
    for index, expectation in enumerate(campaign.model.expect):
        if not isinstance(expectation, MeanRiskExpectation | CollisionExpectation):
            continue
        kind = "max_mean_risk" if isinstance(expectation, MeanRiskExpectation) \
            else "max_collision_chance"
        loc: tuple[str | int, ...] = ("expect", index, kind)
        chain = chains.get(expectation.path)
        broken = [] if chain is None else waivers.split(
            campaign.model.waivers, expectation.path, "command",
            evaluator.check_chain(chain, rover), lambda violation: str(violation.rule))[0]
        if broken:
            rules = ", ".join(dict.fromkeys(repr(str(v.rule)) for v in broken))
            what = "mean risk" if kind == "max_mean_risk" else "collision chance"
            problems.append(error(
                "C220", f"expect[{index}].{kind}: path {expectation.path!r} breaks the command "
                        f"rule {rules} of {rulebook}: it is rejected and never simulated, so "
                        f"its {what} could never be judged",
                campaign.locations.span(loc, at_key=True),
                hint="expect its rejection instead ({path: …, verdict: fail}), change the "
                     "chain, or waive the rule (waivers, with command_rules: true)"))
            continue
        if not isinstance(expectation, CollisionExpectation):
            continue
        for level in expectation.max_collision_chance:
            if level in levels:
                continue
            has = ("chance of any hit (named any, collision, hit, collision.any or hit_any) "
                   "nor of any obstacle level") if level == "any" else \
                f"chance of obstacle level {level} (one whose name ends in {level})"
            example = "hit_any = sum over parts (sum over levels (collision.hits)) > 0" \
                if level == "any" else f"hit_{level} = any over parts " \
                                       f"(collision.hits[{level}] > 0)"
            reads = "" if getattr(evaluator, "needs_collisions", False) \
                else "; it reads no collisions"
            problems.append(error(
                "C220", f"expect[{index}].max_collision_chance.{level}: {rulebook} has no "
                        f"{has}{reads}: the chance is never computed, so this expectation "
                        "could never be judged", campaign.locations.span((*loc, level),
                                                                     at_key=True),
                hint=f"give the rulebook one (e.g. `chance {example}`), or drop {level} from "
                     "the expectation"))
    return problems
