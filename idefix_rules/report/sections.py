"""Report sections that explain: the decision banner, the interactive map, sensitivity, indices.

Plain HTML strings; every text from the results file is escaped. The interactive parts are
driven by :mod:`.script` from the JSON of :mod:`.interactive`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from html import escape
from typing import Any

from idefix_rules.campaign.input.wording import verdict_reasons
from idefix_rules.campaign.outcome.decision import (
    Decision,
    PathFacts,
    decide,
    verdict_counts,
)
from idefix_rules.report.data import ReportData
from idefix_rules.report.html import Image
from idefix_rules.results.format import SEARCHED_RUNS


def path_reasons(data: ReportData) -> dict[str, list[str]]:
    """Each path's failing (or undecided) verdict rules in percent: as the console said them
    (summary.json's `reasons`, an undecided rule with the runs that would decide it), else
    from the stored verdict."""
    return {path.name: list(path.row.reasons) or verdict_reasons(path.verdict, data.confidence)
            for path in data.paths if path.verdict}


def report_decision(data: ReportData) -> Decision:
    """The decision stored with the evaluation, else worked out from the stored verdicts."""
    stored = data.decision
    if isinstance(stored, Mapping) and stored.get("kind") in ("send", "none", "unsettled"):
        return Decision(stored["kind"], stored.get("path"), str(stored.get("text", "")),
                        tuple(str(r) for r in stored.get("reasons", ())))
    if not data.evaluated_paths and any(p.status == "simulated" for p in data.paths):
        # nothing scored: say why instead of deciding on verdicts no path has
        state = data.header.state or "complete"
        if state != "complete" and data.header.runs_mode == SEARCHED_RUNS:
            # interrupted before it stored its outcome (the search's section stands in for
            # this banner once it has)
            return Decision("unsettled", None, (
                f"none yet: the worst-case search is {state} and its runs so far were never "
                "evaluated; a search cannot be resumed: run `idefix-verify worst` again"))
        text = (f"none yet: the campaign is {state} and its runs so far were never evaluated; "
                "continue it with `--resume` (the command its interruption printed), or score "
                "what is stored with `idefix-verify evaluate`" if state != "complete" else
                "none yet: the campaign's runs were never evaluated; score them with "
                "`idefix-verify evaluate`")
        return Decision("unsettled", None, text)
    reasons = path_reasons(data)
    return decide([PathFacts(p.name, p.row.verdict or p.status, p.row.undecided, p.row.rank,
                             reasons.get(p.name, []),
                             tuple(item.get("rule", "") for item in p.row.waivers))
                   for p in data.paths])


def decision_html(data: ReportData) -> str:
    """The banner: what to send (or that nothing is acceptable), then CI's outcome."""
    decision = report_decision(data)
    ci = ""
    if data.expectations:
        held = sum(1 for e in data.expectations if e.get("held"))
        ci = f"CI expectations: {held} of {len(data.expectations)} held"
        if data.exit_code is not None:
            ci += f" (exit {data.exit_code})"
    elif data.exit_code is not None:
        ci = verdict_counts([(p.row.verdict or p.status, not p.row.undecided)
                             for p in data.paths], data.exit_code)
    # why the exit code is 2 although the expectations say otherwise, as the console says it
    problems = "".join(f"<li>{escape(problem_text(problem))}</li>" for problem in data.problems)
    return (f'<div class="banner {decision.kind}" id="decision"><b>Decision:</b> '
            f"{escape(decision.text)}" + (f'<div class="ci">{escape(ci)}</div>' if ci else "")
            + (f'<ul class="ci problems">{problems}</ul>' if problems else "") + "</div>")


def problem_text(problem: Mapping[str, Any]) -> str:
    """A stored problem (summary.json's ``problems``) as the console says it, in one line.

    >>> problem_text({"code": "C215", "severity": "error", "message": "no match",
    ...               "path": "c.yaml", "line": 3, "column": 5, "hint": "remove it"})
    'c.yaml:3:5: error[C215]: no match (remove it)'
    """
    where = ":".join(str(part) for part in (problem.get("path"), problem.get("line"),
                                            problem.get("column")) if part is not None)
    hint = f" ({problem['hint']})" if problem.get("hint") else ""
    return (f"{where or '<input>'}: {problem.get('severity', 'error')}"
            f"[{problem.get('code', '')}]: {problem.get('message', '')}{hint}")


def interactive_html(payload_json: str, order: Sequence[str],
                     colours: Mapping[str, str], worst: bool = False) -> str:
    """The interactive result map with its legend, path switches and the run panel;
    ``worst``: the page is a worst-case search's, whose worst runs the map marks."""
    switches = "".join(
        f'<label><input type="checkbox" value="{escape(name)}" checked> '
        f'<span class="swatch" style="background:{escape(colours.get(name, "#333"))}">'
        f"</span>{escape(name)}</label>" for name in order)
    legend = ("<span>solid: the reference run (body centre)</span><span>dashed: the ideal "
              "(commanded) path</span><span>thin: wheel tracks of the reference run</span>"
              "<span>✕ first contact with an obstacle (at the touching wheel)</span>"
              "<span>dashed ring: the obstacle level's buffer zone</span>")
    if worst:
        legend += ("<span>dotted, with a ● and a label: the path's worst run found by the "
                   "search (body centre); click the label to open it</span>")
    return (
        '<section id="map-section"><h2>Result map (paper Fig. 8), interactive</h2>'
        "<p>Hover a cell for its risk and, per path, the runs that crossed it and their "
        "dominant index; click it to open the worst of the runs this page holds there. "
        "Switch paths on and off below; the colour is the mean of the run maxima over the "
        "paths switched on.</p>"
        f'<div class="legend" id="imap-paths">{switches}</div>'
        f'<div class="legend">{legend}</div>'
        '<div class="scale"><span>risk 0 safe</span><span class="bar"></span>'
        "<span>1 critical</span></div>"
        '<div class="imap" id="imap"><canvas aria-label="interactive result map"></canvas>'
        '<div class="tip"></div></div>'
        '<div class="runpanel" id="runpanel"><h3></h3><p class="params muted"></p>'
        '<div class="charts"></div><p class="muted">Series are thinned to at most 120 '
        "points; each point keeps its interval's extreme (maximum; minimum for clearance), so "
        "no peak over a limit is lost. Red dashed: the rulebook's limit of the index reading "
        "that signal.</p></div>"
        f'<script id="report-data" type="application/json">{payload_json}</script>'
        "</section>")


def sensitivity_html(sensitivity: Mapping[str, Any], images: Sequence[Image],
                     titles: Mapping[str, str]) -> str:
    """Which uncertain parameter drives each path's risk and its dominant index."""
    if not sensitivity:
        return ""
    parts = ['<section id="sensitivity"><h2>Sensitivity: which parameter drives the risk</h2>'
             "<p>Spearman rank correlation ρ between each sampled parameter and the run risk "
             "I_max (and the raw value of the path's dominant index) over the stored Monte "
             "Carlo runs, with 95 % intervals (Fisher z); bold when the interval excludes 0. "
             "Positive: a larger parameter value goes with a higher risk. It reads monotonic "
             "influence; no new simulation is needed.</p>"]
    parts += [image.tag() for image in images]
    for name, record in sensitivity.items():
        dominant = record.get("dominant_index")
        head = ("Parameter", "ρ with I_max", "95 % interval",
                f"ρ with {dominant}" if dominant else "ρ with the dominant index")
        by_name = {item["parameter"]: item for item in record.get("dominant", [])}
        rows = []
        for item in record.get("risk", []):
            other = by_name.get(item["parameter"])
            rho = f"{item['rho']:+.2f}"
            rows.append("<tr><td>" + escape(item["parameter"]) + "</td><td class=\"num\">"
                        + (f"<b>{rho}</b>" if item.get("significant") else rho)
                        + f"</td><td class=\"num\">{item['ci95'][0]:+.2f} … "
                        f"{item['ci95'][1]:+.2f}</td><td class=\"num\">"
                        + (f"{other['rho']:+.2f}" if other else "–") + "</td></tr>")
        title = f" ({titles[dominant]})" if dominant and titles.get(dominant) else ""
        parts.append(f"<h3>{escape(name)}</h3><p>{record.get('runs', 0)} runs; dominant index "
                     f"{escape(str(dominant or '–'))}{escape(title)}.</p>")
        if not rows:  # say why, rather than show a bare header
            note = record.get("note") or ("no parameter's correlation with I_max could be "
                                          "computed")
            parts.append(f'<p class="note">No sensitivity for this path: {escape(note)}.</p>')
            continue
        parts.append('<div class="scroll"><table><thead><tr>'
                     + "".join(f"<th>{escape(h)}</th>" for h in head)
                     + "</tr></thead><tbody>" + "".join(rows) + "</tbody></table></div>")
    parts.append("</section>")
    return "".join(parts)


def indices_html(info: Mapping[str, Mapping[str, str]], limits: Mapping[str, str]) -> str:
    """Every index with its title, limit and rationale (the symbols used everywhere)."""
    if not info:
        return ""
    items = "".join(
        f"<dt>{escape(name)} — {escape(entry.get('title') or '')}"
        + (f" <span class=\"muted\">(limit {escape(limits[name])})</span>"
           if limits.get(name) else "") + "</dt>"
        f"<dd>{escape(entry.get('rationale') or 'no rationale given')}</dd>"
        for name, entry in info.items())
    return (f'<section id="indices"><h2>Indices of the rulebook</h2><dl class="indices">{items}'
            "</dl></section>")
