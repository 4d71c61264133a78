"""The simulation stage: command rules → reference runs → pre-screen → Monte Carlo → results.h5.

:func:`simulate_campaign` chains the stages; evaluation is a separate stage
(:mod:`idefix_rules.campaign.evaluation.evaluate`) joined to this one only by the results file.
"""

from __future__ import annotations

import contextlib
import dataclasses
import heapq
import json
import os
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from idefix_rules import __version__
from idefix_rules.campaign.input import sampling, waivers
from idefix_rules.campaign.input.load import (
    Campaign,
    PathSpec,
    initial_position_sigma,
    nominal_parameters,
    rover_geometry,
    stop_limit,
    where_set,
)
from idefix_rules.campaign.input.validate import planned_draws
from idefix_rules.campaign.input.wording import (
    DisplayUnits,
    range_text,
    violation_text,
    written_unit_at,
)
from idefix_rules.campaign.simulation import resume as resuming
from idefix_rules.campaign.simulation import timeouts as run_timeouts
from idefix_rules.campaign.simulation.pool import DaskPool, LocalPool, Outcome, Then, Timeouts
from idefix_rules.campaign.simulation.prescreen import finding_text, prescreen_reference
from idefix_rules.campaign.simulation.processes import timeout_reason
from idefix_rules.campaign.simulation.worker import InputProblem, RunTask, simulate
from idefix_rules.campaign.storage import diskspace
from idefix_rules.campaign.storage.store import (
    FORMAT_VERSION,
    RESUMABLE_FORMAT_VERSIONS,
    STATUS_FAILED,
    ResultStore,
    run_bytes,
)
from idefix_rules.commands import RoverGeometry
from idefix_rules.errors import Diagnostic, InfrastructureError, Span, UserInputError, error
from idefix_rules.fmu.runner import PARAMETER_REJECTED
from idefix_rules.fmu.terrain import Terrain
from idefix_rules.results import terrain as stored_terrain
from idefix_rules.results.terrain import TerrainSource, file_sha256
from idefix_rules.timestamps import now_iso

if TYPE_CHECKING:
    from idefix_rules.campaign.evaluation.remembered import RememberedCollisions

RESULTS_FILE = "results.h5"

TERRAIN_PARAMETER = "terrain.file"


class Progress(Protocol):
    """What the simulation reports while it works (the CLI shows it; tests ignore it)."""

    def message(self, text: str) -> None: ...

    def note(self, text: str) -> None:
        """A line said while runs go on (a path stopped, a check given up): it ends nothing,
        unlike :meth:`message`, which starts a new phase."""
        ...

    def start_path(self, name: str, total: int, done: int, failed: int = 0) -> None:
        """Runs of path ``name`` begin: ``total`` planned, ``done`` of them stored already
        (a resumed campaign's), ``failed`` of those failed."""
        ...

    def run_finished(self, name: str, ok: bool) -> None: ...


class SilentProgress:
    def message(self, text: str) -> None:
        pass

    def note(self, text: str) -> None:
        pass

    def start_path(self, name: str, total: int, done: int, failed: int = 0) -> None:
        pass

    def run_finished(self, name: str, ok: bool) -> None:
        pass


@dataclass(frozen=True)
class SimulationOptions:
    workers: int | None = None  # None: the campaign's, else all cores
    run_timeout: float | None = None  # None: the default (campaign/simulation/timeouts.py); 0: none
    resume: bool = False
    scheduler: str | None = None  # Dask scheduler address
    dask_local: bool = False


@dataclass
class PathPlan:
    spec: PathSpec
    stop_time: float
    samples: int
    ideal_duration: float
    status: str = "pending"
    reason: str = ""
    reference: dict[str, np.ndarray] | None = None


@dataclass
class SimulationSummary:
    results: Path
    plans: list[PathPlan] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    fmu_seconds: float = 0.0  # summed time workers spent inside FmuRunner.run
    write_seconds: float = 0.0  # time the parent spent storing Monte Carlo runs
    simulated_runs: int = 0
    path_seconds: dict[str, float] = field(default_factory=dict)  # the same, per path


class RunStage(Protocol):
    """What simulates a campaign's runs once the reference runs are stored (the Monte Carlo
    stage by default): it allocates and writes the runs of the ``simulated`` paths into
    ``store``, with :func:`run_and_store`."""

    def __call__(self, campaign: Campaign, evaluator: Any, rover: RoverGeometry,
                 fmu: FmuSource, fmu_parameters: Mapping[str, float | str],
                 plans: list[PathPlan], store: ResultStore, options: SimulationOptions,
                 progress: Progress, summary: SimulationSummary, collisions: Any) -> None: ...


def plan_path(campaign: Campaign, spec: PathSpec, rover: RoverGeometry) -> PathPlan:
    return PathPlan(spec, *stop_limit(campaign, spec.chain, rover))


def open_pool(function: Any, options: SimulationOptions, campaign: Campaign,
              timeouts: Timeouts, persistent: bool = False) -> Any:
    """The campaign's pool: local processes, or Dask. ``persistent``: its workers (and the
    FMU each has loaded) serve map after map until the caller closes it."""
    if options.scheduler or options.dask_local:
        return DaskPool(function, address=options.scheduler,
                        workers=options.workers or campaign.workers, run_timeout=timeouts,
                        persistent=persistent)
    return LocalPool(function, workers=options.workers or campaign.workers,
                     run_timeout=timeouts, persistent=persistent)


@contextlib.contextmanager
def _map(pool: Any, tasks: Iterable[tuple[Any, RunTask]], close: bool = True
         ) -> Iterator[Iterator[tuple[Any, Outcome]]]:
    """The pool's results; on any exit (Ctrl-C included) busy workers are ended at once.
    ``close``: close the pool after its last result too (a persistent pool stays open)."""
    results = pool.map(tasks)
    try:
        yield results
    finally:
        results.close()
        if close:
            pool.close()


def simulate_campaign(campaign: Campaign, evaluator: Any, fmu_path: Path,
                      fmu_parameters: Mapping[str, float | str],
                      options: SimulationOptions | None = None,
                      progress: Progress | None = None,
                      collisions: Any = None,
                      terrain: tuple[Terrain, TerrainSource] | None = None,
                      stage: RunStage | None = None) -> SimulationSummary:
    """Run every stage up to a complete ``results.h5``; returns what happened per path.

    ``fmu_parameters`` are the run-independent parameters (terrain file, regolith values).
    ``terrain`` is the terrain the runs are simulated on and where it came from: stored in
    the results file when it is created (or resumed without one), so that the file alone
    re-scores as the campaign did (:mod:`idefix_rules.results.terrain`).
    ``stage`` replaces the Monte Carlo stage (fixed or adaptive) after the reference runs:
    the worst-case search (:mod:`idefix_rules.campaign.worst`) chooses its runs itself.
    """
    options = options or SimulationOptions()
    progress = progress or SilentProgress()
    results = campaign.output / RESULTS_FILE
    rover = rover_geometry(campaign)
    summary = SimulationSummary(results)
    warning = _sampling_warning(campaign)
    if warning:
        summary.warnings.append(warning)  # said once, with the outcome
    store = _open_store(campaign, evaluator, fmu_path, results, options.resume, terrain)
    was_complete = options.resume and str(store.attrs.get("state", "")) == "complete"
    unpacked = contextlib.ExitStack()
    try:
        fmu = FmuSource(str(fmu_path), _unzip_once(fmu_path, options, unpacked))
        store.attrs["state"] = "running"
        store.file.flush()
        plans = [plan_path(campaign, spec, rover) for spec in campaign.paths]
        summary.plans = plans
        _command_rules(campaign, evaluator, rover, plans, store)
        # a worst-case search (``stage``) draws its own worlds: no planned draws to check
        _reference_runs(campaign, evaluator, rover, fmu, fmu_parameters, plans, store,
                        options, progress, collisions, summary, draws=stage is None
                        or campaign.adaptive is not None)
        if stage is not None:
            stage(campaign, evaluator, rover, fmu, fmu_parameters, plans, store, options,
                  progress, summary, collisions)
        elif campaign.adaptive is not None:
            # the adaptive stage (campaign/adaptive.py) sits above this module: its
            # caller passes it as ``stage``
            raise ValueError("an adaptive campaign (runs: auto) needs its stage: pass "
                             "stage=adaptive_monte_carlo")
        else:
            _monte_carlo(campaign, fmu, fmu_parameters, plans, store, options, progress,
                         summary)
        complete = resuming.nothing_left(store, [p.spec.name for p in plans])
        diskspace.require(store.folder, 0, "record the end of the simulation")
        store.attrs["state"] = "complete" if complete else "interrupted"
        if not (complete and was_complete and summary.simulated_runs == 0):
            # resuming a complete campaign simulates nothing: it keeps its finishing time
            store.attrs["finished"] = now_iso() if complete else ""
    except BaseException:
        if store.file.id.valid and diskspace.free_bytes(store.folder) >= diskspace.MARGIN:
            with contextlib.suppress(Exception):  # a disk filling up may refuse even this
                store.attrs["state"] = "interrupted"
        with contextlib.suppress(Exception):  # the error on its way says what went wrong
            store.close()
        raise
    finally:
        unpacked.close()  # the pools are closed by now: no worker uses the folder any more
        store.close()
    return summary


def _sampling_warning(campaign: Campaign) -> str | None:
    method = campaign.model.uncertainty.method
    if campaign.adaptive is not None:
        return sampling.adaptive_sampling_note(method)
    return sampling.sobol_warning(method, campaign.runs)


def run_settings(campaign: Campaign) -> dict[str, Any]:
    """The root attributes that say how many runs a campaign asked for (compared on resume)."""
    adaptive = campaign.adaptive
    paired = campaign.model.uncertainty.paired
    if adaptive is None:
        return {"runs": campaign.runs, "runs_mode": "fixed",
                "sampling": campaign.model.uncertainty.method, "paired": paired}

    return {"runs": adaptive.max_runs, "runs_mode": "auto", "min_runs": adaptive.min_runs,
            "batch_runs": adaptive.batch_runs, "sampling": sampling.ADAPTIVE_SAMPLING,
            "paired": paired}


@dataclass(frozen=True)
class FmuSource:
    """The FMU the workers run: its file, and the folder it was extracted to once (None:
    each worker extracts it)."""

    path: str
    unzipped: str | None


def _unzip_once(fmu_path: Path, options: SimulationOptions,
                stack: contextlib.ExitStack) -> str | None:
    """Extract the FMU once into a temporary folder the campaign owns until it ends.

    Workers on a remote Dask cluster cannot see a local folder: there every worker extracts
    the FMU itself (None).
    """
    if options.scheduler:
        return None
    from idefix_rules.fmu import extract_fmu

    folder = stack.enter_context(tempfile.TemporaryDirectory(prefix="idefix-fmu-"))
    return str(extract_fmu(fmu_path, folder))


def _open_store(campaign: Campaign, evaluator: Any, fmu_path: Path, results: Path,
                resume: bool, terrain: tuple[Terrain, TerrainSource] | None) -> ResultStore:
    fmu_hash = file_sha256(fmu_path)
    if resume and results.exists():
        diskspace.require(results.parent, 0, f"continue {results.name}")
        store = ResultStore.open(results, writable=True)
        expected = {"format_version": FORMAT_VERSION, "campaign_sha256": campaign.sha256,
                    **run_settings(campaign), "seed": campaign.seed, "fmu_sha256": fmu_hash}
        for key, value in expected.items():
            stored = store.attrs.get(key)
            if key == "paired" and stored is None:
                stored = False  # written before campaigns were paired: every path drew its own
            if key == "format_version" and stored in RESUMABLE_FORMAT_VERSIONS:
                continue  # its full-size run datasets are a block allocation of every row
            if stored != value:
                store.close()
                shown = stored.item() if isinstance(stored, np.generic) else stored
                raise UserInputError(error(
                    "H010", f"cannot resume {results}: its {key} is {shown!r}, "
                            f"this campaign's is {value!r}", Span(str(results)),
                    hint="resume with the same campaign file, --runs, --max-runs, --min-runs, "
                         "--seed and FMU, or choose another --out"))
        resumed = json.loads(str(store.attrs.get("resumed", "[]")))
        store.attrs["resumed"] = json.dumps([*resumed, now_iso()])
        if terrain is not None and not stored_terrain.has_terrain(store.file):
            # written before results held their terrain: the one the runs now see is stored
            with store.structural_change(stored_terrain.stored_bytes(terrain[0]),
                                         f"store the terrain in {results.name}", 0):
                stored_terrain.write_terrain(store.file, *terrain)
        # paths allocated now grow by blocks; the terrain is stored
        store.attrs["format_version"] = FORMAT_VERSION
        return store
    rulebook_text = campaign.rulebook.read_text(encoding="utf-8")
    if terrain is not None:  # checked before the file is made (or the last one set aside)
        diskspace.require(results.parent, stored_terrain.stored_bytes(terrain[0]),
                          f"store the terrain in {results.name}")
    store = ResultStore.create(results, {
        "campaign_name": campaign.name,
        "campaign_path": str(campaign.source),
        "campaign_sha256": campaign.sha256,
        "package_version": __version__,
        "fmu_path": str(fmu_path),
        "fmu_sha256": fmu_hash,
        "seed": campaign.seed,
        **run_settings(campaign),
        "seed_derivation": sampling.seed_derivation(campaign.model.uncertainty.paired),
        "started": now_iso(),
        "resumed": "[]",
        "finished": "",
        "state": "running",
        "output_interval": campaign.model.simulation.output_interval,
    }, {"campaign": campaign.text, "rulebook": rulebook_text})
    try:
        text = store.file["provenance"]["rulebook"]
        text.attrs["name"] = evaluator.name
        text.attrs["version"] = evaluator.version
        text.attrs["sha256"] = evaluator.source_hash
        text.attrs["path"] = str(campaign.rulebook)
        if terrain is not None:
            stored_terrain.write_terrain(store.file, *terrain)
        store.file.flush()
    except BaseException:
        with contextlib.suppress(Exception):  # the error on its way says what went wrong
            store.close()
        raise
    return store


def _command_rules(campaign: Campaign, evaluator: Any, rover: RoverGeometry,
                   plans: list[PathPlan], store: ResultStore) -> None:
    for plan in plans:
        name = plan.spec.name
        if store.has_path(name):
            group = store.path_group(name)
            if group.attrs.get("status", "pending") == "pending" \
                    or resuming.reference_lost(store, name):
                # killed before its reference run was stored, or that run was lost to the
                # infrastructure: the path starts again
                del store.file["paths"][name]
            else:
                plan.status = str(group.attrs.get("status", "pending"))
                plan.reason = str(group.attrs.get("reason", ""))
                plan.reference = store.reference(name)
                continue
        violations, waived = waivers.split(campaign.model.waivers, name, "command",
                                           evaluator.check_chain(plan.spec.chain, rover),
                                           lambda violation: str(violation.rule))
        store.create_path(name, plan.spec.index, plan.spec.chain, {
            "status": "pending", "reason": "", "stop_time": plan.stop_time,
            "samples": plan.samples, "ideal_duration": plan.ideal_duration})
        _record_waived(store, name, waived)
        if violations:
            plan.status = "rejected"
            units = DisplayUnits.from_campaign_text(campaign.text)
            plan.reason = "; ".join(violation_text(v, units) for v in violations)
            store.set_path_status(name, plan.status, plan.reason)


def _record_waived(store: ResultStore, name: str, waived: list[waivers.WaivedRule]) -> None:
    """Keep a path's waived command and prescreen rules with it (the evaluation reads them)."""
    if waived:
        attrs = store.path_group(name).attrs
        attrs[waivers.STORED_ATTRIBUTE] = waivers.to_store(
            str(attrs.get(waivers.STORED_ATTRIBUTE, "")), waived)


def run_task(campaign: Campaign, fmu: FmuSource, plan: PathPlan,
             parameters: Mapping[str, float | str], encode: bool = False,
             check: str | None = None, run: int = -1) -> RunTask:
    """The task simulating one run of ``plan``'s chain with ``parameters`` (SI, by the
    campaign's names); ``encode``: the worker hands back the chunks the results file stores;
    ``check``: the token of the collision check the worker runs on run ``run`` too
    (:func:`~idefix_rules.campaign.simulation.worker.run_checks`)."""
    maps = campaign.model.fmu
    return RunTask(
        fmu_path=fmu.path,
        unzipped=fmu.unzipped,
        signal_map=tuple(maps.signals.items()) if maps.signals is not None else None,
        # The campaign maps FMU variable → our name (like signals); the runner wants ours → FMU.
        parameter_map=tuple((ours, theirs) for theirs, ours in maps.parameters.items())
        if maps.parameters is not None else None,
        parameters=tuple(parameters.items()),
        chain=plan.spec.chain,
        stop_time=plan.stop_time,
        output_interval=campaign.model.simulation.output_interval,
        samples=plan.samples,
        chain_delivery=maps.chain.delivery,
        chain_inputs=tuple(maps.chain.inputs.items()),
        done_at=maps.done_at,
        rover=rover_geometry(campaign) if maps.chain.delivery == "inputs" else None,
        encode=encode,
        check=check,
        run=run,
    )


@dataclass(frozen=True)
class DrawCheck:
    """An extreme draw of an uncertain parameter, set up in the FMU before any Monte Carlo
    run: ``run`` of path ``path`` draws ``value`` (SI) for ``parameter``."""

    parameter: str
    value: float
    path: str
    run: int
    planned: int  # the runs planned per path (an adaptive campaign's cap)


@dataclass(frozen=True)
class SetupProbe:
    """The FMU set up once with the nominal parameters (no step simulated), before the
    reference runs: an FMU that never finishes its set-up stops the campaign after one
    set-up timeout instead of one per reference run and draw check."""

    path: str


def _draw_checks(campaign: Campaign, fmu: FmuSource, plans: Sequence[PathPlan],
                 nominal: Mapping[str, float | str]) -> list[tuple[DrawCheck, RunTask]]:
    """For each uncertain parameter, its smallest and largest draw over every planned run of
    ``plans`` (an interval of the FMU's holds the draws when it holds these two), each with
    the other parameters nominal, as tasks that only set the FMU up (stop time 0)."""
    planned, draws = planned_draws(campaign, [plan.spec.name for plan in plans])
    found: dict[tuple[str, float], DrawCheck] = {}
    for plan in plans:
        for key, values in draws[plan.spec.name].items():
            values = np.asarray(values, dtype=float)
            if not values.size:
                continue
            for run in (int(np.argmin(values)), int(np.argmax(values))):
                value = float(values[run])
                found.setdefault((key, value), DrawCheck(key, value, plan.spec.name, run,
                                                         planned))
    by_name = {plan.spec.name: plan for plan in plans}
    return [(check, dataclasses.replace(
        run_task(campaign, fmu, by_name[check.path], {**nominal, check.parameter: check.value}),
        stop_time=0.0, samples=1)) for check in found.values()]


def _refused_draw(campaign: Campaign, check: DrawCheck, outcome: Outcome) -> list[Diagnostic]:
    """The mistake an extreme draw the FMU refused is (F110 at the distribution's line,
    naming the run that draws it); nothing when the FMU took it, or failed for another
    reason (the runs report that as theirs)."""
    if not (outcome.ok and isinstance(outcome.value, InputProblem)):
        return []
    refused = []
    for diagnostic in outcome.value.diagnostics:
        placed = _where_set(campaign, diagnostic)
        if placed.code != "F110":
            continue
        refused.append(dataclasses.replace(
            placed, message=f"{placed.message}: run {check.run} of path {check.path} draws it "
                            f"(of {check.planned} planned), before any run was simulated",
            hint="bound the distribution inside the range the FMU allows (a truncated_normal "
                 "with low and high, a uniform), or narrow it"))
    return refused


def _reference_runs(campaign: Campaign, evaluator: Any, rover: RoverGeometry, fmu: FmuSource,
                    fmu_parameters: Mapping[str, float | str], plans: list[PathPlan],
                    store: ResultStore, options: SimulationOptions, progress: Progress,
                    collisions: Any, summary: SimulationSummary, draws: bool = True) -> None:
    todo = [p for p in plans if p.status == "pending"]
    if todo:
        _run_references(campaign, evaluator, rover, fmu, fmu_parameters, todo, store, options,
                        progress, collisions, summary, draws)
    tried = [p for p in plans if p.status in ("reference_failed", "simulated", "excluded")]
    if tried and all(plan.status == "reference_failed" for plan in tried):
        # Nothing could be simulated at all: the FMU or its set-up is broken, not a chain (a
        # resumed campaign whose reference runs all failed is in the same state)
        reasons = sorted({plan.reason for plan in tried})
        raise InfrastructureError("every reference run failed, so nothing was simulated: "
                                  + "; ".join(reasons))


def _run_references(campaign: Campaign, evaluator: Any, rover: RoverGeometry, fmu: FmuSource,
                    fmu_parameters: Mapping[str, float | str], todo: list[PathPlan],
                    store: ResultStore, options: SimulationOptions, progress: Progress,
                    collisions: Any, summary: SimulationSummary, draws: bool) -> None:
    """The reference runs of the paths ``todo``, after the FMU's set-up on its own."""
    nominal = {**fmu_parameters, **nominal_parameters(campaign)}
    progress.message(f"reference runs of {len(todo)} path(s)")
    tasks: list[tuple[Any, RunTask]] = [(plan.spec.name, run_task(campaign, fmu, plan, nominal))
                                        for plan in todo]
    # the extreme draws of every uncertain parameter, each set up in the FMU beside the
    # reference runs (no step simulated): a value the FMU refuses stops the campaign now
    checks = _draw_checks(campaign, fmu, todo, nominal) if draws else []
    by_name = {plan.spec.name: plan for plan in todo}
    timeouts = run_timeouts.reference_timeouts(by_name, options.run_timeout)
    setup_timeout = run_timeouts.setup_timeout(options.run_timeout)

    def timeout(key: Any) -> float | None:
        if isinstance(key, SetupProbe | DrawCheck):  # set-up alone: no step simulated
            return setup_timeout
        return timeouts(key)

    pool = open_pool(simulate, options, campaign, timeout, persistent=True)
    probe = SetupProbe(todo[0].spec.name)
    try:
        with _map(pool, [(probe, dataclasses.replace(tasks[0][1], stop_time=0.0, samples=1))],
                  close=False) as results:
            for _, outcome in results:
                _raise_input_problem(campaign, outcome)
                if not outcome.ok and setup_timeout is not None and \
                        outcome.reason == timeout_reason(setup_timeout):
                    raise InfrastructureError(
                        f"the FMU did not finish setting up (instantiation, parameters, "
                        f"initialisation; no step simulated) within {setup_timeout:g} s, so "
                        "nothing was simulated: it hangs there, or needs a longer "
                        "--run-timeout (docs/operations.md, \"Timeouts\")")
    except BaseException:
        pool.close()
        raise
    refused: list[Diagnostic] = []
    with _map(pool, tasks + [(check, task) for check, task in checks]) as results:
        for name, outcome in results:
            if isinstance(name, DrawCheck):
                refused += _refused_draw(campaign, name, outcome)
                continue
            _reference_outcome(campaign, evaluator, rover, store, by_name[name], nominal,
                               outcome, collisions, summary)
    if refused:
        raise UserInputError(refused[:1], sources={str(campaign.source): campaign.text})


def _reference_outcome(campaign: Campaign, evaluator: Any, rover: RoverGeometry,
                       store: ResultStore, plan: PathPlan, nominal: Mapping[str, float | str],
                       outcome: Outcome, collisions: Any, summary: SimulationSummary) -> None:
    """Store a reference run and apply the pre-screen to it."""
    name = plan.spec.name
    _raise_input_problem(campaign, outcome)
    numeric = {k: float(v) for k, v in nominal.items() if not isinstance(v, str)}
    if not outcome.ok:
        plan.status, plan.reason = "reference_failed", outcome.reason
        store.write_reference(name, None, numeric, outcome.reason)
        store.set_path_status(name, plan.status, plan.reason)
        return
    plan.reference = outcome.value.signals
    summary.fmu_seconds += outcome.value.seconds
    summary.path_seconds[name] = summary.path_seconds.get(name, 0.0) + outcome.value.seconds
    store.write_reference(name, plan.reference, numeric)
    store.path_group(name).attrs[run_timeouts.COST_ATTRIBUTE] = outcome.value.seconds
    findings, waived = waivers.split(
        campaign.model.waivers, name, "prescreen",
        prescreen_reference(evaluator, plan.spec.chain, rover, initial_position_sigma(campaign),
                            plan.reference, collisions),
        lambda finding: str(getattr(finding, "rule", "")))
    _record_waived(store, name, waived)
    if findings:
        plan.status = "excluded"
        plan.reason = "; ".join(finding_text(f) for f in findings)
    else:
        plan.status = "simulated"
    store.set_path_status(name, plan.status, plan.reason)


def _raise_input_problem(campaign: Campaign, outcome: Outcome) -> None:
    """A mistake in the campaign found inside a worker stops the campaign (exit 2)."""
    if outcome.ok and isinstance(outcome.value, InputProblem):
        raise UserInputError([_where_set(campaign, d) for d in outcome.value.diagnostics],
                             sources={str(campaign.source): campaign.text})


def _where_set(campaign: Campaign, diagnostic: Diagnostic) -> Diagnostic:
    """A parameter the FMU refused (F110), pointed at the campaign line that set it (a
    regolith value, or an uncertain parameter's distribution) instead of the FMU file."""
    match = PARAMETER_REJECTED.match(diagnostic.message) if diagnostic.code == "F110" else None
    if match is None:
        return diagnostic
    names = {match["name"]} | {ours for fmu_name, ours
                               in (campaign.model.fmu.parameters or {}).items()
                               if fmu_name == match["name"]}
    places = where_set(campaign, names)
    if not places:
        return diagnostic
    place = places[0]
    if place[0] == "uncertainty":  # the unit its distribution is written in
        unit = DisplayUnits.from_campaign_text(campaign.text).unit_of(str(place[-1]))
    else:  # a regolith value as written
        unit = written_unit_at(campaign.text, place) or ""
    return dataclasses.replace(diagnostic, span=campaign.span(place),
                               message=range_text(diagnostic.message, unit))


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


def _monte_carlo(campaign: Campaign, fmu: FmuSource, fmu_parameters: Mapping[str, float | str],
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


def local_workers(options: SimulationOptions, campaign: Campaign) -> int:
    """Processes for the evaluation's collision checks: the local pool's size (1 when the
    simulation went to a Dask cluster, whose workers are not on this machine)."""
    if options.scheduler:
        return 1
    return max(1, options.workers or campaign.workers or os.cpu_count() or 1)


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
            _map(pool, tasks, close=own) as results:
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
            _raise_input_problem(campaign, outcome)
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
