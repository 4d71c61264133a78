"""The simulation stage: command rules → reference runs → pre-screen → Monte Carlo → results.h5.

:func:`simulate_campaign` chains the stages (the results file opened in :mod:`.results_file`,
the command rules, reference runs and pre-screen in :mod:`.reference_runs`, the Monte Carlo runs
in :mod:`.monte_carlo`); evaluation is a separate stage
(:mod:`idefix_rules.campaign.evaluation.evaluate`) joined to this one only by the results file.
"""

from __future__ import annotations

import contextlib
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from idefix_rules.campaign.input import sampling
from idefix_rules.campaign.input.campaign_values import rover_geometry
from idefix_rules.campaign.input.load import Campaign
from idefix_rules.campaign.simulation import resume as resuming
from idefix_rules.campaign.simulation.monte_carlo import monte_carlo
from idefix_rules.campaign.simulation.reference_runs import command_rules, reference_runs
from idefix_rules.campaign.simulation.results_file import open_store
from idefix_rules.campaign.simulation.run_stage import (
    FmuSource,
    Progress,
    RunStage,
    SilentProgress,
    SimulationOptions,
    SimulationSummary,
    plan_path,
)
from idefix_rules.campaign.storage import diskspace
from idefix_rules.fmu.terrain import Terrain
from idefix_rules.results.terrain import TerrainSource
from idefix_rules.timestamps import now_iso

# the types of simulate_campaign's arguments, for callers that import them with it
__all__ = ["RESULTS_FILE", "TERRAIN_PARAMETER", "Progress", "RunStage", "SilentProgress",
           "SimulationOptions", "SimulationSummary", "simulate_campaign"]

RESULTS_FILE = "results.h5"
# The FMU extracted for the campaign's workers, in its output folder while it runs.
UNPACKED_FMU = ".idefix-fmu"

TERRAIN_PARAMETER = "terrain.file"


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
    store = open_store(campaign, evaluator, fmu_path, results, options.resume, terrain,
                       terrain_seen=TERRAIN_PARAMETER in fmu_parameters)
    was_complete = options.resume and str(store.attrs.get("state", "")) == "complete"
    unpacked = contextlib.ExitStack()
    try:
        fmu = FmuSource(str(fmu_path), _unzip_once(fmu_path, campaign.output, options, unpacked),
                        _tool_only(campaign, fmu_path))
        store.attrs["state"] = "running"
        store.file.flush()
        plans = [plan_path(campaign, spec, rover) for spec in campaign.paths]
        summary.plans = plans
        command_rules(campaign, evaluator, rover, plans, store)
        # a worst-case search (``stage``) draws its own worlds: no planned draws to check
        reference_runs(campaign, evaluator, rover, fmu, fmu_parameters, plans, store,
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
            monte_carlo(campaign, fmu, fmu_parameters, plans, store, options, progress,
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


def _tool_only(campaign: Campaign, fmu_path: Path) -> frozenset[str]:
    """The campaign's geometry values the FMU has no variable for (the tool reads them)."""
    from idefix_rules.campaign.input.campaign_values import tool_only_parameters
    from idefix_rules.fmu.description import describe_fmu

    variables = describe_fmu(fmu_path).variables
    return tool_only_parameters(campaign, (name for name, variable in variables.items()
                                           if variable.settable))


def _unzip_once(fmu_path: Path, output: Path, options: SimulationOptions,
                stack: contextlib.ExitStack) -> str | None:
    """Extract the FMU once into :data:`UNPACKED_FMU` in the campaign's output folder, which
    the campaign owns, and remove it when the campaign ends. A campaign killed on its way
    leaves it there, not in the system's temporary folder, and the next campaign in that
    folder replaces it.

    Workers on a remote Dask cluster cannot see a local folder: there every worker extracts
    the FMU itself (None).
    """
    if options.scheduler:
        return None
    from idefix_rules.fmu import extract_fmu

    folder = output / UNPACKED_FMU
    shutil.rmtree(folder, ignore_errors=True)  # a killed campaign's
    stack.callback(shutil.rmtree, folder, ignore_errors=True)
    return str(extract_fmu(fmu_path, folder))
