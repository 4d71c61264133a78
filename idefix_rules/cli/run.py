"""``idefix-verify run CAMPAIGN.yaml`` (or just ``idefix-verify CAMPAIGN.yaml``)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Table

from idefix_rules.campaign.evaluation import CampaignEvaluation
from idefix_rules.campaign.load import load_campaign
from idefix_rules.campaign.outputs import ExpectationResult
from idefix_rules.campaign.schema import MAX_RUNS
from idefix_rules.campaign.simulate import RESULTS_FILE, SimulationOptions
from idefix_rules.cli.destinations import output_file, output_folder
from idefix_rules.errors import Span, UserInputError, error

NAME = "run"
HELP = ("Run a campaign: simulate every command chain (reference + Monte Carlo), evaluate "
        "with the rulebook, print pass/fail and the ranking. Exit 0 all expectations hold, "
        "1 a path or expectation failed, 2 invalid input, 3 infrastructure error.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("campaign", type=Path, help="campaign file (YAML)")
    parser.add_argument("--runs", type=_run_count, metavar="N|auto",
                        help="Monte Carlo runs per path "
                        f"(overrides the campaign's `runs`; at most {MAX_RUNS}), or `auto`: "
                        "simulate in batches and stop each path once its verdict is decided "
                        "and its rank settled")
    parser.add_argument("--max-runs", type=_run_count_only, metavar="N",
                        help="with runs auto: the most runs per path (overrides `max_runs`)")
    parser.add_argument("--min-runs", type=_run_count_only, metavar="N",
                        help="with runs auto: runs before the first look (overrides "
                             "`min_runs`)")
    parser.add_argument("--out", type=output_folder, help="output folder (overrides `output`)")
    parser.add_argument("--seed", type=_non_negative_int, help="campaign seed (overrides "
                        "`uncertainty.seed`)")
    parser.add_argument("--workers", type=_positive_int,
                        help="worker processes (default: the campaign's, else all cores)")
    parser.add_argument("--run-timeout", type=_positive_float, metavar="SECONDS",
                        help="a run taking longer is killed and recorded as failed")
    parser.add_argument("--resume", action="store_true",
                        help="continue an interrupted campaign: simulate only missing runs")
    parser.add_argument("--junit", type=output_file, metavar="FILE",
                        help="write JUnit XML: one test case per path and per expectation")
    parser.add_argument("--quiet", action="store_true",
                        help="no progress bars (CI logs); the result table is still printed")
    parser.add_argument("--no-report", action="store_true", help="skip the HTML report")
    cluster = parser.add_mutually_exclusive_group()
    cluster.add_argument("--scheduler", metavar="ADDRESS",
                         help="run on a Dask distributed cluster (scheduler address)")
    cluster.add_argument("--dask-local", action="store_true",
                         help="run on a local Dask cluster instead of the process pool")


def _positive_int(text: str) -> int:
    value = _integer(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive whole number, got {text}")
    return value


def _run_count(text: str) -> int | str:
    if text.strip().lower() == "auto":
        return "auto"
    return _run_count_only(text)


def _run_count_only(text: str) -> int:
    value = _positive_int(text)
    if value > MAX_RUNS:
        raise argparse.ArgumentTypeError(f"at most {MAX_RUNS} runs per path, got {text}")
    return value


def _non_negative_int(text: str) -> int:
    value = _integer(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0, got {text}")
    return value


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not 0 < value < math.inf:  # also refuses nan and inf (no timeout: leave it out)
        raise argparse.ArgumentTypeError(f"expected a finite positive number, got {text}")
    return value


class RichProgress:
    """Progress bars with ETA per path (the simulation's :class:`Progress` protocol)."""

    def __init__(self, console: Console, quiet: bool) -> None:
        self.console = console
        self.quiet = quiet
        self.bars: Progress | None = None
        self.tasks: dict[str, Any] = {}

    def message(self, text: str) -> None:
        if not self.quiet:
            self.stop()
            self.console.print(f"[dim]{text}[/dim]")

    def start_path(self, name: str, total: int, done: int) -> None:
        if self.quiet:
            return
        if self.bars is None:
            self.bars = Progress(TextColumn("{task.description:<24}"), BarColumn(),
                                 MofNCompleteColumn(), TextColumn("{task.fields[failed]}"),
                                 TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn(),
                                 console=self.console, transient=False)
            self.bars.start()
        self.tasks[name] = self.bars.add_task(name, total=total, completed=done, failed="")
        self.failed: dict[str, int] = getattr(self, "failed", {})
        self.failed[name] = 0

    def run_finished(self, name: str, ok: bool) -> None:
        if self.bars is None or name not in self.tasks:
            return
        if not ok:
            self.failed[name] += 1
        label = f"[red]{self.failed[name]} failed[/red]" if self.failed[name] else ""
        self.bars.update(self.tasks[name], advance=1, failed=label)

    def stop(self) -> None:
        if self.bars is not None:
            self.bars.stop()
            self.bars = None


def make_console() -> Console:
    """Rich console; wide enough for the table when output goes to a file or CI log."""
    console = Console(highlight=False)
    if not console.is_terminal:
        console = Console(highlight=False, width=150)
    return console


def _percent(value: float | None) -> str:
    return "–" if value is None else f"{100.0 * value:.1f}"


def results_table(evaluation: CampaignEvaluation) -> Table:
    """The paper's Table 1, plus verdict, rank and dominant index."""
    table = Table(title="Path evaluation", title_justify="left")
    table.add_column("path")
    table.add_column("risk %", justify="right")
    table.add_column("95 % CI", justify="right")
    for level in ("L1", "L2", "L3"):
        table.add_column(f"hit {level} %", justify="right")
    table.add_column("energy mAs", justify="right")
    table.add_column("time s", justify="right")
    table.add_column("runs", justify="right")
    table.add_column("verdict")
    table.add_column("rank", justify="right")
    table.add_column("dominant")
    for path in sorted(evaluation.paths, key=lambda p: (p.rank is None, p.rank or 0, p.index)):
        verdict = path.verdict_text
        style = {"pass": "green", "fail": "red"}.get(verdict, "yellow")
        shown = f"[{style}]{verdict}[/{style}]"
        if path.undecided:
            shown += " [yellow](not decided)[/yellow]"
        ci = f"{_percent(path.risk_ci[0])}–{_percent(path.risk_ci[1])}" if path.risk_ci else "–"
        runs = f"{path.completed}/{path.runs}" if path.runs else "–"
        if path.failed:
            runs += f" [red]({path.failed} failed)[/red]"
        table.add_row(
            path.name, _percent(path.mean_risk), ci,
            *(_percent(path.collision_chance.get(level)) for level in ("L1", "L2", "L3")),
            "–" if path.energy is None else f"{path.energy * 1000.0:.1f}",
            "–" if path.time is None else f"{path.time:.1f}",
            runs, shown, "–" if path.rank is None else str(path.rank),
            path.dominant_index or "–",
        )
    return table


def print_outcome(console: Console, evaluation: CampaignEvaluation,
                  expectations: list[ExpectationResult], code: int,
                  warnings: list[str]) -> None:
    console.print(results_table(evaluation))
    for path in evaluation.paths:
        if path.reason:
            console.print(f"[yellow]{path.name}[/yellow] {path.status}: {path.reason}")
        if path.stop_reason:
            console.print(f"  {path.name}: runs: {path.stop_reason}")
        for reason in path.verdict_reasons:
            console.print(f"  {path.name}: {reason}")
        for run, reason in sorted(path.failures.items())[:10]:
            console.print(f"  [red]{path.name} run {run} failed[/red]: {reason}")
        if path.failed > 10:
            console.print(f"  [red]… and {path.failed - 10} more failed runs[/red]")
    if evaluation.ranking:
        console.print("ranking: " + " > ".join(evaluation.ranking))
    for expectation in expectations:
        mark = "[green]✓[/green]" if expectation.held else "[red]✗[/red]"
        console.print(f"{mark} expect {expectation.description}: {expectation.message}")
    for text in warnings:
        console.print(f"[yellow]warning:[/yellow] {text}")
    console.print(f"exit code {code}: " + ("verified" if code == 0 else "verification failed"))


def run(args: argparse.Namespace) -> int:
    from idefix_rules.campaign.runner import run_campaign

    console = make_console()
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
    options = SimulationOptions(workers=args.workers, run_timeout=args.run_timeout,
                                resume=args.resume, scheduler=args.scheduler,
                                dask_local=args.dask_local)
    progress = RichProgress(console, args.quiet)
    if args.resume and not (campaign.output / RESULTS_FILE).exists():
        console.print(f"[yellow]warning:[/yellow] nothing to resume in {campaign.output}: "
                      "simulating every run")
    try:
        result = run_campaign(campaign, options, progress, junit=args.junit,
                              report=not args.no_report)
    except KeyboardInterrupt:
        progress.stop()
        again = f"idefix-verify {args.campaign} --resume"
        for flag, value in (("--out", args.out), ("--runs", args.runs), ("--seed", args.seed),
                            ("--max-runs", args.max_runs), ("--min-runs", args.min_runs)):
            if value is not None:
                again += f" {flag} {value}"
        console.print(f"[yellow]interrupted[/yellow]: continue with `{again}`")
        return 130  # as the dispatcher would, without saying "interrupted" twice
    finally:
        progress.stop()
    print_outcome(console, result.evaluation, result.expectations, result.exit_code,
                  result.warnings)
    console.print(f"results: {result.results}")
    if result.report is not None:
        console.print(f"report: {result.report}")
    return result.exit_code
