"""One campaign end to end: load → simulate → store → evaluate → outputs (the CLI renders).

>>> from idefix_rules.campaign.runner import run_campaign  # doctest: +SKIP
>>> result = run_campaign(load_campaign("campaigns/rock-detour.yaml"))  # doctest: +SKIP
>>> result.exit_code  # doctest: +SKIP
0
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from idefix_rules.campaign.adaptive import adaptive_monte_carlo
from idefix_rules.campaign.evaluation.evaluate import (
    CampaignEvaluation,
    PathResult,
    evaluate_store,
)
from idefix_rules.campaign.evaluation.gate import gate_again
from idefix_rules.campaign.evaluation.remembered import RememberedCollisions
from idefix_rules.campaign.evaluation.sensitivity import store_sensitivity
from idefix_rules.campaign.evaluation.slip import slip_warning
from idefix_rules.campaign.evaluation.spread import spread_warnings
from idefix_rules.campaign.input import waivers
from idefix_rules.campaign.input.areas import unplaced_area_warnings
from idefix_rules.campaign.input.environment import TERRAIN_FILE, build_terrain, write_terrain
from idefix_rules.campaign.input.fmu_checks import check_fmu, describe_warnings
from idefix_rules.campaign.input.load import Campaign, initial_position_sigma, rover_geometry
from idefix_rules.campaign.input.validate import (
    check_drawn_starts_on_terrain,
    check_paths_on_terrain,
    check_polygons_on_terrain,
    check_rocks_on_terrain,
    check_simulation_size,
    check_start_on_terrain,
    check_tolerance_start,
    prepare_output,
)
from idefix_rules.campaign.input.wording import DisplayUnits
from idefix_rules.campaign.outcome import outputs
from idefix_rules.campaign.outcome.held import held_warnings
from idefix_rules.campaign.simulation.dask_pool import ClusterError
from idefix_rules.campaign.simulation.resume import resume_command, stored_resume_command
from idefix_rules.campaign.simulation.simulate import (
    RESULTS_FILE,
    TERRAIN_PARAMETER,
    Progress,
    SimulationOptions,
    local_workers,
    simulate_campaign,
)
from idefix_rules.campaign.storage import diskspace
from idefix_rules.campaign.storage.journal import roll_back
from idefix_rules.campaign.storage.ownership import FolderLock, own_folder
from idefix_rules.campaign.storage.revision import Revision
from idefix_rules.campaign.storage.store import STATUS_COMPLETE, ResultStore
from idefix_rules.errors import (
    Diagnostic,
    IdefixError,
    InfrastructureError,
    Span,
    UserInputError,
    error,
)
from idefix_rules.files import previous_path, report_outputs, set_aside, write_atomic
from idefix_rules.fmu.terrain import Terrain
from idefix_rules.results.campaign import STORED_RULEBOOK, StoredCampaign
from idefix_rules.results.collisions import CollisionFunction, ObstacleCheck, collision_function
from idefix_rules.results.format import is_search
from idefix_rules.results.terrain import StoredTerrain, TerrainSource, terrain_for_resume

_T = TypeVar("_T")
SUMMARY_FILE = "summary.json"
EXPIRED_WAIVER = "C213"
# What the evaluation stores per complete run, at most (indices and raw values, I_max, time,
# energy, chances, collision counts and details, the clearance profile), for the free-space
# check before it starts.
EVALUATION_BYTES_PER_RUN = 3072
REPORT_FILE = "report.html"


@dataclass
class CampaignResult:
    """Everything a campaign run produced, as data."""

    results: Path
    evaluation: CampaignEvaluation
    expectations: list[outputs.ExpectationResult]
    summary: dict[str, Any]
    exit_code: int
    warnings: list[str] = field(default_factory=list)
    report: Path | None = None
    # Wall-clock seconds per stage, and seconds workers spent inside FmuRunner.run.
    timings: dict[str, float] = field(default_factory=dict)
    # Mistakes of the campaign only the evaluation shows (a waiver matching nothing): exit 2.
    problems: list[Diagnostic] = field(default_factory=list)
    # What was done besides, to say as notes (a stale lock taken over).
    notes: list[str] = field(default_factory=list)


def compile_rulebook_file(path: Path) -> Any:
    """Load, check and compile a rulebook (UserInputError on any mistake)."""
    from idefix_rules.rulebook import compile_rulebook, load_rulebook

    return compile_rulebook(load_rulebook(path))


def rulebook_info(evaluator: Any, path: Path) -> dict[str, str]:
    return {"name": str(evaluator.name), "version": str(evaluator.version),
            "sha256": str(evaluator.source_hash), "path": str(path)}


class PathClock:
    """Seconds each path's evaluation took (from its start to the next path's or to
    :meth:`seconds`), for JUnit's ``time``; passes each start on to ``then``."""

    def __init__(self, then: Any = None) -> None:
        self.then = then
        self.started: list[tuple[str, float]] = []
        self.took: dict[str, float] = {}

    def start(self, name: str, runs: int) -> None:
        self._close()
        self.started.append((name, time.perf_counter()))
        if self.then is not None:
            self.then(name, runs)

    def _close(self) -> None:
        if self.started and self.started[-1][0] not in self.took:
            name, began = self.started[-1]
            self.took[name] = time.perf_counter() - began

    def seconds(self, plus: dict[str, float] | None = None) -> dict[str, float]:
        """Evaluation seconds per path, plus ``plus`` (simulation seconds) where given."""
        self._close()
        total = dict(plus or {})
        for name, value in self.took.items():
            total[name] = total.get(name, 0.0) + value
        return total


def _fmu_cached() -> bool:
    """Whether the built-in rover FMU is already built for these sources."""
    try:
        from idefix_rules.fmu.build import MODEL_IDENTIFIER, cache_dir, source_hash

        return (cache_dir() / f"{MODEL_IDENTIFIER}-{source_hash()[:16]}.fmu").exists()
    except Exception:  # cannot tell: say nothing rather than something wrong
        return True


def resolve_fmu(campaign: Campaign) -> Path:
    if campaign.fmu is not None:
        return campaign.fmu
    from idefix_rules.fmu import default_fmu_path

    return Path(default_fmu_path())


@contextlib.contextmanager
def claimed_output(campaign: Campaign, junit: Path | None = None,
                   resume: bool = False) -> Iterator[FolderLock]:
    """The campaign's output folder, created and owned by this process for the ``with`` block
    (``C208`` when another campaign owns it), with the last run's outputs set aside at once:
    ``summary.json``, ``report.html``, the JUnit file and, unless resuming, ``results.h5``
    become ``*.previous.*``. From then on nothing in the folder speaks for another run."""
    check_junit_destination(junit, *campaign_files(campaign))
    _check_terrain_source(campaign)
    existed = campaign.output.exists()
    prepare_output(campaign)
    sources = {str(campaign.source): campaign.text}
    try:
        with own_folder(campaign.output, span=Span(str(campaign.output)),
                        sources=sources) as lock:
            set_aside(campaign.output / SUMMARY_FILE, *report_outputs(campaign.output), junit,
                      None if resume else campaign.output / RESULTS_FILE)
            yield lock
    finally:
        if not existed:  # a campaign refused before writing anything leaves no folder behind
            with contextlib.suppress(OSError):
                campaign.output.rmdir()  # only when empty


JUNIT_CODE = "C703"


def check_junit_destination(junit: Path | None, inputs: Iterable[Path | None],
                            outputs: Iterable[Path]) -> None:
    """Refuse (``C703``, exit 2) a JUnit destination that names an input of the command (the
    campaign, its rulebook, FMU, terrain file; a results file re-scored), one of the files it
    writes (``results.h5``, ``summary.json``, the report …), or any existing file that is not
    a JUnit report: the file given is set aside as ``*.previous.*`` and replaced by XML, so a
    slip of the argument would put XML where the campaign or its results were."""
    if junit is None:
        return
    target = junit.resolve()
    for path in [*inputs, *outputs]:
        if path is not None and path.resolve() == target:
            raise UserInputError(error(
                JUNIT_CODE, f"--junit {junit} is a file this command reads or writes "
                            f"({path}); it would be replaced by the JUnit report",
                Span(str(junit)), hint="give the JUnit report a file of its own, e.g. "
                                       "--junit junit.xml"))
    if target.is_file() and not _is_junit_report(target):
        raise UserInputError(error(
            JUNIT_CODE, f"--junit {junit} is an existing file that is not a JUnit report; "
                        "it would be replaced (set aside as "
                        f"{previous_path(junit).name})", Span(str(junit)),
            hint="give a new file name, or delete the file first if it is meant to go"))


def _is_junit_report(path: Path) -> bool:
    """Whether an existing file may be replaced by a JUnit report: an empty file (``touch``,
    ``mktemp``), or an XML document (UTF-8 or UTF-16 with its byte order mark) whose first
    element is ``testsuites`` or ``testsuite`` (ours or another tool's, after any
    declaration, stylesheet instruction, comment or document type)."""
    try:
        with path.open("rb") as handle:
            head = handle.read(8192)
    except OSError:
        return False
    if not head.strip():
        return True
    encoding = "utf-16" if head[:2] in (b"\xff\xfe", b"\xfe\xff") else "utf-8"
    text = head.decode(encoding, errors="replace").lstrip("\ufeff")
    prolog = re.compile(r"\s*(<\?.*?\?>|<!--.*?-->|<!DOCTYPE[^>]*>)", re.DOTALL)
    while (found := prolog.match(text)) is not None:
        text = text[found.end():]
    return re.match(r"\s*<testsuites?[\s/>]", text) is not None


def _check_terrain_source(campaign: Campaign) -> None:
    """A DEM the campaign reads is never the terrain file it writes into its output folder
    (C217): the run would replace it with itself plus the campaign's rocks, and every run
    after would add the rocks again."""
    if campaign.dem is None:
        return
    written = campaign.output / TERRAIN_FILE
    if campaign.dem.resolve() in (written.resolve(), previous_path(written).resolve()):
        raise UserInputError(error(
            "C217", f"environment.terrain.dem: the DEM is the terrain file this campaign "
                    f"writes into its output folder ({TERRAIN_FILE}); the run would replace it",
            campaign.span(("environment", "terrain", "dem")),
            hint="keep the DEM beside the campaign, or write the campaign's output elsewhere"),
            sources={str(campaign.source): campaign.text})


def campaign_files(campaign: Campaign) -> tuple[list[Path | None], list[Path]]:
    """What a campaign run reads (its files) and writes (its output folder's files and what
    they are set aside as)."""
    inputs: list[Path | None] = [campaign.source, campaign.rulebook, campaign.fmu, campaign.dem]
    written = [RESULTS_FILE, SUMMARY_FILE, REPORT_FILE, TERRAIN_FILE]
    outputs = [campaign.output / name for name in written]
    outputs += [previous_path(path) for path in outputs]
    return inputs, outputs


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


@dataclass
class PreparedSimulation:
    """What simulating a campaign needs once its inputs are checked: the compiled rulebook,
    the FMU, the run-independent FMU parameters (the terrain file), the obstacle checker
    (None when the rulebook reads no collision) and the warnings to say with the outcome."""

    evaluator: Any
    fmu_path: Path
    fixed: dict[str, float | str]
    collisions: CollisionFunction | None
    warnings: list[str]
    terrain: Terrain  # what the runs are simulated on, stored in the results file
    source: TerrainSource  # where it came from


def prepare_simulation(campaign: Campaign, say: Callable[[str], None],
                       again: str, resume: bool = False,
                       planned_runs: bool = True) -> PreparedSimulation:
    """Compile the rulebook, check the waivers and the FMU's mapping, build the terrain (and
    write it where the FMU reads it) and the obstacle checker; every mistake is a
    :class:`UserInputError` before anything is simulated. ``again`` is the command that goes
    on after a full disk was freed; ``resume``: the terrain stored in the results file so far
    is the one the missing runs are simulated on. ``planned_runs``: the campaign simulates its
    planned Monte Carlo runs, whose draws are checked (False for a worst-case search, which
    draws worlds of its own)."""
    say(f"compiling the rulebook {campaign.rulebook.name}")
    evaluator = compile_rulebook_file(campaign.rulebook)
    # the campaign's mistakes, every one found before any is said (a check that needs what a
    # failed one would give is skipped: the terrain's checks without a terrain)
    problems: list[Diagnostic] = list(waivers.waiver_problems(campaign, evaluator.rulebook))
    # the texts each failure quotes from (a DEM's own text is never quoted: it is given empty)
    sources: dict[str, str] = {str(campaign.source): campaign.text}

    def gather(check: Callable[[], _T]) -> _T | None:
        try:
            return check()
        except UserInputError as failure:
            problems.extend(failure.diagnostics)
            sources.update(failure.sources)
            return None

    gather(lambda: check_tolerance_start(campaign, evaluator))
    if campaign.fmu is None and not _fmu_cached():
        say("building the rover FMU from its C sources (once; cached afterwards)")
    fmu_path = resolve_fmu(campaign)
    mapping = gather(lambda: check_fmu(campaign, fmu_path, evaluator))
    gather(lambda: check_simulation_size(campaign))
    say("preparing the terrain")
    terrain = gather(lambda: build_terrain(campaign.model.environment, campaign.dem))
    if terrain is not None:
        extent = terrain.extent
        gather(lambda: _check_on_terrain(campaign, extent, planned_runs))
    if problems:
        raise UserInputError(problems, sources=sources)
    assert mapping is not None and terrain is not None
    # said once, with the outcome
    warnings = describe_warnings(mapping.warnings, {str(campaign.source): campaign.text})
    fixed: dict[str, float | str] = {}
    source = TerrainSource.of(campaign.dem)
    if resume:  # the runs still missing are simulated on the terrain stored so far
        terrain, notes = _resumed_terrain(campaign.output / RESULTS_FILE, terrain, source)
        warnings += notes
    if mapping.terrain_input:
        doing, then = "write the terrain file", f"free space, then run `{again}`"
        diskspace.require(campaign.output, terrain.heights.size * 8, doing, then)
        with diskspace.guard(campaign.output, doing, then):
            fixed[TERRAIN_PARAMETER] = str(write_terrain(terrain, campaign.output))
    collisions = collision_function(campaign.model.environment, evaluator, terrain,
                                    rover_geometry(campaign))
    return PreparedSimulation(evaluator, fmu_path, fixed, collisions, warnings, terrain,
                              source)


def _run_owned(campaign: Campaign, options: SimulationOptions, progress: Progress | None,
               junit: Path | None, report: bool) -> CampaignResult:
    started = time.perf_counter()
    say = progress.message if progress is not None else (lambda text: None)
    # How far a phase is, where the progress shows it (an ETA); optional in the protocol.
    advance = getattr(progress, "advance", None) or (lambda fraction, detail="": None)
    again = resume_command(campaign.source, campaign.output, campaign.runs, campaign.seed,
                           campaign.adaptive.min_runs if campaign.adaptive else None)
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
            f"(or `idefix-verify evaluate {simulation.results}`)")
    try:
        with evaluation_revision(store, then) as revision:
            evaluation = evaluate_store(store, evaluator, rover_geometry(campaign),
                                        initial_position_sigma(campaign), collisions,
                                        rulebook_info(evaluator, campaign.rulebook),
                                        workers=local_workers(options, campaign),
                                        on_path=clock.start, into=revision.store,
                                        waivers=campaign.model.waivers)
            result = _finish(revision, evaluation, campaign, campaign.output, junit,
                             campaign.name, clock.seconds(simulation.path_seconds), then)
    finally:
        store.close()
    evaluated = time.perf_counter()
    result.warnings.extend(warnings + simulation.warnings)
    _warn_lost_runs(result, again)
    if report:
        say("writing the report (per-sample risk maps, figures)")
        try:
            result.report = write_report(result.results, campaign.output,
                                         "the results and summary.json are written; free space, "
                                         f"then `idefix-verify report {result.results}`",
                                         advance)
        except KeyboardInterrupt as stop:  # the results and summary.json are complete
            raise ReportInterrupted(result) from stop
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


def _resumed_terrain(results: Path, terrain: Terrain, source: TerrainSource
                     ) -> tuple[Terrain, list[str]]:
    """The terrain a ``--resume`` of ``results`` simulates on (the stored one) and what to say
    about it (:func:`~idefix_rules.results.terrain.terrain_for_resume`)."""
    if not results.is_file():
        return terrain, []
    roll_back(results)  # a change of its structure a kill cut off (journal.py)
    try:
        store = ResultStore.open(results)
    except UserInputError:  # not a results file: resuming it says so, with what to do
        return terrain, []
    try:
        return terrain_for_resume(store.file, terrain, source, results)
    finally:
        store.close()


def _warn_lost_runs(result: CampaignResult, again: str) -> None:
    lost = outputs.infrastructure_failures(result.evaluation)
    if lost:
        result.warnings.append(f"{lost} run(s) were lost to the infrastructure (killed from "
                               "outside, or lost by the cluster), not failed for a reason of "
                               f"their own (exit code 3); run them again with `{again}`")


def _not_writable(path: Path, failure: OSError | str) -> UserInputError:
    reason = failure if isinstance(failure, str) else (failure.strerror or str(failure))
    return UserInputError(error(
        "H002", f"cannot write the evaluation of {path}: {reason}", Span(str(path)),
        hint="the evaluation writes a new version of the results file beside it: its "
             "folder must be writable (copy the results elsewhere to evaluate them)"))


def _check_writable_results_folder(results: Path) -> None:
    """Before anything is set aside: the evaluation writes beside ``results``."""
    folder = results.parent
    if folder.is_dir() and not os.access(folder, os.W_OK | os.X_OK):
        raise _not_writable(results, f"its folder {folder} is not writable")


def _check_on_terrain(campaign: Campaign, extent: tuple[float, float, float, float],
                      planned_runs: bool = True) -> None:
    """Rocks, the rover's start and its chains on the terrain, every mistake said at once (a
    chain is checked only from a start on the terrain: from one off it, every chain is off)."""
    problems: list[Diagnostic] = []

    def gather(check: Callable[[Campaign, tuple[float, float, float, float]], None]) -> bool:
        try:
            check(campaign, extent)
        except UserInputError as failure:
            problems.extend(failure.diagnostics)
            return False
        return True

    gather(check_rocks_on_terrain)
    gather(check_polygons_on_terrain)
    terrain_given = campaign.model.environment.terrain.dem is not None \
        or campaign.model.environment.terrain.synthetic is not None
    # the built-in rover starts at initial.x, initial.y on the terrain it is given (a foreign
    # FMU may start from parameters of its own; without a terrain the ground is flat
    # everywhere)
    if campaign.fmu is None and terrain_given and gather(check_start_on_terrain):
        gather(check_paths_on_terrain)
        if planned_runs:
            gather(check_drawn_starts_on_terrain)
    if problems:
        raise UserInputError(problems, sources={str(campaign.source): campaign.text})


def evaluation_revision(store: ResultStore, then: str) -> Revision:
    """The new version of ``store``'s results file the evaluation writes into
    (:mod:`idefix_rules.campaign.storage.revision`), once the disk has room for it and for the
    evaluation (``DiskFull`` otherwise, ``then`` saying what to do next)."""
    try:
        revision = Revision(store.path)
    except OSError as failure:
        if failure.errno not in (errno.EACCES, errno.EPERM, errno.EROFS):
            raise
        raise _not_writable(store.path, failure) from None
    try:
        diskspace.require(store.folder, revision.needed(evaluation_bytes(store)),
                          f"write the evaluation into {store.path.name}", then)
    except BaseException:
        revision.discard()
        raise
    return revision


def _finish(revision: Revision, evaluation: CampaignEvaluation, campaign: Campaign,
            output: Path, junit: Path | None, name: str,
            seconds: dict[str, float] | None = None, then: str = "",
            expect: bool = True, steps: EvaluationSteps | None = None) -> CampaignResult:
    """Store the summary with the evaluation, put the new results file in place, then write
    ``summary.json`` (and JUnit). A waiver that matched nothing makes the exit code 2.
    ``expect``: the campaign's expectations are checked (not for a worst-case search's
    runs, which say nothing about how often a world occurs); ``steps`` hears how far it
    got."""
    steps = steps or EvaluationSteps()
    model = campaign.model
    expected = model.expect if expect else []
    checks = outputs.check_expectations(expected, evaluation)
    code = outputs.exit_code(evaluation, checks, bool(expected))
    problems = waivers.unused(model.waivers, evaluation, campaign.span)
    if problems and code != outputs.EXIT_INFRASTRUCTURE:
        code = outputs.EXIT_INPUT
    results = str(revision.path.resolve())
    data = outputs.summary(evaluation, checks, code, store_sensitivity(revision.store.file),
                           results, problems)
    revision.store.file.require_group("evaluation").attrs["summary"] = \
        json.dumps(data, default=str)
    revision.commit(f"write the evaluation into {revision.path.name}", then)
    steps.stored = True
    written = f"the evaluation is stored in {results}; free space, then write the outputs " \
              f"again with `idefix-verify evaluate {results}`"
    with diskspace.guard(output, f"write {SUMMARY_FILE}", written):
        outputs.write_summary(output / SUMMARY_FILE, data)
    steps.summary = True
    if junit is not None:
        try:
            junit.parent.mkdir(parents=True, exist_ok=True)
            with diskspace.guard(junit.parent, f"write {junit.name}", written):
                write_atomic(junit, outputs.junit_xml(evaluation, checks, name, seconds,
                                                      results, problems))
        except OSError as failure:  # the results are stored already: say so
            raise UserInputError(error(
                "C207", f"cannot write the JUnit file {junit}: {failure.strerror or failure}",
                Span(str(junit)), hint=f"the results are in {revision.path}")) from None
    slipped = slip_warning(evaluation.slip)
    warnings = [slipped] if slipped else []
    warnings += spread_warnings([path.risk_spread for path in evaluation.paths])
    return CampaignResult(revision.path, evaluation, checks, data, code, warnings,
                          problems=problems)


def evaluation_bytes(store: ResultStore) -> int:
    """About what writing the evaluation of ``store`` takes (before compression): per
    complete run its indices, I_max, time, energy, chances and collision results."""
    total = 0
    for name in store.path_names:
        if not store.has_runs(name):
            continue
        status = store.run_status(name)
        total += int(np.sum(status == STATUS_COMPLETE)) * EVALUATION_BYTES_PER_RUN \
            + status.size * 2
    return total


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


@dataclass
class EvaluationSteps:
    """How far an evaluation of stored results got: the outputs it set aside (their new
    names), whether the new evaluation is in the results file, and ``summary.json`` written."""

    set_aside: list[Path] = field(default_factory=list)
    stored: bool = False
    summary: bool = False


class EvaluationInterrupted(KeyboardInterrupt):
    """Ctrl-C while stored results were evaluated again: ``steps`` says what is done (the
    results file keeps its previous evaluation until ``steps.stored``)."""

    def __init__(self, results: Path, output: Path, steps: EvaluationSteps) -> None:
        super().__init__("interrupted while evaluating")
        self.results = results
        self.output = output
        self.steps = steps


def rescore(results: Path, rulebook: Path | None = None, junit: Path | None = None,
            out: Path | None = None) -> CampaignResult:
    """Evaluate stored results again, with their own or another rulebook; no simulation.

    A symbolic link is followed: the file it names is evaluated and rewritten, in its own
    folder (where its outputs go, unless ``out``). That folder (and ``out``) are owned for
    the time (``C208`` while a campaign writes there). Once the new evaluation is being
    written (nothing refused it), what spoke for the one it replaces is set aside: the
    ``summary.json``, report and figures in ``out`` and beside the results, and the JUnit
    file. Ctrl-C is :class:`EvaluationInterrupted`."""
    if results.is_symlink():  # the evaluation is renamed over the file, not over the link
        results = results.resolve()
    output = out or results.parent
    _check_writable_results_folder(results)
    check_junit_destination(junit, [results, rulebook],
                            [output / name for name in (SUMMARY_FILE, REPORT_FILE)]
                            + [previous_path(output / name)
                               for name in (SUMMARY_FILE, REPORT_FILE)]
                            + [previous_path(results)])
    with contextlib.ExitStack() as owned:
        notes = []
        if results.parent.is_dir() and os.access(results.parent, os.W_OK):
            notes.append(owned.enter_context(own_folder(results.parent, elsewhere=None)).note)
            roll_back(results)  # a change of its structure a kill cut off (journal.py)
        store = ResultStore.open(results)  # read only: the evaluation writes a new version
        owned.callback(store.close)
        # what spoke for the evaluation this replaces: the summary, the report with its
        # figures (here and, with --out elsewhere, beside the results) and the JUnit file
        stale = [output / SUMMARY_FILE, *report_outputs(output), junit]
        if output.resolve() != results.parent.resolve():
            output.mkdir(parents=True, exist_ok=True)
            notes.append(owned.enter_context(own_folder(output)).note)
            stale += [results.parent / SUMMARY_FILE, *report_outputs(results.parent)]
        steps = EvaluationSteps()
        try:
            result = _rescore_owned(store, results, rulebook, junit, output, stale, steps)
        except KeyboardInterrupt:
            raise EvaluationInterrupted(results, output, steps) from None
        result.notes[:0] = [note for note in notes if note is not None]
        return result


def _rescore_owned(store: ResultStore, results: Path, rulebook: Path | None,
                   junit: Path | None, output: Path, stale: list[Path | None],
                   steps: EvaluationSteps) -> CampaignResult:
    stored = StoredCampaign(store)
    stub = stored.require_campaign()
    model = stub.model
    search = is_search(store.attrs)
    if rulebook is None:
        from idefix_rules.rulebook import compile_rulebook

        # Spans point into the stored text: results.h5:/provenance/rulebook:LINE:COLUMN; the
        # evaluation records the file absolute, as it records the results and campaign
        rulebook_path = Path(f"{results.resolve()}:{STORED_RULEBOOK}")
        evaluator = compile_rulebook(stored.checked_rulebook())
    else:
        rulebook_path = rulebook.resolve()
        evaluator = compile_rulebook_file(rulebook)
    # The stored campaign's waivers against this rulebook and today's date, as a run checks
    # them: a waiver that expired since the campaign ran no longer covers its failure.
    mistakes = waivers.waiver_problems(stub, evaluator.rulebook, stored=True)
    try:
        check_tolerance_start(stub, evaluator, stored=True)
    except UserInputError as failure:
        mistakes += failure.diagnostics
    if mistakes:
        if any(mistake.code == EXPIRED_WAIVER for mistake in mistakes):
            # the stored evaluation waived on an approval that has lapsed: its outputs no
            # longer hold today, though nothing is scored again
            set_aside(*stale)
        raise UserInputError(mistakes, sources={stub.locations.path: stub.text})
    _check_stored_signals(store, evaluator, results)
    # the terrain matters to the scores only through the collision and area checks
    ground = stored.ground() if getattr(evaluator, "needs_collisions", False) \
        else StoredTerrain(None)
    collisions = stored.collision_function(evaluator)
    clock = PathClock()
    then = f"{results} is unchanged; free space, then evaluate again"
    gate = None
    if rulebook is not None:  # its command rules and prescreen, as a campaign would apply them
        units = DisplayUnits.from_campaign_text(stub.text)

        def gate(result: PathResult) -> None:
            gate_again(result, evaluator, store.chain(result.name), stored.rover, stored.sigma,
                       store.reference(result.name), collisions, model.waivers, units)

    state = str(store.attrs.get("state", "complete"))
    with evaluation_revision(store, then) as revision:
        # nothing refused the evaluation and the disk has room: it is being written now
        steps.set_aside = set_aside(*stale)
        if state == "running":  # this process owns the folder: no campaign writes the file,
            state = "interrupted"  # the one that did was killed
            revision.store.attrs["state"] = state
        evaluation = evaluate_store(store, evaluator, stored.rover, stored.sigma, collisions,
                                    rulebook_info(evaluator, rulebook_path),
                                    on_path=clock.start, into=revision.store,
                                    waivers=model.waivers, gate=gate)
        name = str(store.attrs.get("campaign_name", "campaign"))
        result = _finish(revision, evaluation, stub, output, junit, name, clock.seconds(),
                         then, expect=not search, steps=steps)
    result.warnings.extend(held_warnings(store.attrs, results, stub.source,
                                         bool(model.expect), state))
    _warn_lost_runs(result, stored_resume_command(store.attrs, stub.source, results.parent))
    result.warnings.extend(ground.warnings)
    result.warnings.extend(describe_warnings(unplaced_area_warnings(stub, evaluator),
                                             {stub.locations.path: stub.text}))
    return result


def _check_stored_signals(store: ResultStore, evaluator: Any, results: Path) -> None:
    """The rulebook may read only FMU signals the stored runs hold (a rulebook other than the
    campaign's can need one its FMU map did not provide)."""
    from idefix_rules.signals import FMU_SIGNALS

    required = {name for name in getattr(evaluator, "required_signals", ())
                if name in FMU_SIGNALS}
    problems = []
    for name in store.path_names:
        runs = store.path_group(name).get("runs")
        signals = runs.get("signals") if runs is not None else None
        if signals is None:
            continue  # rejected or excluded before simulation: nothing to evaluate
        missing = sorted(required - set(signals))
        if missing:
            problems.append(error(
                "H011", f"the rulebook reads {', '.join(map(repr, missing))}, which the stored "
                        f"runs of path {name!r} do not hold", Span(str(results)),
                hint="the campaign's FMU signal map did not provide it: simulate again with "
                     "it mapped, or score with a rulebook that does not read it"))
    if problems:
        raise UserInputError(problems)
