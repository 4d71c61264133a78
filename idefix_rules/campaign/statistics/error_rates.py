"""How often a campaign decides wrongly, simulated on synthetic streams of known means.

Many adaptive campaigns are run at once with numpy, one stream per row: the runs are drawn
with a known true value, looked at every ``BATCH`` runs up to a cap, and each campaign stops
at its first look where the decision is settled, with the bounds, levels and decision rules of
a real campaign (:mod:`~idefix_rules.campaign.statistics.bernoulli`,
:mod:`~idefix_rules.campaign.statistics.sequential`,
:class:`~idefix_rules.campaign.statistics.budget.AlphaBudget`):

* a verdict rule ``statistic <= limit`` with an indifference margin δ passes when the upper
  bound is below the limit, fails when the lower bound is above it, and is *marginal* when
  both lie within δ of it (a pass or a failure wins over marginal);
* a pair of paths compared in the same worlds is ordered when its interval excludes 0 and
  tied when it lies within ± the margin (a tie wins).

A simulated bound here reads every run count up to the look (a campaign's running
intersection reads fewer), so these error rates are, if anything, above a campaign's.
``benchmarks/bench_error_rates.py`` prints :func:`table`; the test suite asserts every wrong
rate is at most α within three binomial standard errors.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from idefix_rules.campaign.statistics import bernoulli
from idefix_rules.campaign.statistics.budget import AlphaBudget
from idefix_rules.campaign.statistics.sequential import rejections, running_log_capital
from idefix_rules.rulebook.judging import Judging

ALPHA = 0.05
BATCH = 32
PASS, FAIL, NEAR, OPEN = "pass", "fail", "marginal", "open"
FIRST, SECOND, TIED = "first safer", "second safer", "tied"
CHUNK = 500  # replications simulated at once (memory stays flat)


@dataclass(frozen=True)
class Outcomes:
    """The first decided outcome of each simulated campaign and the runs it used."""

    outcome: np.ndarray  # str per replication
    runs: np.ndarray  # runs used per replication (the cap when open)


@dataclass(frozen=True)
class Row:
    """One setting of the error-rate table."""

    setting: str
    truth: str
    wrong_outcomes: tuple[str, ...]
    replications: int
    wrong: float  # share of campaigns that decided wrongly
    decided: float  # share that decided before the cap
    mean_runs: float  # runs per campaign (per path)

    def cells(self) -> tuple[str, ...]:
        return (self.setting, self.truth, " or ".join(self.wrong_outcomes),
                f"{self.wrong:.4f}", f"{100 * self.decided:.0f} %", f"{self.mean_runs:.0f}")


HEADER = ("setting", "truth", "wrong outcomes", "wrong", "decided", "mean runs")


def tolerance(replications: int, alpha: float = ALPHA) -> float:
    """Three binomial standard errors of an error rate of ``alpha``."""
    return 3.0 * math.sqrt(alpha * (1.0 - alpha) / replications)


def _first_decided(decisions: Sequence[tuple[str, np.ndarray]], looks: Sequence[int]
                   ) -> Outcomes:
    """From per-outcome (replications, runs) flags "settled by then" (in priority order),
    the outcome at the first look where any holds."""
    count = decisions[0][1].shape[0]
    outcome = np.full(count, OPEN, dtype=object)
    runs = np.full(count, looks[-1])
    waiting = np.ones(count, dtype=bool)
    for look in looks:
        for name, flags in decisions:
            now = waiting & flags[:, look - 1]
            outcome[now] = name
            runs[now] = look
            waiting &= ~now
    return Outcomes(outcome, runs)


def looks_up_to(cap: int) -> list[int]:
    """An adaptive campaign's looks with ``min_runs = batch_runs = BATCH``."""
    return [*range(BATCH, cap, BATCH), cap]


def chance_rule(draws: np.ndarray, limit: float, margin: float, levels: tuple[float, float],
                looks: Sequence[int]) -> Outcomes:
    """``chance(x) <= limit`` (margin δ) on 0/1 ``draws`` (replications, runs)."""
    events = np.cumsum(draws, axis=1).astype(np.int64)
    runs = np.arange(1, draws.shape[1] + 1)
    # the evidence depends on (events, runs) only: computed once per pair that occurs
    counts = np.arange(int(events.max()) + 1)[:, None]
    alpha_low, alpha_high = levels

    def rejected(candidate: float, side: str, alpha: float) -> np.ndarray:
        evidence = (bernoulli.log_evidence_below if side == "upper"
                    else bernoulli.log_evidence_above)
        with np.errstate(invalid="ignore", divide="ignore"):
            table = evidence(np.minimum(counts, runs), runs, candidate)
        found = table[events, runs - 1]
        return np.maximum.accumulate(found >= math.log(1.0 / alpha), axis=1)

    return _verdict(rejected, limit, margin, alpha_low, alpha_high, looks)


def mean_rule(values: np.ndarray, limit: float, margin: float, levels: tuple[float, float],
              looks: Sequence[int]) -> Outcomes:
    """``mean <= limit`` (margin δ) on values in [0, 1] (replications, runs), e.g. run risks."""
    alpha_low, alpha_high = levels

    def rejected(candidate: float, side: str, alpha: float) -> np.ndarray:
        if not 0.0 <= candidate <= 1.0:
            return np.full(values.shape, (candidate > 1.0) == (side == "upper"))
        return rejections(values, candidate, alpha, side)

    return _verdict(rejected, limit, margin, alpha_low, alpha_high, looks)


def _verdict(rejected: Callable[[float, str, float], np.ndarray], limit: float, margin: float,
             alpha_low: float, alpha_high: float, looks: Sequence[int]) -> Outcomes:
    decisions = [(PASS, rejected(limit, "upper", alpha_high)),
                 (FAIL, rejected(limit, "lower", alpha_low))]
    if margin > 0:
        decisions.append((NEAR, rejected(limit - margin, "lower", alpha_low)
                          & rejected(limit + margin, "upper", alpha_high)))
    return _first_decided(decisions, looks)


def pair(first: np.ndarray, second: np.ndarray, alpha: float, margin: float,
         looks: Sequence[int]) -> Outcomes:
    """Two paths' run risks in the same worlds (replications, runs): the paired comparison,
    each side of its interval at ``alpha``."""
    unit = (first - second + 1.0) / 2.0

    def rejected(candidate: float, side: str) -> np.ndarray:
        return rejections(unit, (candidate + 1.0) / 2.0, alpha, side)

    decisions = []
    if margin > 0:
        decisions.append((TIED, rejected(-margin, "lower") & rejected(margin, "upper")))
    decisions += [(FIRST, rejected(0.0, "upper")), (SECOND, rejected(0.0, "lower"))]
    return _first_decided(decisions, looks)


def worlds(rng: np.random.Generator, shape: tuple[int, int], gap: float
           ) -> tuple[np.ndarray, np.ndarray]:
    """Run risks of two paths in the same worlds: a shared world term and each path's own
    noise, means 0.5 and 0.5 + ``gap`` (exact: nothing is clipped)."""
    world = 0.3 * rng.uniform(-1, 1, shape)
    first = 0.5 + world + 0.1 * rng.uniform(-1, 1, shape)
    second = 0.5 + gap + world + 0.1 * rng.uniform(-1, 1, shape)
    return first, second


def risks(rng: np.random.Generator, shape: tuple[int, int], mean: float) -> np.ndarray:
    """Run risks in [0, 1] with the given mean: Beta(a, b) with a + b = 8 (spread 0.15)."""
    return rng.beta(8.0 * mean, 8.0 * (1.0 - mean), shape)


def _budget(paths: int, comparisons: int, units: int) -> AlphaBudget:
    return AlphaBudget(ALPHA, paths, comparisons, Judging({}, units))


def _row(setting: str, truth: str, wrong: tuple[str, ...], simulate: Callable[
        [np.random.Generator, int], Outcomes], replications: int, seed: int) -> Row:
    rng = np.random.default_rng(seed)
    outcomes, runs = [], []
    for start in range(0, replications, CHUNK):
        found = simulate(rng, min(CHUNK, replications - start))
        outcomes.append(found.outcome)
        runs.append(found.runs)
    outcome, used = np.concatenate(outcomes), np.concatenate(runs)
    return Row(setting, truth, wrong, replications, float(np.isin(outcome, wrong).mean()),
               float((outcome != OPEN).mean()), float(used.mean()))


def _family(rng: np.random.Generator, count: int, paths: int, chances: int, cap: int,
            spent: bool = True) -> Outcomes:
    """``paths`` paths, each with ``risk <= 70 %`` and ``chances`` rules ``chance <= 5 %``,
    every statistic exactly at its limit (every path truly passes); no margins. A campaign is
    wrong when any path fails. ``spent``: the campaign's budget; else every bound at α."""
    budget = _budget(paths, paths - 1, 1 + chances)
    levels = (budget.fail_alpha, budget.pass_alpha) if spent else (ALPHA, ALPHA)
    looks = looks_up_to(cap)
    wrong = np.zeros(count, dtype=bool)
    decided = np.ones(count, dtype=bool)
    used = np.zeros(count)
    for _ in range(paths):
        rules = [mean_rule(risks(rng, (count, cap), 0.7), 0.7, 0.0, levels, looks)]
        rules += [chance_rule((rng.random((count, cap)) < 0.05).astype(np.float64), 0.05, 0.0,
                              levels, looks) for _ in range(chances)]
        outcome = np.vstack([rule.outcome for rule in rules])
        wrong |= (outcome == FAIL).any(axis=0)
        decided &= (outcome != OPEN).all(axis=0)
        used += np.max(np.vstack([rule.runs for rule in rules]), axis=0) / paths
    return Outcomes(np.where(wrong, FAIL, np.where(decided, PASS, OPEN)), used)


def _running_evidence(draws: np.ndarray, limit: float, side: str) -> np.ndarray:
    """The running maximum of the chance's log evidence against ``limit`` (the mixture
    martingale of :mod:`~idefix_rules.campaign.statistics.bernoulli`: no bets to tune)."""
    events = np.cumsum(draws, axis=1).astype(np.int64)
    runs = np.arange(1, draws.shape[1] + 1)
    counts = np.arange(int(events.max()) + 1)[:, None]
    evidence = (bernoulli.log_evidence_below if side == "upper"
                else bernoulli.log_evidence_above)
    with np.errstate(invalid="ignore", divide="ignore"):
        table = evidence(np.minimum(counts, runs), runs, limit)
    return np.asarray(np.maximum.accumulate(table[events, runs - 1], axis=1))


def _recycled_family(rng: np.random.Generator, count: int, cap: int, failing: int = 2,
                     passing: int = 3, chances: int = 1) -> Outcomes:
    """A paired campaign of ``failing + passing`` paths, each with ``risk <= 70 %`` and
    ``chances`` rules ``chance <= 5 %``: the failing ones at risk 85 %, the others with every
    statistic exactly at its limit. At each look the levels are raised by the paths shown to
    fail (the fixed point of :func:`~idefix_rules.campaign.statistics.budget.recycled`, bets
    tuned for the first levels); a path stops once decided. Wrong when a path at its limits is
    shown to fail or a failing one to pass."""
    paths = failing + passing
    first = _budget(paths, paths - 1, 1 + chances)
    tuned = (first.fail_alpha, first.pass_alpha)
    # per path, per rule: (fail-side, pass-side) running evidence, log scale
    evidence = []
    for position in range(paths):
        mean = 0.85 if position < failing else 0.7
        risk = risks(rng, (count, cap), mean)
        rules = [(running_log_capital(risk, 0.7, "lower", tuned[0]),
                  running_log_capital(risk, 0.7, "upper", tuned[1]))]
        for _ in range(chances):
            draws = (rng.random((count, cap)) < 0.05).astype(np.float64)
            rules.append((_running_evidence(draws, 0.05, "lower"),
                          _running_evidence(draws, 0.05, "upper")))
        evidence.append(rules)
    # the levels with k paths shown to fail, k = 0 … paths
    raised = [first.recycle(map(str, range(k))) for k in range(paths + 1)]
    fail_levels = np.array([b.fail_alpha for b in raised])
    pass_levels = np.array([b.pass_alpha for b in raised])
    looks = looks_up_to(cap)
    outcome = np.full((paths, count), OPEN, dtype=object)
    stopped_at = np.full((paths, count), looks[-1])
    for look in looks:
        shown = np.zeros(count, dtype=int)
        while True:  # the fixed point: more shown to fail, higher levels
            fail_level, pass_level = fail_levels[shown], pass_levels[shown]
            failed = np.zeros((paths, count), dtype=bool)
            passed = np.ones((paths, count), dtype=bool)
            for position, rules in enumerate(evidence):
                for fail_side, pass_side in rules:
                    failed[position] |= fail_side[:, look - 1] >= np.log(1.0 / fail_level)
                    passed[position] &= pass_side[:, look - 1] >= np.log(1.0 / pass_level)
            now = np.where(outcome == OPEN, failed, outcome == FAIL)
            more = now.sum(axis=0)
            if np.array_equal(more, shown):
                break
            shown = more
        decided_now = (outcome == OPEN) & (failed | passed)
        outcome[decided_now] = np.where(failed, FAIL, PASS)[decided_now]
        stopped_at[decided_now] = look
    wrong = (outcome[failing:] == FAIL).any(axis=0) | (outcome[:failing] == PASS).any(axis=0)
    decided = (outcome != OPEN).all(axis=0)
    return Outcomes(np.where(wrong, FAIL, np.where(decided, PASS, OPEN)),
                    stopped_at.mean(axis=0))


def settings(cap: int = 1000) -> Iterator[tuple[str, str, tuple[str, ...],
                                                Callable[[np.random.Generator, int], Outcomes]]]:
    """The settings of the table: (setting, truth, wrong outcomes, simulation)."""
    looks = looks_up_to(cap)
    one = _budget(1, 0, 1)  # one path, one rule: α on each side
    single = (one.fail_alpha, one.pass_alpha)

    def chances(p: float, limit: float, margin: float) -> Callable[..., Outcomes]:
        return lambda rng, n: chance_rule((rng.random((n, cap)) < p).astype(np.float64),
                                          limit, margin, single, looks)

    def means(mean: float, limit: float, margin: float) -> Callable[..., Outcomes]:
        return lambda rng, n: mean_rule(risks(rng, (n, cap), mean), limit, margin, single,
                                        looks)

    two = _budget(2, 1, 1)  # two paired paths: each side of the comparison at α / 3

    def pairs(gap: float, margin: float) -> Callable[..., Outcomes]:
        return lambda rng, n: pair(*worlds(rng, (n, cap), gap), two.comparison_alpha, margin,
                                   looks)

    yield ("chance(x) <= 1 %, no events", "p = 0", (FAIL, NEAR), chances(0.0, 0.01, 0.0))
    yield ("chance(x) <= 5 % ± 2.5 %", "p = 5 % (at the limit)", (FAIL,),
           chances(0.05, 0.05, 0.025))
    yield ("chance(x) <= 5 % ± 2.5 %", "p = 8.125 % (1.25 δ above)", (PASS, NEAR),
           chances(0.08125, 0.05, 0.025))
    yield ("chance(x) < 5 %, no margin", "p = 5 % (at the limit)", (PASS,),
           chances(0.05, 0.05 - 1e-12, 0.0))
    yield ("risk <= 70 % ± 2 %", "mean 70 % (at the limit)", (FAIL,), means(0.7, 0.7, 0.02))
    yield ("risk <= 70 % ± 2 %", "mean 72.5 % (1.25 δ above)", (PASS, NEAR),
           means(0.725, 0.7, 0.02))
    yield ("pair, indifference 2 %", "equal risks", (FIRST, SECOND), pairs(0.0, 0.02))
    yield ("pair, indifference 2 %", "second riskier by 2.5 %", (TIED, SECOND),
           pairs(0.025, 0.02))
    yield ("pair, no indifference", "equal risks", (FIRST, SECOND), pairs(0.0, 0.0))
    yield ("3 paths × (risk + 4 chances), no margins", "every statistic at its limit",
           (FAIL,), lambda rng, n: _family(rng, n, 3, 4, min(cap, 400)))
    yield ("5 paths × (risk + 1 chance), levels raised by failures",
           "2 paths at risk 85 %, 3 with every statistic at its limit", (FAIL,),
           lambda rng, n: _recycled_family(rng, n, min(cap, 400)))


def table(replications: int = 2000, cap: int = 1000, seed: int = 20261127) -> list[Row]:
    """Every setting of :func:`settings`, ``replications`` campaigns each."""
    return [_row(setting, truth, wrong, simulate, replications, seed + position)
            for position, (setting, truth, wrong, simulate) in enumerate(settings(cap))]


def unspent(replications: int = 2000, cap: int = 400, seed: int = 20261127) -> Row:
    """The last setting of :func:`table` with every bound at α instead of the budget's
    levels: what the budget prevents."""
    return _row("3 paths × (risk + 4 chances), every bound at α", "every statistic at its limit",
                (FAIL,), lambda rng, n: _family(rng, n, 3, 4, cap, spent=False), replications,
                seed)


def markdown(rows: Sequence[Row]) -> str:
    """The table as Markdown (as in docs/campaign-format.md)."""
    lines = ["| " + " | ".join(HEADER) + " |", "| " + " | ".join("---" for _ in HEADER) + " |"]
    lines += ["| " + " | ".join(row.cells()) + " |" for row in rows]
    return "\n".join(lines)
