"""Paths compared in the same simulated worlds: the per-world differences of their run risks.

In a paired campaign run ``j`` of every path is the same drawn world
(:mod:`idefix_rules.campaign.input.sampling`), so ``dⱼ = I_max(A, j) − I_max(B, j)`` measures what
the choice of chain changes in that world. The ``dⱼ`` of the worlds both paths completed are
independent, lie in [−1, 1], and their mean is the difference of the paths' risks; the hedged
capital confidence sequence (:mod:`idefix_rules.campaign.statistics.sequential`) of ``(dⱼ + 1) /
2`` gives an anytime-valid interval for it. The spread of the worlds drops out of the difference,
so the interval is far narrower than the two paths' own intervals side by side.

A pair is decided when its interval says so:

* ``tied`` — the interval lies inside ``(−margin, +margin)`` (the rulebook's
  ``combine { indifference = … }``): the risks differ by less than the margin, whichever is lower;
* ``first`` / ``second`` safer — otherwise, the interval lies below / above 0;
* ``open`` — neither yet.

Each side of the interval is a one-sided bound at the campaign's comparison α
(:class:`~idefix_rules.campaign.statistics.budget.AlphaBudget`): the decision depends only on the
chain to send against each other chain that may pass (:func:`needed`), so only those comparisons
spend α (``P − 1`` at first, fewer as chains are shown to fail); pairs among the other chains
are shown but decide nothing (``docs/campaign-format.md``, "How α is spent").

>>> import numpy as np
>>> rows = np.arange(200)
>>> [pair] = compare_pairs({"a": (rows, np.full(200, 0.5)), "b": (rows, np.full(200, 0.5))},
...                        ["a", "b"], alpha=0.05, margin=0.05)
>>> pair.outcome, pair.shared, pair.equal
('tied', 200, 200)
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from itertools import combinations, pairwise
from typing import Any

import numpy as np

from idefix_rules.campaign.statistics.sequential import one_sided_bound
from idefix_rules.units import percent_text

TIED = "tied"
FIRST_SAFER = "first safer"
SECOND_SAFER = "second safer"
OPEN = "open"

RunRisks = tuple[np.ndarray, np.ndarray]  # (run rows, I_max of those runs)


@dataclass(frozen=True)
class PairComparison:
    """Two paths compared in the worlds both completed."""

    first: str
    second: str
    shared: int  # worlds (run numbers) both paths completed
    first_safer: int  # of those, worlds where the first path's I_max is lower
    second_safer: int
    equal: int
    difference: float  # mean of I_max(first) − I_max(second) over the shared worlds
    low: float  # the confidence sequence's interval of that difference
    high: float
    confidence: float  # of each side of this pair's interval (1 − the comparison α)
    margin: float  # the indifference margin
    outcome: str  # tied | first safer | second safer | open
    needed: bool = True  # the decision depends on it (the chain to send against another)
    runs_needed: int | None = None  # open at the end: paired runs that would settle it

    @property
    def settled(self) -> bool:
        return self.outcome != OPEN

    def order(self) -> int | None:
        """-1 when the first ranks above the second, 1 below, 0 tied, None open."""
        return {FIRST_SAFER: -1, SECOND_SAFER: 1, TIED: 0}.get(self.outcome)

    def to_dict(self) -> dict[str, Any]:
        return {"paths": [self.first, self.second], "shared_runs": self.shared,
                "first_safer": self.first_safer, "second_safer": self.second_safer,
                "equal": self.equal, "risk_difference": self.difference,
                "ci": [self.low, self.high], "confidence": self.confidence,
                "indifference": self.margin, "outcome": self.outcome,
                "needed": self.needed, "runs_needed": self.runs_needed}


    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> PairComparison:
        """The comparison back from :meth:`to_dict` (``summary.json``'s ``pairs``)."""
        first, second = (str(name) for name in data["paths"])
        low, high = (float(value) for value in data["ci"])
        return cls(first, second, int(data["shared_runs"]), int(data["first_safer"]),
                   int(data["second_safer"]), int(data["equal"]),
                   float(data["risk_difference"]), low, high, float(data["confidence"]),
                   float(data["indifference"]), str(data["outcome"]),
                   bool(data.get("needed", True)),
                   None if data.get("runs_needed") is None else int(data["runs_needed"]))


def _points(value: float) -> str:
    """A risk difference in percentage points, signed: ``-13.0 %``, ``+2.4 %``."""
    return f"{100.0 * value:+.1f} %"


def seen_from(pair: PairComparison, subject: str) -> tuple[str, int, float, float, float]:
    """The comparison with ``subject`` (one of the pair) first: the other path, in how many
    shared worlds ``subject`` was the safer, and its risk minus the other's with that
    difference's interval (low, high)."""
    if subject == pair.first:
        return pair.second, pair.first_safer, pair.difference, pair.low, pair.high
    return pair.first, pair.second_safer, -pair.difference, -pair.high, -pair.low


def describe(pair: PairComparison, subject: str) -> str:
    """The comparison in words with ``subject`` (one of the pair) first: in how many of the
    shared worlds it was the safer, its risk minus the other's and that difference's interval,
    and what the interval decides.

    >>> pair = PairComparison("arc", "straight", 200, 174, 20, 6, -0.13, -0.16, -0.10, 0.95,
    ...                       0.02, FIRST_SAFER)
    >>> describe(pair, "arc")  # doctest: +NORMALIZE_WHITESPACE
    'arc is safer than straight in 87 % of the same worlds (174 of 200):
     risk -13.0 % (95 % CI -16.0 % … -10.0 %)'
    >>> describe(pair, "straight")  # doctest: +NORMALIZE_WHITESPACE
    'straight is riskier than arc: safer in 10 % of the same worlds (20 of 200):
     risk +13.0 % (95 % CI +10.0 % … +16.0 %)'
    """
    other, safer, difference, low, high = seen_from(pair, subject)
    share = (f"{100.0 * safer / pair.shared:.0f} % of the same worlds ({safer} of {pair.shared})"
             if pair.shared else "none of the same worlds (no world both completed)")
    numbers = (f"risk {_points(difference)} ({percent_text(pair.confidence)} CI "
               f"{_points(low)} … {_points(high)})")
    if pair.outcome == TIED:
        return (f"{subject} and {other} are tied (risk difference within "
                f"±{100.0 * pair.margin:.3g} %): {subject} safer in {share}: {numbers}")
    if pair.outcome == OPEN and not pair.needed:
        return (f"{subject} vs {other} not compared further (no decision depends on their "
                f"order): {subject} safer in {share}: {numbers}")
    if pair.outcome == OPEN:
        return f"{subject} vs {other} not settled: {subject} safer in {share}: {numbers}"
    if high < 0:
        return f"{subject} is safer than {other} in {share}: {numbers}"
    return f"{subject} is riskier than {other}: safer in {share}: {numbers}"


def adjacent(ranking: Sequence[str], pairs: Sequence[PairComparison]
             ) -> list[tuple[str, PairComparison]]:
    """``(higher-ranked path, its comparison with the next)`` for each neighbour pair of the
    ranking that was compared."""
    found = []
    for above, below in pairwise(ranking):
        pair = find(pairs, above, below)
        if pair is not None:
            found.append((above, pair))
    return found


def shown(ranking: Sequence[str], pairs: Sequence[PairComparison]
          ) -> list[tuple[str, PairComparison]]:
    """:func:`adjacent`, then each pair the decision depends on that is not a neighbour pair
    (the chain to send against one further down), seen from its higher-ranked path."""
    found = adjacent(ranking, pairs)
    taken = {id(pair) for _, pair in found}
    place = {name: position for position, name in enumerate(ranking)}
    for pair in pairs:
        if pair.needed and id(pair) not in taken and pair.first in place \
                and pair.second in place:
            above = min((pair.first, pair.second), key=lambda name: place[name])
            found.append((above, pair))
    return found


def difference_interval(differences: np.ndarray, alpha: float, sequential: bool = True,
                        tuned: float | None = None) -> tuple[float, float]:
    """The mean of ``differences`` (values in [−1, 1], run order) between a lower and an upper
    bound, each at ``alpha``: anytime-valid when ``sequential``, else with bets tuned for
    their number; ``tuned``: the level the bets are tuned for (by default ``alpha``)."""
    unit = (np.asarray(differences, dtype=np.float64) + 1.0) / 2.0
    fixed = None if sequential else int(unit.size)
    low = one_sided_bound(unit, alpha, "lower", fixed, tuned)
    high = one_sided_bound(unit, alpha, "upper", fixed, tuned)
    return 2.0 * low - 1.0, 2.0 * high - 1.0


def outcome(low: float, high: float, margin: float) -> str:
    """What an interval of the risk difference decides (a tie first: the interval says the
    difference is smaller than anything that matters, even when it also excludes 0)."""
    if margin > 0 and -margin < low and high < margin:
        return TIED
    if high < 0:
        return FIRST_SAFER
    if low > 0:
        return SECOND_SAFER
    return OPEN


def compare(first: str, second: str, first_risks: RunRisks, second_risks: RunRisks,
            alpha: float, margin: float, sequential: bool = True,
            tuned: float | None = None) -> PairComparison:
    """One pair on the worlds both completed, in run order; each side of its interval at
    ``alpha`` (bets tuned for ``tuned``, by default ``alpha``)."""
    rows, first_at, second_at = np.intersect1d(first_risks[0], second_risks[0],
                                               assume_unique=True, return_indices=True)
    differences = (np.asarray(first_risks[1], dtype=np.float64)[first_at]
                   - np.asarray(second_risks[1], dtype=np.float64)[second_at])
    if rows.size:
        low, high = difference_interval(differences, alpha, sequential, tuned)
        mean = float(differences.mean())
    else:
        low, high, mean = -1.0, 1.0, float("nan")
    return PairComparison(first, second, int(rows.size), int(np.sum(differences < 0)),
                          int(np.sum(differences > 0)), int(np.sum(differences == 0)), mean,
                          low, high, 1.0 - alpha, margin, outcome(low, high, margin))


def compare_pairs(risks: Mapping[str, RunRisks], order: Sequence[str], alpha: float,
                  margin: float, sequential: bool = True,
                  tuned: float | None = None) -> list[PairComparison]:
    """Every pair of the paths in ``order`` (first before second as listed), each side of its
    interval at ``alpha`` (bets tuned for ``tuned``, by default ``alpha``)."""
    names = [name for name in order if name in risks]
    return [compare(a, b, risks[a], risks[b], alpha, margin, sequential, tuned)
            for a, b in combinations(names, 2)]


def paired_differences(first_risks: RunRisks, second_risks: RunRisks) -> np.ndarray:
    """I_max(first) − I_max(second) over the worlds both completed, in run order."""
    _, first_at, second_at = np.intersect1d(first_risks[0], second_risks[0],
                                            assume_unique=True, return_indices=True)
    return (np.asarray(first_risks[1], dtype=np.float64)[first_at]
            - np.asarray(second_risks[1], dtype=np.float64)[second_at])


def needed(contenders: Sequence[str]) -> set[frozenset[str]]:
    """The pairs the decision depends on: ``contenders`` are the paths that pass or may
    still pass, best first; the first (the chain to send) against each of the others.

    >>> sorted(sorted(pair) for pair in needed(["b", "a", "c"]))
    [['a', 'b'], ['b', 'c']]
    """
    return {frozenset((contenders[0], other)) for other in contenders[1:]}


def mark_needed(pairs: Sequence[PairComparison], contenders: Sequence[str]
                ) -> list[PairComparison]:
    """``pairs`` with ``needed`` set from :func:`needed`."""
    wanted = needed(contenders) if contenders else set()
    return [dataclasses.replace(pair, needed=frozenset((pair.first, pair.second)) in wanted)
            for pair in pairs]


def find(pairs: Sequence[PairComparison], first: str, second: str) -> PairComparison | None:
    for pair in pairs:
        if (pair.first, pair.second) in ((first, second), (second, first)):
            return pair
    return None


def shared_ranks(ranking: Sequence[str], passed: Mapping[str, bool],
                 pairs: Sequence[PairComparison]) -> tuple[dict[str, int], list[tuple[str, str]]]:
    """Ranks (1 = best) for ``ranking`` (best first) where a path tied with the one before it
    (both passing or both not) shares its rank; and those ties, in ranking order."""
    ranks: dict[str, int] = {}
    ties: list[tuple[str, str]] = []
    for position, name in enumerate(ranking, start=1):
        ranks[name] = position
        if position == 1:
            continue
        before = ranking[position - 2]
        pair = find(pairs, before, name)
        if pair is not None and pair.outcome == TIED and passed.get(before) == passed.get(name):
            ranks[name] = ranks[before]
            ties.append((before, name))
    return ranks, ties


def uses_paired_risk(rulebook: Any) -> bool:
    """Whether the rulebook ranks first by ``risk`` (ascending), the key paired differences
    decide."""
    keys = rulebook.ranking.keys
    return bool(keys) and not keys[0].descending and getattr(keys[0].expr, "name", None) == "risk"
