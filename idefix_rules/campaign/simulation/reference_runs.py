"""Each path before its Monte Carlo runs: its command rules (a path that breaks one is
rejected), the FMU's set-up probed once, the path's reference run with the extreme draws of the
uncertain parameters set up beside it (a value the FMU refuses stops the campaign), and the
pre-screen applied to that run (a path it excludes is simulated no further)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from idefix_rules.campaign.input import waivers
from idefix_rules.campaign.input.campaign_values import initial_position_sigma, nominal_parameters
from idefix_rules.campaign.input.load import Campaign
from idefix_rules.campaign.input.sampling import planned_draws
from idefix_rules.campaign.input.wording import DisplayUnits, violation_text
from idefix_rules.campaign.simulation import resume as resuming
from idefix_rules.campaign.simulation import timeouts as run_timeouts
from idefix_rules.campaign.simulation.pool import Outcome
from idefix_rules.campaign.simulation.prescreen import finding_text, prescreen_reference
from idefix_rules.campaign.simulation.processes import timeout_reason
from idefix_rules.campaign.simulation.run_stage import (
    FmuSource,
    PathPlan,
    Progress,
    SimulationOptions,
    SimulationSummary,
)
from idefix_rules.campaign.simulation.run_tasks import (
    open_pool,
    placed_in_campaign,
    pool_results,
    raise_input_problem,
    run_task,
)
from idefix_rules.campaign.simulation.worker import InputProblem, RunTask, simulate
from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.commands import RoverGeometry
from idefix_rules.errors import Diagnostic, InfrastructureError, UserInputError


def command_rules(campaign: Campaign, evaluator: Any, rover: RoverGeometry,
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
        placed = placed_in_campaign(campaign, diagnostic)
        if placed.code != "F110":
            continue
        refused.append(dataclasses.replace(
            placed, message=f"{placed.message}: run {check.run} of path {check.path} draws it "
                            f"(of {check.planned} planned), before any run was simulated",
            hint="bound the distribution inside the range the FMU allows (a truncated_normal "
                 "with low and high, a uniform), or narrow it"))
    return refused


def reference_runs(campaign: Campaign, evaluator: Any, rover: RoverGeometry, fmu: FmuSource,
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
        with pool_results(pool, [(probe, dataclasses.replace(tasks[0][1], stop_time=0.0,
                                                             samples=1))],
                          close=False) as results:
            for _, outcome in results:
                raise_input_problem(campaign, outcome)
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
    with pool_results(pool, tasks + [(check, task) for check, task in checks]) as results:
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
    raise_input_problem(campaign, outcome)
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
