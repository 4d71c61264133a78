"""Runs as tasks for the campaign's pool: the task of one run (:func:`run_task`), the pool
that runs them (local processes or Dask, and the local processes the evaluation's collision
checks take, :func:`local_workers`) and its results, its busy workers ended on any exit, and a
mistake of the campaign a worker found (an FMU refusing a parameter) raised at the campaign
line that set it."""

from __future__ import annotations

import contextlib
import dataclasses
import os
from collections.abc import Iterable, Iterator, Mapping
from typing import Any

from idefix_rules.campaign.input.campaign_values import rover_geometry, where_set
from idefix_rules.campaign.input.fmu_variable_checks import fmu_loc, loc_span
from idefix_rules.campaign.input.load import Campaign
from idefix_rules.campaign.input.wording import DisplayUnits, range_text, written_unit_at
from idefix_rules.campaign.simulation.pool import DaskPool, LocalPool, Outcome, Timeouts
from idefix_rules.campaign.simulation.run_stage import FmuSource, PathPlan, SimulationOptions
from idefix_rules.campaign.simulation.worker import InputProblem, RunTask
from idefix_rules.errors import Diagnostic, UserInputError
from idefix_rules.fmu.mapping import PARAMETER_REJECTED


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
def pool_results(pool: Any, tasks: Iterable[tuple[Any, RunTask]], close: bool = True
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
        parameters=tuple((k, v) for k, v in parameters.items() if k not in fmu.tool_only),
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


def raise_input_problem(campaign: Campaign, outcome: Outcome) -> None:
    """A mistake in the campaign found inside a worker stops the campaign (exit 2)."""
    if outcome.ok and isinstance(outcome.value, InputProblem):
        raise UserInputError([placed_in_campaign(campaign, d)
                              for d in outcome.value.diagnostics],
                             sources={str(campaign.source): campaign.text})


def placed_in_campaign(campaign: Campaign, diagnostic: Diagnostic) -> Diagnostic:
    """A parameter the FMU refused (F110), pointed at the campaign line that set it (a
    regolith value, or an uncertain parameter's distribution) instead of the FMU file; an
    output that is no 'command' (C520) at the campaign's map of it, else at the FMU."""
    if diagnostic.code == "C520":
        mapped = [variable for variable, signal in (campaign.model.fmu.signals or {}).items()
                  if signal == "command"]
        loc = ("fmu", "signals", mapped[0]) if mapped else fmu_loc(campaign)
        return dataclasses.replace(diagnostic, span=loc_span(campaign, loc))
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


def local_workers(options: SimulationOptions, campaign: Campaign) -> int:
    """Processes for the evaluation's collision checks: the local pool's size (1 when the
    simulation went to a Dask cluster, whose workers are not on this machine)."""
    if options.scheduler:
        return 1
    return max(1, options.workers or campaign.workers or os.cpu_count() or 1)
