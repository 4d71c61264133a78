"""What the evaluation says of each path and of the campaign, and a path's stored status."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from idefix_rules.campaign.evaluation.spread import RiskSpread
from idefix_rules.campaign.input.waivers import STORED_ATTRIBUTE, WaivedRule
from idefix_rules.campaign.input.waivers import stored as stored_waivers
from idefix_rules.campaign.simulation.processes import is_infrastructure
from idefix_rules.campaign.statistics.budget import AlphaBudget
from idefix_rules.campaign.statistics.stopping import STOP_FIXED
from idefix_rules.campaign.storage.store import STATUS_COMPLETE, STATUS_NOT_NEEDED
from idefix_rules.results.reader import StoredResults


@dataclass
class PathResult:
    """What the evaluation says about one path (the terminal table, JSON and JUnit read it)."""

    name: str
    index: int
    status: str
    reason: str = ""
    runs: int = 0
    completed: int = 0
    failures: dict[int, str] = field(default_factory=dict)
    statistics: Any = None
    verdict: Any = None
    rank: int | None = None
    dominant_index: str | None = None
    mean_risk: float | None = None
    risk_ci: tuple[float, float] | None = None
    chances: dict[str, float] = field(default_factory=dict)
    collision_chance: dict[str, float] = field(default_factory=dict)
    energy: float | None = None
    time: float | None = None
    passed: bool | None = None
    undecided: bool = False
    verdict_reasons: list[str] = field(default_factory=list)
    stop_reason: str = ""  # why the Monte Carlo part ended (adaptive or fixed count)
    # complete runs still driving at the stop limit (their time is the limit); None: the runs
    # have neither 'command' nor 'done', so whether a chain finished is not known
    unfinished: int | None = None
    stop_time: float | None = None  # s, the path's stop limit
    # roughly how many runs would decide each verdict rule that is not decided (None: no
    # estimate, e.g. a compound condition or more than a million runs)
    runs_needed: dict[str, int | None] = field(default_factory=dict)
    # rule failures the campaign's waivers cover on this path (campaign/input/waivers.py)
    waivers: list[WaivedRule] = field(default_factory=list)
    # the spread of the run risks, and their share at the limit (campaign/evaluation/spread.py)
    risk_spread: RiskSpread | None = None

    @property
    def failed(self) -> int:
        """Runs failed for a reason of their own (what counts against the path)."""
        return len(self.failures) - self.lost

    @property
    def missing(self) -> int:
        """Runs planned but neither complete nor failed: never simulated (the campaign was
        interrupted before them). The rulebook's ``failed`` statistic counts them as failed."""
        return max(0, self.runs - self.completed - len(self.failures))

    @property
    def lost(self) -> int:
        """Runs lost to the infrastructure (``infrastructure: …``): no verdict on the path,
        ``--resume`` runs them again."""
        return sum(is_infrastructure(reason) for reason in self.failures.values())

    @property
    def marginal(self) -> bool:
        """Not passed because a statistic lies within its rule's margin of the limit, with no
        rule failing decidedly: neither shown to pass nor to fail."""
        return bool(getattr(self.verdict, "marginal", False)) and not self.passed

    @property
    def held(self) -> bool:
        """Shown to pass (or to fail only waived rules), with every verdict rule decided:
        what a campaign without expectations asks of every path for exit 0."""
        return self.verdict_text in ("pass", "waived") and not self.undecided

    @property
    def verdict_text(self) -> str:
        if self.status == "rejected":
            return "rejected"
        if self.status == "excluded":
            return "excluded"
        if self.status not in ("simulated",) or self.passed is None:
            return "error"
        if not self.passed:
            return "marginal" if self.marginal else "fail"
        return "waived" if self.waivers else "pass"


@dataclass
class CampaignEvaluation:
    paths: list[PathResult]
    ranking: list[str]
    rulebook: dict[str, str]
    provenance: dict[str, Any]
    # Assumed vs simulated slip per path (idefix_rules.campaign.evaluation.slip.SlipCheck).
    slip: list[Any] = field(default_factory=list)
    # Paired campaigns: every pair of ranked paths in the same worlds
    # (idefix_rules.campaign.statistics.pairwise.PairComparison), and the tied neighbours of the
    # ranking.
    paired: bool = False
    indifference: float = 0.0
    pairs: list[Any] = field(default_factory=list)
    ties: list[tuple[str, str]] = field(default_factory=list)
    # how α was spent over the paths' verdicts and the comparisons (campaign/statistics/budget.py)
    budget: AlphaBudget | None = None

    def path(self, name: str) -> PathResult:
        for result in self.paths:
            if result.name == name:
                return result
        raise KeyError(name)



def fixed_stop_reason(result: PathResult) -> str:
    """Why a path of a fixed campaign ended its Monte Carlo runs: its run count, or how many of
    them an interrupted campaign simulated."""
    if not result.missing:
        return f"{STOP_FIXED} ({result.runs} runs)"
    return (f"interrupted: {result.runs - result.missing} of the {result.runs} planned runs "
            "simulated (the others count as failed)")


def stored_path_result(store: StoredResults, name: str) -> PathResult:
    """A path's stored status and run counts (failures included), not yet evaluated."""
    group = store.path_group(name)
    result = PathResult(name=name, index=int(group.attrs["index"]),
                        status=str(group.attrs.get("status", "pending")),
                        reason=str(group.attrs.get("reason", "")),
                        stop_reason=str(group.attrs.get("stop_reason", "")),
                        waivers=stored_waivers(str(group.attrs.get(STORED_ATTRIBUTE, ""))))
    if result.status == "simulated" and store.has_runs(name):
        status = store.run_status(name)
        limit = judged_rows(store, name)
        if limit is not None:
            status = status[:limit]
        # rows an adaptive campaign never needed (or its looks never asked for) are not runs
        # of the path
        result.runs = int(np.sum(status != STATUS_NOT_NEEDED))
        result.completed = int(np.sum(status == STATUS_COMPLETE))
        result.failures = {run: reason for run, reason in store.failures(name).items()
                           if limit is None or run < limit}
    return result


def judged_rows(store: StoredResults, name: str) -> int | None:
    """The rows of an adaptive campaign's path its looks asked for (its ``runs_used``: the
    look it stopped at, or the one under way when the campaign was interrupted or ended for
    lost runs): the path's runs. None for a fixed campaign (every row is a run) and for a
    path no look has asked for runs yet."""
    if str(store.attrs.get("runs_mode", "fixed")) != "auto":
        return None
    used = store.path_group(name).attrs.get("runs_used")
    return None if used is None else int(used)

