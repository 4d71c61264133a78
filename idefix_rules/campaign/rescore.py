"""Stored results evaluated again (``idefix-verify evaluate``), with their own rulebook or
another and without simulating: the stored campaign's waivers, start and signals checked against
the rulebook, the evaluation written as a campaign writes it, and what spoke for the evaluation
it replaces set aside (:func:`rescore`)."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import Any

from idefix_rules.campaign.evaluation.evaluate import evaluate_store
from idefix_rules.campaign.evaluation.gate import gate_again
from idefix_rules.campaign.evaluation.path_result import PathResult
from idefix_rules.campaign.evaluation_writing import (
    CampaignResult,
    EvaluationSteps,
    PathClock,
    check_writable_results_folder,
    evaluation_revision,
    finish_evaluation,
    rulebook_info,
    warn_lost_runs,
)
from idefix_rules.campaign.input import waivers
from idefix_rules.campaign.input.areas import unplaced_area_warnings
from idefix_rules.campaign.input.fmu_checks import describe_warnings
from idefix_rules.campaign.input.validate import check_tolerance_start
from idefix_rules.campaign.input.wording import DisplayUnits
from idefix_rules.campaign.outcome.held import held_warnings
from idefix_rules.campaign.output_folder import REPORT_FILE, SUMMARY_FILE, check_junit_destination
from idefix_rules.campaign.preparation import compile_rulebook_file
from idefix_rules.campaign.simulation.resume import stored_resume_command
from idefix_rules.campaign.storage.journal import roll_back
from idefix_rules.campaign.storage.ownership import FolderInUse, own_folder
from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.errors import IdefixError, Span, UserInputError, error
from idefix_rules.files import previous_path, report_outputs, set_aside, set_aside_report
from idefix_rules.results.campaign import STORED_RULEBOOK, StoredCampaign
from idefix_rules.results.format import is_search
from idefix_rules.results.terrain import StoredTerrain

EXPIRED_WAIVER = "C213"


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
    file. Refused, it sets aside only the JUnit file (it writes none for this command; the
    rest still speaks for the evaluation the results file holds), and nothing when the
    refusal is the JUnit file itself (``C703``) or it is the one a campaign owning the
    folder writes. Ctrl-C is :class:`EvaluationInterrupted`."""
    if results.is_symlink():  # the evaluation is renamed over the file, not over the link
        results = results.resolve()
    output = out or results.parent
    check_junit_destination(junit, [results, rulebook],
                            [output / name for name in (SUMMARY_FILE, REPORT_FILE)]
                            + [previous_path(output / name)
                               for name in (SUMMARY_FILE, REPORT_FILE)]
                            + [previous_path(results)])
    steps = EvaluationSteps()
    try:
        return _rescore(results, rulebook, junit, output, steps)
    except IdefixError as refusal:
        # refused, or failed before the new evaluation was stored: no JUnit file of this
        # command will be written (one written after that is this command's, and stays)
        if junit is not None and not steps.stored and not (
                isinstance(refusal, FolderInUse) and refusal.may_write(junit)):
            with contextlib.suppress(OSError):
                set_aside_report(junit)
        raise


def _rescore(results: Path, rulebook: Path | None, junit: Path | None, output: Path,
             steps: EvaluationSteps) -> CampaignResult:
    check_writable_results_folder(results)
    with contextlib.ExitStack() as owned:
        notes = []
        if results.parent.is_dir() and os.access(results.parent, os.W_OK):
            notes.append(owned.enter_context(own_folder(results.parent, elsewhere=None,
                                                        junit=junit)).note)
            roll_back(results)  # a change of its structure a kill cut off (journal.py)
        store = ResultStore.open(results)  # read only: the evaluation writes a new version
        owned.callback(store.close)
        # what spoke for the evaluation this replaces: the summary, the report with its
        # figures (here and, with --out elsewhere, beside the results) and the JUnit file
        stale = [output / SUMMARY_FILE, *report_outputs(output)]
        if output.resolve() != results.parent.resolve():
            output.mkdir(parents=True, exist_ok=True)
            notes.append(owned.enter_context(own_folder(output, junit=junit)).note)
            stale += [results.parent / SUMMARY_FILE, *report_outputs(results.parent)]
        try:
            result = _rescore_owned(store, results, rulebook, junit, output, stale, steps)
        except KeyboardInterrupt:
            raise EvaluationInterrupted(results, output, steps) from None
        result.notes[:0] = [note for note in notes if note is not None]
        return result


def _rescore_owned(store: ResultStore, results: Path, rulebook: Path | None,
                   junit: Path | None, output: Path, stale: list[Path],
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
            set_aside_report(junit)
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
        steps.set_aside = set_aside(*stale) + set_aside_report(junit)
        if state == "running":  # this process owns the folder: no campaign writes the file,
            state = "interrupted"  # the one that did was killed
            revision.store.attrs["state"] = state
        evaluation = evaluate_store(store, evaluator, stored.rover, stored.sigma, collisions,
                                    rulebook_info(evaluator, rulebook_path),
                                    on_path=clock.start, into=revision.store,
                                    waivers=model.waivers, gate=gate)
        name = str(store.attrs.get("campaign_name", "campaign"))
        again = stored_resume_command(store.attrs, stub.source, results.parent)
        result = finish_evaluation(revision, evaluation, stub, output, junit, name,
                                   clock.seconds(), then, expect=not search, steps=steps,
                                   again=again)
    result.warnings.extend(held_warnings(store.attrs, results, stub.source,
                                         bool(model.expect), state))
    warn_lost_runs(result, again)
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
