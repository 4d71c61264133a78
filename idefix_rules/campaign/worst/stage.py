"""The worst-case search as the simulation stage of a campaign (after its reference runs).

Each round, every path still searching asks its :class:`~.search.PathSearch` for a batch of
worlds; all batches are simulated together on the campaign's pool (local processes or Dask,
:func:`~idefix_rules.campaign.simulation.monte_carlo.run_and_store`) and stored as the path's next
rows of runs, like Monte Carlo runs, with the values each world gives its parameters; then each
path's new runs are evaluated with the rulebook and their run risks told to its search. Rows the
search did not need are marked *not needed*, as an adaptive campaign marks them.

Reproducible whatever the worker count or backend: a path's search draws from its own generator,
``SeedSequence(seed, spawn_key=(WORST_STREAM, h))`` with ``h`` the first 32 bits of the sha256
of the path's name, and a round waits for all of its runs, which are evaluated in row order.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import h5py
import numpy as np

from idefix_rules.campaign.evaluation.evaluate import evaluate_path
from idefix_rules.campaign.input import sampling
from idefix_rules.campaign.input.campaign_values import initial_position_sigma, nominal_parameters
from idefix_rules.campaign.input.distributions import Fixed
from idefix_rules.campaign.input.load import Campaign
from idefix_rules.campaign.simulation.monte_carlo import (
    PlannedRuns,
    TaskMaker,
    monte_carlo_pool,
    parameter_info,
    run_and_store,
)
from idefix_rules.campaign.simulation.prescreen import run_context
from idefix_rules.campaign.simulation.run_stage import (
    FmuSource,
    PathPlan,
    Progress,
    SimulationOptions,
    SimulationSummary,
)
from idefix_rules.campaign.simulation.run_tasks import run_task
from idefix_rules.campaign.simulation.worker import RunTask
from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.campaign.worst.search import PathSearch, SearchSettings
from idefix_rules.campaign.worst.space import QuantileSpace
from idefix_rules.commands import RoverGeometry
from idefix_rules.results.format import SEARCHED_RUNS

WORST_STREAM = 0x776F7273  # "wors": keeps the search's draws apart from any campaign's
RUNS_MODE = SEARCHED_RUNS
SAMPLING = "cross_entropy"
SEED_DERIVATION = ("worst-case search: path p draws from SeedSequence(seed, spawn_key="
                   f"({WORST_STREAM}, h)) with h the first 32 bits of sha256(p); row j is the "
                   "j-th world the search asked for (cross-entropy generations, then the "
                   "failure boundary's rounds)")


def search_seed(seed: int, name: str) -> np.random.SeedSequence:
    """The seed of path ``name``'s search."""
    return np.random.SeedSequence(seed, spawn_key=(WORST_STREAM,
                                                   *sampling.path_stream(name, paired=False)))


@dataclass
class WorstStage:
    """The stage :func:`~idefix_rules.campaign.simulation.simulate.simulate_campaign` runs
    instead of the Monte Carlo part; afterwards :attr:`searches` holds every searched path's
    search."""

    settings: SearchSettings
    workers: int = 1  # processes for the collision checks of each round's evaluation
    searches: dict[str, PathSearch] = field(default_factory=dict)
    space: QuantileSpace | None = None

    def __call__(self, campaign: Campaign, evaluator: Any, rover: RoverGeometry,
                 fmu: FmuSource, fmu_parameters: Mapping[str, float | str],
                 plans: list[PathPlan], store: ResultStore, options: SimulationOptions,
                 progress: Progress, summary: SimulationSummary, collisions: Any) -> None:
        parameters = campaign.model.uncertainty.parameters
        space = self.space = QuantileSpace.of(parameters, self.settings.tail)
        # each path searches worlds of its own (search_seed): run j of two paths is not
        # the same world, so the file is unpaired whatever the campaign says
        store.attrs.update({"runs": self.settings.runs, "runs_mode": RUNS_MODE,
                            "sampling": SAMPLING, "paired": False,
                            "seed_derivation": SEED_DERIVATION,
                            "worst_threshold": self.settings.threshold,
                            "worst_tail": self.settings.tail,
                            "worst_axes": self.settings.axes,
                            "worst_rounds": self.settings.rounds})
        base = {**fmu_parameters, **nominal_parameters(campaign)}
        sigma = initial_position_sigma(campaign)
        by_name = {plan.spec.name: plan for plan in plans}
        for plan in plans:
            if plan.status != "simulated" or plan.reference is None:
                continue
            name = plan.spec.name
            planned = {key: np.full(self.settings.runs, spec.value if isinstance(spec, Fixed)
                                    else np.nan) for key, spec in parameters.items()}
            shapes = {key: tuple(np.shape(value)) for key, value in plan.reference.items()}
            store.allocate_runs(name, self.settings.runs, shapes, planned,
                                parameter_info(campaign, list(planned)))
            risk, dominant = reference_risk(evaluator, plan, rover, sigma, collisions)
            self.searches[name] = PathSearch(space, self.settings,
                                             np.random.default_rng(search_seed(campaign.seed,
                                                                               name)),
                                             risk, dominant)
            progress.start_path(name, self.settings.runs, 0)
        # one pool for every round: its workers keep their loaded FMU from round to round
        pool = monte_carlo_pool(campaign, by_name, store, options) if self.searches else None
        try:
            self._rounds(campaign, evaluator, rover, fmu, base, by_name, store, options,
                         progress, summary, collisions, sigma, pool)
        finally:
            if pool is not None:
                pool.close()
        for name, search in self.searches.items():
            store.mark_not_needed(name, search.used)
            store.path_group(name).attrs["runs_used"] = search.used
            store.path_group(name).attrs["stop_reason"] = (
                f"worst-case search: {search.used} of {self.settings.runs} runs used")
        store.file.flush()

    def _rounds(self, campaign: Campaign, evaluator: Any, rover: RoverGeometry,
                fmu: FmuSource, base: Mapping[str, float | str],
                by_name: Mapping[str, PathPlan], store: ResultStore,
                options: SimulationOptions, progress: Progress, summary: SimulationSummary,
                collisions: Any, sigma: float, pool: Any) -> None:
        """Round after round: simulate what every search asks for next, score it, tell it."""
        space = self.space
        assert space is not None
        while True:
            batches = {name: (search.used, search.ask())
                       for name, search in self.searches.items()}
            batches = {name: batch for name, batch in batches.items() if len(batch[1])}
            if not batches:
                break
            worlds: dict[str, tuple[int, dict[str, np.ndarray]]] = {}
            for name, (start, points) in batches.items():
                worlds[name] = (start, space.values(points))
                store.set_parameters(name, start, worlds[name][1])
            rows = {name: np.arange(start, start + len(points), dtype=np.int64)
                    for name, (start, points) in batches.items()}
            make = _world_task(campaign, fmu, base, by_name, worlds)
            run_and_store(campaign, PlannedRuns(rows, make), by_name, store, options, progress,
                          summary, pool)
            for name, (start, points) in batches.items():
                risks, dominants = batch_risks(store, name, evaluator, rover, sigma, collisions,
                                               start, len(points), self.workers)
                self.searches[name].tell(risks, dominants)


def _world_task(campaign: Campaign, fmu: FmuSource, base: Mapping[str, float | str],
                plans: Mapping[str, PathPlan],
                worlds: Mapping[str, tuple[int, Mapping[str, np.ndarray]]]
                ) -> TaskMaker:
    """What makes the task of run ``run`` of a path: the world at ``run - start`` of the
    path's batch ``(start, values)`` in ``worlds``."""
    def make(name: str, run: int) -> RunTask:
        start, values = worlds[name]
        world = dict(base)
        world.update({key: float(column[run - start]) for key, column in values.items()})
        return run_task(campaign, fmu, plans[name], world, encode=True)

    return make


def reference_risk(evaluator: Any, plan: PathPlan, rover: RoverGeometry, sigma: float,
                   collisions: Any) -> tuple[float, str | None]:
    """I_max and the dominant index of the reference run scored as a run: the nominal world's
    risk (the search's starting point), without simulating it again."""
    reference = plan.reference or {}
    signals = {key: np.asarray(value)[None, ...] for key, value in reference.items()}
    if collisions is not None:
        extra, _ = collisions(signals)
        signals.update(extra)
    evaluation = evaluator.evaluate(signals, run_context(plan.spec.chain, rover, sigma,
                                                        reference), per_sample=False)
    return float(evaluation.i_max[0]), dominant_name(evaluation, 0)


def dominant_name(evaluation: Any, row: int) -> str | None:
    names = list(evaluation.index_names)
    code = int(np.asarray(evaluation.dominant)[row])
    return names[code] if 0 <= code < len(names) else None


def batch_risks(store: ResultStore, name: str, evaluator: Any, rover: RoverGeometry,
                sigma: float, collisions: Any, start: int, count: int,
                workers: int = 1) -> tuple[np.ndarray, list[str | None]]:
    """Run risks (NaN for a failed run) and dominant indices of rows ``start … start+count-1``."""
    risks = np.full(count, np.nan)
    dominants: list[str | None] = [None] * count
    evaluation, extra = evaluate_path(store, name, evaluator, rover, sigma, collisions,
                                      workers=workers, within=slice(start, start + count))
    if evaluation is not None:
        for position, row in enumerate(np.asarray(extra["rows"])):
            risks[int(row) - start] = float(evaluation.i_max[position])
            dominants[int(row) - start] = dominant_name(evaluation, position)
    return risks, dominants


def stored_record(store: ResultStore, record: Mapping[str, Any]) -> None:
    """Keep the search's outcome (``worst.json``) inside the results file, ``/worst/record``."""
    group = store.file.require_group("worst")
    if "record" in group:
        del group["record"]
    group.create_dataset("record", data=json.dumps(record), dtype=h5py.string_dtype("utf-8"))
    store.file.flush()


def read_record(file: Any) -> dict[str, Any] | None:
    """The search's outcome stored in a results file (an h5py.File), None in a campaign's."""
    group = file.get("worst")
    if group is None or "record" not in group:
        return None
    value = group["record"][()]
    text = value.decode("utf-8") if isinstance(value, bytes) else str(value)
    loaded = json.loads(text)
    return loaded if isinstance(loaded, dict) else None
