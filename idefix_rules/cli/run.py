"""``idefix-verify run CAMPAIGN.yaml`` (or just ``idefix-verify CAMPAIGN.yaml``)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from idefix_rules.cli.destinations import output_file, output_folder, scheduler_address
from idefix_rules.cli.numbers import (
    run_count,
    run_count_only,
    seconds,
    seed_number,
    worker_count,
)
from idefix_rules.errors import IdefixError, Span, UserInputError, error
from idefix_rules.limits import MAX_RUNS, MAX_WORKERS
from idefix_rules.shell import command_line

if TYPE_CHECKING:
    from rich.console import Console

    from idefix_rules.campaign.input.load import Campaign
    from idefix_rules.campaign.simulation.run_stage import SimulationOptions
    from idefix_rules.cli.progress import PlainProgress, RichProgress

NAME = "run"
HELP = ("Run a campaign: simulate every command chain (reference + Monte Carlo), evaluate "
        "with the rulebook, print pass/fail and the ranking. Exit 0 all expectations hold, "
        "1 a path or expectation failed, 2 invalid input, 3 infrastructure error.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("campaign", type=Path, help="campaign file (YAML)")
    parser.add_argument("--runs", type=run_count, metavar="N|auto",
                        help="Monte Carlo runs per path "
                        f"(overrides the campaign's `runs`; at most {MAX_RUNS}), or `auto`: "
                        "simulate in batches and stop each path once its verdict is decided "
                        "and its rank settled")
    parser.add_argument("--max-runs", type=run_count_only, metavar="N",
                        help="with runs auto: the most runs per path (overrides `max_runs`)")
    parser.add_argument("--min-runs", type=run_count_only, metavar="N",
                        help="with runs auto: runs before the first look (overrides "
                             "`min_runs`)")
    parser.add_argument("--out", type=output_folder, help="output folder (overrides `output`)")
    parser.add_argument("--seed", type=seed_number, help="campaign seed, 0 … 2^64 - 1 (overrides "
                        "`uncertainty.seed`)")
    parser.add_argument("--workers", type=worker_count,
                        help=f"worker processes, at most {MAX_WORKERS}, or auto: all cores "
                             "(default: the campaign's `workers`, else all cores)")
    parser.add_argument("--run-timeout", type=seconds, metavar="SECONDS",
                        help="a run taking longer is killed and recorded as failed (default: "
                             "derived from the path's simulated duration and the measured "
                             "cost of its reference run, see docs/operations.md; 0: none)")
    parser.add_argument("--resume", action="store_true",
                        help="continue an interrupted campaign: simulate only missing runs")
    parser.add_argument("--junit", type=output_file, metavar="FILE",
                        help="write JUnit XML: a case per path and per expectation; its "
                        "failures are exactly what sets the exit code (docs/ci.md)")
    parser.add_argument("--quiet", action="store_true",
                        help="no progress at all; the results are still printed (without it, "
                             "progress is bars on a terminal and plain lines in a log: a line "
                             "per phase with its duration and per 10 %% of each path's runs)")
    parser.add_argument("--no-report", action="store_true", help="skip the HTML report")
    cluster = parser.add_mutually_exclusive_group()
    cluster.add_argument("--scheduler", metavar="ADDRESS", type=scheduler_address,
                         help="run on a Dask distributed cluster (scheduler address)")
    cluster.add_argument("--dask-local", action="store_true",
                         help="run on a local Dask cluster instead of the process pool")


def stored_titles(results: Path) -> dict[str, str]:
    """Index titles of the rulebook stored in a results file (empty when unreadable)."""
    from idefix_rules.campaign.storage.store import ResultStore
    from idefix_rules.cli.outcome import index_titles
    from idefix_rules.rulebook import check_text

    try:
        store = ResultStore.open(results)
        try:
            text = store.text("rulebook")
        finally:
            store.close()
        checked = check_text(text, "rulebook.rules").checked
    except Exception:  # titles are a courtesy: a table without them is still right
        return {}
    return index_titles(checked.rulebook) if checked is not None else {}


def run(args: argparse.Namespace) -> int:
    from rich.markup import escape

    # the campaign's modules (scipy among them, about a second) are imported before the
    # output folder is taken: a Ctrl-C meanwhile leaves nothing to resume
    import idefix_rules.campaign.runner  # noqa: F401
    from idefix_rules.campaign.input.load import declared_output
    from idefix_rules.campaign.output_folder import claimed_output, set_aside_refused
    from idefix_rules.campaign.simulation.resume import (
        continue_command,
        interrupted_runs,
        stored_campaign,
        stored_search,
    )
    from idefix_rules.campaign.simulation.run_stage import SimulationOptions
    from idefix_rules.campaign.simulation.simulate import RESULTS_FILE
    from idefix_rules.cli.console import make_console
    from idefix_rules.cli.progress import make_progress
    from idefix_rules.files import previous_path

    console = make_console()
    try:
        campaign = _campaign(args)
    except IdefixError as refusal:
        # refused before the folder is taken: what this run will not write is set aside
        # all the same, so that no earlier run's summary or JUnit speaks for it
        set_aside_refused(args.out.resolve() if args.out else declared_output(args.campaign),
                          args.junit, refusal)
        raise
    options = SimulationOptions(workers=args.workers, run_timeout=args.run_timeout,
                                resume=args.resume, scheduler=args.scheduler,
                                dask_local=args.dask_local)
    progress = make_progress(console, args.quiet)
    results = campaign.output / RESULTS_FILE
    interrupted = None if args.resume else interrupted_runs(results)
    # another campaign's results there (and in the copy kept before them) are set aside or
    # replaced: said, so that no finished campaign goes without a word
    had_results = results.is_file()
    search = not args.resume and stored_search(results)
    others = {} if args.resume else {
        path: held for path in (results, previous_path(results))
        if (held := stored_campaign(path)) is not None and held != campaign.name
        and not (search and path == results)}
    # Owned, and the last run's outputs set aside, before anything slow happens.
    with claimed_output(campaign, args.junit, args.resume) as lock:
        if lock.note is not None:
            console.print(f"[yellow]note:[/yellow] {escape(lock.note)}")
        if interrupted is not None and interrupted[0] > 0:  # runs worth resuming
            stored, planned = interrupted
            # the stored campaign's runs and seed, which may not be this command's
            again = continue_command(previous_path(results), args.campaign,
                                     _execution(args)) or _again(args)
            console.print(
                f"[yellow]note:[/yellow] {escape(str(results))} held an interrupted campaign "
                f"({stored} of {planned} Monte Carlo runs stored): it is set aside as "
                f"{escape(previous_path(results).name)} and this run starts from zero; to "
                f"continue it instead, stop now (Ctrl-C), rename it back to "
                f"{escape(results.name)} and run `{escape(again)}`")
        if search:  # its record goes aside with it
            console.print(f"[yellow]note:[/yellow] {escape(str(results))} held a worst-case "
                          f"search (idefix-verify worst): it is kept as "
                          f"{escape(previous_path(results).name)}, its worst.json as "
                          f"worst.previous.json")
        for path, name in others.items():
            if path == results and not (interrupted is not None and interrupted[0] > 0):
                console.print(f"[yellow]note:[/yellow] {escape(str(results))} held the results "
                              f"of another campaign ({escape(name)}): they are kept as "
                              f"{escape(previous_path(results).name)}")
            elif path != results and had_results:
                console.print(f"[yellow]note:[/yellow] {escape(str(path))}, the results of "
                              f"another campaign ({escape(name)}), is replaced by the ones "
                              f"{escape(results.name)} held")
        if args.resume and not (campaign.output / RESULTS_FILE).exists():
            console.print(f"[yellow]warning:[/yellow] nothing to resume in {campaign.output}: "
                          "simulating every run")
        return _run_owned(args, campaign, options, progress, console)


def _campaign(args: argparse.Namespace) -> Campaign:
    """The campaign file with this command's options applied (C701, C702 when they do not
    fit it)."""
    from idefix_rules.campaign.input.load import load_campaign

    campaign = load_campaign(args.campaign)
    adaptive = args.runs == "auto" or (args.runs is None and campaign.adaptive is not None)
    if not adaptive and (args.max_runs is not None or args.min_runs is not None):
        raise UserInputError(error(
            "C702", "--max-runs and --min-runs apply to an adaptive campaign only",
            Span(str(args.campaign)), hint="add --runs auto, or write 'runs: auto' in the "
                                          "campaign"))
    campaign = campaign.with_overrides(
        runs=args.runs, seed=args.seed,
        output=args.out.resolve() if args.out else None, workers=args.workers,
        max_runs=args.max_runs, min_runs=args.min_runs)
    if campaign.adaptive is not None and campaign.adaptive.min_runs > campaign.adaptive.max_runs:
        raise UserInputError(error(
            "C701", f"min_runs {campaign.adaptive.min_runs} exceeds max_runs "
                    f"{campaign.adaptive.max_runs}", Span(str(args.campaign)),
            hint="give --max-runs at least the minimum (or a smaller --min-runs)"))
    return campaign


def _again(args: argparse.Namespace) -> str:
    """This command with ``--resume``: what continues the campaign."""
    words: list[object] = ["idefix-verify", args.campaign, "--resume"]
    for flag, value in (("--out", args.out), ("--runs", args.runs), ("--seed", args.seed),
                        ("--max-runs", args.max_runs), ("--min-runs", args.min_runs)):
        if value is not None:
            words += [flag, value]
    return command_line(*words, *_execution(args))


def _execution(args: argparse.Namespace) -> list[object]:
    """This command's options a resume of it is given again (workers, cluster, run timeout,
    JUnit file, report)."""
    from idefix_rules.campaign.simulation.resume import execution_options

    return execution_options(args.workers, args.scheduler, args.dask_local, args.run_timeout,
                             args.junit, not args.no_report)


def _run_owned(args: argparse.Namespace, campaign: Campaign, options: SimulationOptions,
               progress: RichProgress | PlainProgress, console: Console) -> int:
    from rich.markup import escape

    from idefix_rules.campaign.runner import ReportFailed, ReportInterrupted, run_campaign
    from idefix_rules.cli.outcome import print_outcome

    def complete(done: Any) -> None:
        """A complete campaign's answer, said before what the report stage left undone."""
        progress.stop()
        print_outcome(console, done.evaluation, done.expectations, done.exit_code,
                      done.warnings, stored_titles(done.results), [("results", done.results)])
        if done.problems:  # why the exit code would have been 2 (a waiver matching nothing)
            print(UserInputError(done.problems, sources={str(campaign.source): campaign.text})
                  .render(), file=sys.stderr)

    try:
        result = run_campaign(campaign, options, progress, junit=args.junit,
                              report=not args.no_report)
    except ReportInterrupted as stop:
        complete(stop.result)
        console.print(f"[yellow]interrupted[/yellow] while writing the report: the results "
                      f"and summary.json are complete (exit code {stop.result.exit_code} "
                      f"without the interrupt); write the report with "
                      f"`{escape(command_line('idefix-verify', 'report', stop.result.results))}`")
        return 130  # as the dispatcher would, without saying "interrupted" twice
    except ReportFailed as stop:
        complete(stop.result)
        failure = stop.failure
        # the tool's own errors say what they were writing (a full disk: the report and its
        # figures); a plain OSError is said with the stage it broke
        print(failure.render() if isinstance(failure, IdefixError) else
              f"error: the report could not be written: {type(failure).__name__}: {failure}",
              file=sys.stderr)
        console.print(f"the results and summary.json are complete (exit code "
                      f"{stop.result.exit_code} without the report's failure); once that is "
                      f"put right, write the report with "
                      f"`{escape(command_line('idefix-verify', 'report', stop.result.results))}`",
                      markup=False)
        return stop.exit_code
    except KeyboardInterrupt:
        progress.stop()
        console.print(f"[yellow]interrupted[/yellow]: continue with `{escape(_again(args))}`")
        return 130  # as the dispatcher would, without saying "interrupted" twice
    finally:
        progress.stop()
    files: list[tuple[str, object]] = [("results", result.results)]
    if result.report is not None:
        files.append(("report", result.report))
    print_outcome(console, result.evaluation, result.expectations, result.exit_code,
                  result.warnings, stored_titles(result.results), files)
    if result.problems:  # a waiver matching nothing: said at its line, exit 2
        raise UserInputError(result.problems, sources={str(campaign.source): campaign.text})
    return result.exit_code
