"""The console's account of a campaign: decision, Table 1, why, CI's outcome.

Order: the details first (the path table, each path's failing verdicts in the rulebook's terms,
in percent, ✗ for a rule failed and ? for one not decided yet, the expectations, each warning
once, the files written), then the answer last, where the screen ends: the ``Decision:`` line
(what to send), the ranking, each path's verdict in one line and the line
``CI expectations: N of M held (exit K)``. The table is the paper's Table 1 when it fits the
console; when it does not (80 columns), every path becomes a short block of lines instead, so
no name is ever cut.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.measure import Measurement
from rich.table import Table

from idefix_rules.campaign.evaluation.path_result import CampaignEvaluation, PathResult
from idefix_rules.campaign.evaluation.slip import unmeasured_text
from idefix_rules.campaign.input.wording import (
    bounds_label,
    confidence_text,
    percent,
    unfinished_text,
)
from idefix_rules.campaign.outcome.decision import (
    Decision,
    campaign_confidence,
    campaign_decision,
    near_rules,
    path_confidence,
    reason_items,
    rule_name,
    verdict_counts,
    verdict_parts,
)
from idefix_rules.campaign.outcome.expectation_checks import ExpectationResult
from idefix_rules.campaign.simulation.processes import is_infrastructure
from idefix_rules.campaign.statistics import pairwise
from idefix_rules.campaign.statistics.pairwise import OPEN
from idefix_rules.campaign.statistics.stopping import STOP_FIXED
from idefix_rules.cli.console import print_whole

LEVELS = ("L1", "L2", "L3")
STYLES = {"pass": "green", "fail": "red", "waived": "magenta", "marginal": "yellow"}


def _ordered(evaluation: CampaignEvaluation) -> list[PathResult]:
    return sorted(evaluation.paths, key=lambda p: (p.rank is None, p.rank or 0, p.index))


def _number(value: float | None, scale: float = 1.0) -> str:
    return "–" if value is None else f"{value * scale:.1f}"


def _pct(value: float | None) -> str:
    return "–" if value is None else f"{100.0 * value:.1f}"


def _verdict(path: PathResult) -> str:
    verdict = path.verdict_text
    style = STYLES.get(verdict, "yellow")
    shown = f"[{style}]{verdict}[/{style}]"
    if path.undecided:
        shown += " [yellow](not decided)[/yellow]"
    return shown


def _dominant(path: PathResult, titles: Mapping[str, str]) -> str:
    name = path.dominant_index
    if not name:
        return "–"
    title = titles.get(name)
    return f"{escape(name)} ({escape(title)})" if title else escape(name)


def results_table(evaluation: CampaignEvaluation, titles: Mapping[str, str]) -> Table:
    """The paper's Table 1, plus verdict, rank and dominant index (with its title)."""
    table = Table(title="Path evaluation", title_justify="left")
    table.add_column("path", no_wrap=True)
    table.add_column("risk %", justify="right")
    # "family-wise 95 % bounds" on two lines, so the column stays as narrow as its numbers
    confidence = confidence_text(campaign_confidence(evaluation.paths))
    table.add_column(f"family-wise\n{confidence} bounds", justify="right")
    for level in LEVELS:
        table.add_column(f"hit {level} %", justify="right")
    table.add_column("energy mAs", justify="right")
    table.add_column("time s", justify="right")
    table.add_column("runs", justify="right")
    table.add_column("verdict")
    table.add_column("rank", justify="right")
    table.add_column("dominant index")
    for path in _ordered(evaluation):
        ci = f"{_pct(path.risk_ci[0])}–{_pct(path.risk_ci[1])}" if path.risk_ci else "–"
        runs = f"{path.completed}/{path.runs}" if path.runs else "–"
        if path.failed:
            runs += f" [red]({path.failed} failed)[/red]"
        table.add_row(
            escape(path.name), _pct(path.mean_risk), ci,
            *(_pct(path.collision_chance.get(level)) for level in LEVELS),
            _number(path.energy, 1000.0), _number(path.time), runs, _verdict(path),
            "–" if path.rank is None else str(path.rank), _dominant(path, titles))
    return table


def ranked_name(path: PathResult) -> str:
    """``#1 name`` (``name`` without a rank): what the short block of a path starts with,
    never broken across lines."""
    return f"#{path.rank} {path.name}" if path.rank is not None else path.name


def path_lines(path: PathResult, titles: Mapping[str, str]) -> list[str]:
    """One path as a few short lines (the narrow layout)."""
    rank = f"#{path.rank} " if path.rank is not None else ""
    lines = [f"[bold]{rank}{escape(path.name)}[/bold]  {_verdict(path)}"]
    if path.mean_risk is not None:
        ci = (f" ({bounds_label(path_confidence(path))} {_pct(path.risk_ci[0])}–"
              f"{_pct(path.risk_ci[1])})"
              if path.risk_ci else "")
        lines.append(f"  risk {percent(path.mean_risk)}{ci}")
        hits = "  ".join(f"{level} {_pct(path.collision_chance.get(level))}"
                         for level in LEVELS)
        lines.append(f"  hit chance %: {hits}")
        runs = f"{path.completed}/{path.runs}"
        if path.failed:
            runs += f" [red]({path.failed} failed)[/red]"
        lines.append(f"  energy {_number(path.energy, 1000.0)} mAs · time "
                     f"{_number(path.time)} s · runs {runs}")
        lines.append(f"  dominant index: {_dominant(path, titles)}")
    return lines


def fits(console: Console, table: Table) -> bool:
    """Whether the table fits the console without shrinking a column."""
    unbounded = console.options.update(width=10_000)
    return Measurement.get(console, unbounded, table).maximum <= console.width


def print_decision(console: Console, decision: Decision, names: Sequence[str] = ()) -> None:
    """The ``Decision:`` line; the path ``names`` it holds, and ``Decision: send NAME``, are
    never broken across lines."""
    style = {"send": "green", "none": "red"}.get(decision.kind, "yellow")  # marginal: yellow
    keep = [*names, *([f"Decision: send {decision.path}"] if decision.kind == "send" else [])]
    print_whole(console, f"[bold]Decision:[/bold] [{style}]{escape(decision.text)}[/{style}]",
                keep)


def ci_line(expectations: Sequence[ExpectationResult], code: int,
            evaluation: CampaignEvaluation) -> str:
    """CI's outcome, kept apart from the decision: what the exit code asserts."""
    if code == 3:  # runs lost to the cluster: no verdict on the chains until they are re-run
        return "CI: runs were lost to the infrastructure, not a verdict (exit 3)"
    if expectations:
        held = sum(1 for e in expectations if e.held)
        return f"CI expectations: {held} of {len(expectations)} held (exit {code})"
    return verdict_counts([(p.verdict_text, p.held) for p in evaluation.paths], code)


FAILED_MARK = "✗"
UNDECIDED_MARK = "?"
NEAR_MARK = "≈"
LEGEND = (f"{FAILED_MARK} rule failed · {UNDECIDED_MARK} rule not decided yet (its limit is "
          f"inside the bounds: run more) · {NEAR_MARK} within the rule's margin of its limit "
          "(neither passed nor failed) · family-wise: every bound shown holds at once with the "
          "rulebook's confidence, so each alone is wider than a plain interval")


def verdict_title(path: PathResult) -> str:
    """``#1 name`` (``– name`` without a rank): what a path's verdict line starts with."""
    return f"{'–' if path.rank is None else f'#{path.rank}'} {path.name}"


def verdict_line(path: PathResult) -> str:
    """A path's verdict in one line: rank, name, verdict, risk, the rules it fails and those
    not decided yet (by name; the details are printed above the answer)."""
    rank = f"#{path.rank}" if path.rank is not None else "–"
    parts = [f"{rank} [bold]{escape(path.name)}[/bold]: {_verdict(path)}"]
    parts.extend(escape(part) for part in verdict_parts(path))
    parts.extend(f"{escape(w.rule)} {escape(w.text())}" for w in path.waivers)
    return "  " + " · ".join(parts)


def print_answer(console: Console, evaluation: CampaignEvaluation,
                 expectations: Sequence[ExpectationResult], code: int) -> Decision:
    """The answer, printed last so it is what the screen ends on: the decision, the ranking,
    each path's verdict in one line, then CI's outcome. A line holding a path name is
    wrapped only where the name stays whole (:func:`print_whole`)."""
    decision = campaign_decision(evaluation)
    names = [path.name for path in evaluation.paths]
    console.rule(style="dim")
    print_decision(console, decision, names)
    if evaluation.ranking:
        print_whole(console, "[bold]Ranking:[/bold] "
                    + " > ".join(escape(n) for n in evaluation.ranking), names)
        _print_ties(console, evaluation, names)
        for above, pair in pairwise.adjacent(evaluation.ranking, evaluation.pairs):
            print_whole(console, "  " + pairwise.describe(pair, above), names, markup=False)
    for path in _ordered(evaluation):
        print_whole(console, verdict_line(path), [verdict_title(path), *names])
    style = "green" if code == 0 else "red"
    console.print(f"[{style}]{ci_line(expectations, code, evaluation)}[/{style}]")
    return decision


def print_outcome(console: Console, evaluation: CampaignEvaluation,
                  expectations: list[ExpectationResult], code: int, warnings: list[str],
                  titles: Mapping[str, str] | None = None,
                  files: Sequence[tuple[str, object]] = ()) -> Decision:
    """The details (table or per-path blocks, reasons, slip, expectations, warnings, the files
    written), then the answer (:func:`print_answer`) last. A line holding a path name is
    wrapped only where the name stays whole (:func:`print_whole`)."""
    titles = titles or {}
    names = [path.name for path in evaluation.paths]
    table = results_table(evaluation, titles)
    wide = fits(console, table)
    if wide:
        console.print(table)
    else:
        console.print("[bold]Path evaluation[/bold] (best first)")
    marks = False
    for path in _ordered(evaluation) if not wide else evaluation.paths:
        if not wide:
            header, *lines = path_lines(path, titles)
            print_whole(console, header, [ranked_name(path)])
            for line in lines:
                console.print(line)
        if path.reason:
            print_whole(console, f"  [yellow]{escape(path.name)}[/yellow] {path.status}: "
                                 f"{escape(path.reason)}", names)
        if path.stop_reason and not path.stop_reason.startswith(STOP_FIXED):
            print_whole(console, f"  {escape(path.name)}: runs: {escape(path.stop_reason)}",
                        names)
        if path.unfinished and path.stop_time is not None:
            text = unfinished_text(path.name, path.unfinished, path.completed, path.stop_time)
            print_whole(console, f"  [yellow]{escape(text)}[/yellow]", names)
        near = near_rules(path)
        for decided, reason in reason_items(path):
            marks = True
            mark = (f"[yellow]{NEAR_MARK}[/yellow]" if rule_name(reason) in near
                    else f"[red]{FAILED_MARK}[/red]" if decided
                    else f"[yellow]{UNDECIDED_MARK}[/yellow]")
            print_whole(console, f"  {mark} {escape(path.name)}: {escape(reason)}" if wide
                        else f"  {mark} {escape(reason)}", names)
        for waived in path.waivers:
            print_whole(console, f"  [magenta]waived[/magenta] {escape(path.name)}: "
                                 f"{waived.kind} {escape(waived.rule)}: "
                                 f"{escape(waived.text())}", names)
        for run, reason in sorted(path.failures.items())[:10]:
            if is_infrastructure(reason):  # no failure of the path's: --resume runs it again
                print_whole(console, f"  [yellow]{escape(path.name)} run {run} lost[/yellow]: "
                                     f"{escape(reason)}", names)
            else:
                print_whole(console, f"  [red]{escape(path.name)} run {run} failed[/red]: "
                                     f"{escape(reason)}", names)
        if len(path.failures) > 10:
            console.print(f"  [red]… and {len(path.failures) - 10} more failed or lost "
                          "runs[/red]")
    if marks:
        console.print(f"[dim]{escape(LEGEND)}[/dim]")
    # assumed vs simulated slip (campaign/evaluation/slip.py); a disagreement is a warning
    # instead, a reference run that gives no slip is said as not measured (never as agreeing)
    measured = [c for c in evaluation.slip if c.measured is not None]
    agreeing = bool(measured) and not any(c.disagrees for c in measured)
    unmeasured = unmeasured_text(evaluation.slip)
    if agreeing or unmeasured:
        said = [f"slip: rulebook assumes theoretical_slip = "
                f"{100 * evaluation.slip[0].assumed:.1f} %"]
        if agreeing:
            said.append("reference runs measured " + ", ".join(
                f"{c.path} {100 * (c.measured or 0.0):.1f} %" for c in measured))
        if unmeasured:
            said.append(unmeasured)
        print_whole(console, "; ".join(said), names, markup=False)
    for expectation in expectations:
        mark = "[green]✓[/green]" if expectation.held else "[red]✗[/red]"
        print_whole(console, f"{mark} expect {escape(expectation.description)}: "
                             f"{escape(expectation.message)}", names)
    for text in dict.fromkeys(warnings):  # each said once
        print_whole(console, f"[yellow]warning:[/yellow] {escape(text)}", names)
    for label, value in files:
        console.print(f"{label}: {escape(str(value))}")
    return print_answer(console, evaluation, expectations, code)


def index_titles(rulebook: Any) -> dict[str, str]:
    """``{index name: title}`` of a rule model (``Rulebook``)."""
    return {index.name: index.title for index in getattr(rulebook, "indices", ())
            if getattr(index, "title", None)}


def _print_ties(console: Console, evaluation: CampaignEvaluation,
                names: Sequence[str]) -> None:
    """One line per tie of the ranking: ``tie: A = B (risk difference within ±2 %)``; one per
    comparison the decision depends on that is still open, with the paired runs that would
    settle it."""
    margin = f"{evaluation.indifference * 100:.3g} %"
    for first, second in evaluation.ties:
        print_whole(console, f"tie: {first} = {second} (risk difference within ±{margin})",
                    names, markup=False)
    for pair in evaluation.pairs:
        if pair.needed and pair.outcome == OPEN:
            print_whole(console, open_pair_text(pair), names, markup=False)


def open_pair_text(pair: Any) -> str:
    """``open: a vs b after 400 paired runs (risk difference −1.2 … +0.8 %): about 1,900
    paired runs would settle it at the present spread``."""
    low, high = f"{100 * pair.low:+.1f}", f"{100 * pair.high:+.1f}"
    needed = (f"about {pair.runs_needed:,} paired runs would settle it at the present spread"
              if pair.runs_needed is not None else
              "no run count up to 1,000,000 is estimated to settle it")
    return (f"open: {pair.first} vs {pair.second} after {pair.shared} paired runs (risk "
            f"difference {low} … {high} %): {needed}")
