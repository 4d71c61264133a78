"""``idefix-verify evaluate results.h5 [--rulebook R]``: re-score stored results."""

from __future__ import annotations

import argparse
from pathlib import Path

from idefix_rules.cli.destinations import output_file, output_folder

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
    parser.add_argument("--quiet", action="store_true", help="accepted for symmetry with run")


def run(args: argparse.Namespace) -> int:
    from rich.console import Console

    from idefix_rules.campaign.runner import rescore
    from idefix_rules.cli.console import make_console
    from idefix_rules.cli.outcome import print_outcome
    from idefix_rules.cli.run import stored_titles

    console = make_console()
    with Console(stderr=True).status("evaluating the stored runs (collision checks, rulebook)"):
        result = rescore(args.results, args.rulebook, args.junit, args.out)
    print_outcome(console, result.evaluation, result.expectations, result.exit_code,
                  result.warnings, stored_titles(result.results))
    if result.problems:  # a waiver matching nothing: said at its line, exit 2
        from idefix_rules.errors import UserInputError

        raise UserInputError(result.problems)
    return result.exit_code
