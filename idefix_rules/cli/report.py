"""``idefix-verify report results.h5 [-o DIR]``: the HTML report of a stored campaign.

Writes ``report.html`` (self-contained: figures and data embedded, its own small script, no
request of any kind) and the figures as PNG into ``DIR`` (default: the folder of the results
file). Exit 0 when written, 2 when the results file is missing or not a results file.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from idefix_rules.cli.destinations import output_folder

NAME = "report"
HELP = ("Write the HTML report of a results file: the decision, Table 1, an interactive "
        "result map (hover a cell, switch paths, open a run's time series), printable maps, "
        "the final-error box plots, sensitivity, what drove the risk, rule coverage; "
        "report.html (one offline file) plus the figures as PNG.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("results", type=Path, metavar="RESULTS_H5",
                        help="results file written by a campaign run (results.h5)")
    parser.add_argument("-o", "--out", type=output_folder, default=None, metavar="DIR",
                        help="output folder (default: the results file's folder)")


def run(args: argparse.Namespace) -> int:
    from idefix_rules.campaign.runner import write_report
    from idefix_rules.cli.console import make_console, status

    out = args.out if args.out is not None else args.results.resolve().parent
    # -o was checked as it was read; the results' folder is checked here (a missing results
    # file is said first, H001, when it is read)
    if args.out is None and args.results.is_file():
        from idefix_rules.cli.destinations import writable_folder
        from idefix_rules.errors import Span, UserInputError, error

        problem = writable_folder(out)
        if problem is not None:
            raise UserInputError(error(
                "C205", f"output folder {out} cannot be used: {problem}", Span(str(args.results)),
                hint="the report goes beside the results file by default: give a folder this "
                     "user can write with -o DIR"))
    if args.out is not None:
        _refuse_another_campaigns_folder(args.results, out)
    # a report already there (of this campaign or any other) is kept, as a run keeps it
    from idefix_rules.files import report_outputs, set_aside
    from idefix_rules.report import REPORT_FILE

    set_aside(*report_outputs(out, REPORT_FILE))
    with status("writing the report"):
        page = write_report(args.results, out, "free space, then run this command again")
    make_console().print(f"report written: [bold]{page}[/bold]")
    return 0


def _refuse_another_campaigns_folder(results: Path, out: Path) -> None:
    """A report written beside another results file would speak for that campaign: its
    folder's summary.json and results.h5 would sit next to a report.html of this one (C714)."""
    from idefix_rules.errors import Span, UserInputError, error

    other = out / "results.h5"
    try:
        same = other.samefile(results)
    except OSError:  # no results file there (or this one is missing: H001 says so)
        return
    if not same:
        raise UserInputError(error(
            "C714", f"{out} holds another results file ({other.name}): a report of "
                    f"{results} written there would speak for the runs that file holds",
            Span(str(results)),
            hint=f"leave out -o (the report goes beside {results.name}) or give a folder "
                 "without a results file"))
