"""The results diff: stored runs re-scored under two rulebooks, path by path, no simulation.

For every path of a results file each rulebook first decides whether the path would be run at
all: its command rules on the stored chain (``rejected``) and its prescreen on the stored
reference run (``excluded``). Paths both rulebooks accept are scored in one pass over the
stored runs (:func:`idefix_rules.results.scoring.score_chunks`): each chunk of signals is read
once (only the signals either rulebook needs) and evaluated under both. A rulebook whose
evaluation the results file stores (same text, made by this version of the tool, over every
complete run) takes its per-run values from there instead, without reading a signal.
Collision signals come from the stored ``collisions/hits`` when the obstacle levels and buffers
of both rulebooks equal those they were computed with, else from the obstacle checker on the
stored poses (once per chunk when both rulebooks have the same levels;
:class:`idefix_rules.results.collisions.CollisionSources`). Then statistics, verdicts and the
ranking of each side, and the runs whose I_max moved most with the index responsible (the one
whose weighted value changed most).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from idefix_rules import __version__
from idefix_rules.campaign.evaluation.evaluate import concatenate
from idefix_rules.campaign.evaluation.fill_result import fill_result, risk_ceiling
from idefix_rules.campaign.evaluation.gate import NOT_SIMULATED, gate_again
from idefix_rules.campaign.evaluation.path_result import PathResult, stored_path_result
from idefix_rules.campaign.evaluation.scoring import judge_paths, ranked_paths
from idefix_rules.campaign.input.waivers import waive_verdict
from idefix_rules.campaign.input.wording import DisplayUnits
from idefix_rules.campaign.outcome.decision import path_confidence, reasons_of
from idefix_rules.campaign.outcome.held import held_warnings
from idefix_rules.campaign.statistics.budget import alpha_budget
from idefix_rules.commands import Command
from idefix_rules.diff.evaluators import values_only
from idefix_rules.diff.source import RulebookSource
from idefix_rules.results.campaign import StoredCampaign
from idefix_rules.results.collisions import CollisionSources, collision_reads, source_sha256
from idefix_rules.results.format import drawn_paired
from idefix_rules.results.runs import ParallelRuns
from idefix_rules.results.scoring import score_chunks, stored_evaluation

# Runs read and evaluated at a time. 64, not 128: with three chunks in flight (one read ahead,
# two evaluated) a path of 1000 runs keeps both cores busy for more of its time, and the
# arrays of a chunk stay small enough for the allocator to reuse freed memory instead of
# taking new pages from the kernel, which zeroes them (half the system time, half the memory).
DEFAULT_CHUNK_RUNS = 64
DEFAULT_TOP_RUNS = 5
DEFAULT_THREADS = 2
PATHS_AT_ONCE = 2
# |Δ I_max| below this is rounding, not a change.
MOVE_TOLERANCE = 1e-9

FailOn = Literal["verdict", "rank", "never"]
FAIL_ON: tuple[str, ...] = ("verdict", "rank", "never")


@dataclass(frozen=True)
class SideResult:
    """One path under one rulebook: verdict, risk, rank, chances, dominant index counts."""

    verdict: str  # pass, fail, rejected, excluded, error, not simulated
    undecided: bool = False
    reasons: tuple[str, ...] = ()
    mean_risk: float | None = None
    risk_ci: tuple[float, float] | None = None
    rank: int | None = None
    chances: dict[str, float] = field(default_factory=dict)
    dominant_counts: dict[str, int] = field(default_factory=dict)
    runs: int = 0
    confidence: float = 0.95  # the family-wise confidence of risk_ci (the rulebook's)

    def to_dict(self) -> dict[str, Any]:
        return {"verdict": self.verdict, "undecided": self.undecided,
                "reasons": list(self.reasons), "mean_risk": self.mean_risk,
                "risk_ci": list(self.risk_ci) if self.risk_ci is not None else None,
                "confidence": self.confidence,
                "rank": self.rank, "chances": dict(self.chances),
                "dominant_counts": dict(self.dominant_counts), "runs": self.runs}


@dataclass(frozen=True)
class RunMove:
    """A run whose I_max changed: old → new, and the index whose weighted value moved most."""

    run: int
    old_i_max: float
    new_i_max: float
    index: str
    old_dominant: str
    new_dominant: str

    @property
    def delta(self) -> float:
        return self.new_i_max - self.old_i_max

    def to_dict(self) -> dict[str, Any]:
        return {**self.__dict__, "delta": self.delta}


@dataclass(frozen=True)
class PathDiff:
    name: str
    old: SideResult
    new: SideResult
    changed_runs: int = 0  # runs whose I_max changed
    dominant_changed: int = 0  # runs whose dominant index changed
    top_runs: tuple[RunMove, ...] = ()

    @property
    def verdict_changed(self) -> bool:
        return self.old.verdict != self.new.verdict

    @property
    def rank_changed(self) -> bool:
        return self.old.rank != self.new.rank

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "old": self.old.to_dict(), "new": self.new.to_dict(),
                "verdict_changed": self.verdict_changed, "rank_changed": self.rank_changed,
                "changed_runs": self.changed_runs, "dominant_changed": self.dominant_changed,
                "top_runs": [m.to_dict() for m in self.top_runs]}


@dataclass(frozen=True)
class ResultsFileDiff:
    """The diff of one results file. ``collisions``: ``stored``, ``recomputed`` or ``none``."""

    results: str
    campaign: str
    paths: tuple[PathDiff, ...]
    old_ranking: tuple[str, ...]
    new_ranking: tuple[str, ...]
    collisions: str
    timings: dict[str, float] = field(default_factory=dict)
    # what the file holds (a search, a campaign not complete), the terrain the collision and
    # area checks used, areas the campaign left unplaced
    warnings: tuple[str, ...] = ()
    # the sides ("old", "new") whose per-run values came from the stored evaluation
    stored_evaluation: tuple[str, ...] = ()

    @property
    def first_changed(self) -> bool:
        return self.old_ranking[:1] != self.new_ranking[:1]

    def to_dict(self) -> dict[str, Any]:
        return {"results": self.results, "campaign": self.campaign,
                "paths": [p.to_dict() for p in self.paths],
                "old_ranking": list(self.old_ranking), "new_ranking": list(self.new_ranking),
                "first_changed": self.first_changed, "collisions": self.collisions,
                "timings": dict(self.timings), "warnings": list(self.warnings),
                "stored_evaluation": list(self.stored_evaluation)}


@dataclass(frozen=True)
class ResultsDiff:
    files: tuple[ResultsFileDiff, ...]

    def verdict_changes(self) -> list[tuple[str, PathDiff]]:
        return [(f.results, p) for f in self.files for p in f.paths if p.verdict_changed]

    def exit_code(self, fail_on: str = "verdict") -> int:
        """0: nothing the policy gates on changed; 1: it did (see ``docs/diff.md``)."""
        if fail_on == "never":
            return 0
        for file in self.files:
            if file.first_changed or any(p.verdict_changed for p in file.paths):
                return 1
            if fail_on == "rank" and any(p.rank_changed for p in file.paths):
                return 1
        return 0

    def exit_reason(self, fail_on: str, code: int) -> str:
        """What the exit code says, in words: ``exit code 1: 1 path verdict(s) changed
        (fail-on verdict)``."""
        changes = self.verdict_changes()
        if code == 0:
            if changes:  # only where nothing is gated (fail-on never)
                return (f"exit code 0: {len(changes)} path verdict(s) changed, not gated "
                        f"(fail-on {fail_on})")
            return f"exit code 0: no verdict changes (fail-on {fail_on})"
        what = []
        if changes:
            what.append(f"{len(changes)} path verdict(s) changed")
        if any(f.first_changed for f in self.files):
            what.append("the first-ranked path changed")
        if not what:
            what.append("a rank changed")
        return f"exit code 1: {', '.join(what)} (fail-on {fail_on})"

    def to_dict(self) -> dict[str, Any]:
        return {"files": [f.to_dict() for f in self.files]}


# ----------------------------------------------------------------------------- one side

@dataclass
class _Side:
    """Working state of one rulebook on one path."""

    evaluator: Any
    result: PathResult
    evaluation: Any = None
    rows: np.ndarray | None = None  # the runs of ``evaluation`` (the path's complete runs)
    statistics: Any = None

    @property
    def evaluates(self) -> bool:
        return self.result.status == "simulated" and self.result.completed > 0


def _gate(side: _Side, chain: tuple[Command, ...], context: dict[str, Any],
          reference: dict[str, np.ndarray] | None, collisions: Any) -> None:
    """Command rules and prescreen of this side's rulebook, as a campaign would apply them,
    with the stored campaign's waivers (as ``evaluate --rulebook`` does: each side is the plan's
    verdict under that rulebook; ``--waivers`` lists the waivers a change touches)."""
    gate_again(side.result, side.evaluator, chain, context["rover"], context["sigma"],
               reference, collisions, context["waivers"], context["units"])


def _side_result(side: _Side) -> SideResult:
    result = side.result
    verdict = NOT_SIMULATED if result.status == NOT_SIMULATED else result.verdict_text
    # in the rulebook's words and percent, as `run` says them
    reasons = tuple(reasons_of(result)) or ((result.reason,) if result.reason else ())
    counts = dict(getattr(side.statistics, "dominant_counts", {}) or {})
    return SideResult(verdict, bool(result.undecided), reasons, result.mean_risk,
                      result.risk_ci, result.rank, dict(result.chances), counts,
                      result.completed if side.evaluation is not None else 0,
                      path_confidence(result))


# ----------------------------------------------------------------------------- one file

def _top_moves(rows: np.ndarray, old: Any, new: Any, top: int
               ) -> tuple[int, int, tuple[RunMove, ...]]:
    """Runs whose I_max changed, dominant-index changes, and the ``top`` largest moves.

    The index responsible for a move is the new dominant index when I_max rose (its weighted
    value rose to the new I_max) and the old dominant index when I_max fell (its weighted value
    fell below the old I_max).
    """
    delta = new.i_max - old.i_max
    moved = np.abs(delta) > MOVE_TOLERANCE
    old_dominant = np.asarray(old.index_names, dtype=object)[old.dominant]
    new_dominant = np.asarray(new.index_names, dtype=object)[new.dominant]
    dominant_changed = int(np.sum(old_dominant != new_dominant))
    order = np.argsort(-np.abs(delta), kind="stable")
    chosen = [int(i) for i in order[:top] if moved[i]]
    moves = tuple(RunMove(int(rows[i]), float(old.i_max[i]), float(new.i_max[i]),
                          str(new_dominant[i] if delta[i] > 0 else old_dominant[i]),
                          str(old_dominant[i]), str(new_dominant[i])) for i in chosen)
    return int(np.sum(moved)), dominant_changed, moves


def diff_results_file(path: Path, old: RulebookSource, new: RulebookSource,
                      top: int = DEFAULT_TOP_RUNS, chunk_runs: int = DEFAULT_CHUNK_RUNS,
                      threads: int = DEFAULT_THREADS, reuse: bool = True) -> ResultsFileDiff:
    """Re-score one stored campaign under ``old`` and ``new``; see the module docstring.
    ``reuse``: take a rulebook's per-run values from the stored evaluation when they are its
    own (False: score every run again)."""
    started = time.perf_counter()
    timings = {"read": 0.0, "collisions": 0.0, "evaluate": 0.0}
    stored = StoredCampaign.open(path)
    runs = ParallelRuns(stored.store, threads)
    try:
        store = stored.store
        campaign = stored.require_campaign()
        context = {"rover": stored.rover, "sigma": stored.sigma,
                   "units": DisplayUnits.from_campaign_text(campaign.text),
                   "waivers": tuple(campaign.model.waivers)}
        evaluators = [values_only(old.checked), values_only(new.checked)]
        digests = [source_sha256(old.checked), source_sha256(new.checked)]
        collisions = CollisionSources(stored, evaluators, (old.checked, new.checked))
        timings["prepare"] = time.perf_counter() - started
        reused: set[int] = set()
        scoring: list[tuple[str, list[_Side], Future[tuple[int, int, tuple[RunMove, ...]]]
                            | None]] = []
        # Two paths are scored at a time: while one path's last chunks are evaluated the
        # next one's first are read, so the cores do not wait at every path's start and end.
        pool = ThreadPoolExecutor(PATHS_AT_ONCE, thread_name_prefix="diff-path")
        try:
            for name in store.path_names:
                sides = [_Side(e, stored_path_result(store, name)) for e in evaluators]
                chain = store.chain(name)
                reference = store.reference(name)
                for position, side in enumerate(sides):
                    _gate(side, chain, context, reference, collisions.function(position))
                pending = None
                if any(side.evaluates for side in sides):
                    from_store = [_stored_side(stored, name, side, digest) if reuse else False
                                  for side, digest in zip(sides, digests, strict=True)]
                    reused |= {i for i, used in enumerate(from_store) if used}
                    scores = any(side.evaluates and side.evaluation is None for side in sides)
                    sources = collisions.for_path(name) if scores else [None] * len(sides)
                    pending = pool.submit(_score_path, stored, runs, name, reference, sides,
                                          sources, chunk_runs, top, timings, threads)
                scoring.append((name, sides, pending))
            path_sides = [(name, sides, (0, 0, ()) if pending is None else pending.result())
                          for name, sides, pending in scoring]
        except BaseException:
            pool.shutdown(cancel_futures=True)  # an error or Ctrl-C: no queued path is scored
            raise
        pool.shutdown()
        _judge(stored, evaluators, path_sides)
        rankings = []
        for position, evaluator in enumerate(evaluators):
            stats = {name: sides[position].statistics for name, sides, _ in path_sides
                     if sides[position].statistics is not None}
            ranking = tuple(evaluator.rank(stats)) if stats else ()
            for name, sides, _ in path_sides:
                result = sides[position].result
                result.rank = ranking.index(name) + 1 if name in ranking else None
            rankings.append(ranking)
        paths = tuple(PathDiff(name, _side_result(sides[0]), _side_result(sides[1]), *moves)
                      for name, sides, moves in path_sides)
        timings["total"] = time.perf_counter() - started
        return ResultsFileDiff(str(path), str(store.attrs.get("campaign_name", "")), paths,
                               rankings[0], rankings[1], collisions.describe(), timings,
                               (*held_warnings(store.attrs, path, campaign.source),
                                *collisions.warnings, *_unplaced_areas(stored, evaluators)),
                               tuple(label for i, label in enumerate(("old", "new"))
                                     if i in reused))
    finally:
        runs.close()
        stored.close()


def _unplaced_areas(stored: StoredCampaign, evaluators: Sequence[Any]) -> list[str]:
    """C210 for each side: an area its rulebook declares that the stored campaign gives no
    polygons (its signals are 0 in every run: a rule reading them holds vacuously)."""
    from idefix_rules.campaign.input.areas import unplaced_area_warnings
    from idefix_rules.campaign.input.fmu_checks import describe_warnings

    campaign = stored.require_campaign()
    return [f"{label} rulebook: {text}" for label, evaluator in zip(("old", "new"), evaluators,
                                                                     strict=True)
            for text in describe_warnings(unplaced_area_warnings(campaign, evaluator),
                                          {str(campaign.source): campaign.text})]


def _stored_side(stored: StoredCampaign, name: str, side: _Side, digest: str) -> bool:
    """Take the side's per-run values from the stored evaluation when they are its own (see
    :func:`~idefix_rules.results.scoring.stored_evaluation`; a path whose stored collisions
    are incomplete is scored again). True when taken."""
    if not side.evaluates:
        return False
    if collision_reads(side.evaluator) and \
            "evaluation/collisions/hits" not in stored.store.path_group(name):
        return False
    found = stored_evaluation(stored.store, name, side.evaluator, digest, __version__)
    if found is None:
        return False
    side.rows, side.evaluation = found
    return True


def _score_path(stored: StoredCampaign, runs: ParallelRuns, name: str,
                reference: dict[str, np.ndarray] | None, sides: list[_Side],
                sources: list[Any], chunk_runs: int, top: int,
                timings: dict[str, float], threads: int
                ) -> tuple[int, int, tuple[RunMove, ...]]:
    """Score the sides that evaluate and have no stored values; statistics and verdicts of
    every side that evaluates; the runs that moved most."""
    scored = [side.evaluator if side.evaluates and side.evaluation is None else None
              for side in sides]
    if any(evaluator is not None for evaluator in scored):
        parts: list[list[Any]] = [[] for _ in sides]
        all_rows = []
        for chunk in score_chunks(runs, name, scored, stored.context(name, reference),
                                  [source if evaluator is not None else None
                                   for source, evaluator in zip(sources, scored, strict=True)],
                                  chunk_runs=chunk_runs, threads=threads, timings=timings):
            all_rows.append(chunk.rows)
            for position, evaluation in enumerate(chunk.evaluations):
                if evaluation is not None:
                    parts[position].append(evaluation)
        rows = np.concatenate(all_rows) if all_rows else np.zeros(0, dtype=np.int64)
        for side, side_parts in zip(sides, parts, strict=True):
            if side_parts:
                side.evaluation, side.rows = concatenate(side_parts), rows
    active = [side for side in sides if side.evaluates and side.evaluation is not None]
    if len(active) == 2 and active[0].rows is not None and active[0].rows.size:
        return _top_moves(active[0].rows, sides[0].evaluation, sides[1].evaluation, top)
    return 0, 0, ()


def _judge(stored: StoredCampaign, evaluators: Sequence[Any],
           path_sides: Sequence[tuple[str, list[_Side], Any]]) -> None:
    """Each rulebook's statistics and verdict of every path it evaluates, with the bounds and
    levels the campaign's evaluation judges with (campaign/statistics/bounds.py): the paths
    together, since a path shown to fail raises the others' levels (budget.py)."""
    store = stored.store
    adaptive = str(store.attrs.get("runs_mode", "fixed")) == "auto"
    paths, paired = ranked_paths(store), drawn_paired(store.attrs)
    waivers = stored.campaign.model.waivers if stored.campaign is not None else ()
    for position, evaluator in enumerate(evaluators):
        active = {name: sides[position] for name, sides, _ in path_sides
                  if sides[position].evaluates and sides[position].evaluation is not None}
        inputs = {name: (side.evaluation, side.result,
                         side.rows if side.rows is not None else np.zeros(0, dtype=np.int64),
                         float(store.path_group(name).attrs.get("stop_time", 0.0)))
                  for name, side in active.items()}
        _, judged = judge_paths(evaluator, inputs, alpha_budget(evaluator, paths, paired),
                                adaptive, waivers)
        for name, side in active.items():
            side.statistics = judged[name][0]
            # the campaign's waivers, as its evaluation applies them: a waived failure is
            # `waived` on both sides, and a change that ends it shows as a verdict change
            verdict, waived = waive_verdict(evaluator.verdict(side.statistics), waivers, name)
            side.result.waivers.extend(waived)
            fill_result(side.result, side.evaluation, side.statistics, verdict,
                        risk_ceiling(evaluator))


def diff_results(paths: Sequence[Path], old: RulebookSource, new: RulebookSource,
                 top: int = DEFAULT_TOP_RUNS, chunk_runs: int = DEFAULT_CHUNK_RUNS,
                 threads: int = DEFAULT_THREADS, reuse: bool = True) -> ResultsDiff:
    """:func:`diff_results_file` for every results file."""
    return ResultsDiff(tuple(diff_results_file(Path(p), old, new, top, chunk_runs, threads,
                                               reuse) for p in paths))


__all__ = ["FAIL_ON", "PathDiff", "ResultsDiff", "ResultsFileDiff", "RunMove", "SideResult",
           "diff_results", "diff_results_file"]
