"""``idefix-verify worst CAMPAIGN.yaml``: the worst case of each chain, and how far it is.

Prints, per path, the nominal world's run risk, the worst world found (its risk, dominant index
and how rare it is) and the smallest change from the nominal world found to make the chain
critical; then each path's worst world parameter by parameter (value and quantile) and its
failure boundary along every ray searched. ``worst.json`` holds the same as data
(docs/worst-case.md).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from idefix_rules.campaign.load import load_campaign
from idefix_rules.campaign.simulate import SimulationOptions
from idefix_rules.campaign.wording import DisplayUnits, parameter_text, percent
from idefix_rules.campaign.worst.outcome import rarity, sigmas
from idefix_rules.cli.destinations import output_folder
from idefix_rules.cli.numbers import integer, positive_int, seconds, seed_number
from idefix_rules.cli.progress import PlainProgress, make_progress
from idefix_rules.cli.run import make_console

NAME = "worst"
HELP = ("Search each chain's uncertainty for the worlds of highest run risk (cross-entropy "
        "method on the campaign's FMU and pool) and the smallest change from the nominal "
        "world that makes it critical; stores the searched runs (results.h5, for evaluate, "
        "diff and report) and worst.json in <output>/worst. Exit 0 when searched, 2 invalid "
        "input, 3 infrastructure error.")

DEFAULT_RUNS = 250


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("campaign", type=Path, help="campaign file (YAML)")
    parser.add_argument("--runs", type=positive_int, default=DEFAULT_RUNS, metavar="N",
                        help="run budget per path, search and boundary together (default "
                             f"{DEFAULT_RUNS}: a quarter of a 1000-run campaign)")
    parser.add_argument("--seed", type=seed_number, help="seed of the search, 0 … 2^64 - 1 "
                        "(default: the campaign's `uncertainty.seed`)")
    parser.add_argument("--workers", type=positive_int,
                        help="worker processes (default: the campaign's, else all cores)")
    parser.add_argument("--out", type=output_folder,
                        help="output folder (default: the campaign's output folder + /worst)")
    parser.add_argument("--critical", type=_level, default=1.0, metavar="LEVEL",
                        help="run risk I_max at which a run counts as critical, in (0, 1] or "
                             "as a percentage (default 1: an index at its critical limit)")
    parser.add_argument("--tail", type=_tail, default=None, metavar="P",
                        help="search worlds whose every parameter lies within its P … 1-P "
                             "quantiles (default 0.0001)")
    parser.add_argument("--axes", type=_count, default=2, metavar="K",
                        help="most sensitive parameters whose axis the failure boundary is "
                             "also searched along (default 2)")
    parser.add_argument("--rounds", type=positive_int, default=3, metavar="R",
                        help="bisection rounds of the failure boundary, each shrinking its "
                             "bracket to a quarter (default 3)")
    parser.add_argument("--run-timeout", type=seconds, metavar="SECONDS",
                        help="a run taking longer is killed and recorded as failed (default: "
                             "as for a campaign; 0: none)")
    parser.add_argument("--quiet", action="store_true", help="no progress")
    parser.add_argument("--no-report", action="store_true", help="skip the HTML report")
    cluster = parser.add_mutually_exclusive_group()
    cluster.add_argument("--scheduler", metavar="ADDRESS",
                         help="run on a Dask distributed cluster (scheduler address)")
    cluster.add_argument("--dask-local", action="store_true",
                         help="run on a local Dask cluster instead of the process pool")


def _level(text: str) -> float:
    raw = text.strip()
    scale = 1.0
    if raw.endswith("%"):
        raw, scale = raw[:-1].strip(), 0.01
    try:
        if not raw.isascii():
            raise ValueError(raw)
        value = float(raw) * scale
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a run risk such as 1, 0.9 or 90 %, "
                                         f"got {text!r}") from None
    if not 0.0 < value <= 1.0:
        raise argparse.ArgumentTypeError(f"a run risk lies in (0, 1] (0 % … 100 %), got {text}")
    return value


def _tail(text: str) -> float:
    try:
        if not text.isascii():
            raise ValueError(text)
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a probability such as 0.0001, got "
                                         f"{text!r}") from None
    if not 0.0 < value < 0.5:
        raise argparse.ArgumentTypeError(f"a tail probability lies in (0, 0.5), got {text}")
    return value


def _count(text: str) -> int:
    value = integer(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0, got {text}")
    return value


def run(args: argparse.Namespace) -> int:
    from idefix_rules.campaign.worst.pipeline import default_output, run_worst
    from idefix_rules.campaign.worst.search import SearchSettings
    from idefix_rules.campaign.worst.space import DEFAULT_TAIL

    console = make_console()
    campaign = load_campaign(args.campaign)
    output = (args.out or default_output(campaign)).resolve()
    # a fixed count: an adaptive campaign's settings mean nothing to the search
    campaign = campaign.with_overrides(runs=args.runs, seed=args.seed, output=output,
                                       workers=args.workers)
    settings = SearchSettings(runs=args.runs, threshold=args.critical,
                              tail=args.tail if args.tail is not None else DEFAULT_TAIL,
                              rounds=args.rounds, axes=args.axes)
    options = SimulationOptions(workers=args.workers, run_timeout=args.run_timeout,
                                scheduler=args.scheduler, dask_local=args.dask_local)
    progress = make_progress(console, args.quiet)
    if isinstance(progress, PlainProgress):
        progress.runs_label = "searched runs"
    try:
        result = run_worst(campaign, settings, options, progress, report=not args.no_report)
    except KeyboardInterrupt:
        progress.stop()
        console.print("[yellow]interrupted[/yellow]: the search is not resumable; run it again")
        return 130
    finally:
        progress.stop()
    units = DisplayUnits.from_campaign_text(campaign.text)
    print_worst(console, result.record, units)
    for warning in result.warnings:
        console.print(f"[yellow]warning:[/yellow] {escape(warning)}")
    console.print(f"results: {escape(str(result.results))}")
    console.print(f"worst case: {escape(str(result.record_file))}")
    if result.report is not None:
        console.print(f"report: {escape(str(result.report))}")
    return 0


def _risk(value: float | None) -> str:
    return percent(value, 1)


def _change(path: Mapping[str, Any]) -> str:
    change = path.get("smallest_change")
    if path.get("nominal_critical"):
        return "none: the nominal world is critical"
    if change is None:
        return "no critical world found" if not path.get("critical") \
            else "not found along the rays searched"
    return f"{sigmas(change['distance'])} ({escape(str(change['direction']))})"


def print_worst(console: Console, record: Mapping[str, Any], units: DisplayUnits) -> None:
    """The search's outcome: a table per path, then each path's worst world and boundary."""
    threshold = float(record.get("threshold", 1.0))
    table = Table(title=f"Worst case per path ({record.get('runs')} runs per path at most, "
                        f"critical at I_max ≥ {_risk(threshold)})", title_justify="left")
    for column in ("path", "nominal I_max", "worst I_max", "dominant", "as far out as¹",
                   "smallest change to critical"):
        table.add_column(column, overflow="fold")
    for path in record.get("paths", []):
        if path.get("status") != "searched":
            table.add_row(escape(path["name"]), "–", "–", "–", "–",
                          f"not searched: {escape(path['status'])}")
            continue
        worst = path["worst"]
        table.add_row(escape(path["name"]), _risk(path["nominal"]["risk"]),
                      _risk(worst["risk"]), escape(str(worst.get("dominant_index") or "–")),
                      rarity(worst["tail_probability"]), _change(path))
    console.print(table)
    console.print("¹ the share of the campaign's worlds at least as far from the median world as "
                  "the worst one (docs/worst-case.md)")
    stored_units = {entry["name"]: entry.get("unit", "") for entry in record.get("parameters",
                                                                                 [])}
    for path in record.get("paths", []):
        if path.get("status") != "searched":
            reason = f": {path['reason']}" if path.get("reason") else ""
            console.print(f"[bold]{escape(path['name'])}[/bold] not searched "
                          f"({escape(path['status'])}{escape(reason)})")
            continue
        _print_path(console, path, stored_units, units)


def _world(world: Mapping[str, Any], stored_units: Mapping[str, str],
           units: DisplayUnits) -> str:
    parts = []
    for name, entry in world["parameters"].items():
        value = parameter_text(name, float(entry["value"]), stored_units.get(name, ""), units)
        parts.append(f"{escape(name)} {escape(value)} (q {_quantile(entry['quantile'])})")
    return ", ".join(parts)


def _quantile(value: float) -> str:
    if value <= 0.0 or value >= 1.0 or not math.isfinite(value):
        return f"{value:g}"
    if 0.001 <= value <= 0.999:
        return f"{value:.3f}"
    return f"{value:.1e}"


def _print_path(console: Console, path: Mapping[str, Any], stored_units: Mapping[str, str],
                units: DisplayUnits) -> None:
    worst = path["worst"]
    runs = (f"{path['runs_used']} runs: {path['search_runs']} searching, "
            f"{path['boundary_runs']} on the boundary")
    if path.get("failed_runs"):
        runs += f", {path['failed_runs']} failed"
    console.print(f"[bold]{escape(path['name'])}[/bold] ({runs})")
    where = "the nominal world" if worst.get("run") is None else f"run {worst['run']}"
    console.print(f"  worst: I_max {_risk(worst['risk'])} "
                  f"({escape(str(worst.get('dominant_index') or '–'))}) in {where}, "
                  f"{sigmas(worst['distance'])} from the nominal world; as far out as "
                  f"{rarity(worst['tail_probability'])} of the campaign's worlds")
    console.print(f"    {_world(worst, stored_units, units)}")
    if path.get("sensitivity"):
        shown = ", ".join(f"{escape(a['parameter'])} ρ {a['rho']:+.2f}"
                          + ("" if a.get("significant") else " (not significant)")
                          for a in path["sensitivity"])
        console.print(f"  most sensitive: {shown}")
    for boundary in path.get("boundaries", []):
        label = escape(str(boundary["direction"]))
        if not boundary["found"]:
            console.print(f"  boundary {label}: none up to {sigmas(boundary['searched_to'])}")
            continue
        low, high = boundary["bracket"]
        console.print(f"  boundary {label}: between {sigmas(low)} and {sigmas(high)}; "
                      "critical at")
        critical = boundary.get("critical_world")
        if critical is not None:
            console.print(f"    {_world(critical, stored_units, units)} "
                          f"(I_max {_risk(critical['risk'])}, run {critical['run']})")
    if path.get("nominal_critical"):
        console.print("  the nominal world is already critical: no change is needed")
    elif not path.get("critical"):
        console.print(f"  no world searched reaches I_max {_risk(path['threshold'])}: no "
                      "failure boundary within the searched worlds")
