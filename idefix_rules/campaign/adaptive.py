"""The Monte Carlo stage of an adaptive campaign (``runs: auto``): batches, looks, stops.

Every path still running gets the runs up to the next look (``min_runs``, then every
``batch_runs``, at most ``max_runs``); once all of them are stored, the new runs are evaluated,
every ranked path's statistics are put on confidence sequences and
:func:`~idefix_rules.campaign.statistics.stopping.settle` says which paths stop
(docs/campaign-format.md, "Adaptive campaigns"). A stopped path's remaining rows are marked
``not needed`` in ``runs/status``.

Determinism: run ``j`` of a path always draws from ``SeedSequence(seed, spawn_key=(*s, j))``
with the path's stream ``s`` (``()`` for every path of a paired campaign: run ``j`` is the same
world for every path; :mod:`idefix_rules.campaign.input.sampling`). Runs are independent of each
other (the confidence sequences need them, so a Latin hypercube or Sobol design of
the campaign is not used here), and a look reads exactly the runs below its run count in run
order. The stopping point therefore depends on the seed only, never on the number of workers,
the backend or the order runs finish in. ``--resume`` replays the looks on the stored runs, which
gives the same decisions, and simulates only what is missing.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from idefix_rules.campaign.evaluation.evaluate import (
    DEFAULT_CHUNK_RUNS,
    concatenate,
    evaluate_path,
)
from idefix_rules.campaign.evaluation.remembered import RememberedCollisions, run_collisions
from idefix_rules.campaign.evaluation.scoring import failing_paths
from idefix_rules.campaign.input import sampling, waivers
from idefix_rules.campaign.input.campaign_values import initial_position_sigma, nominal_parameters
from idefix_rules.campaign.simulation.monte_carlo import (
    PlannedRuns,
    monte_carlo_pool,
    parameter_info,
    path_stream,
    run_and_store,
    sampled_task,
)
from idefix_rules.campaign.simulation.pool import LocalPool
from idefix_rules.campaign.simulation.resume import is_infrastructure, runs_to_simulate
from idefix_rules.campaign.simulation.run_stage import (
    FmuSource,
    PathPlan,
    Progress,
    SimulationOptions,
    SimulationSummary,
)
from idefix_rules.campaign.simulation.run_tasks import local_workers
from idefix_rules.campaign.simulation.worker import run_checks
from idefix_rules.campaign.statistics import pairwise
from idefix_rules.campaign.statistics.bounds import failure_sequence, judged_statistics
from idefix_rules.campaign.statistics.budget import AlphaBudget, alpha_budget, recycled
from idefix_rules.campaign.statistics.stopping import expected_paths, settle, stop_reason
from idefix_rules.campaign.storage.store import (
    STATUS_COMPLETE,
    STATUS_FAILED,
    ResultStore,
)
from idefix_rules.commands import RoverGeometry
from idefix_rules.results.scoring import FirstPassCache

NO_COMPLETE_RUN = "stopped: no run of the path completed"


def adaptive_monte_carlo(campaign: Any, evaluator: Any, rover: RoverGeometry, fmu: FmuSource,
                         fmu_parameters: Mapping[str, float | str], plans: list[PathPlan],
                         store: ResultStore, options: SimulationOptions, progress: Progress,
                         summary: SimulationSummary, collisions: Any = None) -> None:
    """Simulate in batches until every path is stopped (decided, or at ``max_runs``)."""
    settings = campaign.adaptive
    base = {**fmu_parameters, **nominal_parameters(campaign)}
    sampled: dict[str, dict[str, np.ndarray]] = {}
    running: dict[str, PathPlan] = {}
    for plan in plans:
        if plan.status != "simulated" or plan.reference is None:
            continue
        name = plan.spec.name
        values = sampling.sample_path(campaign.model.uncertainty.parameters,
                                      sampling.ADAPTIVE_SAMPLING, campaign.seed,
                                      path_stream(campaign, name), settings.max_runs)
        # created, or (resumed) taken up for the blocks of rows still to allocate
        shapes = {key: tuple(np.shape(value)) for key, value in plan.reference.items()}
        store.allocate_runs(name, settings.max_runs, shapes, values,
                            parameter_info(campaign, list(values)))
        sampled[name] = values
        running[name] = plan
        runs_to_simulate(store, name, reset=True)  # lost to the infrastructure: to simulate
        # the looks are replayed from the first: where a path stops is theirs to say again
        # (the same place, bit for bit; a stop a file of an earlier version made on runs that
        # were then lost is not kept)
        store.unmark_not_needed(name)
        status = store.run_status(name)
        # rows a stop before a --resume marked not needed are no runs stored (the looks
        # replayed stop the path there again)
        progress.start_path(name, settings.max_runs,
                            int(np.sum((status == STATUS_COMPLETE) | (status == STATUS_FAILED))),
                            int(np.sum(status == STATUS_FAILED)), up_to=True)
    parts: dict[str, list[Any]] = {name: [] for name in running}
    rows: dict[str, list[np.ndarray]] = {name: [] for name in running}
    drawn_paired = bool(campaign.model.uncertainty.paired)
    paired = drawn_paired and pairwise.uses_paired_risk(evaluator.rulebook)
    budget = alpha_budget(evaluator, len(running), drawn_paired)
    done = dict.fromkeys(running, 0)
    statistics: dict[str, Any] = {}
    sigma = initial_position_sigma(campaign)
    # the paths the campaign's expectations name: their verdicts are decided, never left
    # open as moot (statistics/stopping.py); None: the exit code reads every verdict
    watched = expected_paths(campaign.model.expect) if campaign.model.expect else None
    # a path not simulated (rejected, excluded, its reference run failed for a reason of its
    # own) is no pass: without expectations the exit code is 1 whatever the open verdicts say;
    # a reference run lost to the infrastructure is not (exit code 3, and --resume runs it)
    exit_failing = any(makes_exit_failing(plan.status, plan.reason) for plan in plans)
    # a reference run lost to the infrastructure: its path joins the looks after --resume,
    # so the looks run now would judge one path too few (the levels, the comparisons) and
    # could stop the others where an undisturbed campaign would not
    lost_reference = next(
        (f"not judged: the reference run of {plan.spec.name} was lost to the infrastructure; "
         "--resume simulates it and goes on" for plan in plans
         if plan.status == "reference_failed" and is_infrastructure(plan.reason)), None)
    # the paths simulated under a waived command or prescreen rule: `waived` whatever their
    # verdict, they rank below every chain that passes clean (campaign/outcome/decision.py)
    waived_before = {name for name in running
                     if waivers.stored(str(store.path_group(name).attrs.get(
                         waivers.STORED_ATTRIBUTE, "")))}
    # the workers check each run they simulate (local pool); a look's new runs not checked
    # so (Dask, runs stored before a --resume) are split over the local processes for their
    # collision checks (the pool waits meanwhile; at most 64 runs a chunk); each chunk's
    # checks depend on its poses alone, and the first pass of reductions over runs keeps
    # chunks of 64 whatever the split (its sums depend on the chunking in the last bit)
    checkers = local_workers(options, campaign)
    # the path-level values' first pass over every run so far: each look folds its new
    # whole chunks onto those of the looks before (the same sums, bit for bit)
    across_cache = FirstPassCache()
    # what each path was last judged on (its runs up to its last look), to judge it again
    # when the chains shown to fail raise the levels (statistics/budget.py), stopped or not
    judged: dict[str, tuple[Any, Any, float, np.ndarray]] = {}
    if lost_reference is not None:  # no look: P paths are judged together, not P - 1
        for name in running:
            _pause(store, name, 0, lost_reference)
            progress.note(f"{name}: {lost_reference}")
        running = {}
    # one pool for every look: its workers keep their loaded FMU from batch to batch
    with contextlib.ExitStack() as stack:
        pool = stack.enter_context(contextlib.closing(
            monte_carlo_pool(campaign, running, store, options))) if running else None
        # its workers are forked at its first map, after this: they hold the check
        remember = collisions if _checked_in_workers(collisions, evaluator, pool) else None
        check = stack.enter_context(run_checks(
            functools.partial(run_collisions, remember.checker))) \
            if remember is not None else None
        for look in settings.looks():
            if not running:
                break
            for name in running:  # the rows this look asks for: the path's runs so far
                store.path_group(name).attrs["runs_used"] = look
            _simulate_rows(campaign, fmu, base, running, sampled, done, look, store, options,
                           progress, summary, pool, check, remember)
            lost = {name: _lost_below(store, name, look) for name in running}
            if any(lost.values()):
                # a look judges every row below it: with rows lost it would judge fewer runs
                # than an undisturbed campaign, and stop on it; no path is judged at this
                # look, none is stopped for good, and --resume replays the looks from the
                # first with the lost runs simulated (the same decisions, bit for bit)
                paused = lost_reason(look, sum(lost.values()))
                for name in running:
                    _pause(store, name, look, paused)
                    progress.note(f"{name}: {paused}")
                break
            for name, plan in running.items():
                new = look - done[name]  # rows; the complete ones among them are checked
                evaluation, extra = evaluate_path(store, name, evaluator, rover, sigma,
                                                  collisions, within=slice(done[name], look),
                                                  workers=checkers,
                                                  chunk_runs=min(DEFAULT_CHUNK_RUNS, max(
                                                      8, -(-new // checkers))),
                                                  across_cache=across_cache)
                if evaluation is not None:
                    parts[name].append(evaluation)
                    rows[name].append(np.asarray(extra["rows"]))
                done[name] = look
                if parts[name]:
                    whole = concatenate(parts[name])
                    # runs lost to the infrastructure are no failure of the path's
                    failed = np.array(sorted(
                        run for run, reason in store.failures(name).items()
                        if run < look and not is_infrastructure(reason)), dtype=np.int64)
                    fixed = evaluator.path_statistics(whole, failed_runs=failed.size)
                    judged[name] = (whole, fixed, plan.stop_time,
                                    failure_sequence(np.concatenate(rows[name]), failed))
                    statistics[name] = judged_statistics(*judged[name][:3], budget,
                                                         sequential=True,
                                                         failures=judged[name][3])
            budget = _raised(budget, statistics, judged, evaluator, campaign.model.waivers)
            pairs = pairwise.compare_pairs(
                {name: (np.concatenate(rows[name]),
                        np.asarray(concatenate(parts[name]).i_max)) for name in statistics},
                list(statistics), budget.comparison_alpha,
                evaluator.checked.indifference, tuned=budget.comparison_tuned) if paired else []
            settlements = settle(evaluator, statistics, pairs, watched=watched,
                                 waivers=campaign.model.waivers, waived_before=waived_before,
                                 levels_final=budget.at_floor, exit_failing=exit_failing,
                                 # at the cap nothing goes on: no level can rise after it
                                 running=running if look < settings.max_runs else ())
            for name in list(running):
                settlement = settlements.get(name)
                reason = NO_COMPLETE_RUN if settlement is None else \
                    stop_reason(settlement, look, settings.max_runs)
                if reason is None:
                    continue
                _stop(store, name, look, reason)
                progress.note(f"{name}: {reason}")
                del running[name]


def makes_exit_failing(status: str, reason: str) -> bool:
    """Whether a path the looks do not judge makes the exit code 1 already: rejected,
    excluded, or its reference run failed for a reason of its own; not one whose reference run
    was lost to the infrastructure (exit code 3; ``--resume`` runs it again).

    >>> [makes_exit_failing(*s) for s in (("simulated", ""), ("rejected", "prescreen"),
    ...  ("reference_failed", "the simulation process crashed (SIGSEGV)"),
    ...  ("reference_failed", "infrastructure: killed by SIGKILL 3 times"))]
    [False, True, True, False]
    """
    if status in ("rejected", "excluded"):
        return True
    return status == "reference_failed" and not is_infrastructure(reason)


def _raised(budget: AlphaBudget, statistics: dict[str, Any],
            judged: Mapping[str, tuple[Any, Any, float, np.ndarray]], evaluator: Any,
            waivers: Sequence[Any]) -> AlphaBudget:
    """The budget raised by the paths shown to fail so far (statistics/budget.py,
    ``recycled``; ``statistics`` are judged at ``budget`` already): every path (``judged``:
    what each was last judged on, a stopped path's runs up to its stop) is judged again at
    each raised level, in ``statistics``, as the evaluation stage will judge it at the end."""
    current = budget

    def failing(at: AlphaBudget) -> list[str]:
        nonlocal current
        if at.per_path != current.per_path:  # the levels moved (not once at their floor)
            current = at
            for name, (whole, fixed, stop_time, failures) in judged.items():
                statistics[name] = judged_statistics(whole, fixed, stop_time, at,
                                                     sequential=True, failures=failures)
        return failing_paths(evaluator, statistics, waivers)

    return recycled(budget, failing)


def _simulate_rows(campaign: Any, fmu: FmuSource, base: Mapping[str, float | str],
                   running: Mapping[str, PathPlan], sampled: Mapping[str, dict[str, np.ndarray]],
                   done: Mapping[str, int], look: int, store: ResultStore,
                   options: SimulationOptions, progress: Progress,
                   summary: SimulationSummary, pool: Any, check: str | None = None,
                   remember: RememberedCollisions | None = None) -> None:
    """Simulate and store every missing run below ``look`` of the running paths (each
    checked for collisions by its worker too, when ``check`` names the workers' check)."""
    rows = {}
    for name in running:
        # stored before a --resume: skipped; lost to the infrastructure: simulated again
        missing = runs_to_simulate(store, name, reset=True)
        rows[name] = missing[(missing >= done[name]) & (missing < look)]

    def check_of(name: str) -> str | None:
        """The check token a task of path ``name`` carries, asked as each task is made: none
        for a path over the memory budget for kept checks (its looks check it), and none for
        any path once a check failed in a worker."""
        if remember is None or name in remember.given_up or remember.worker_failure:
            return None
        return check

    run_and_store(campaign, PlannedRuns(rows, sampled_task(campaign, fmu, base, running, sampled,
                                                           check_of)),
                  running, store, options, progress, summary, pool, remember)


def _checked_in_workers(collisions: Any, evaluator: Any, pool: Any) -> bool:
    """Whether the workers check each run's collisions where they simulate it: the looks
    then score their runs with the checks kept (no second pass over the poses, no processes
    forked for it at every look). Only on a local pool whose workers are forked, holding the
    check; on Dask or spawned workers every look checks its runs."""
    return (isinstance(collisions, RememberedCollisions) and collisions.usable_for(evaluator)
            and isinstance(pool, LocalPool) and pool.forks)


def lost_reason(look: int, lost: int) -> str:
    """Why the looks ended at ``look`` rows with ``lost`` runs below it lost to the
    infrastructure.

    >>> lost_reason(32, 3).split("; ")
    ['not judged after 32 runs: 3 runs of the campaign lost to the infrastructure', \
'--resume simulates them and goes on']
    """
    what = "1 run" if lost == 1 else f"{lost} runs"
    return (f"not judged after {look} runs: {what} of the campaign lost to the infrastructure; "
            "--resume simulates them and goes on")


def _lost_below(store: ResultStore, name: str, look: int) -> int:
    """How many of path ``name``'s rows below ``look`` were lost to the infrastructure."""
    return sum(1 for run, reason in store.failures(name).items()
               if run < look and is_infrastructure(reason))


def _pause(store: ResultStore, name: str, runs: int, reason: str) -> None:
    """Record that the looks ended at ``runs`` rows without judging path ``name``: its rows
    from there on stay to simulate (``--resume`` goes on)."""
    group = store.path_group(name)
    group.attrs["runs_used"] = runs
    group.attrs["stop_reason"] = reason
    store.file.flush()


def _stop(store: ResultStore, name: str, runs: int, reason: str) -> None:
    """Record that a path stopped after ``runs`` runs and why; later rows are not needed."""
    store.mark_not_needed(name, runs)
    group = store.path_group(name)
    group.attrs["runs_used"] = runs
    group.attrs["stop_reason"] = reason
    store.file.flush()
