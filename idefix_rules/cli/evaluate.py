"""``idefix-verify evaluate results.h5 [--rulebook R]``: re-score stored results."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from idefix_rules.cli.destinations import output_file, output_folder
from idefix_rules.shell import command_line

if TYPE_CHECKING:
    from idefix_rules.campaign.rescore import EvaluationInterrupted

NAME = "evaluate"
HELP = ("Evaluate a stored campaign (results.h5) again without simulating, with the rulebook "
        "it was run with or another one (--rulebook); rewrites its evaluation and "
        "summary.json. Exit codes as for `run`.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("results", type=Path, help="results.h5 of a campaign")
    parser.add_argument("--rulebook", type=Path,
                        help="rulebook to score with (default: the one stored in the results)")
    parser.add_argument("--junit", type=output_file, metavar="FILE", help="write JUnit XML")
    parser.add_argument("--out", type=output_folder,
                        help="folder for summary.json (default: next to results.h5)")
    parser.add_argument("--quiet", action="store_true",
                        help="no progress at all (no spinner while the stored runs are "
                             "evaluated); the results are still printed")


def run(args: argparse.Namespace) -> int:
    from rich.markup import escape

    from idefix_rules.campaign.rescore import EvaluationInterrupted, rescore
    from idefix_rules.cli.console import make_console, status
    from idefix_rules.cli.outcome import print_outcome
    from idefix_rules.cli.run import stored_titles

    console = make_console()
    try:
        with status("evaluating the stored runs (collision checks, rulebook)", args.quiet):
            result = rescore(args.results, args.rulebook, args.junit, args.out)
    except EvaluationInterrupted as stop:
        console.print(interrupted_text(stop, again(args)), markup=False)
        return 130  # as the dispatcher would, without saying "interrupted" twice
    for note in result.notes:  # as a run says them, before its outcome
        console.print(f"[yellow]note:[/yellow] {escape(note)}")
    print_outcome(console, result.evaluation, result.expectations, result.exit_code,
                  result.warnings, stored_titles(result.results))
    if result.problems:  # a waiver matching nothing: said at its line, exit 2
        from idefix_rules.errors import UserInputError

        raise UserInputError(result.problems)
    return result.exit_code


def again(args: argparse.Namespace) -> str:
    """This command again: what evaluates the stored results anew."""
    words: list[object] = ["idefix-verify", "evaluate", args.results]
    for flag, value in (("--rulebook", args.rulebook), ("--junit", args.junit),
                        ("--out", args.out)):
        if value is not None:
            words += [flag, value]
    return command_line(*words)


def interrupted_text(stop: EvaluationInterrupted, command: str) -> str:
    """What a Ctrl-C left of an evaluation (``interrupted: …``), and the command that does it
    again."""
    steps = stop.steps
    moved = [path.name for path in steps.set_aside if path.suffix != ".png"]
    figures = len(steps.set_aside) - len(moved)
    aside = ", ".join(moved) + (f" and {figures} figure{'s' if figures > 1 else ''}"
                                if figures else "")
    if steps.stored:
        summary = stop.output / "summary.json"
        done = f"the new evaluation is stored in {stop.results}; {summary} is " + \
            ("written" if steps.summary else "not written")
    elif steps.set_aside:
        done = (f"{stop.results} is unchanged (it holds the evaluation it had); the outputs "
                f"that spoke for that evaluation are set aside ({aside})")
    else:
        done = f"nothing was written: {stop.results} and its outputs are as they were"
    return f"interrupted: {done}; evaluate again with `{command}`"
