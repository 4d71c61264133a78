"""``idefix-verify test [PATH…]``: run the example cases of rulebooks (case files).

Each case file names its rulebook; every case is evaluated with the compiled rulebook on its
synthetic runs (no simulation) and its expectations compared. Coverage and mutation testing
count the cases of all the case files of a rulebook together. Exit 0 when every case passes,
1 when a case fails (or rule coverage is below ``--min-coverage``, or a mutant survives
``--mutate`` below ``--min-mutation-score``), 2 when a case file or its rulebook is broken or an
option is out of range (each mistake located), as ``docs/testing-rulebooks.md`` describes.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from idefix_rules.cli.encoding import json_text
from idefix_rules.errors import UserInputError, render_diagnostics

if TYPE_CHECKING:
    from rich.console import Console

# idefix_rules.testing.mutations.NUDGE in percent, the default of --nudge (a test holds them
# equal; the command line is read without importing the mutations)
DEFAULT_NUDGE_PERCENT = 10.0

NAME = "test"
HELP = ("Run the example cases of rulebooks (case files, default rulebooks/tests/): "
        "'N passed, N failed'; --coverage and --mutate count all case files of a rulebook "
        "together; exit 0 when all pass, 1 when one fails, rule coverage is below "
        "--min-coverage or a mutant survives (below --min-mutation-score), 2 for a broken "
        "case file or an option out of range.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("paths", nargs="*", type=Path, metavar="PATH",
                        help="case files (.yaml) or folders holding them "
                             "(default: rulebooks/tests)")
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="one line per case instead of one character")
    parser.add_argument("--coverage", action="store_true",
                        help="for every rule: did the cases bring it across its limit, near it, "
                             "or never touch it")
    parser.add_argument("--min-coverage", metavar="PERCENT", default=None,
                        help="exit 1 when fewer than PERCENT %% of the rules were brought "
                             "across their limit by the cases (implies --coverage); 90 or "
                             "90%% (a bare fraction such as 0.9 is refused: write 0.9%% if "
                             "that is meant)")
    parser.add_argument("--mutate", action="store_true",
                        help="run every mutant of each rulebook (reducer swaps, thresholds, "
                             "limits and factors nudged both ways, weights, dropped terms, "
                             "flipped operators) against all its cases; print the mutation "
                             "score and the surviving mutants with their line:col")
    parser.add_argument("--min-mutation-score", metavar="PERCENT", default=None,
                        help="with --mutate: exit 0 when at least PERCENT %% of the mutants "
                             "are killed, even if some survive (default: any survivor "
                             "exits 1; implies --mutate); 90 or 90%% (a bare fraction such "
                             "as 0.9 is refused: write 0.9%% if that is meant)")
    parser.add_argument("--nudge", metavar="PERCENT", default=str(DEFAULT_NUDGE_PERCENT),
                        help="how far a mutant moves a threshold, limit, nominal or factor, "
                             f"both ways (default {DEFAULT_NUDGE_PERCENT:g} %%)")
    parser.add_argument("--format", choices=("text", "json"), default="text",
                        help="text (default) or the outcomes as JSON")



def _percent(text: str | None, option: str, code: str, gate: bool = True) -> float | None:
    """A percentage option's value: ``90`` or ``90%``. For a ``gate``, a bare number from 0
    to 1 written with a point (``0.9``, ``1.0``) is refused: read as 0.9 % or 1 %, a gate that
    low passes everything (a fraction meant), so the sign is asked for when so small a
    percentage is meant; ``1`` is 1 %."""
    from idefix_rules.errors import error

    if text is None:
        return None
    written = text.strip()
    signed = written.endswith("%")
    try:
        value = float(written.removesuffix("%").strip())
    except ValueError:
        raise UserInputError(error(code, f"{option} {text!r} is not a number: a percentage "
                                         "such as 90 or 90%")) from None
    if gate and not signed and 0 < value <= 1 and "." in written:
        raise UserInputError(error(
            code, f"{option} {text} would be {value:g} %, which looks like a fraction: the "
                  f"option counts in percent", hint=f"write {option} {value * 100:g} for "
                  f"{value * 100:g} %, or {option} {value:g}% if {value:g} % is meant"))
    return value

def run(args: argparse.Namespace) -> int:
    from idefix_rules.cli.console import make_console
    from idefix_rules.errors import error
    from idefix_rules.testing import discover_case_files, load_case_file, run_case_file
    from idefix_rules.testing.coverage import by_rulebook, coverage_of_files, coverage_percent
    from idefix_rules.testing.mutation_score import MutationReport, score_mutants
    from idefix_rules.testing.runner import FileOutcome

    args.min_coverage = _percent(args.min_coverage, "--min-coverage", "T014")
    args.min_mutation_score = _percent(args.min_mutation_score, "--min-mutation-score", "T015")
    # a nudge read too small fails loudly (its mutants survive): a bare 0.5 is 0.5 %
    args.nudge = _percent(args.nudge, "--nudge", "T015", gate=False)
    if args.min_coverage is not None and not 0 <= args.min_coverage <= 100:
        raise UserInputError(error("T014", "--min-coverage is a percentage from 0 to 100"))
    if args.min_mutation_score is not None and not 0 <= args.min_mutation_score <= 100:
        raise UserInputError(error("T015", "--min-mutation-score is a percentage from 0 to "
                                           "100"))
    if not 0 < args.nudge < 100:
        raise UserInputError(error("T015", "--nudge is a percentage above 0 and below 100"))
    started = time.perf_counter()
    try:
        files = discover_case_files(args.paths)
    except UserInputError as nothing:  # T013: with --format json, said as JSON too
        if args.format != "json":
            raise
        print(json_text({"files": [], "broken": [d.to_dict() for d in nothing.diagnostics],
                         "passed": 0, "failed": 0, "exit_code": 2}, indent=2))
        return 2
    console = make_console(soft_wrap=True)
    broken: list[UserInputError] = []
    outcomes: list[FileOutcome] = []
    for path in files:
        try:
            case_file = load_case_file(path)
        except UserInputError as failure:
            broken.append(failure)
            continue
        outcomes.append(run_case_file(case_file))
    passed = sum(o.passed for f in outcomes for o in f.outcomes)
    failed = sum(not o.passed for f in outcomes for o in f.outcomes)
    groups = by_rulebook(outcomes)
    want_coverage = args.coverage or args.min_coverage is not None
    coverages = [coverage_of_files(g) for g in groups] if want_coverage else []
    percent = coverage_percent([item for c in coverages for item in c]) if coverages else None
    low_coverage = (args.min_coverage is not None and percent is not None
                    and percent < args.min_coverage)
    want_mutation = args.mutate or args.min_mutation_score is not None
    # mutants are scored only against passing cases: a failing case kills every mutant
    reports: list[MutationReport] = [
        score_mutants([f.case_file for f in g], args.nudge / 100) for g in groups
    ] if want_mutation and not failed and not broken else []
    low_score = any(_low_score(r, args.min_mutation_score) for r in reports)
    code = 2 if broken else 1 if failed or low_coverage or low_score else 0
    elapsed = time.perf_counter() - started
    if args.format == "json":
        data: dict[str, Any] = {
            "files": [{"path": f.case_file.path, "rulebook": f.case_file.rulebook_path,
                       "cases": [o.to_dict() for o in f.outcomes]} for f in outcomes],
            "broken": [d.to_dict() for b in broken for d in b.diagnostics],
            "passed": passed, "failed": failed, "exit_code": code}
        if want_coverage:
            data["coverage"] = [{**item.to_dict(), "rulebook": g[0].case_file.rulebook_path}
                                for g, c in zip(groups, coverages, strict=True) for item in c]
            data["coverage_percent"] = percent
            data["coverage_rulebooks"] = [
                {"rulebook": g[0].case_file.rulebook_path,
                 "files": [f.case_file.path for f in g], "percent": coverage_percent(c)}
                for g, c in zip(groups, coverages, strict=True)]
        if want_mutation:
            data["mutation"] = [r.to_dict() for r in reports]
        print(json_text(data, indent=2))
        return code
    for problem in broken:
        console.print(render_diagnostics(problem.diagnostics, problem.sources), markup=False)
    for file in outcomes:
        _print_file(console, file, args.verbose)
    for file in outcomes:
        for outcome in file.outcomes:
            if outcome.passed:
                continue
            console.print(f"\n[bold red]FAILED[/bold red] {outcome.case.span} "
                          f"{outcome.case.name}")
            if outcome.case.description:
                console.print(f"  {outcome.case.description}", markup=False)
            for mismatch in outcome.mismatches:
                console.print("  " + mismatch.render().replace("\n", "\n  "), markup=False)
    if want_coverage:
        for group, items in zip(groups, coverages, strict=True):
            _print_coverage(console, group, items)
        if percent is not None:
            console.print(f"rule coverage: {percent:.0f} % of rules brought across their limit"
                          + (f" (minimum {args.min_coverage:g} %)"
                             if args.min_coverage is not None else ""),
                          style="red" if low_coverage else None, markup=False)
    if want_mutation:
        if failed or broken:
            console.print("mutation testing skipped: the cases must pass first", style="red",
                          markup=False)
        for report in reports:
            _print_mutation(console, report, args.min_mutation_score)
    summary = [f"{failed} failed"] if failed else []
    summary.append(f"{passed} passed")
    if broken:
        summary.append(f"{len(broken)} broken case file{'s' if len(broken) != 1 else ''}")
    style = "red" if code else "green"
    console.print(f"{', '.join(summary)} in {elapsed:.2f}s", style=style, markup=False)
    return code


def _print_file(console: Console, file: Any, verbose: bool) -> None:
    if verbose:
        console.print(f"{file.case_file.path} (rulebook {file.case_file.rulebook_path})",
                      markup=False)
        for outcome in file.outcomes:
            state = "[green]PASSED[/green]" if outcome.passed else "[red]FAILED[/red]"
            console.print(f"  {state} {outcome.case.name}")
        return
    marks = "".join("." if o.passed else "F" for o in file.outcomes)
    console.print(f"{file.case_file.path} {marks}", markup=False)


_STATE_STYLE = {"across": "green", "near": "yellow", "untouched": "red"}


def _print_coverage(console: Console, group: list[Any], items: list[Any]) -> None:
    from rich.table import Table

    cases = sum(len(f.outcomes) for f in group)
    files = ", ".join(f"{f.case_file.path} ({len(f.outcomes)})" for f in group)
    table = Table(title=f"rule coverage: {group[0].case_file.rulebook_path} "
                        f"({cases} cases from {files})", title_justify="left")
    for column in ("kind", "rule", "coverage", "closest", "cases"):
        table.add_column(column, overflow="fold")
    for item in items:
        style = _STATE_STYLE[item.state]
        table.add_row(item.kind, item.name, f"[{style}]{item.label}[/{style}]", item.detail,
                      ", ".join(item.cases[:3]) + (" …" if len(item.cases) > 3 else ""))
    console.print(table)


def _low_score(report: Any, minimum: float | None) -> bool:
    if minimum is None:
        return bool(report.survivors)
    return bool(report.score < minimum)


def _print_mutation(console: Console, report: Any, minimum: float | None) -> None:
    """The score line and one line per survivor: ``FILE:LINE:COL kind rule: change``."""
    low = _low_score(report, minimum)
    console.print(f"\nmutation testing: {report.rulebook} against "
                  f"{', '.join(report.files)}", markup=False)
    for result in report.survivors:
        mutant = result.mutant
        console.print(f"  SURVIVED {mutant.span} [{mutant.category}] {mutant}", markup=False)
    skipped = len(report.results) - len(report.scored)
    console.print(f"mutation score: {report.score:.1f} % ({report.killed} of "
                  f"{len(report.scored)} mutants killed, {len(report.survivors)} survived"
                  + (f", {skipped} skipped as invalid" if skipped else "") + ")"
                  + (f" (minimum {minimum:g} %)" if minimum is not None else ""),
                  style="red" if low else "green", markup=False)
