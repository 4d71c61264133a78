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

>>> from idefix_rules.rulebook.judging import Judging
>>> spent = AlphaBudget(0.05, paths=3, comparisons=2, judging=Judging({"risk": "upper"}, 5))
>>> spent.pass_alpha, spent.fail_alpha, spent.levels("risk")
(0.01, 0.002, (0.002, 0.01))
"""

from __future__ import annotations

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

    @property
    def per_path(self) -> float:
        """β: each path's verdict, and each comparison, gets this much."""
        return self.alpha / max(1, self.paths + self.comparisons)

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
                "directions": dict(self.judging.directions)}


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
