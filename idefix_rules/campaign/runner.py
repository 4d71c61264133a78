"""One campaign end to end: load → simulate → store → evaluate → outputs (the CLI renders).

>>> from idefix_rules.campaign.runner import run_campaign  # doctest: +SKIP
>>> result = run_campaign(load_campaign("campaigns/rock-detour.yaml"))  # doctest: +SKIP
>>> result.exit_code  # doctest: +SKIP
0
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from idefix_rules.campaign import outputs
from idefix_rules.campaign.environment import build_terrain, read_terrain, write_terrain
from idefix_rules.campaign.evaluation import (
    CampaignEvaluation,
    collision_function,
    evaluate_store,
)
from idefix_rules.campaign.load import Campaign
from idefix_rules.campaign.schema import CampaignFile
from idefix_rules.campaign.simulate import (
    TERRAIN_PARAMETER,
    Progress,
    SimulationOptions,
    initial_position_sigma,
    rover_geometry,
    simulate_campaign,
)
from idefix_rules.campaign.store import ResultStore
from idefix_rules.campaign.validate import (
    check_parameters,
    check_rocks_on_terrain,
    check_signal_map,
    check_simulation_size,
    prepare_output,
)
from idefix_rules.campaign.yamlsource import load_yaml
from idefix_rules.errors import InfrastructureError, Span, UserInputError, error

SUMMARY_FILE = "summary.json"


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


def compile_rulebook_file(path: Path) -> Any:
    """Load, check and compile a rulebook (UserInputError on any mistake)."""
    from idefix_rules.rulebook import compile_rulebook, load_rulebook

    return compile_rulebook(load_rulebook(path))


def rulebook_info(evaluator: Any, path: Path) -> dict[str, str]:
    return {"name": str(evaluator.name), "version": str(evaluator.version),
            "sha256": str(evaluator.source_hash), "path": str(path)}


def resolve_fmu(campaign: Campaign) -> Path:
    if campaign.fmu is not None:
        return campaign.fmu
    from idefix_rules.fmu import default_fmu_path

    return Path(default_fmu_path())


def _local_workers(options: SimulationOptions, campaign: Campaign) -> int:
    """Processes for the evaluation's collision checks: the local pool's size (1 when the
    simulation went to a Dask cluster, whose workers are not on this machine)."""
    if options.scheduler:
        return 1
    return max(1, options.workers or campaign.workers or os.cpu_count() or 1)


def run_campaign(campaign: Campaign, options: SimulationOptions | None = None,
                 progress: Progress | None = None, junit: Path | None = None,
                 report: bool = True) -> CampaignResult:
    """Simulate, evaluate and write ``results.h5``, ``summary.json`` (and JUnit when asked)."""
    options = options or SimulationOptions()
    started = time.perf_counter()
    evaluator = compile_rulebook_file(campaign.rulebook)
    fmu_path = resolve_fmu(campaign)
    variables = check_parameters(campaign, fmu_path)
    check_signal_map(campaign, evaluator.required_signals)
    check_simulation_size(campaign)
    prepare_output(campaign)
    fixed: dict[str, float | str] = {}
    terrain = build_terrain(campaign.model.environment, campaign.dem)
    check_rocks_on_terrain(campaign, terrain.extent)
    if campaign.fmu is None or TERRAIN_PARAMETER in variables:
        fixed[TERRAIN_PARAMETER] = str(write_terrain(terrain, campaign.output))
    collisions = collision_function(campaign.model.environment, evaluator, terrain)
    try:
        simulation = simulate_campaign(campaign, evaluator, fmu_path, fixed, options, progress,
                                       collisions)
    except OSError as failure:  # the results file could not be written (disk full, locked …)
        raise InfrastructureError(f"writing {campaign.output / 'results.h5'} failed: "
                                  f"{failure}") from failure
    simulated = time.perf_counter()
    if progress is not None:
        progress.message("evaluating")
    store = ResultStore.open(simulation.results, writable=True)
    try:
        evaluation = evaluate_store(store, evaluator, rover_geometry(campaign),
                                    initial_position_sigma(campaign), collisions,
                                    rulebook_info(evaluator, campaign.rulebook),
                                    workers=_local_workers(options, campaign))
        result = _finish(store, evaluation, campaign.model, campaign.output, junit, campaign.name)
    finally:
        store.close()
    evaluated = time.perf_counter()
    result.warnings.extend(simulation.warnings)
    if report:
        result.report = write_report(result.results, campaign.output)
    result.timings = {"preparation_and_simulation": simulated - started,
                      "evaluation": evaluated - simulated,
                      "report": time.perf_counter() - evaluated,
                      "total": time.perf_counter() - started,
                      "inside_fmu": simulation.fmu_seconds,
                      "writing": simulation.write_seconds,
                      "simulated_runs": float(simulation.simulated_runs)}
    return result


def _finish(store: ResultStore, evaluation: CampaignEvaluation, model: CampaignFile,
            output: Path, junit: Path | None, name: str) -> CampaignResult:
    checks = outputs.check_expectations(model.expect, evaluation)
    code = outputs.exit_code(evaluation, checks, bool(model.expect))
    data = outputs.summary(evaluation, checks, code)
    store.file.require_group("evaluation").attrs["summary"] = json.dumps(data, default=str)
    store.file.flush()
    outputs.write_summary(output / SUMMARY_FILE, data)
    if junit is not None:
        try:
            junit.parent.mkdir(parents=True, exist_ok=True)
            junit.write_text(outputs.junit_xml(evaluation, checks, name), encoding="utf-8")
        except OSError as failure:  # the results are stored already: say so
            raise UserInputError(error(
                "C207", f"cannot write the JUnit file {junit}: {failure.strerror or failure}",
                Span(str(junit)), hint=f"the results are in {store.file.filename}")) from None
    return CampaignResult(Path(store.file.filename), evaluation, checks, data, code)


def write_report(results: Path, output: Path) -> Path:
    """The HTML report (``report.html`` and figures) next to the results."""
    from idefix_rules.report import write_report as write_html_report

    return Path(write_html_report(results, output))


def rescore(results: Path, rulebook: Path | None = None, junit: Path | None = None,
            out: Path | None = None) -> CampaignResult:
    """Evaluate stored results again, with their own or another rulebook; no simulation."""
    store = ResultStore.open(results, writable=True)
    try:
        stub = stored_campaign(store)
        model = stub.model
        if rulebook is None:
            text = store.text("rulebook")
            stored = store.file["provenance"]["rulebook"].attrs
            rulebook_path = Path(str(stored.get("path", "rulebook.rules")))
            evaluator = _compile_text(text, rulebook_path)
        else:
            rulebook_path = rulebook
            evaluator = compile_rulebook_file(rulebook)
        _check_stored_signals(store, evaluator, results)
        output = out or results.parent
        collisions = collision_function(model.environment, evaluator,
                                        read_terrain(results.parent))
        evaluation = evaluate_store(store, evaluator, rover_geometry(stub),
                                    initial_position_sigma(stub), collisions,
                                    rulebook_info(evaluator, rulebook_path))
        name = str(store.attrs.get("campaign_name", "campaign"))
        result = _finish(store, evaluation, model, output, junit, name)
        state = str(store.attrs.get("state", "complete"))
        if state != "complete":  # its missing runs count as failed: say why
            runs = f"--runs {store.attrs.get('runs')}"
            if str(store.attrs.get("runs_mode", "fixed")) == "auto":
                runs = (f"--runs auto --max-runs {store.attrs.get('runs')} --min-runs "
                        f"{store.attrs.get('min_runs')}")
            result.warnings.append(
                f"{results} holds a campaign that is {state}: runs never simulated count as "
                f"failed; continue it with `idefix-verify {stub.source} --resume --out "
                f"{results.parent} {runs} --seed {store.attrs.get('seed')}`")
        return result
    finally:
        store.close()


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


def _compile_text(text: str, path: Path) -> Any:
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        copy = Path(folder) / path.name
        copy.write_text(text, encoding="utf-8")
        return compile_rulebook_file(copy)


def stored_campaign(store: ResultStore) -> Campaign:
    """The campaign a results file was simulated from, rebuilt from its stored text (for
    geometry, uncertainty and environment; the FMU and DEM are not resolved)."""
    campaign_text = store.text("campaign")
    campaign_path = str(store.attrs.get("campaign_path", "campaign.yaml"))
    document = load_yaml(campaign_text, campaign_path)
    model = CampaignFile.model_validate(document.data)
    return _campaign_stub(model, Path(campaign_path).parent, campaign_text, campaign_path)


def _campaign_stub(model: CampaignFile, base: Path, text: str, path: str) -> Campaign:
    """A :class:`Campaign` rebuilt from stored text (for geometry and uncertainty only)."""
    from idefix_rules.campaign.load import PathSpec
    from idefix_rules.campaign.yamlsource import SourceMap
    from idefix_rules.commands import Command

    paths = tuple(PathSpec(name, index, tuple(Command(c.max_wheel_rate, c.delta_position,
                                                      c.delta_heading) for c in chain))
                  for index, (name, chain) in enumerate(model.paths.items()))
    return Campaign(source=Path(path), text=text,
                    sha256=hashlib.sha256(text.encode("utf-8")).hexdigest(), model=model,
                    paths=paths, rulebook=base / model.rulebook, output=base / model.output,
                    fmu=None, dem=None, runs=model.run_count, seed=model.uncertainty.seed,
                    workers=None, locations=SourceMap(path), adaptive=model.adaptive)
