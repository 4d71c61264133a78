"""Whether each ``expect:`` entry of a campaign holds, as its statistics show it."""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import Any

from idefix_rules.campaign.evaluation.path_result import CampaignEvaluation, PathResult
from idefix_rules.campaign.input.expectations import (
    ANY_HIT_CHANCES,
    CollisionExpectation,
    MeanRiskExpectation,
    PathVerdictExpectation,
    RankFirstExpectation,
)
from idefix_rules.campaign.statistics import pairwise
from idefix_rules.campaign.statistics.bernoulli import anytime_bounds


@dataclass(frozen=True)
class ExpectationResult:
    description: str
    held: bool
    message: str
    seconds: float = 0.0  # time the check took (JUnit ``time``)
    # The paths whose results it reads (every path for ``rank_first``): a path that lost runs
    # to the infrastructure leaves it unjudged (JUnit says so as an error, not a failure).
    paths: tuple[str, ...] = ()


def percent(value: float | None) -> str:
    """A fraction in percent with one decimal, ``n/a`` for none."""
    return "n/a" if value is None else f"{100.0 * value:.1f} %"


def check_expectation(expectation: Any, evaluation: CampaignEvaluation) -> ExpectationResult:
    """Whether one ``expect:`` entry holds, with a message saying what was found.

    An expectation holds only where the campaign's statistics show it, as a verdict does: a
    mean risk whose upper bound is within the limit, collision chances whose upper bounds
    are, a first rank settled against every other ranked chain. Where the bounds straddle the
    limit (or the rank is open) it does not hold and says it is not decided at this number of
    runs: a campaign of two runs proves nothing (docs/ci.md, "Expectations")."""
    if isinstance(expectation, RankFirstExpectation):
        return _rank_first(expectation.rank_first, evaluation)
    path = evaluation.path(expectation.path)
    if isinstance(expectation, PathVerdictExpectation):
        wanted = expectation.verdict
        got = path.verdict_text
        held = got == wanted or (wanted == "fail" and got in ("rejected", "excluded")) \
            or (wanted == "pass" and got == "waived")  # a waived failure counts as held
        message = f"verdict {got}"
        if path.undecided:
            message += UNDECIDED
            held = False
        if path.failed:
            message += f"; {path.failed} failed run(s)"
        says = {"pass": "passes", "fail": "fails"}.get(wanted, "is within a margin of a limit")
        return ExpectationResult(f"{path.name} {says}", held, message)
    if isinstance(expectation, MeanRiskExpectation):
        bound = expectation.max_mean_risk
        risk = path.mean_risk
        low, high = path.risk_ci if path.risk_ci is not None else (risk, risk)
        held = risk is not None and high is not None and high <= bound and not path.failed
        message = f"mean risk {percent(risk)}"
        if low is not None and high is not None and path.risk_ci is not None:
            message += f" (bounds {percent(low)}–{percent(high)})"
        if risk is not None and not held and low is not None and high is not None \
                and low <= bound < high:
            message += UNDECIDED
        return ExpectationResult(f"{path.name} mean risk <= {percent(bound)}", held,
                                 message + (f"; {path.failed} failed run(s)" if path.failed
                                            else ""))
    assert isinstance(expectation, CollisionExpectation)
    problems = []
    found = []
    open_levels = []
    alpha = evaluation.budget.alpha if evaluation.budget is not None else DEFAULT_ALPHA
    for level, bound in expectation.max_collision_chance.items():
        bounds = _any_bounds(path, alpha) if level == "any" else (
            None if path.collision_chance.get(level) is None
            else (path.collision_chance[level],
                  *chance_bounds(path.collision_chance[level], path.completed, alpha)))
        if bounds is None:
            found.append(f"{level} {percent(None)}")
            problems.append(level)
            continue
        chance, low, high = bounds
        found.append(f"{level} {percent(chance)} (bounds {percent(low)}–{percent(high)})")
        if high > bound:
            problems.append(level)
            if low <= bound:
                open_levels.append(level)
    held = not problems and not path.failed and path.status == "simulated"
    shown = ", ".join(f"{lvl} <= {percent(b)}"
                      for lvl, b in expectation.max_collision_chance.items())
    return ExpectationResult(f"{path.name} collision chance {shown}", held,
                             "collision chance " + ", ".join(found)
                             + (UNDECIDED if open_levels and held is False else ""))


def chance_bounds(chance: float, runs: int, alpha: float) -> tuple[float, float]:
    """A chance's one-sided bounds at ``alpha`` each, valid however the run count was reached
    (a fixed count, or an adaptive campaign's stop, which could fool a Clopper-Pearson
    interval): :func:`~idefix_rules.campaign.statistics.bernoulli.anytime_bounds`."""
    return anytime_bounds(round(chance * runs), runs, alpha)


def _any_bounds(path: PathResult, alpha: float) -> tuple[float, float, float] | None:
    """The chance of a hit of any level, and its bounds: a dedicated chance's where the
    rulebook has one; else from the per-level chances, which the union only bounds: at least
    the largest (its lower bound), at most their sum (the sum of their upper bounds)."""
    for key in ANY_HIT_CHANCES:
        if key in path.chances:
            return (path.chances[key], *chance_bounds(path.chances[key], path.completed, alpha))
    values = list(path.collision_chance.values())
    if not values:
        return None
    each = [chance_bounds(value, path.completed, alpha) for value in values]
    return (max(values), max(low for low, _ in each),
            min(1.0, sum(high for _, high in each)))


UNDECIDED = " (not decided at this number of runs)"
DEFAULT_ALPHA = 0.05


def _rank_first(name: str, evaluation: CampaignEvaluation) -> ExpectationResult:
    """``rank_first``: ranked first, and settled so against every other ranked chain: a
    chain shown to pass ranks above one shown not to; else by the risk, compared in the same
    worlds on a paired campaign, by the risks' bounds apart on an unpaired one. A tie with the
    chain ranked first shares the first rank and holds, saying so."""
    description = f"{name} ranks first"
    ranking = ", ".join(evaluation.ranking) or "(none)"
    me = evaluation.path(name) if name in evaluation.ranking else None
    # first in the ranking, or sharing the first rank (a tie, ordered by name there)
    if me is None or (evaluation.ranking[0] != name and me.rank != 1):
        return ExpectationResult(description, False, f"ranking: {ranking}")
    ties: list[str] = []
    open_with: list[str] = []
    shown_to_pass = bool(me.passed) and not me.undecided
    for other in evaluation.paths:
        if other.name == name or other.rank is None:
            continue
        if shown_to_pass and other.passed is False and not other.undecided:
            continue  # passing chains rank first, and these two verdicts are decided
        pair = pairwise.find(evaluation.pairs, name, other.name) if evaluation.pairs else None
        if pair is not None:
            order = pair.order()
            ahead = order if pair.first == name else (None if order is None else -order)
            if ahead == 0:
                ties.append(other.name)
            elif ahead != -1:
                open_with.append(other.name)
        elif me.risk_ci is None or other.risk_ci is None or not me.risk_ci[1] < other.risk_ci[0]:
            open_with.append(other.name)
    message = f"ranking: {ranking}"
    if ties:
        message += f"; tied with {', '.join(ties)} within the indifference margin"
    if open_with:
        message += (f"; its lead over {', '.join(open_with)} is not settled"
                    f"{UNDECIDED}")
    return ExpectationResult(description, not open_with, message)


def check_expectations(expectations: list[Any],
                       evaluation: CampaignEvaluation) -> list[ExpectationResult]:
    results = []
    for expectation in expectations:
        started = time.perf_counter()
        result = check_expectation(expectation, evaluation)
        read = (tuple(p.name for p in evaluation.paths)
                if isinstance(expectation, RankFirstExpectation) else (expectation.path,))
        results.append(dataclasses.replace(result, seconds=time.perf_counter() - started,
                                           paths=read))
    return results
