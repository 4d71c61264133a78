"""The evaluation written, as a campaign, a re-scoring and a worst-case search write it:
the new version of the results file it goes into (once the disk has room for it), the rulebook
and the seconds per path it records, and :func:`finish_evaluation`, which stores the summary
with it, writes ``summary.json`` (and JUnit) and hands back the :class:`CampaignResult`."""

from __future__ import annotations

import errno
import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from idefix_rules.campaign.evaluation.path_result import CampaignEvaluation
from idefix_rules.campaign.evaluation.sensitivity import store_sensitivity
from idefix_rules.campaign.evaluation.slip import slip_warning
from idefix_rules.campaign.evaluation.spread import spread_warnings
from idefix_rules.campaign.input import waivers
from idefix_rules.campaign.input.load import Campaign
from idefix_rules.campaign.outcome import outputs
from idefix_rules.campaign.outcome.expectation_checks import ExpectationResult, check_expectations
from idefix_rules.campaign.outcome.junit import junit_xml
from idefix_rules.campaign.output_folder import SUMMARY_FILE
from idefix_rules.campaign.storage import diskspace
from idefix_rules.campaign.storage.revision import Revision
from idefix_rules.campaign.storage.store import STATUS_COMPLETE, ResultStore
from idefix_rules.errors import Diagnostic, Span, UserInputError, error
from idefix_rules.files import write_atomic
from idefix_rules.shell import command_line

# What the evaluation stores per complete run, at most (indices and raw values, I_max, time,
# energy, chances, collision counts and details, the clearance profile), for the free-space
# check before it starts.
EVALUATION_BYTES_PER_RUN = 3072


@dataclass
class CampaignResult:
    """Everything a campaign run produced, as data."""

    results: Path
    evaluation: CampaignEvaluation
    expectations: list[ExpectationResult]
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


def warn_lost_runs(result: CampaignResult, again: str) -> None:
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


def check_writable_results_folder(results: Path) -> None:
    """Before anything is set aside: the evaluation writes beside ``results``."""
    folder = results.parent
    if folder.is_dir() and not os.access(folder, os.W_OK | os.X_OK):
        raise _not_writable(results, f"its folder {folder} is not writable")


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


def finish_evaluation(revision: Revision, evaluation: CampaignEvaluation,
                      campaign: Campaign, output: Path, junit: Path | None, name: str,
                      seconds: dict[str, float] | None = None, then: str = "",
                      expect: bool = True, steps: EvaluationSteps | None = None,
                      again: str | None = None) -> CampaignResult:
    """Store the summary with the evaluation, put the new results file in place, then write
    ``summary.json`` (and JUnit). A waiver that matched nothing makes the exit code 2.
    ``expect``: the campaign's expectations are checked (not for a worst-case search's
    runs, which say nothing about how often a world occurs); ``steps`` hears how far it
    got; ``again``: the command that runs again the runs lost to the infrastructure."""
    steps = steps or EvaluationSteps()
    model = campaign.model
    expected = model.expect if expect else []
    checks = check_expectations(expected, evaluation)
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
    # what writes the outputs again from the stored evaluation, with this command's JUnit
    # file and summary folder
    rewrite = command_line("idefix-verify", "evaluate", results,
                           *(["--junit", junit] if junit is not None else []),
                           *(["--out", output] if output.resolve() != revision.path.parent
                             .resolve() else []))
    written = f"the evaluation is stored in {results}; free space, then write the outputs " \
              f"again with `{rewrite}`"
    # summary.json, which gives the exit code, comes last: the outputs are written both or
    # neither, so none gives an exit code the command does not exit with
    if junit is not None:
        _write_junit(junit, junit_xml(evaluation, checks, name, seconds, results, problems,
                                      again), written, f"the results are in {revision.path}; "
                     f"once {junit} can be written, write the outputs again with `{rewrite}`")
    try:
        with diskspace.guard(output, f"write {SUMMARY_FILE}", written):
            outputs.write_summary(output / SUMMARY_FILE, data)
    except BaseException:
        if junit is not None:
            junit.unlink(missing_ok=True)
        raise
    steps.summary = True
    slipped = slip_warning(evaluation.slip)
    warnings = [slipped] if slipped else []
    warnings += spread_warnings([path.risk_spread for path in evaluation.paths])
    return CampaignResult(revision.path, evaluation, checks, data, code, warnings,
                          problems=problems)


def _write_junit(junit: Path, text: str, written: str, hint: str) -> None:
    """The JUnit file, whole or not at all: a full disk is :class:`DiskFull` (exit 3, as every
    full disk, ``written`` saying what to do), a place it cannot go (no permission, a folder
    there, a read-only file system) is ``C207`` (exit 2) with ``hint``."""
    try:
        with diskspace.guard(junit.parent, f"write {junit.name}", written):
            junit.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(junit, text)
    except OSError as failure:  # a full disk is DiskFull by now: this is the file's place
        raise UserInputError(error(
            "C207", f"cannot write the JUnit file {junit}: {failure.strerror or failure}",
            Span(str(junit)), hint=hint)) from None


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


@dataclass
class EvaluationSteps:
    """How far an evaluation of stored results got: the outputs it set aside (their new
    names), whether the new evaluation is in the results file, and ``summary.json`` written."""

    set_aside: list[Path] = field(default_factory=list)
    stored: bool = False
    summary: bool = False
