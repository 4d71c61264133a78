"""The evaluation stage: results.h5 + compiled rulebook → per-run indices, statistics, verdicts.

Runs are read chunk by chunk (memory bounded in the number of runs); only complete runs are
evaluated, failed ones are passed to the rulebook's statistics as ``failed_runs`` so a path with
failed runs cannot silently pass. When the rulebook reads ``collision.*`` signals the obstacle
checker runs on the stored poses of each chunk and its results are stored too. What it says of
each path is in :mod:`~idefix_rules.campaign.evaluation.path_result` (filled by
:mod:`~idefix_rules.campaign.evaluation.fill_result`); what it stores, in
:mod:`~idefix_rules.campaign.evaluation.evaluation_datasets`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from idefix_rules.campaign.evaluation.evaluation_datasets import (
    drop_evaluation,
    raw_units,
    write_campaign_evaluation,
    write_path_evaluation,
)
from idefix_rules.campaign.evaluation.fill_result import fill_result, fill_runs_needed, risk_ceiling
from idefix_rules.campaign.evaluation.path_result import (
    CampaignEvaluation,
    PathResult,
    fixed_stop_reason,
    judged_rows,
    stored_path_result,
)
from idefix_rules.campaign.evaluation.remembered import RememberedCollisions, collision_pieces
from idefix_rules.campaign.evaluation.scoring import decision_pairs, judge_paths, ranked_paths
from idefix_rules.campaign.input.waivers import waive_verdict
from idefix_rules.campaign.simulation.prescreen import run_context
from idefix_rules.campaign.statistics import pairwise
from idefix_rules.campaign.statistics.budget import alpha_budget
from idefix_rules.campaign.statistics.stopping import restated, settled_outcome
from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.chain_end import ended, nothing_to_execute
from idefix_rules.commands import Command, RoverGeometry
from idefix_rules.plain import as_plain
from idefix_rules.results.collisions import ChunkCollisions, CollisionFunction
from idefix_rules.results.format import drawn_paired
from idefix_rules.results.reader import StoredResults
from idefix_rules.results.runs import ParallelRuns, complete_rows
from idefix_rules.results.scoring import FirstPassCache, score_chunks

if TYPE_CHECKING:
    from idefix_rules.campaign.input.schema import Waiver

DEFAULT_CHUNK_RUNS = 64


def without_samples(evaluation: Any) -> Any:
    """The evaluation with its per-sample arrays dropped (they are large; chunks are joined)."""
    empty = {name: np.empty((evaluation.runs, 0)) for name in evaluation.per_sample}
    return dataclasses.replace(evaluation, per_sample=empty)


def concatenate(evaluations: Sequence[Any]) -> Any:
    """One evaluation over all runs from per-chunk evaluations."""
    return type(evaluations[0]).concat(list(evaluations))


def chain_finished(signals: Mapping[str, np.ndarray], chain: Sequence[Command]
                   ) -> np.ndarray | None:
    """Per run (axis 0) whether its chain was complete within the stop time
    (:func:`idefix_rules.chain_end.ended`, as the evaluator reads a run's time); None when
    the runs have neither ``command`` nor ``done``.

    >>> one = (Command(0.05, 0.3, 0.0),)
    >>> chain_finished({"command": np.array([[0.0, -1.0, -1.0], [0.0, 0.0, 0.0],
    ...                                      [-1.0, -1.0, -1.0]])}, one)
    array([ True, False, False])
    """
    if "command" not in signals and "done" not in signals:
        return None
    return np.asarray(ended(signals.get("command"), signals.get("done"),
                            started=nothing_to_execute(chain), commands=len(chain)).any(axis=1))


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
            finished.append(chain_finished(chunk.signals, context.chain))
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
                drop_evaluation(target, name)
        results.append(result)
        if result.status != "simulated" or not store.has_runs(name):
            continue
        if on_path is not None:
            on_path(name, result.completed)
        limit = judged_rows(store, name)  # an adaptive path: the rows its looks asked for
        evaluation, extra = evaluate_path(store, name, evaluator, rover, sigma, collisions,
                                          chunk_runs, workers,
                                          within=None if limit is None else slice(0, limit))
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
            write_path_evaluation(target, name, evaluation, extra, stats, verdict,
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
        write_campaign_evaluation(target, evaluator, rulebook_info, ranking, ties)
    return campaign_eval


def _slip_checks(store: ResultStore, evaluator: Any, info: Mapping[str, str]) -> list[Any]:
    """The rulebook's assumed slip beside each reference run's (see campaign/evaluation/slip.py)."""
    settings = getattr(evaluator, "derived_settings", None)
    if settings is None:
        return []
    from idefix_rules.campaign.evaluation.slip import slip_checks

    name = f"rulebook {info.get('name', '')} {info.get('version', '')}".strip()
    return slip_checks(store, float(settings.theoretical_slip), name)

