"""One campaign end to end: load → simulate → store → evaluate → outputs (the CLI renders).

>>> from idefix_rules.campaign.runner import run_campaign  # doctest: +SKIP
>>> result = run_campaign(load_campaign("campaigns/rock-detour.yaml"))  # doctest: +SKIP
>>> result.exit_code  # doctest: +SKIP
0
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from idefix_rules.campaign.adaptive import adaptive_monte_carlo
from idefix_rules.campaign.evaluation.evaluate import evaluate_store
from idefix_rules.campaign.evaluation.remembered import RememberedCollisions
from idefix_rules.campaign.evaluation_writing import (
    CampaignResult,
    PathClock,
    evaluation_revision,
    finish_evaluation,
    rulebook_info,
    warn_lost_runs,
)
from idefix_rules.campaign.input.campaign_values import initial_position_sigma, rover_geometry
from idefix_rules.campaign.input.load import Campaign
from idefix_rules.campaign.output_folder import REPORT_FILE, claimed_output
from idefix_rules.campaign.preparation import prepare_simulation
from idefix_rules.campaign.rescore import EvaluationInterrupted, rescore
from idefix_rules.campaign.simulation.dask_pool import ClusterError
from idefix_rules.campaign.simulation.resume import execution_options, resume_command
from idefix_rules.campaign.simulation.run_stage import Progress, SimulationOptions
from idefix_rules.campaign.simulation.run_tasks import local_workers
from idefix_rules.campaign.simulation.simulate import simulate_campaign
from idefix_rules.campaign.storage import diskspace
from idefix_rules.campaign.storage.store import STATUS_COMPLETE, ResultStore
from idefix_rules.errors import IdefixError, InfrastructureError
from idefix_rules.results.collisions import ObstacleCheck
from idefix_rules.shell import command_line

# rescore and the result type beside the campaign's pipeline, for callers that import them here
__all__ = ["REPORT_BYTES", "REPORT_BYTES_PER_PATH", "CampaignResult", "EvaluationInterrupted",
           "ReportFailed", "ReportInterrupted", "rescore", "run_campaign", "write_report"]


def run_campaign(campaign: Campaign, options: SimulationOptions | None = None,
                 progress: Progress | None = None, junit: Path | None = None,
                 report: bool = True) -> CampaignResult:
    """Simulate, evaluate and write ``results.h5``, ``summary.json`` (and JUnit when asked).

    The output folder is owned by this campaign while it runs (:func:`claimed_output`)."""
    options = options or SimulationOptions()
    with claimed_output(campaign, junit, options.resume) as lock:
        try:
            result = _run_owned(campaign, options, progress, junit, report)
        except (ReportInterrupted, ReportFailed) as stop:  # the campaign is complete: its
            if lock.note is not None:                      # notes go with it
                stop.result.warnings.insert(0, lock.note)
            raise
        if lock.note is not None:
            result.warnings.insert(0, lock.note)
        return result


class ReportInterrupted(KeyboardInterrupt):
    """Ctrl-C while the report was written: the campaign itself is complete (``result``:
    its results file, evaluation, ``summary.json`` and JUnit are written; the report is
    not, and an earlier ``report.html`` is left as it was)."""

    def __init__(self, result: CampaignResult) -> None:
        super().__init__("interrupted while writing the report")
        self.result = result


class ReportFailed(Exception):
    """The report could not be written (a full disk, a file it cannot replace): the campaign
    itself is complete (``result``, as for :class:`ReportInterrupted`); ``failure`` says
    why, and its exit code (3 for the machine's, or the error's own) is the command's."""

    def __init__(self, result: CampaignResult, failure: Exception) -> None:
        super().__init__(f"the report could not be written: {failure}")
        self.result = result
        self.failure = failure
        self.exit_code = failure.exit_code if isinstance(failure, IdefixError) else 3


def _run_owned(campaign: Campaign, options: SimulationOptions, progress: Progress | None,
               junit: Path | None, report: bool) -> CampaignResult:
    started = time.perf_counter()
    say = progress.message if progress is not None else (lambda text: None)
    # How far a phase is, where the progress shows it (an ETA); optional in the protocol.
    advance = getattr(progress, "advance", None) or (lambda fraction, detail="": None)
    again = resume_command(campaign.source, campaign.output, campaign.runs, campaign.seed,
                           campaign.adaptive.min_runs if campaign.adaptive else None,
                           execution_options(options.workers, options.scheduler,
                                             options.dask_local, options.run_timeout, junit,
                                             report))
    prepared = prepare_simulation(campaign, say, again, options.resume)
    evaluator, fmu_path, fixed, collisions = (prepared.evaluator, prepared.fmu_path,
                                              prepared.fixed, prepared.collisions)
    terrain, source = prepared.terrain, prepared.source
    warnings = prepared.warnings
    if campaign.adaptive is not None and isinstance(collisions, ObstacleCheck):
        # the looks' collision checks, kept for the evaluation stage (not checked again)
        collisions = RememberedCollisions(collisions)
    try:
        with diskspace.guard(campaign.output, "simulate the campaign",
                             f"free space, then continue with `{again}`"):
            simulation = simulate_campaign(
                campaign, evaluator, fmu_path, fixed, options, progress, collisions,
                (terrain, source),
                stage=adaptive_monte_carlo if campaign.adaptive is not None else None)
    except BrokenPipeError:  # stdout's reader went away (`| head`): the dispatcher ends
        raise                # quietly (141); the results file is marked interrupted
    except OSError as failure:  # the results file could not be written (locked …)
        raise InfrastructureError(f"writing {campaign.output / 'results.h5'} failed: "
                                  f"{failure}") from failure
    except ClusterError as failure:  # the cluster broke: the runs stored so far stay
        raise InfrastructureError(f"{failure}; every run finished so far is stored, continue "
                                  f"with `{again}`") from failure
    simulated = time.perf_counter()
    store = ResultStore.open(simulation.results)  # read only: the evaluation writes a new version
    checks = " (collision checks and rulebook)" if collisions is not None else ""
    complete = {name: int(np.sum(store.run_status(name) == STATUS_COMPLETE))
                for name in store.path_names if store.has_runs(name)}
    total = sum(complete.values())
    say(f"evaluating {total} runs of {len(complete)} path(s){checks}")
    began: list[int] = []

    def evaluating(name: str, runs: int) -> None:
        advance(sum(began) / total if total else 0.0, name)
        began.append(complete.get(name, runs))

    clock = PathClock(evaluating)
    then = (f"the simulated runs are stored; free space, then evaluate them with `{again}` "
            f"(or `{command_line('idefix-verify', 'evaluate', simulation.results)}`)")
    try:
        with evaluation_revision(store, then) as revision:
            evaluation = evaluate_store(store, evaluator, rover_geometry(campaign),
                                        initial_position_sigma(campaign), collisions,
                                        rulebook_info(evaluator, campaign.rulebook),
                                        workers=local_workers(options, campaign),
                                        on_path=clock.start, into=revision.store,
                                        waivers=campaign.model.waivers)
            result = finish_evaluation(revision, evaluation, campaign, campaign.output,
                                       junit, campaign.name,
                                       clock.seconds(simulation.path_seconds), then,
                                       again=again)
    finally:
        store.close()
    evaluated = time.perf_counter()
    result.warnings.extend(warnings + simulation.warnings)
    warn_lost_runs(result, again)
    if report:
        say("writing the report (per-sample risk maps, figures)")
        try:
            again_report = command_line("idefix-verify", "report", result.results)
            result.report = write_report(result.results, campaign.output,
                                         "the results and summary.json are written; free space, "
                                         f"then `{again_report}`", advance)
        except KeyboardInterrupt as stop:  # the results and summary.json are complete
            raise ReportInterrupted(result) from stop
        except BrokenPipeError:  # stdout's reader went away: nothing is left to say
            raise
        except (OSError, IdefixError) as failure:  # a full disk, a folder where a figure goes
            raise ReportFailed(result, failure) from failure
    result.timings = {"preparation_and_simulation": simulated - started,
                      "evaluation": evaluated - simulated,
                      "report": time.perf_counter() - evaluated,
                      "total": time.perf_counter() - started,
                      "inside_fmu": simulation.fmu_seconds,
                      "writing": simulation.write_seconds,
                      "simulated_runs": float(simulation.simulated_runs)}
    return result


REPORT_BYTES = 2 * 1024 * 1024
REPORT_BYTES_PER_PATH = 1024 * 1024


def write_report(results: Path, output: Path, then: str = "",
                 advance: Callable[[float, str], None] | None = None) -> Path:
    """The HTML report (``report.html`` and figures) next to the results (``DiskFull``
    before anything is written when the disk has not room for it); ``advance(fraction,
    stage)`` hears how far it is."""
    from idefix_rules.report import write_report as write_html_report

    store = ResultStore.open(results)  # UserInputError for a missing or foreign file
    try:
        paths = len(store.file["paths"])
    finally:
        store.close()
    doing = f"write {REPORT_FILE} and its figures"
    output.mkdir(parents=True, exist_ok=True)
    diskspace.require(output, REPORT_BYTES + REPORT_BYTES_PER_PATH * paths, doing, then)
    with diskspace.guard(output, doing, then):
        return Path(write_html_report(results, output, advance))
