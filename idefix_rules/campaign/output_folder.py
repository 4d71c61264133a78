"""A campaign's output folder, owned by one campaign at a time, and the files it holds:
:func:`claimed_output` owns the folder while a campaign writes there and sets the last run's
outputs aside at once, :func:`campaign_files` names what a run reads and writes, and
:func:`check_junit_destination` refuses a ``--junit`` file that is one of those, or an existing
file that is not a JUnit report (``C703``)."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterable, Iterator
from pathlib import Path

from idefix_rules.campaign.input.environment import TERRAIN_FILE
from idefix_rules.campaign.input.load import Campaign
from idefix_rules.campaign.input.validate import prepare_output
from idefix_rules.campaign.simulation.simulate import RESULTS_FILE
from idefix_rules.campaign.storage.ownership import FolderInUse, FolderLock, own_folder
from idefix_rules.errors import IdefixError, Span, UserInputError, error
from idefix_rules.files import (
    is_junit_report,
    previous_path,
    previous_report_path,
    report_outputs,
    set_aside,
    set_aside_report,
)
from idefix_rules.results.format import SEARCH_RECORD_FILE

SUMMARY_FILE = "summary.json"
REPORT_FILE = "report.html"


@contextlib.contextmanager
def claimed_output(campaign: Campaign, junit: Path | None = None,
                   resume: bool = False) -> Iterator[FolderLock]:
    """The campaign's output folder, created and owned by this process for the ``with`` block
    (``C208`` when another campaign owns it), with the last run's outputs set aside at once:
    ``summary.json``, ``report.html`` and, unless resuming, ``results.h5`` (and a search's
    ``worst.json``) become ``*.previous.*``, the JUnit file ``*.xml.previous``. From then on
    nothing in the folder speaks for another run. Refused before it owns the folder, the
    campaign sets aside what it will not write again (:func:`set_aside_refused`); refused for
    its ``--junit`` destination (``C703``), it moves nothing."""
    check_junit_destination(junit, *campaign_files(campaign))
    existed = campaign.output.exists()
    sources = {str(campaign.source): campaign.text}
    try:
        with contextlib.ExitStack() as owned:
            try:
                _check_terrain_source(campaign)
                _check_terrain_file(campaign)
                prepare_output(campaign)
                lock = owned.enter_context(own_folder(
                    campaign.output, span=Span(str(campaign.output)), sources=sources,
                    junit=junit))
            except IdefixError as refusal:
                set_aside_refused(campaign.output, junit, refusal)
                raise
            # a search's record there would speak for results no longer beside it
            moved = set_aside(campaign.output / SUMMARY_FILE, *report_outputs(campaign.output),
                              None if resume else campaign.output / RESULTS_FILE,
                              None if resume else campaign.output / SEARCH_RECORD_FILE)
            set_aside_report(junit)
            try:
                yield lock
            except UserInputError:
                if previous_path(campaign.output / RESULTS_FILE) in moved:
                    _results_back(campaign.output)
                raise
    finally:
        if not existed:  # a campaign refused before writing anything leaves no folder behind
            with contextlib.suppress(OSError):
                campaign.output.rmdir()  # only when empty


def _results_back(folder: Path) -> None:
    """A run refused (exit 2) after it set the last results aside, having simulated no Monte
    Carlo run (a drawn value the FMU refuses, F110, is found beside the reference runs):
    those results go back in place, over what the refused run began, as they stay when a
    run is refused before it takes the folder. Left aside, a second refused run replaced
    them with the first one's stub."""
    from idefix_rules.campaign.simulation.resume import interrupted_runs

    results = folder / RESULTS_FILE
    began = interrupted_runs(results) if results.exists() else (0, 0)
    if began is None or began[0] > 0:  # complete, unreadable, or runs worth resuming
        return
    with contextlib.suppress(OSError):
        os.replace(previous_path(results), results)


def set_aside_refused(folder: Path | None, junit: Path | None,
                      refusal: BaseException | None = None) -> None:
    """A run refused before it owns its output folder writes none of its outputs: the
    ``--junit`` file and the ``folder``'s ``summary.json`` and report (not its results, which
    a ``--resume`` or ``evaluate`` may want) are set aside now, so that none of them speaks
    for this run. The folder is owned while they are moved; a folder another process owns
    (``refusal`` C208, or owned meanwhile) is left as it is, and so is the JUnit file its
    owner writes. A file that cannot be moved stays: the refusal is what is said."""
    if junit is not None and not (isinstance(refusal, FolderInUse)
                                  and refusal.may_write(junit)):
        with contextlib.suppress(OSError):
            set_aside_report(junit)
    if folder is None or isinstance(refusal, FolderInUse) or not folder.is_dir():
        return
    with contextlib.suppress(IdefixError, OSError), own_folder(folder):
        set_aside(folder / SUMMARY_FILE, *report_outputs(folder))


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
    if target.is_file() and not is_junit_report(target):
        raise UserInputError(error(
            JUNIT_CODE, f"--junit {junit} is an existing file that is not a JUnit report; "
                        "it would be replaced (set aside as "
                        f"{previous_report_path(junit).name})", Span(str(junit)),
            hint="give a new file name, or delete the file first if it is meant to go"))


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


def _check_terrain_file(campaign: Campaign) -> None:
    """A terrain file's mistakes (its header, grid and rocks: docs/terrain-format.md), said
    before the folder is taken: reading one costs what copying it does (a few MB; 128 MB at
    most), and the run reads it again. A DEM of bare heights needs the campaign's cell and is
    read once, by the run."""
    from idefix_rules.fmu.terrain import HEIGHT_GRID_SUFFIXES, read_terrain

    dem = campaign.dem
    if dem is not None and dem.suffix.lower() not in HEIGHT_GRID_SUFFIXES and dem.is_file():
        read_terrain(dem)


def campaign_files(campaign: Campaign) -> tuple[list[Path | None], list[Path]]:
    """What a campaign run reads (its files) and writes (its output folder's files and what
    they are set aside as)."""
    inputs: list[Path | None] = [campaign.source, campaign.rulebook, campaign.fmu, campaign.dem]
    written = [RESULTS_FILE, SUMMARY_FILE, REPORT_FILE, TERRAIN_FILE]
    outputs = [campaign.output / name for name in written]
    outputs += [previous_path(path) for path in outputs]
    return inputs, outputs
