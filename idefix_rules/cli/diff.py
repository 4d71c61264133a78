"""``idefix-verify diff OLD NEW [--results results.h5 …]``: what a rulebook change does.

``OLD`` and ``NEW`` are rulebook files or ``PATH@REV`` (the file at a git revision). Without
``--results`` the rules are compared (exit 0). With ``--results`` the stored runs are re-scored
under both rulebooks (no simulation) and the exit code gates on verdict changes (see
``docs/diff.md``).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rich.console import Console

    from idefix_rules.diff.results import PathDiff, ResultsDiff, ResultsFileDiff, SideResult
    from idefix_rules.diff.rules import RuleChange, RuleDiff

NAME = "diff"
HELP = ("Compare two rulebook versions (files or PATH@REV git revisions): the rules that "
        "changed and, with --results, what the change does to stored campaigns (re-scored, "
        "no simulation). Exit 0 when no verdict changes, 1 when a path's verdict or the "
        "first-ranked path changes, 2 on invalid input.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("old", metavar="OLD", help="earlier rulebook: a file or PATH@REV")
    parser.add_argument("new", metavar="NEW", help="later rulebook: a file or PATH@REV")
    parser.add_argument("--results", type=Path, nargs="+", metavar="RESULTS_H5",
                        help="stored campaign(s) to re-score under both rulebooks")
    parser.add_argument("--waivers", type=Path, metavar="CAMPAIGN_YAML",
                        help="list the campaign's waivers whose rule changed, was removed or "
                             "is affected between OLD and NEW")
    parser.add_argument("--fail-on", choices=("verdict", "rank", "never"), default="verdict",
                        help="with --results: exit 1 when a path's verdict or the first-ranked "
                             "path changes (verdict, the default), also when any rank "
                             "changes (rank), or never")
    parser.add_argument("--top", type=int, default=5, metavar="N",
                        help="runs whose I_max moved most, per path (default 5)")
    parser.add_argument("--chunk-runs", type=int, default=64, metavar="N",
                        help="runs read and evaluated at a time (memory bound; default 64)")
    parser.add_argument("--threads", type=int, default=2, metavar="N",
                        help="chunks evaluated at the same time (default 2)")
    parser.add_argument("--format", choices=("text", "json", "md"), default="text",
                        help="text tables (default), the data as JSON, or md: the rule "
                             "changes as a Markdown changelog entry")


def run(args: argparse.Namespace) -> int:
    from idefix_rules.cli.console import make_console
    from idefix_rules.diff import diff_rules, load_source
    from idefix_rules.diff.results import diff_results
    from idefix_rules.errors import UserInputError, error
    from idefix_rules.plain import as_plain

    if args.top < 0 or args.chunk_runs < 1 or args.threads < 1:
        raise UserInputError(error("D020", "--top must be ≥ 0, --chunk-runs and --threads ≥ 1"))
    old, new = load_source(args.old), load_source(args.new)
    rules = diff_rules(old.checked, new.checked, old.label, new.label)
    touched = None
    if args.waivers is not None:
        from idefix_rules.campaign.input.load import load_campaign
        from idefix_rules.diff.waivers import touched_waivers

        touched = touched_waivers(rules.changes, load_campaign(args.waivers).model.waivers)
    results = None
    if args.results:
        results = diff_results(_once(args.results), old, new, args.top, args.chunk_runs,
                               args.threads)
    code = results.exit_code(args.fail_on) if results is not None else 0
    if args.format == "json":
        data: dict[str, Any] = {"rules": rules.to_dict(),
                                "results": results.to_dict() if results is not None else None,
                                "fail_on": args.fail_on, "exit_code": code}
        if touched is not None:
            data["waivers"] = [waiver.to_dict() for waiver in touched]
        print(json.dumps(as_plain(data), indent=2, default=str, allow_nan=False))
        return code
    if args.format == "md":
        from idefix_rules.diff.changelog import changelog, results_markdown

        print(changelog(rules))
        if results is not None:
            print()
            print(results_markdown(results, args.fail_on, code))
        return code
    console = make_console()
    print_rules(console, rules)
    if touched is not None:
        console.print(f"[bold]waivers[/bold] of {args.waivers} whose rule changed: "
                      f"{len(touched) or 'none'}", markup=True)
        for waiver in touched:
            console.print(f"  {waiver.text()}", markup=False)
    if results is not None:
        for file in results.files:
            print_results(console, file)
        print_exit(console, results, args.fail_on, code)
    return code


def _once(files: list[Path]) -> list[Path]:
    """Each results file once, however often (or under whichever name) it was given: a file
    scored twice would count its verdict changes twice."""
    import os
    import sys

    kept: list[Path] = []
    seen: set[object] = set()
    for file in files:
        try:  # the file itself, whatever names it (a symbolic or a hard link)
            status = os.stat(file)
            key: object = (status.st_dev, status.st_ino)
        except OSError:  # missing: said when it is read
            key = file.resolve()
        if key in seen:
            print(f"note: {file} was given more than once; it is scored once", file=sys.stderr)
            continue
        seen.add(key)
        kept.append(file)
    return kept


# ----------------------------------------------------------------------------- rules

def _field_text(change: RuleChange) -> str:
    lines = []
    for item in change.fields:
        old = item.old if item.old is not None else "—"
        new = item.new if item.new is not None else "—"
        if change.kind == "added":
            text = f"{item.field}: {new}"
        elif change.kind == "removed":
            text = f"{item.field}: {old}"
        else:
            text = f"{item.field}: {old} → {new}" if old != new else f"{item.field}: {old}"
        si_old, si_new = item.old_si, item.new_si
        if change.kind == "changed" and si_old is not None and si_new is not None:
            if si_old != si_new and (si_old, si_new) != (item.old, item.new):
                text += f"  [{si_old} → {si_new}]"
        elif (si_new or si_old) and (si_new or si_old) != (item.new or item.old):
            text += f"  [= {si_new or si_old}]"
        lines.append(text)
    if change.reads_changed:
        through = ""
        if change.upstream and set(change.upstream) != set(change.reads_changed):
            through = " (through " + ", ".join(change.upstream) + ")"
        lines.append("reads changed: " + ", ".join(change.reads_changed) + through)
    return "\n".join(lines)


def _rationale_text(change: RuleChange) -> str:
    if change.rationale_changed:
        return f"was: {change.old_rationale or '—'}\nnow: {change.rationale or '—'}"
    return change.rationale or ""


_KIND_STYLE = {"added": "green", "removed": "red", "changed": "yellow", "affected": "cyan"}
_DIRECTION_STYLE = {"stricter": "bold red", "looser": "bold green", "unknown": "magenta"}


def print_rules(console: Console, diff: RuleDiff) -> None:
    from rich.table import Table

    old, new = diff.old, diff.new
    console.print(f"[bold]rulebook diff[/bold]: {old.name} {old.version} ({old.label}) → "
                  f"{new.name} {new.version} ({new.label})")
    if diff.identical:
        console.print("the rules are the same (comments and layout aside)")
        for warning in diff.warnings:
            console.print(f"[bold yellow]warning:[/bold yellow] {warning}")
        return
    table = Table(show_lines=True)
    for column in ("section", "name", "change", "direction", "what", "rationale"):
        table.add_column(column, overflow="fold")
    for change in diff.changes:
        style = _KIND_STYLE.get(change.kind, "")
        way = _DIRECTION_STYLE.get(change.direction, "")
        table.add_row(change.section, change.name, f"[{style}]{change.kind}[/{style}]",
                      f"[{way}]{change.direction}[/{way}]" if way else change.direction,
                      _field_text(change), _rationale_text(change))
    console.print(table)
    counts = diff.counts()
    console.print(", ".join(f"{n} {kind}" for kind, n in counts.items() if n) + "; "
                  + ", ".join(f"{n} {way}" for way, n in diff.directions().items() if n))
    for warning in diff.warnings:
        console.print(f"[bold yellow]warning:[/bold yellow] {warning}")


# ----------------------------------------------------------------------------- results

def _number(value: float | None, digits: int = 3) -> str:
    return "—" if value is None else f"{value:.{digits}f}"


def _risk(side: SideResult) -> str:
    """Risk in percent, as `run` shows it, its family-wise bounds below: ``73.5 %`` /
    ``72.9–74.0 at 95 %``."""
    from idefix_rules.campaign.input.wording import confidence_text

    if side.mean_risk is None:
        return "—"
    interval = (f"\n{100 * side.risk_ci[0]:.1f}–{100 * side.risk_ci[1]:.1f} at "
                f"{confidence_text(side.confidence)}" if side.risk_ci else "")
    return f"{100 * side.mean_risk:.1f} %{interval}"


def _verdict(side: SideResult) -> str:
    return side.verdict + (" (undecided)" if side.undecided else "")


def _arrow(old: str, new: str, changed: bool) -> str:
    text = f"{old} → {new}" if old != new else old
    return f"[bold red]{text}[/bold red]" if changed else text


def _chances(path: PathDiff) -> str:
    names = list(dict.fromkeys([*path.old.chances, *path.new.chances]))
    lines = []
    for name in names:
        old, new = path.old.chances.get(name), path.new.chances.get(name)
        if old != new:
            lines.append(f"{name}: {_percent(old)} → {_percent(new)}")
    return "\n".join(lines)


def _percent(value: float | None) -> str:
    return "—" if value is None else f"{100 * value:.1f} %"


def _dominant(side: SideResult) -> str:
    counts = {k: v for k, v in side.dominant_counts.items() if v}
    if not counts:
        return "—"
    return ", ".join(f"{k} {v}" for k, v in sorted(counts.items(), key=lambda kv: -kv[1]))


def _one_line(side: SideResult) -> str:
    return _risk(side).replace("\n", " (") + (")" if side.risk_ci else "")


def _path_block(path: PathDiff) -> list[str]:
    """A path's results diff as a few lines (the narrow layout)."""
    rank_old = str(path.old.rank) if path.old.rank is not None else "—"
    rank_new = str(path.new.rank) if path.new.rank is not None else "—"
    lines = [f"[bold]{path.name}[/bold]: "
             f"{_arrow(_verdict(path.old), _verdict(path.new), path.verdict_changed)}"
             f" · rank {_arrow(rank_old, rank_new, False)}",
             f"  risk {_one_line(path.old)} → {_one_line(path.new)}"]
    chances = _chances(path)
    if chances:
        lines.append("  chances: " + "; ".join(chances.splitlines()))
    lines.append(f"  dominant index (runs): {_dominant(path.old)} → {_dominant(path.new)}"
                 f" · runs moved {path.changed_runs} of {path.new.runs or path.old.runs}")
    return lines


def print_results(console: Console, file: ResultsFileDiff) -> None:
    from rich.markup import escape
    from rich.table import Table

    from idefix_rules.cli.outcome import fits

    reused = (f"; {' and '.join(file.stored_evaluation)}: per-run values of the stored "
              "evaluation") if file.stored_evaluation else ""
    console.print(f"\n[bold]results[/bold]: {file.results} (campaign {file.campaign}; "
                  f"collisions {file.collisions}{reused})")
    for warning in file.warnings:
        console.print(f"[bold yellow]warning:[/bold yellow] {escape(warning)}")
    table = Table(show_lines=True)
    table.add_column("path", no_wrap=True)
    table.add_column("verdict", overflow="fold")
    table.add_column("risk (family-wise bounds)", min_width=10, overflow="fold")
    for column in ("rank", "chances that changed", "dominant index (runs)", "runs moved"):
        table.add_column(column, overflow="fold")
    for path in file.paths:
        rank_old = str(path.old.rank) if path.old.rank is not None else "—"
        rank_new = str(path.new.rank) if path.new.rank is not None else "—"
        table.add_row(
            path.name, _arrow(_verdict(path.old), _verdict(path.new), path.verdict_changed),
            f"{_risk(path.old)}\n→ {_risk(path.new)}",
            _arrow(rank_old, rank_new, False), _chances(path),
            f"{_dominant(path.old)}\n→ {_dominant(path.new)}",
            f"{path.changed_runs} of {path.new.runs or path.old.runs}")
    if fits(console, table):
        console.print(table)
    else:  # narrow: a short block per path, so no name or number is cut
        for path in file.paths:
            for line in _path_block(path):
                console.print(line)
    for path in file.paths:
        if not path.top_runs:
            continue
        moves = Table(title=f"{path.name}: runs whose I_max moved most", title_justify="left")
        for column in ("run", "I_max % old → new", "Δ % points", "because of",
                       "dominant old → new"):
            moves.add_column(column)
        for move in path.top_runs:
            moves.add_row(str(move.run),
                          f"{100 * move.old_i_max:.1f} → {100 * move.new_i_max:.1f}",
                          f"{100 * move.delta:+.1f}", move.index,
                          _arrow(move.old_dominant, move.new_dominant, False))
        console.print(moves)
    for path in file.paths:
        if path.verdict_changed:
            for label, side in (("old", path.old), ("new", path.new)):
                for reason in side.reasons[:3]:
                    console.print(f"  {path.name} ({label}): {reason}")
    console.print(f"ranking old: {' > '.join(file.old_ranking) or '—'}")
    console.print(f"ranking new: {' > '.join(file.new_ranking) or '—'}"
                  + ("  [bold red](first-ranked path changed)[/bold red]"
                     if file.first_changed else ""))


def print_exit(console: Console, results: ResultsDiff, fail_on: str, code: int) -> None:
    console.print(results.exit_reason(fail_on, code), markup=False)
