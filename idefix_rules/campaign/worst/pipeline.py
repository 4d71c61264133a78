"""``idefix-verify worst``: a campaign's worst-case search end to end.

load campaign → check the search → reference runs → search (:mod:`.stage`) → ``results.h5``
→ evaluation (as a campaign's) → ``worst.json`` → report. The output folder is the campaign's
``<output>/worst`` (``--out`` overrides), owned like a campaign's while the search runs, so the
campaign's own results are never touched.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py

from idefix_rules.campaign.evaluation.evaluate import evaluate_store
from idefix_rules.campaign.evaluation.sensitivity import store_sensitivity
from idefix_rules.campaign.evaluation_writing import evaluation_revision, rulebook_info
from idefix_rules.campaign.input.campaign_values import initial_position_sigma, rover_geometry
from idefix_rules.campaign.input.load import Campaign
from idefix_rules.campaign.outcome import outputs
from idefix_rules.campaign.output_folder import claimed_output
from idefix_rules.campaign.preparation import prepare_simulation
from idefix_rules.campaign.runner import write_report
from idefix_rules.campaign.simulation.monte_carlo import parameter_info
from idefix_rules.campaign.simulation.resume import execution_options, search_command
from idefix_rules.campaign.simulation.run_stage import Progress, SimulationOptions
from idefix_rules.campaign.simulation.simulate import RESULTS_FILE, simulate_campaign
from idefix_rules.campaign.storage import diskspace
from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.campaign.worst.outcome import (
    FORMAT,
    FORMAT_VERSION,
    METHOD,
    parameter_records,
    path_record,
    skipped_record,
)
from idefix_rules.campaign.worst.search import SearchSettings
from idefix_rules.campaign.worst.space import QuantileSpace
from idefix_rules.campaign.worst.stage import WorstStage, stored_record
from idefix_rules.errors import InfrastructureError, Span, UserInputError, error
from idefix_rules.files import set_aside, write_atomic
from idefix_rules.results.format import SEARCH_RECORD_FILE, SEARCHED_RUNS
from idefix_rules.shell import command_line

RECORD_FILE = SEARCH_RECORD_FILE
FOLDER = "worst"  # inside the campaign's output folder


@dataclass
class WorstResult:
    """What a search produced, as data (the CLI renders it)."""

    record: dict[str, Any]
    results: Path
    record_file: Path
    report: Path | None = None
    warnings: list[str] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)
    # what was done besides, said as notes (a stale lock taken over), as a run says them
    notes: list[str] = field(default_factory=list)


def default_output(campaign: Campaign) -> Path:
    return campaign.output / FOLDER


def check_search(campaign: Campaign, settings: SearchSettings) -> QuantileSpace:
    """The campaign's quantile space, once it is known the search can run (exit 2 otherwise:
    nothing uncertain, a budget too small for the number of parameters)."""
    space = QuantileSpace.of(campaign.model.uncertainty.parameters, settings.tail)
    sources = {str(campaign.source): campaign.text}
    if space.dimensions == 0:
        raise UserInputError(error(
            "C710", "nothing to search: the campaign's uncertainty has no parameter that "
                    "varies (only fixed values, or none)",
            campaign.span(("uncertainty", "parameters")),
            hint="give the parameters the search may vary a distribution under "
                 "uncertainty.parameters (docs/campaign-format.md)"), sources)
    needed = settings.minimum_runs(space.dimensions)
    if settings.runs < needed:
        population = settings.population(space.dimensions)
        raise UserInputError(error(
            "C711", f"--runs {settings.runs} is too small for a search over "
                    f"{space.dimensions} uncertain parameter(s): it needs at least {needed} "
                    f"runs per path (a first generation of "
                    f"{settings.first_generation(space.dimensions)}, one more of {population}, "
                    f"and {settings.boundary_runs(space.dimensions)} for the failure boundary)",
            Span(str(campaign.source)), hint=f"give --runs {needed} or more"))
    return space


def check_folder(campaign: Campaign) -> None:
    """The search's folder must not hold a campaign's results: they would be set aside
    (``results.previous.h5``) for the search's (C713)."""
    results = campaign.output / RESULTS_FILE
    if not results.is_file() or not h5py.is_hdf5(results):
        return
    try:
        with h5py.File(results, "r") as file:
            mode = file.attrs.get("runs_mode")
            ours = file.attrs.get("format") == "idefix-results"
    except OSError:
        return
    if ours and str(mode) != SEARCHED_RUNS:
        raise UserInputError(error(
            "C713", f"{campaign.output} holds a campaign's results ({RESULTS_FILE}): a search "
                    "there would set them aside", Span(str(results)),
            hint=f"leave out --out (the search writes into {_unmoved_default(campaign)}) "
                 "or give a folder of its own"))


def _unmoved_default(campaign: Campaign) -> Path:
    """Where the search writes without --out: the campaign file's own output, not the one
    --out gave ``campaign`` (``campaign.output`` is the search's folder here)."""
    return (campaign.source.parent / campaign.model.output).resolve() / FOLDER


def _check_threshold(campaign: Campaign, evaluator: Any, settings: SearchSettings) -> None:
    weights = dict(getattr(evaluator.checked, "weights", {}) or {})
    highest = max(weights.values(), default=0.0)
    if settings.threshold > highest + 1e-12:
        raise UserInputError(error(
            "C712", f"no run can reach the critical level {settings.threshold:g}: the "
                    f"largest index weight of rulebook {evaluator.name} is {highest:g}, and "
                    "a run's I_max is at most its largest weight",
            Span(str(campaign.rulebook)),
            hint=f"give --critical {highest:g} or less"))


def run_worst(campaign: Campaign, settings: SearchSettings,
              options: SimulationOptions | None = None, progress: Progress | None = None,
              report: bool = True) -> WorstResult:
    """Search every path of ``campaign`` (its ``output`` is the search's folder) and write
    ``results.h5``, ``worst.json`` and the report there."""
    options = options or SimulationOptions()
    space = check_search(campaign, settings)
    check_folder(campaign)
    with claimed_output(campaign) as lock:
        set_aside(campaign.output / RECORD_FILE)
        result = _run_owned(campaign, settings, space, options, progress, report)
        if lock.note is not None:
            result.notes.insert(0, lock.note)
        return result


def _again(campaign: Campaign, settings: SearchSettings, options: SimulationOptions,
           report: bool) -> str:
    """The command that runs this search again: its budget, seed, shape and options."""
    return search_command(campaign.source, campaign.output, settings.runs, campaign.seed,
                          settings.threshold, settings.tail, settings.axes, settings.rounds,
                          execution_options(options.workers, options.scheduler,
                                            options.dask_local, options.run_timeout,
                                            report=report))


def _run_owned(campaign: Campaign, settings: SearchSettings, space: QuantileSpace,
               options: SimulationOptions, progress: Progress | None,
               report: bool) -> WorstResult:
    started = time.perf_counter()
    say = progress.message if progress is not None else (lambda text: None)
    again = _again(campaign, settings, options, report)
    prepared = prepare_simulation(campaign, say, again, planned_runs=False)
    evaluator = prepared.evaluator
    _check_threshold(campaign, evaluator, settings)
    workers = 1 if options.scheduler else max(
        1, options.workers or campaign.workers or os.cpu_count() or 1)
    stage = WorstStage(settings, workers=workers)
    try:
        with diskspace.guard(campaign.output, "search the worst case",
                             f"free space, then run `{again}`"):
            simulation = simulate_campaign(campaign, evaluator, prepared.fmu_path,
                                           prepared.fixed, options, progress,
                                           prepared.collisions,
                                           (prepared.terrain, prepared.source), stage=stage)
    except BrokenPipeError:  # stdout's reader went away (`| head`): the dispatcher ends
        raise                # quietly (141); the results file is marked interrupted
    except OSError as failure:  # the results file could not be written (locked …)
        raise InfrastructureError(f"writing {campaign.output / RESULTS_FILE} failed: "
                                  f"{failure}") from failure
    simulated = time.perf_counter()
    results = simulation.results
    info = rulebook_info(evaluator, campaign.rulebook)
    record = _record(campaign, settings, space, stage, simulation.plans, info,
                     str(results.resolve()))
    say("evaluating the searched runs (as a campaign's, for evaluate, diff and report)")
    store = ResultStore.open(results)
    then = ("the searched runs are stored; free space, then "
            f"`{command_line('idefix-verify', 'evaluate', results)}`")
    try:
        with evaluation_revision(store, then) as revision:
            evaluation = evaluate_store(store, evaluator, rover_geometry(campaign),
                                        initial_position_sigma(campaign), prepared.collisions,
                                        info, workers=workers, into=revision.store,
                                        waivers=campaign.model.waivers)
            data = outputs.summary(evaluation, [], outputs.EXIT_OK,
                                   store_sensitivity(revision.store.file), str(results))
            revision.store.file.require_group("evaluation").attrs["summary"] = \
                json.dumps(data, default=str)
            stored_record(revision.store, record)
            revision.commit(f"write the evaluation into {results.name}", then)
    finally:
        store.close()
    record_file = campaign.output / RECORD_FILE
    write_atomic(record_file, json.dumps(record, indent=1) + "\n")
    evaluated = time.perf_counter()
    result = WorstResult(record, results, record_file, warnings=list(prepared.warnings))
    if report:
        say("writing the report")
        again_report = command_line("idefix-verify", "report", results)
        result.report = write_report(results, campaign.output,
                                     f"free space, then `{again_report}`")
    result.timings = {"simulation_and_search": simulated - started,
                      "evaluation": evaluated - simulated,
                      "report": time.perf_counter() - evaluated,
                      "total": time.perf_counter() - started,
                      "inside_fmu": simulation.fmu_seconds,
                      "simulated_runs": float(simulation.simulated_runs)}
    return result


def _record(campaign: Campaign, settings: SearchSettings, space: QuantileSpace,
            stage: WorstStage, plans: list[Any], rulebook: dict[str, str],
            results: str) -> dict[str, Any]:
    info = parameter_info(campaign, list(space.names))
    paths = []
    for plan in plans:
        name = plan.spec.name
        search = stage.searches.get(name)
        paths.append(path_record(name, search) if search is not None
                     else skipped_record(name, plan.status, plan.reason))
    return {
        "format": FORMAT, "format_version": FORMAT_VERSION, "results": results,
        "campaign": {"name": campaign.name, "path": str(campaign.source),
                     "sha256": campaign.sha256},
        "rulebook": rulebook,
        "seed": campaign.seed, "runs": settings.runs, "threshold": settings.threshold,
        "tail": settings.tail, "rounds": settings.rounds, "axes": settings.axes,
        "method": METHOD,
        "parameters": parameter_records(
            space, {name: str(entry["unit"]) for name, entry in info.items()},
            {name: json.loads(str(entry["distribution"])) for name, entry in info.items()}),
        "paths": paths,
    }


def highest_risks(record: dict[str, Any]) -> dict[str, float | None]:
    """The worst run risk found per searched path (for the benchmark and the console)."""
    found = {}
    for path in record.get("paths", []):
        worst = path.get("worst")
        found[str(path["name"])] = None if worst is None else worst.get("risk")
    return found


def results_folder(campaign: Campaign, out: Path | None) -> Path:
    return (out or default_output(campaign)).resolve()


__all__ = ["FOLDER", "RECORD_FILE", "RESULTS_FILE", "WorstResult", "check_search",
           "highest_risks", "run_worst"]
