"""The results diff: stored runs re-scored under two rulebooks, path by path, no simulation.

For every path of a results file each rulebook first decides whether the path would be run at
all: its command rules on the stored chain (``rejected``) and its prescreen on the stored
reference run (``excluded``). Paths both rulebooks accept are evaluated in one pass over the
stored runs: each chunk of signals is read once (only the signals either rulebook needs) and
evaluated under both. Collision signals come from the stored ``collisions/hits`` when the
obstacle levels and buffers of both rulebooks equal those they were computed with, else from
the obstacle checker on the stored poses (once per chunk when both rulebooks have the same
levels). Then statistics, verdicts and the ranking of each side, and the runs whose I_max moved
most with the index responsible (the one whose weighted value changed most).
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from idefix_rules.campaign.budget import alpha_budget
from idefix_rules.campaign.decision import reasons_of
from idefix_rules.campaign.environment import named_areas
from idefix_rules.campaign.evaluation import (
    PathResult,
    collision_function,
    complete_chunks,
    concatenate,
    fill_result,
    prescreen_reference,
    run_context,
    stored_path_result,
)
from idefix_rules.campaign.runner import stored_campaign
from idefix_rules.campaign.scoring import judge_path, ranked_paths
from idefix_rules.campaign.simulate import initial_position_sigma, rover_geometry
from idefix_rules.campaign.store import STATUS_COMPLETE, ResultStore
from idefix_rules.campaign.stored_terrain import terrain_for_rescoring
from idefix_rules.commands import Command, RoverGeometry
from idefix_rules.diff.evaluators import (
    STORED_COLLISIONS,
    area_reads,
    can_use_stored,
    collision_reads,
    collision_setup,
    ground_key,
    stored_rulebook,
    values_only,
)
from idefix_rules.diff.reader import MappedRuns
from idefix_rules.diff.source import RulebookSource
from idefix_rules.errors import UserInputError, error
from idefix_rules.obstacles.named import all_area_signals
from idefix_rules.rulebook.across import first_pass

DEFAULT_CHUNK_RUNS = 128
DEFAULT_TOP_RUNS = 5
DEFAULT_THREADS = 2
# |Δ I_max| below this is rounding, not a change.
MOVE_TOLERANCE = 1e-9

FailOn = Literal["verdict", "rank", "never"]
FAIL_ON: tuple[str, ...] = ("verdict", "rank", "never")
NOT_SIMULATED = "not simulated"


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

    def to_dict(self) -> dict[str, Any]:
        return {"verdict": self.verdict, "undecided": self.undecided,
                "reasons": list(self.reasons), "mean_risk": self.mean_risk,
                "risk_ci": list(self.risk_ci) if self.risk_ci is not None else None,
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
    warnings: tuple[str, ...] = ()  # about the terrain the collision and area checks used

    @property
    def first_changed(self) -> bool:
        return self.old_ranking[:1] != self.new_ranking[:1]

    def to_dict(self) -> dict[str, Any]:
        return {"results": self.results, "campaign": self.campaign,
                "paths": [p.to_dict() for p in self.paths],
                "old_ranking": list(self.old_ranking), "new_ranking": list(self.new_ranking),
                "first_changed": self.first_changed, "collisions": self.collisions,
                "timings": dict(self.timings), "warnings": list(self.warnings)}


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

    def to_dict(self) -> dict[str, Any]:
        return {"files": [f.to_dict() for f in self.files]}


# ----------------------------------------------------------------------------- one side

@dataclass
class _Side:
    """Working state of one rulebook on one path."""

    evaluator: Any
    result: PathResult
    parts: list[Any] = field(default_factory=list)
    evaluation: Any = None
    statistics: Any = None

    @property
    def evaluates(self) -> bool:
        return self.result.status == "simulated" and self.result.completed > 0


def _gate(side: _Side, chain: tuple[Command, ...], context: dict[str, Any],
          reference: dict[str, np.ndarray] | None, collisions: Any) -> None:
    """Command rules and prescreen of this side's rulebook, as a campaign would apply them."""
    result = side.result
    violations = side.evaluator.check_chain(chain, context["rover"])
    if violations:
        result.status, result.reason = "rejected", violations[0].message
        return
    if reference is None:
        return  # the stored status says why (reference failed, pending)
    findings = prescreen_reference(side.evaluator, chain, context["rover"], context["sigma"],
                                   reference, collisions)
    if findings:
        result.status, result.reason = "excluded", findings[0].message
    elif result.status in ("rejected", "excluded"):
        result.status = NOT_SIMULATED
        result.reason = ("the stored campaign did not simulate this path; this rulebook "
                         "would: run the campaign to compare")


def _side_result(side: _Side) -> SideResult:
    result = side.result
    verdict = NOT_SIMULATED if result.status == NOT_SIMULATED else result.verdict_text
    # in the rulebook's words and percent, as `run` says them
    reasons = tuple(reasons_of(result)) or ((result.reason,) if result.reason else ())
    counts = dict(getattr(side.statistics, "dominant_counts", {}) or {})
    return SideResult(verdict, bool(result.undecided), reasons, result.mean_risk,
                      result.risk_ci, result.rank, dict(result.chances), counts,
                      result.completed if side.evaluation is not None else 0)


# ----------------------------------------------------------------------------- collisions

class _Collisions:
    """Collision signals per chunk for each side: stored, or checked once per distinct level
    set."""

    def __init__(self, store: ResultStore, results: Path, evaluators: Sequence[Any],
                 sources: Sequence[RulebookSource], environment: Any) -> None:
        self.evaluators = list(evaluators)
        self.needed = [bool(collision_reads(e) or area_reads(e)) for e in evaluators]
        self._areas: dict[tuple[Any, ...], dict[str, Any]] = {}
        self.store, self.results, self.environment = store, results, environment
        self._functions: dict[tuple[Any, ...], Any] = {}
        self._terrain: Any = None
        # what the user should know about the terrain the checks stand on (an older file
        # holding none, a DEM changed since the simulation)
        self.warnings: list[str] = []
        self.recomputed_paths: list[str] = []
        self.mode = "none"
        if not any(self.needed):
            return
        stored = stored_rulebook(store, [s.checked for s in sources])
        keys = [ground_key(e.checked, self._named_areas(e)) for e in self.evaluators]
        stored_key = ground_key(stored, self._named_areas(stored)) if stored is not None \
            else None
        self.mode = "stored" if can_use_stored(evaluators, stored_key, keys) else "recomputed"

    def describe(self) -> str:
        """``none``, ``stored``, ``recomputed``, or ``stored (recomputed for: a, b)``."""
        if self.mode == "stored" and self.recomputed_paths:
            return f"stored (recomputed for: {', '.join(self.recomputed_paths)})"
        return self.mode

    def function(self, position: int) -> Any:
        """The obstacle checker of side ``position`` (None when its rulebook reads no
        collisions); one per distinct set of obstacle levels, built on first use."""
        if not self.needed[position]:
            return None
        evaluator = self.evaluators[position]
        key = collision_setup(evaluator.checked)
        if key not in self._functions:
            self._functions[key] = collision_function(self.environment, evaluator,
                                                      self._ground())
        return self._functions[key]

    def _ground(self) -> Any:
        """The terrain the campaign was simulated on, read once from the results file
        (None: the rocks on the flat datum, for an older file without one)."""
        if self._terrain is None:
            ground = terrain_for_rescoring(self.store.file, self.results)
            self._terrain = ground.terrain or False
            self.warnings.extend(ground.warnings)
        return self._terrain or None

    def _area_signals(self, position: int, signals: dict[str, np.ndarray]
                      ) -> dict[str, np.ndarray]:
        """The named areas' signals of side ``position`` from the chunk's poses (never stored:
        they are cheap to compute and follow the side's own area declarations)."""
        evaluator = self.evaluators[position]
        if not area_reads(evaluator):
            return {}
        return all_area_signals(self._named_areas(evaluator), signals, RoverGeometry())

    def _named_areas(self, evaluator: Any) -> dict[str, Any]:
        """The named areas of a rulebook (compiled or checked) on this campaign's ground."""
        checked = getattr(evaluator, "checked", evaluator)
        key = collision_setup(checked)
        if key not in self._areas:
            if not checked.areas:
                self._areas[key] = {}
            else:
                self._areas[key] = named_areas(self.environment, checked, self._ground())
        return self._areas[key]

    def stored_for(self, store: ResultStore, name: str) -> dict[str, np.ndarray] | None:
        """The stored collision arrays of a path, or None when they are missing or partial."""
        if self.mode != "stored":
            return None
        group = store.path_group(name).get("evaluation/collisions")
        if group is None:
            return None
        status = store.run_status(name)
        complete = status == STATUS_COMPLETE
        wanted = set().union(*(collision_reads(e) for e in self.evaluators))
        arrays = {}
        for signal, dataset in STORED_COLLISIONS.items():
            if dataset not in group:
                if signal in wanted:
                    return None
                continue
            values = np.asarray(group[dataset][()])
            if values.shape[0] != status.shape[0] or not np.all(np.isfinite(values[complete])):
                return None
            arrays[signal] = values
        return arrays

    def chunk(self, signals: dict[str, np.ndarray], rows: np.ndarray,
              stored: dict[str, np.ndarray] | None) -> list[dict[str, np.ndarray]]:
        """The collision signals of each side for one chunk (empty dict: none needed)."""
        if stored is not None:
            picked = {key: values[rows] for key, values in stored.items()}
            return [{**picked, **self._area_signals(position, signals)} if needed else {}
                    for position, needed in enumerate(self.needed)]
        computed: dict[int, dict[str, np.ndarray]] = {}
        out: list[dict[str, np.ndarray]] = []
        for position in range(len(self.needed)):
            function = self.function(position)
            if function is None:
                out.append({})
                continue
            if id(function) not in computed:
                computed[id(function)] = function(signals)[0]
            out.append(computed[id(function)])
        return out


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
                      threads: int = DEFAULT_THREADS) -> ResultsFileDiff:
    """Re-score one stored campaign under ``old`` and ``new``; see the module docstring."""
    started = time.perf_counter()
    timings = {"read": 0.0, "collisions": 0.0, "evaluate": 0.0}
    store = ResultStore.open(path)
    try:
        try:
            campaign = stored_campaign(store)
        except (KeyError, ValueError) as failure:
            raise UserInputError(error(
                "D010", f"{path}: the stored campaign cannot be read back: {failure}")) from None
        context = {"rover": rover_geometry(campaign), "sigma": initial_position_sigma(campaign)}
        evaluators = [values_only(old.checked), values_only(new.checked)]
        collisions = _Collisions(store, path, evaluators, (old, new),
                                 campaign.model.environment)
        required = set().union(*(e.required_signals | e.optional_signals for e in evaluators))
        prepared = time.perf_counter()
        timings["prepare"] = prepared - started
        path_sides: list[tuple[str, list[_Side], tuple[int, int, tuple[RunMove, ...]]]] = []
        for name in store.path_names:
            sides = [_Side(e, stored_path_result(store, name)) for e in evaluators]
            group = store.path_group(name)
            chain = tuple(Command(*row) for row in group["chain"][()])
            reference = store.reference(name)
            for position, side in enumerate(sides):
                _gate(side, chain, context, reference, collisions.function(position))
            moves: tuple[int, int, tuple[RunMove, ...]] = (0, 0, ())
            active = [side for side in sides if side.evaluates]
            if active:
                moves = _evaluate_path(store, name, chain, reference, sides, active, context,
                                       collisions, required, chunk_runs, top, timings,
                                       threads)
            path_sides.append((name, sides, moves))
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
                               tuple(collisions.warnings))
    finally:
        store.close()


def _evaluate_chunk(sides: list[_Side], active: list[_Side], signals: dict[str, np.ndarray],
                    extra: list[dict[str, np.ndarray]], context: Any,
                    across: dict[int, Any] | None = None) -> list[Any]:
    """One chunk under every active side (their evaluations, in order). Sides with equal
    derived settings and the same collision signals share one signal source: derived signals
    are computed once, and so is every index value or chance the two rulebooks write the same
    (same expression, same constant values). ``across``: each side's path-level values, by
    position in ``sides``."""
    sources: dict[tuple[Any, int], tuple[Any, dict[Any, Any]]] = {}
    parts = []
    for position, (side, collision_signals) in enumerate(zip(sides, extra, strict=True)):
        if side not in active:
            continue
        chunk = {**signals, **collision_signals} if collision_signals else signals
        evaluator = side.evaluator
        key = (evaluator.derived_settings, id(collision_signals) if collision_signals else 0)
        if key not in sources:
            sources[key] = (evaluator.derived_signals(chunk, context), {})
        source, shared = sources[key]
        parts.append(evaluator.evaluate(chunk, context, per_sample=False, source=source,
                                        shared=shared, across=(across or {}).get(position)))
    return parts


def _evaluate_path(store: ResultStore, name: str, chain: tuple[Command, ...],
                   reference: dict[str, np.ndarray] | None, sides: list[_Side],
                   active: list[_Side], context: dict[str, Any], collisions: _Collisions,
                   required: set[str], chunk_runs: int, top: int,
                   timings: dict[str, float], threads: int
                   ) -> tuple[int, int, tuple[RunMove, ...]]:
    run_context_ = run_context(chain, context["rover"], context["sigma"], reference)
    stored = collisions.stored_for(store, name)
    if collisions.mode == "stored" and stored is None:
        collisions.recomputed_paths.append(name)  # not stored for every run: check them
    poses = collisions.mode == "recomputed" or (collisions.mode == "stored" and stored is None)
    all_rows = []
    runs = MappedRuns(store)
    # Path-level values (reductions over runs) of each side: a first pass over the runs.
    evaluating = [side.evaluator if side in active else None for side in sides]
    across = dict(enumerate(first_pass(
        evaluating, lambda names: (signals for _, signals in complete_chunks(
            runs, name, names, chunk_runs, False)), run_context_)))
    pending: deque[Future[list[Any]]] = deque()

    def collect(future: Future[list[Any]]) -> None:
        for side, part in zip(active, future.result(), strict=True):
            side.parts.append(part)

    # Chunks are evaluated on worker threads (numpy releases the GIL in its loops), at most
    # ``threads`` in flight so memory stays bounded; parts are collected in chunk order.
    pool = ThreadPoolExecutor(max_workers=threads) if threads > 1 else None

    def submit(*args: Any) -> Future[list[Any]]:
        if pool is not None:
            return pool.submit(_evaluate_chunk, *args)
        future: Future[list[Any]] = Future()
        future.set_result(_evaluate_chunk(*args))
        return future

    try:
        mark = time.perf_counter()
        for rows, signals in complete_chunks(runs, name, required, chunk_runs, poses):
            now = time.perf_counter()
            timings["read"] += now - mark
            extra = collisions.chunk(signals, rows, stored)
            mark = time.perf_counter()
            timings["collisions"] += mark - now
            pending.append(submit(sides, active, signals, extra, run_context_, across))
            all_rows.append(rows)
            while len(pending) >= max(1, threads):
                collect(pending.popleft())
            now = time.perf_counter()
            timings["evaluate"] += now - mark
            mark = now
        while pending:
            collect(pending.popleft())
        timings["evaluate"] += time.perf_counter() - mark
    finally:
        if pool is not None:
            pool.shutdown(cancel_futures=True)
        runs.close()
    adaptive = str(store.attrs.get("runs_mode", "fixed")) == "auto"
    stop_time = float(store.path_group(name).attrs.get("stop_time", 0.0))
    paths, paired = ranked_paths(store), bool(store.attrs.get("paired", False))
    rows = np.concatenate(all_rows) if all_rows else np.zeros(0, dtype=np.int64)
    for side in active:
        result = side.result
        side.evaluation = concatenate(side.parts)
        side.parts = []
        # the bounds the evaluation of the campaign judges with (campaign/bounds.py)
        side.statistics, _ = judge_path(side.evaluator, side.evaluation, result, rows,
                                        stop_time, alpha_budget(side.evaluator, paths, paired),
                                        adaptive)
        fill_result(result, side.evaluation, side.statistics,
                    side.evaluator.verdict(side.statistics))
    if len(active) == 2 and all_rows:
        return _top_moves(np.concatenate(all_rows), sides[0].evaluation, sides[1].evaluation,
                          top)
    return 0, 0, ()


def diff_results(paths: Sequence[Path], old: RulebookSource, new: RulebookSource,
                 top: int = DEFAULT_TOP_RUNS, chunk_runs: int = DEFAULT_CHUNK_RUNS,
                 threads: int = DEFAULT_THREADS) -> ResultsDiff:
    """:func:`diff_results_file` for every results file."""
    return ResultsDiff(tuple(diff_results_file(Path(p), old, new, top, chunk_runs, threads)
                             for p in paths))


__all__ = ["FAIL_ON", "PathDiff", "ResultsDiff", "ResultsFileDiff", "RunMove", "SideResult",
           "diff_results", "diff_results_file"]
