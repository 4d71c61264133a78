"""The evaluation stage: results.h5 + compiled rulebook → per-run indices, statistics, verdicts.

Runs are read chunk by chunk (memory bounded in the number of runs); only complete runs are
evaluated, failed ones are passed to the rulebook's statistics as ``failed_runs`` so a path with
failed runs cannot silently pass. When the rulebook reads ``collision.*`` signals the obstacle
checker runs on the stored poses of each chunk and its results are stored too.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import h5py
import numpy as np

from idefix_rules.campaign.evaluation.remembered import RememberedCollisions, collision_pieces
from idefix_rules.campaign.evaluation.scoring import decision_pairs, judge_paths, ranked_paths
from idefix_rules.campaign.evaluation.spread import RiskSpread, risk_spread
from idefix_rules.campaign.input.waivers import (
    STORED_ATTRIBUTE,
    WaivedRule,
    to_store,
    waive_verdict,
)
from idefix_rules.campaign.input.waivers import stored as stored_waivers
from idefix_rules.campaign.input.wording import runs_needed_text
from idefix_rules.campaign.simulation.prescreen import run_context
from idefix_rules.campaign.simulation.processes import is_infrastructure
from idefix_rules.campaign.statistics import pairwise
from idefix_rules.campaign.statistics.budget import AlphaBudget, alpha_budget
from idefix_rules.campaign.statistics.runs_needed import runs_needed
from idefix_rules.campaign.statistics.stopping import STOP_FIXED, restated, settled_outcome
from idefix_rules.campaign.storage.store import STATUS_COMPLETE, STATUS_NOT_NEEDED, ResultStore
from idefix_rules.commands import RoverGeometry
from idefix_rules.plain import as_plain
from idefix_rules.results.collisions import (
    CONTACT_COLUMNS,
    ChunkCollisions,
    CollisionFunction,
)
from idefix_rules.results.format import drawn_paired
from idefix_rules.results.reader import StoredResults
from idefix_rules.results.runs import ParallelRuns, complete_rows
from idefix_rules.results.scoring import FirstPassCache, score_chunks
from idefix_rules.signals import AXIS_LABELS

if TYPE_CHECKING:
    from idefix_rules.campaign.input.schema import Waiver

DEFAULT_CHUNK_RUNS = 64
# From this many rows on the evaluation's per-run arrays are stored compressed (shuffle+gzip).
COMPRESSED_ROWS = 1024


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


# The dataset of /evaluation holding the text of the rulebook it was made with.
EVALUATION_RULEBOOK = "rulebook_text"


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


# --- evaluation -------------------------------------------------------------------------------

def without_samples(evaluation: Any) -> Any:
    """The evaluation with its per-sample arrays dropped (they are large; chunks are joined)."""
    empty = {name: np.empty((evaluation.runs, 0)) for name in evaluation.per_sample}
    return dataclasses.replace(evaluation, per_sample=empty)


def concatenate(evaluations: Sequence[Any]) -> Any:
    """One evaluation over all runs from per-chunk evaluations."""
    return type(evaluations[0]).concat(list(evaluations))


def chain_finished(signals: Mapping[str, np.ndarray]) -> np.ndarray | None:
    """Per run (axis 0) whether its chain was complete within the stop time: some sample with
    ``command`` -1, else with ``done`` set (as the evaluator reads a run's time); None when the
    runs have neither signal.

    >>> chain_finished({"command": np.array([[0.0, -1.0, -1.0], [0.0, 1.0, 1.0]])})
    array([ True, False])
    """
    if "command" in signals:
        return np.asarray((np.rint(signals["command"]) == -1).any(axis=1))
    if "done" in signals:
        return np.asarray((np.asarray(signals["done"]) >= 0.5).any(axis=1))
    return None


def evaluate_path(store: StoredResults, name: str, evaluator: Any, rover: RoverGeometry,
                  sigma: float, collisions: CollisionFunction | None,
                  chunk_runs: int = DEFAULT_CHUNK_RUNS, workers: int = 1,
                  within: slice | None = None,
                  across_cache: FirstPassCache | None = None) -> tuple[Any, dict[str, Any]]:
    """Evaluate the complete runs of a path (among the rows ``within``, when given) chunk by
    chunk (:func:`idefix_rules.results.scoring.score_chunks`); returns (evaluation, stored):
    what is stored besides the evaluation (rows, whether each chain finished, collisions).

    ``workers`` > 1 spreads the collision checks over that many processes; ``across_cache``
    keeps the path-level values' first pass for the next call on more runs (an adaptive
    campaign's looks)."""
    context = run_context(store.chain(name), rover, sigma, store.reference(name))
    complete = complete_rows(store.run_status(name), within)
    # an adaptive campaign's checker, keeping the looks' checks for a rulebook that can use them
    remembered = collisions if isinstance(collisions, RememberedCollisions) \
        and collisions.usable_for(evaluator) else None
    known = remembered if remembered is not None and remembered.covers(name, complete) \
        else None  # every run's collisions are kept
    source: ChunkCollisions | None = known.source(name, complete, evaluator) \
        if known is not None else collisions
    parts = []
    hits, buffers, contacts, profiles = [], [], [], []
    details: list[tuple[np.ndarray, np.ndarray]] = []  # per chunk: rows, their JSON texts
    finished: list[np.ndarray | None] = []
    runs = ParallelRuns(store)
    try:
        for chunk in score_chunks(runs, name, [evaluator], context, [source],
                                  chunk_runs=chunk_runs, within=within, workers=workers,
                                  across_chunk_runs=DEFAULT_CHUNK_RUNS,
                                  across_cache=across_cache):
            finished.append(chain_finished(chunk.signals))
            collided = chunk.collisions[0]
            if collided is not None and known is None:
                pieces = collision_pieces(chunk.rows, *collided, chunk.signals.get("t"))
                hits.append(pieces["hits"])
                buffers.append(pieces["buffer"])
                details.extend(pieces["details"])
                if pieces["contact"] is not None:
                    contacts.append(pieces["contact"])
                if pieces["clearance_profile"] is not None:
                    profiles.append(pieces["clearance_profile"])
            parts.append(without_samples(chunk.evaluations[0]))
    finally:
        runs.close()
    evaluation = concatenate(parts) if parts else None
    extra_store: dict[str, Any] = {"rows": complete, "finished": None}
    if finished and all(part is not None for part in finished):
        extra_store["finished"] = np.concatenate([p for p in finished if p is not None])
    if known is not None and parts:
        extra_store.update(known.stored_pieces(name, complete))
    elif collisions is not None and parts:
        extra_store["hits"] = np.concatenate([h for h in hits if h is not None]) \
            if any(h is not None for h in hits) else None
        extra_store["buffer"] = np.concatenate([b for b in buffers if b is not None]) \
            if any(b is not None for b in buffers) else None
        extra_store["details"] = details
        extra_store["contact"] = np.concatenate(contacts) if contacts else None
        extra_store["clearance_profile"] = np.concatenate(profiles) \
            if profiles and len(profiles) == len(parts) else None
        if remembered is not None:
            remembered.record(name, complete, extra_store)
    return evaluation, extra_store


def evaluate_store(store: ResultStore, evaluator: Any, rover: RoverGeometry, sigma: float,
                   collisions: CollisionFunction | None, rulebook_info: dict[str, str],
                   write: bool = True,
                   chunk_runs: int = DEFAULT_CHUNK_RUNS, workers: int = 1,
                   on_path: Callable[[str, int], None] | None = None,
                   into: ResultStore | None = None,
                   waivers: Sequence[Waiver] = (),
                   gate: Callable[[PathResult], None] | None = None) -> CampaignEvaluation:
    """Score every path of a results file; writes the evaluation groups when ``write``, into
    ``into`` when given (a :class:`~idefix_rules.campaign.storage.revision.Revision`'s store, so the
    file read is never written), else into ``store``. ``workers`` processes share the
    collision checks; ``on_path(name, runs)`` is called as each simulated path's evaluation
    starts (progress). ``waivers``: the campaign's; a waived verdict rule counts as held.
    ``gate(result)``: sets a path's status as the campaign would under this rulebook before it
    is scored (:func:`~idefix_rules.campaign.evaluation.gate.gate_again`, for a rulebook other
    than the one the campaign ran with)."""
    target = into if into is not None else store
    results: list[PathResult] = []
    statistics: dict[str, Any] = {}
    run_risks: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    sequential = str(store.attrs.get("runs_mode", "fixed")) == "auto"
    paired = drawn_paired(store.attrs)
    evaluated: dict[str, tuple[Any, PathResult, np.ndarray, float]] = {}
    extras: dict[str, dict[str, Any]] = {}
    for name in store.path_names:
        result = stored_path_result(store, name)
        if gate is not None:
            gate(result)
            if result.status != "simulated" and sequential and result.stop_reason:
                # its looks stopped it on a verdict this rulebook does not give
                result.stop_reason += f"; verdict {result.verdict_text} under this rulebook"
            if write and result.status != "simulated":
                _drop_evaluation(target, name)
        results.append(result)
        if result.status != "simulated" or not store.has_runs(name):
            continue
        if on_path is not None:
            on_path(name, result.completed)
        evaluation, extra = evaluate_path(store, name, evaluator, rover, sigma, collisions,
                                          chunk_runs, workers)
        if evaluation is None:
            result.passed = False
            result.verdict_reasons = ["no complete run to evaluate"]
            if not sequential and not result.stop_reason:  # interrupted before its first run
                result.stop_reason = fixed_stop_reason(result)
            continue
        stop_time = float(store.path_group(name).attrs.get("stop_time", 0.0))
        evaluated[name] = (evaluation, result, np.asarray(extra["rows"]), stop_time)
        extras[name] = extra
    # every path at the budget's levels, raised by the paths shown to fail (budget.py)
    budget, judged = judge_paths(evaluator, evaluated,
                                 alpha_budget(evaluator, ranked_paths(store), paired),
                                 sequential, waivers)
    for name, (evaluation, result, _, stop_time) in evaluated.items():
        extra = extras[name]
        stats, failures = judged[name]
        unwaived = evaluator.verdict(stats)
        verdict, waived = waive_verdict(unwaived, waivers, name)
        if not sequential and not result.stop_reason:
            result.stop_reason = fixed_stop_reason(result)
        elif sequential:  # in the looks' words (statistics/stopping.py)
            # the path's own (prescreen, command) waivers are the result's before the verdict's
            result.stop_reason = restated(result.stop_reason, settled_outcome(
                unwaived, verdict, waived_before=bool(result.waivers)))
        result.waivers.extend(waived)
        statistics[name] = stats
        run_risks[name] = (np.asarray(extra["rows"]), np.asarray(evaluation.i_max))
        fill_result(result, evaluation, stats, verdict, risk_ceiling(evaluator))
        result.stop_time = stop_time
        if extra["finished"] is not None:
            result.unfinished = int(np.sum(~extra["finished"]))
        fill_runs_needed(result, evaluation, verdict, budget, sequential, stop_time, failures)
        if write:
            _write_path_evaluation(target, name, evaluation, extra, stats, verdict,
                                   len(store.run_status(name)), waived, raw_units(evaluator))
    ranking = list(evaluator.rank(statistics)) if statistics else []
    margin = float(getattr(evaluator.checked, "indifference", 0.0))
    pairs = decision_pairs(run_risks, ranking, results, budget, margin, sequential) \
        if paired and pairwise.uses_paired_risk(evaluator.rulebook) else []
    passed = {result.name: bool(result.passed) for result in results}
    ranks, ties = pairwise.shared_ranks(ranking, passed, pairs)
    for result in results:
        if result.name in ranks:
            result.rank = ranks[result.name]
    provenance = {key: as_plain(value) for key, value in store.attrs.items()}
    campaign_eval = CampaignEvaluation(results, ranking, rulebook_info, provenance,
                                       _slip_checks(store, evaluator, rulebook_info),
                                       paired, margin, pairs, ties, budget)
    if write:
        root = target.file.require_group("evaluation")
        for key, value in rulebook_info.items():
            root.attrs[f"rulebook_{key}"] = value
        # the rulebook text this evaluation used (`evaluate --rulebook` judges with another
        # than /provenance/rulebook): what the report draws its limits and maps with
        if EVALUATION_RULEBOOK in root:
            del root[EVALUATION_RULEBOOK]
        root.create_dataset(EVALUATION_RULEBOOK, data=evaluator.checked.rulebook.source,
                            dtype=h5py.string_dtype("utf-8"))
        root.attrs["ranking"] = json.dumps(ranking)
        root.attrs["ties"] = json.dumps(ties)
        from idefix_rules.timestamps import now_iso

        root.attrs["evaluated"] = now_iso()
        target.file.flush()
    return campaign_eval


def _slip_checks(store: ResultStore, evaluator: Any, info: Mapping[str, str]) -> list[Any]:
    """The rulebook's assumed slip beside each reference run's (see campaign/evaluation/slip.py)."""
    settings = getattr(evaluator, "derived_settings", None)
    if settings is None:
        return []
    from idefix_rules.campaign.evaluation.slip import slip_checks

    name = f"rulebook {info.get('name', '')} {info.get('version', '')}".strip()
    return slip_checks(store, float(settings.theoretical_slip), name)


def fill_runs_needed(result: PathResult, evaluation: Any, verdict: Any, budget: AlphaBudget,
                     sequential: bool, stop_time: float,
                     failures: np.ndarray | None = None) -> None:
    """Roughly how many runs would settle each verdict rule that is not decided."""
    result.runs_needed = {
        rule.name: runs_needed(rule, evaluation, budget.levels(rule.statistic or ""),
                               sequential, stop_time, failures,
                               budget.tuned_levels(rule.statistic or ""))
        for rule in verdict.rules if not rule.decided}
    shown = {_reason_text(rule): rule.name for rule in verdict.rules if not rule.decided}
    result.verdict_reasons = [
        f"{text}; {runs_needed_text(result.runs_needed[shown[text]])}" if text in shown else text
        for text in result.verdict_reasons]


def _drop_evaluation(target: ResultStore, name: str) -> None:
    """A path the rulebook scoring it would not simulate (rejected, excluded) keeps no
    evaluation of the rulebook before: the report and readers would show it as current. Its
    status stays the campaign's (what was simulated, so that the next ``evaluate`` gates it
    again from there); what this rulebook says of it is in the summary."""
    group = target.path_group(name)
    if "evaluation" in group:
        del group["evaluation"]


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
        # rows an adaptive campaign never needed are not runs of the path
        result.runs = int(np.sum(status != STATUS_NOT_NEEDED))
        result.completed = int(np.sum(status == STATUS_COMPLETE))
        result.failures = store.failures(name)
    return result


def risk_ceiling(evaluator: Any) -> float:
    """The largest I_max the rulebook can give: its largest index weight (1 without indices)."""
    weights = [float(w) for w in getattr(getattr(evaluator, "checked", None), "weights",
                                         {}).values()]
    return max(weights, default=1.0)


def fill_result(result: PathResult, evaluation: Any, stats: Any, verdict: Any,
                ceiling: float = 1.0) -> None:
    """Copy a path's statistics and verdict into ``result`` (mean risk, chances, reasons …)."""
    result.statistics = stats
    result.verdict = verdict
    risk = stats.risk
    result.mean_risk = _float(risk.value)
    result.risk_ci = (float(risk.low), float(risk.high))
    result.chances = {str(k): float(v.value) for k, v in stats.chances.items()}
    result.collision_chance = collision_chances(result.chances)
    energy = _float(stats.energy.value)  # NaN: the FMU provides no 'energy'
    result.energy = energy if energy is not None and energy == energy else None
    result.time = _float(stats.time.value)
    counts = dict(getattr(stats, "dominant_counts", {}) or {})
    result.dominant_index = max(counts, key=lambda k: counts[k]) if any(counts.values()) \
        else dominant_index(evaluation)
    i_max = getattr(evaluation, "i_max", None)
    result.risk_spread = None if i_max is None else risk_spread(
        result.name, np.asarray(i_max), dict(getattr(evaluation, "values", {}) or {}), ceiling)
    result.passed = bool(verdict.passed)
    result.undecided = not bool(verdict.decided)
    # A decided failure is explained by the rules that fail decidedly; otherwise by the rules
    # that fail or are not decided.
    failed_for_sure = [rule for rule in verdict.rules if not rule.passed and rule.decided]
    shown = failed_for_sure or [rule for rule in verdict.rules
                                if not rule.passed or not rule.decided]
    result.verdict_reasons = [_reason_text(rule) for rule in shown]
    # Failed runs are the rulebook's to judge (a verdict that reads `failed`, else the
    # `no_failed_runs` rule it gets: docs/rulebook-language.md); a run neither complete nor
    # failed (nor lost to the infrastructure) is missing from the results, and a path with one
    # never passes: this is the last guard.
    missing = result.missing
    if missing > 0 and result.passed:
        result.passed = False
        result.verdict_reasons.append(f"{missing} of {result.runs} run(s) missing")


def _reason_text(rule: Any) -> str:
    """``name: message``; the rule's message already says when it is not decided."""
    return f"{rule.name}: {rule.message}"


def _float(value: Any) -> float | None:
    if value is None:
        return None
    try:
        return float(value)
    except (TypeError, ValueError):
        return None


def collision_chances(chances: Mapping[str, float]) -> dict[str, float]:
    """Chance of a collision per level, from the rulebook's chances whose name ends in a level.

    ``hit_L2``, ``collision.L2``, ``collision_L2`` all count as the L2 column.
    """
    found = {}
    for name, value in chances.items():
        for level in AXIS_LABELS["level"]:
            if name.endswith(level) or name.endswith(level.lower()):
                found[level] = value
    return found


def dominant_index(evaluation: Any) -> str | None:
    names = list(getattr(evaluation, "index_names", ()))
    dominant = np.asarray(getattr(evaluation, "dominant", []))
    if not names or dominant.size == 0:
        return None
    valid = dominant[(dominant >= 0) & (dominant < len(names))]
    if valid.size == 0:
        return None
    counts = np.bincount(valid.astype(int), minlength=len(names))
    return str(names[int(np.argmax(counts))])


def raw_units(evaluator: Any) -> dict[str, str]:
    """Each index's value before normalisation in its SI unit ("1": a ratio or a count)."""
    types = getattr(getattr(evaluator, "checked", None), "index_types", {}) or {}
    units = {}
    for name, kind in types.items():
        dimension = getattr(kind, "dimension", None)
        units[str(name)] = "1" if dimension is None or dimension.is_dimensionless \
            else str(dimension)
    return units


def _write_path_evaluation(store: ResultStore, name: str, evaluation: Any,
                           extra: dict[str, Any], stats: Any, verdict: Any, runs: int,
                           waived: Sequence[WaivedRule] = (),
                           units: dict[str, str] | None = None) -> None:
    group = store.path_group(name)
    if "evaluation" in group:
        del group["evaluation"]
    target = group.create_group("evaluation")
    rows = extra["rows"]

    def full(values: np.ndarray, fill: float = np.nan, dtype: Any = np.float64) -> np.ndarray:
        values = np.asarray(values)
        out = np.full((runs, *values.shape[1:]), fill, dtype=dtype)
        out[rows] = values
        return out

    def array(group: h5py.Group, key: str, data: np.ndarray) -> None:
        if runs < COMPRESSED_ROWS:  # small: contiguous costs less than a chunk index
            group.create_dataset(key, data=data)
            return
        # rows of runs not (yet) complete are NaN / 0 and compress to almost nothing
        group.create_dataset(key, data=data, compression="gzip", compression_opts=1,
                             shuffle=True)

    index_names = list(getattr(evaluation, "index_names", ()))
    target.attrs["index_names"] = json.dumps(index_names)
    for section in ("values", "raw"):
        data = getattr(evaluation, section, {}) or {}
        sub = target.create_group("indices" if section == "values" else "raw")
        for key, values in data.items():
            array(sub, key, full(values))
            unit = "1" if section == "values" else (units or {}).get(key)
            if unit is not None:
                sub[key].attrs["unit"] = unit
    array(target, "i_max", full(evaluation.i_max))
    target["i_max"].attrs["unit"] = "1"
    array(target, "dominant", full(evaluation.dominant, -1, np.int16))
    array(target, "time", full(evaluation.time))
    target["time"].attrs["unit"] = "s"
    # 1: the chain was complete within the stop time, 0: still driving at it, -1: not known
    finished = extra.get("finished")
    array(target, "finished", full(finished, -1, np.int8) if finished is not None
          else np.full(runs, -1, dtype=np.int8))
    array(target, "energy", full(evaluation.energy))
    target["energy"].attrs["unit"] = "A·s"
    chances = target.create_group("chances")
    for key, values in (getattr(evaluation, "chances", {}) or {}).items():
        array(chances, key, full(values, 0, np.int8))
    if extra.get("hits") is not None:
        collisions = target.create_group("collisions")
        array(collisions, "hits", full(extra["hits"]))
        if extra.get("buffer") is not None:
            array(collisions, "buffer", full(extra["buffer"]))
        _write_details(collisions, runs, extra.get("details", []))
        if extra.get("contact") is not None:  # per-sample contacts as intervals (format 5)
            table = collisions.create_dataset("contact", data=extra["contact"])
            table.attrs["columns"] = list(CONTACT_COLUMNS)
        if extra.get("clearance_profile") is not None:
            array(collisions, "clearance_profile", full(extra["clearance_profile"]))
            collisions["clearance_profile"].attrs["unit"] = "m"
    target.attrs["statistics"] = json.dumps(as_plain(stats))
    target.attrs["verdict"] = json.dumps(as_plain(verdict))
    # the verdict rules waived on the path, which ``verdict`` leaves out: a reader without the
    # summary (report) still tells a waived path from a passing one
    target.attrs[STORED_ATTRIBUTE] = to_store("", waived)
    store.file.flush()


def _write_details(group: h5py.Group, runs: int,
                   chunks: Sequence[tuple[np.ndarray, np.ndarray]]) -> None:
    """The per-run collision details (``""`` for a run without), written a chunk of runs at a
    time so that only one chunk's texts are ever Python strings."""
    dataset = group.create_dataset("details", shape=(runs,), dtype=h5py.string_dtype("utf-8"))
    for rows, texts in chunks:
        if not len(rows):
            continue
        first, stop = int(rows[0]), int(rows[-1]) + 1
        block = np.full(stop - first, "", dtype=object)
        block[np.asarray(rows) - first] = [text.decode("utf-8") for text in texts]
        dataset[first:stop] = block
