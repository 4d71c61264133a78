"""How a campaign spends the rulebook's confidence over the bounds its decision reads.

α = 1 − ``confidence`` is the chance, at most, that anything the campaign decides is wrong
(family-wise, at every look of an adaptive campaign). The decision rests on

* each path's verdict: per verdict rule, a one-sided bound on the side that decides a pass
  (``risk <= 70 %``: the upper bound of ``risk``) and one on the side that decides a failure;
* the comparisons the decision depends on: the chain to send against each other chain.

α is split evenly over the ``P`` ranked paths and the ``C`` comparisons: each gets
``β = α / (P + C)``.

*A path's verdict* is wrong only in one way, whatever its truth. A path that truly breaks a
rule is said to pass (or to be within the margin when it breaks it by more) only if that
rule's pass-side bound misses: every rule must pass for the path to pass, so the pass-side
bounds need no split over the rules, and each is at ``β``. A path that truly meets every rule is
said to fail (or to be within a margin it is not within) only if some rule's fail-side bound
misses: those are split over the rules, ``β / U`` each, ``U`` being the bounds one path's
verdict can fail on (:func:`idefix_rules.rulebook.judging.judging`).

*The comparisons*: a chain is wrongly said to be safer than the safest chain that passes, or
tied with it while riskier by the margin or more, only if the bound of its risk difference
against that chain misses on one side. There are ``C = P − 1`` such bounds in a paired
campaign (every chain against the safest), each at ``β``; an unpaired campaign compares the
paths' own intervals, ``C = P``. The order among chains that all fail, or between two chains
neither of which is sent, is not decided and spends nothing.

By the union bound, P(some verdict or some comparison the decision depends on is wrong)
≤ ``P·β + C·β = α``.

*Chains shown to fail give their comparison's share back.* A chain that truly breaks a rule
(waivers applied) is never sent while the bounds hold, so no comparison with it is needed (in
an unpaired campaign: no interval of its own): with ``F`` such chains,
a decision rests on ``P`` verdicts and at most ``C − |F|`` comparisons, and ``β_F = α / max(P,
P + C − |F|)`` would do. ``F`` is unknown, but the chains *shown* to fail, ``D``, are a part of
it unless a fail-side bound missed; so each bound is judged at ``β_D = α / max(P, P + C −
|D|)`` (more is shown, the level rises, more may be shown: a fixed point, at most ``P`` steps).
This keeps the guarantee, provided every bound is nested in its level — the bets (the
asymptotic sequence's boundary) stay tuned for the levels of ``D = ∅`` and only the threshold
``1/β`` moves; Clopper–Pearson, Student-t and the mixture martingale of chances are nested
already. Proof: let ``G`` be the event that every bound the truth makes relevant holds at
``β_F`` (at every run count when sequential): the ``P`` verdicts' true sides and the
comparisons among passing chains (paired: the safest one's differences with the others;
unpaired: each passing chain's own interval); ``P(not G) ≤ α`` by the union bound. On ``G``,
while every decision so far is right, ``D ⊆ F``, so ``β_D ≤ β_F``: each bound at ``β_D``
contains its ``β_F`` bound, which holds, so the next decision is right too. By induction over
the looks (and the steps of the fixed point) no decision is wrong on ``G``.
This is the sequentially rejective idea of Holm (1979) and of the graphical procedures of
Bretz, Maurer, Brannath & Posch (Stat. Med. 2009), with the logical restriction that a chain
shown to fail has no comparison to spend on.

>>> from idefix_rules.rulebook.judging import Judging
>>> spent = AlphaBudget(0.05, paths=3, comparisons=2, judging=Judging({"risk": "upper"}, 5))
>>> spent.pass_alpha, spent.fail_alpha, spent.levels("risk")
(0.01, 0.002, (0.002, 0.01))
>>> later = spent.recycle(["straight"])
>>> round(later.pass_alpha, 6), later.tuned_levels("risk")
(0.0125, (0.002, 0.01))
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

from idefix_rules.campaign.statistics.pairwise import uses_paired_risk
from idefix_rules.rulebook.judging import Judging, judging


@dataclass(frozen=True)
class AlphaBudget:
    """α = 1 − confidence spread over ``paths`` verdicts and ``comparisons`` comparisons."""

    alpha: float
    paths: int
    comparisons: int
    judging: Judging = field(default_factory=Judging)
    # ranked paths shown to fail (waivers applied): their comparisons' share is spent again
    shown_failing: tuple[str, ...] = ()

    @property
    def per_path(self) -> float:
        """β: each path's verdict, and each comparison, gets this much."""
        spent_on = max(1, self.paths, self.paths + self.comparisons - len(self.shown_failing))
        return self.alpha / spent_on

    @property
    def at_floor(self) -> bool:
        """Whether the levels are as high as they go (α over the paths alone): no chain shown
        to fail can raise them any more."""
        return len(self.shown_failing) >= self.comparisons

    @property
    def first(self) -> AlphaBudget:
        """The budget before any chain was shown to fail: the levels bets are tuned for."""
        return dataclasses.replace(self, shown_failing=())

    def recycle(self, failing: Iterable[str]) -> AlphaBudget:
        """This budget with ``failing`` (paths shown to fail) among the shown failing too."""
        return dataclasses.replace(
            self, shown_failing=tuple(sorted(set(self.shown_failing) | set(failing))))

    def tuned_levels(self, statistic: str) -> tuple[float, float]:
        """(lower, upper) levels the bets of a statistic's bounds are tuned for: those of
        :attr:`first`, whatever has been shown since, so the bounds stay nested."""
        return self.first.levels(statistic)

    @property
    def comparison_tuned(self) -> float:
        """The level a comparison's bets are tuned for (see :meth:`tuned_levels`)."""
        return self.first.comparison_alpha

    @property
    def pass_alpha(self) -> float:
        """α of the bound that decides a pass (not split over the rules)."""
        return self.per_path

    @property
    def fail_alpha(self) -> float:
        """α of each bound that decides a failure (split over the path's ``units``)."""
        return self.per_path / max(1, self.judging.units)

    @property
    def comparison_alpha(self) -> float:
        """α of each side of a paired comparison's interval."""
        return self.per_path

    def levels(self, statistic: str) -> tuple[float, float]:
        """(α of the lower bound, α of the upper bound) of a path statistic."""
        return self.judging.levels(statistic, self.pass_alpha, self.fail_alpha)

    def to_dict(self) -> dict[str, Any]:
        return {"alpha": self.alpha, "paths": self.paths, "comparisons": self.comparisons,
                "bounds_per_verdict": self.judging.units, "pass_alpha": self.pass_alpha,
                "fail_alpha": self.fail_alpha, "comparison_alpha": self.comparison_alpha,
                "shown_failing": list(self.shown_failing),
                "first_pass_alpha": self.first.pass_alpha,
                "directions": dict(self.judging.directions)}


def shown_to_fail(verdict: Any) -> bool:
    """Whether a verdict (waivers applied) shows its path to fail: decided, not passed and
    not within a margin. Such a path can never be sent, so the α of its comparison is spent
    again (:func:`recycled`)."""
    return bool(verdict.decided and not verdict.passed and not verdict.marginal)


def recycled(budget: AlphaBudget, shown_failing: Callable[[AlphaBudget], Iterable[str]]
             ) -> AlphaBudget:
    """The fixed point of raising ``budget``'s levels by the paths shown to fail at them:
    ``shown_failing(b)`` judges the paths at ``b``'s levels and names those shown to fail
    (waivers applied). A path shown to fail once stays so (on the event the guarantee rests
    on it truly fails); at most ``paths`` steps.

    >>> from idefix_rules.rulebook.judging import Judging
    >>> start = AlphaBudget(0.05, paths=3, comparisons=2, judging=Judging({}, 1))
    >>> shown = {0.01: ["a"], 0.0125: ["a", "b"], 0.016667: ["a", "b"]}
    >>> recycled(start, lambda b: shown[round(b.pass_alpha, 6)]).shown_failing
    ('a', 'b')
    """
    while True:
        more = budget.recycle(shown_failing(budget))
        if more.shown_failing == budget.shown_failing:
            return budget
        budget = more


def alpha_budget(evaluator: Any, paths: int, paired: bool) -> AlphaBudget:
    """The budget of a campaign with ``paths`` ranked (simulated) paths under ``evaluator``'s
    rulebook; ``paired``: the campaign compares paths in the same drawn worlds."""
    alpha = 1.0 - float(evaluator.checked.confidence)
    if paths <= 1:
        comparisons = 0
    elif paired and uses_paired_risk(evaluator.rulebook):
        comparisons = paths - 1
    else:
        comparisons = paths
    return AlphaBudget(alpha, paths, comparisons, judging(evaluator.rulebook))
