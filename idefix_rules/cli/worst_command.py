"""``idefix-verify worst``, run: the search, then its table per path (imported when the command
runs; :mod:`idefix_rules.cli.worst` declares the command and its arguments).

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
from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.input.wording import DisplayUnits, parameter_text, percent
from idefix_rules.campaign.simulation.run_stage import SimulationOptions
from idefix_rules.campaign.worst.outcome import rarity, sigmas
from idefix_rules.cli.console import make_console
from idefix_rules.cli.progress import PlainProgress, make_progress


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
    for note in result.notes:
        console.print(f"[yellow]note:[/yellow] {escape(note)}")
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
