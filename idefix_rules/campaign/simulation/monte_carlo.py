"""The Monte Carlo runs: each path's values drawn and its runs allocated, then every run
made into a task as the pool takes it and stored as it finishes (:func:`run_and_store`, which
the adaptive looks and the worst-case search use as well)."""

from __future__ import annotations

import heapq
import json
import time
from collections import Counter
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from idefix_rules.campaign.input import sampling
from idefix_rules.campaign.input.campaign_values import nominal_parameters
from idefix_rules.campaign.input.load import Campaign
from idefix_rules.campaign.simulation import resume as resuming
from idefix_rules.campaign.simulation import timeouts as run_timeouts
from idefix_rules.campaign.simulation.pool import Then
from idefix_rules.campaign.simulation.run_stage import (
    FmuSource,
    PathPlan,
    Progress,
    SimulationOptions,
    SimulationSummary,
)
from idefix_rules.campaign.simulation.run_tasks import (
    open_pool,
    pool_results,
    raise_input_problem,
    run_task,
)
from idefix_rules.campaign.simulation.worker import RunTask, simulate
from idefix_rules.campaign.storage import diskspace
from idefix_rules.campaign.storage.dataset_layout import run_bytes
from idefix_rules.campaign.storage.store import STATUS_FAILED, ResultStore

if TYPE_CHECKING:
    from idefix_rules.campaign.evaluation.remembered import RememberedCollisions


def parameter_info(campaign: Campaign, names: list[str]) -> dict[str, dict[str, Any]]:
    parameters = campaign.model.uncertainty.parameters
    info = {}
    for name in names:
        spec = parameters.get(name)
        if spec is None:
            info[name] = {"unit": "", "distribution": json.dumps({"distribution": "fixed"})}
        else:
            unit = str(spec.dimension) if not spec.dimension.is_dimensionless else ""
            info[name] = {"unit": unit, "distribution": spec.model_dump_json()}
    return info


def path_stream(campaign: Campaign, name: str) -> sampling.Stream:
    """The spawn-key prefix path ``name`` draws from (shared by every path when paired)."""
    return sampling.path_stream(name, campaign.model.uncertainty.paired)


def monte_carlo(campaign: Campaign, fmu: FmuSource, fmu_parameters: Mapping[str, float | str],
                plans: list[PathPlan], store: ResultStore, options: SimulationOptions,
                progress: Progress, summary: SimulationSummary) -> None:
    base = {**fmu_parameters, **nominal_parameters(campaign)}
    by_name = {plan.spec.name: plan for plan in plans}
    sampled: dict[str, dict[str, np.ndarray]] = {}
    rows: dict[str, np.ndarray] = {}
    for plan in plans:
        if plan.status != "simulated" or plan.reference is None:
            continue
        name = plan.spec.name
        sampled[name] = sampling.sample_path(campaign.model.uncertainty.parameters,
                                             campaign.model.uncertainty.method, campaign.seed,
                                             path_stream(campaign, name), campaign.runs)
        # created, or (resumed) taken up for the blocks of rows still to allocate
        shapes = {key: tuple(np.shape(value)) for key, value in plan.reference.items()}
        store.allocate_runs(name, campaign.runs, shapes, sampled[name],
                            parameter_info(campaign, list(sampled[name])))
        rows[name] = resuming.runs_to_simulate(store, name, reset=True)
        progress.start_path(name, campaign.runs, campaign.runs - len(rows[name]),
                            int(np.sum(store.run_status(name) == STATUS_FAILED)))
    run_and_store(campaign, PlannedRuns(rows, sampled_task(campaign, fmu, base, by_name,
                                                           sampled)),
                  by_name, store, options, progress, summary)


TaskMaker = Callable[[str, int], RunTask]


@dataclass(frozen=True)
class PlannedRuns:
    """Monte Carlo runs to simulate: per path the rows (run numbers, ascending) and what makes
    a row's task. Iterating gives ``((path, run), task)`` with each task made only when it is
    taken, paths interleaved (every row's runs, then the next row's) so every progress bar
    moves from the start: a pool that takes a task when a worker is free holds a few at a
    time, whatever the number of runs.

    >>> planned = PlannedRuns({"b": np.array([0, 1]), "a": np.array([1])},
    ...                       lambda name, run: f"{name}{run}")
    >>> list(planned), planned.counts()
    ([(('b', 0), 'b0'), (('a', 1), 'a1'), (('b', 1), 'b1')], {'b': 2, 'a': 1})
    """

    rows: Mapping[str, np.ndarray]
    make: TaskMaker

    def counts(self) -> dict[str, int]:
        """The runs to simulate per path."""
        return {name: int(np.size(rows)) for name, rows in self.rows.items()}

    def __iter__(self) -> Iterator[tuple[tuple[str, int], RunTask]]:
        def keys(name: str, rows: np.ndarray) -> Iterator[tuple[int, str]]:
            for run in rows:
                yield int(run), name

        for run, name in heapq.merge(*(keys(name, rows) for name, rows in self.rows.items())):
            yield (name, run), self.make(name, run)


def sampled_task(campaign: Campaign, fmu: FmuSource, base: Mapping[str, float | str],
                 plans: Mapping[str, PathPlan],
                 sampled: Mapping[str, Mapping[str, np.ndarray]],
                 check_of: Callable[[str], str | None] | None = None) -> TaskMaker:
    """What makes the task of run ``run`` of a path: its chain with the run-independent
    parameters ``base`` and the run's row of the path's ``sampled`` values (``check_of``:
    the ``check`` of :func:`run_task` by path name, asked as each task is made)."""
    def make(name: str, run: int) -> RunTask:
        parameters = dict(base)
        parameters.update({key: float(values[run]) for key, values in sampled[name].items()})
        return run_task(campaign, fmu, plans[name], parameters, encode=True,
                        check=check_of(name) if check_of is not None else None, run=run)

    return make


def monte_carlo_pool(campaign: Campaign, plans: Mapping[str, PathPlan], store: ResultStore,
                     options: SimulationOptions) -> Any:
    """A persistent pool for Monte Carlo runs of ``plans`` (each run's default timeout from
    its path), for :func:`run_and_store` to use look after look; the caller closes it."""
    return open_pool(simulate, options, campaign,
                     run_timeouts.monte_carlo_timeouts(dict(plans), store, options.run_timeout),
                     persistent=True)


def run_and_store(campaign: Campaign, tasks: PlannedRuns, plans: Mapping[str, PathPlan],
                  store: ResultStore, options: SimulationOptions, progress: Progress,
                  summary: SimulationSummary, pool: Any = None,
                  remember: RememberedCollisions | None = None) -> None:
    """Simulate Monte Carlo runs and store each as it finishes (``plans`` by name give each
    run's default timeout). Tasks are made as the pool takes them, never listed: the parent's
    memory does not grow with the number of runs. ``pool``: a persistent pool
    (:func:`monte_carlo_pool`) to run them on and leave open; else one for these runs.
    ``remember``: keeps the collision checks the workers made of their runs."""
    remaining = Counter({name: count for name, count in tasks.counts().items() if count})
    if not remaining:
        return
    # Room for every run before the first is simulated: each about as large as its path's
    # reference run once stored (docs/operations.md, "Full disk").
    sizes = {name: run_bytes(plan.reference or {}) for name, plan in plans.items()}

    def needed() -> int:
        return sum(sizes[name] * count for name, count in remaining.items())

    def doing() -> str:
        return f"store the {remaining.total()} runs still to simulate"

    diskspace.require(store.folder, needed(), doing())
    own = pool is None
    if own:
        pool = open_pool(simulate, options, campaign,
                         run_timeouts.monte_carlo_timeouts(dict(plans), store,
                                                           options.run_timeout))
    with diskspace.guard(store.folder, doing, needed=needed), \
            pool_results(pool, tasks, close=own) as results:
        for (name, run), outcome in results:
            if isinstance(outcome, Then):  # a stored run's collision check, by its worker
                if remember is None:
                    continue
                if outcome.ok and outcome.value is not None:
                    remember.record(name, np.array([run], dtype=np.int64), outcome.value)
                elif not outcome.ok and remember.worker_failure is None:
                    # the looks check the runs from now on; no worker is asked again
                    remember.worker_failure = outcome.reason
                    progress.note(f"{name}: the collision check of run {run} failed in "
                                     f"its worker ({outcome.reason}); the looks check the "
                                     "runs from now on")
                continue
            raise_input_problem(campaign, outcome)
            summary.simulated_runs += 1
            started = time.perf_counter()
            if outcome.ok:
                store.write_run(name, run, outcome.value.stored)
                summary.fmu_seconds += outcome.value.seconds
                summary.path_seconds[name] = (summary.path_seconds.get(name, 0.0)
                                              + outcome.value.seconds)
            else:
                store.write_failure(name, run, outcome.reason)
            remaining[name] -= 1
            summary.write_seconds += time.perf_counter() - started
            progress.run_finished(name, outcome.ok)
