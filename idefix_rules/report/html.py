"""The self-contained HTML page: inline CSS, figures as base64 PNG data URIs, no script, no URL.

It opens from disk in any browser, offline. Every text from the results file is escaped.
"""

from __future__ import annotations

import base64
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from html import escape

import numpy as np

from idefix_rules.campaign.input.wording import (
    DisplayUnits,
    bounds_label,
    parameter_text,
    unfinished_text,
)
from idefix_rules.campaign.statistics import pairwise
from idefix_rules.report.data import (
    LEVELS,
    NEAR_LIMIT,
    WORST_RUNS,
    PathReport,
    ReportData,
    TableRow,
)
from idefix_rules.units import percent_text

CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; margin: 0;
       color: #1d232a; background: #f6f7f9; line-height: 1.45; }
header { background: #1d2b3a; color: #fff; padding: 18px 28px; }
header h1 { margin: 0 0 6px 0; font-size: 1.5em; }
header .sub { color: #c9d3de; font-size: 0.92em; }
main { padding: 10px 28px 40px 28px; max-width: 1250px; }
section { background: #fff; border: 1px solid #dde2e8; border-radius: 6px; padding: 14px 20px;
          margin: 18px 0; }
h2 { font-size: 1.2em; margin: 0 0 10px 0; }
h3 { font-size: 1.02em; margin: 16px 0 6px 0; }
table { border-collapse: collapse; font-size: 0.9em; margin: 6px 0; }
th, td { border: 1px solid #d5dbe2; padding: 4px 9px; text-align: left; vertical-align: top; }
th { background: #eef1f5; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
code, .hash { font-family: ui-monospace, "DejaVu Sans Mono", monospace; font-size: 0.88em;
              word-break: break-all; }
.pass { color: #1b7f3b; font-weight: 600; } .fail { color: #b3261e; font-weight: 600; }
.other { color: #8a5a00; font-weight: 600; } .muted { color: #66707a; }
.note { background: #fff7e0; border-left: 4px solid #e0a800; padding: 6px 10px; margin: 6px 0; }
figure { margin: 10px 0; } figure img { max-width: 100%; height: auto;
          border: 1px solid #e3e7ec; }
figcaption { font-size: 0.88em; color: #4a545e; }
.scroll { overflow-x: auto; max-width: 100%; }
.banner { padding: 12px 16px; border-radius: 6px; margin: 16px 0 0 0; font-size: 1.08em;
          border-left: 6px solid; background: #fff; }
.banner.send { border-color: #1b7f3b; } .banner.none { border-color: #b3261e; }
.banner.unsettled { border-color: #e0a800; }
.banner .ci { font-size: 0.86em; color: #4a545e; margin-top: 4px; }
dl.indices dt { font-weight: 600; margin-top: 6px; } dl.indices dd { margin: 0 0 0 18px; }
.grid { display: flex; flex-wrap: wrap; gap: 14px; }
.grid figure { flex: 1 1 520px; max-width: calc(50% - 7px); min-width: 0; }
.grid.wide figure { flex: 1 1 100%; max-width: 100%; }
@media (max-width: 1100px) { .grid figure { max-width: 100%; } }
@media (max-width: 900px) { main { padding: 6px 10px 30px 10px; }
  section { padding: 10px 10px; } header { padding: 14px 12px; } }
table.table-one th { white-space: normal; }
/* Narrow windows: each row of the path table becomes a card of label: value lines, every
   column kept */
@media (max-width: 1000px) {
  table.stack, table.stack tbody, table.stack tr, table.stack td { display: block;
    width: auto; }
  table.stack thead { display: none; }
  table.stack tr { border: 1px solid #d5dbe2; border-radius: 4px; margin: 0 0 10px 0;
    padding: 4px 0; }
  table.stack td { border: none; padding: 2px 10px; display: grid;
    grid-template-columns: minmax(9em, 40%) 1fr; gap: 8px; text-align: left;
    white-space: normal; }
  table.stack td::before { content: attr(data-label); font-weight: 600; color: #4a545e; }
}
"""


@dataclass(frozen=True)
class WhyContext:
    """What the "why" section needs besides the data: units, limits, titles."""

    units: DisplayUnits = field(default_factory=DisplayUnits)
    limits: Mapping[str, float] = field(default_factory=dict)
    weights: Mapping[str, float] = field(default_factory=dict)
    titles: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class Image:
    """A figure for the page: its file name next to the report and its PNG bytes."""

    file: str
    png: bytes
    caption: str

    def tag(self) -> str:
        data = base64.b64encode(self.png).decode("ascii")
        return (f'<figure><img alt="{escape(self.caption)}" src="data:image/png;base64,{data}">'
                f"<figcaption>{escape(self.caption)} <span class=\"muted\">"
                f"({escape(self.file)})</span></figcaption></figure>")


def _number(value: float | None, digits: int = 1, scale: float = 1.0) -> str:
    if value is None or not math.isfinite(value):
        return "–"
    return f"{value * scale:.{digits}f}"


def _mean(values: np.ndarray | None, digits: int, scale: float = 1.0) -> str:
    """Mean of the finite values (absolute for signed errors), '–' when there are none."""
    if values is None or not np.isfinite(values).any():
        return "–"
    return _number(float(np.mean(np.abs(values[np.isfinite(values)]))), digits, scale)


def _verdict_class(verdict: str) -> str:
    return {"pass": "pass", "fail": "fail"}.get(verdict, "other")


def ranked(paths: Sequence[PathReport]) -> list[PathReport]:
    """Paths in rank order (best first), the unranked after them in campaign order."""
    return sorted(paths, key=lambda p: (p.row.rank is None, p.row.rank or 0))


def _table(head: Sequence[str], rows: Iterable[Sequence[str]], numeric: set[int] | None = None,
           raw: bool = False, css: str = "", labels: bool = False) -> str:
    """A table; cells are escaped unless ``raw`` (then the caller escaped them). ``labels``
    gives each cell its column's name (``data-label``), for the stacked narrow layout."""
    numeric = numeric or set()
    parts = [f'<table class="{css}">' if css else "<table>"]
    if any(head):
        parts += ["<thead><tr>", *(f"<th>{escape(h)}</th>" for h in head), "</tr></thead>"]
    parts.append("<tbody>")
    for row in rows:
        parts.append("<tr>")
        for position, cell in enumerate(row):
            text = cell if raw else escape(cell)
            kind = ' class="num"' if position in numeric else ""
            label = (f' data-label="{escape(head[position])}"'
                     if labels and position < len(head) else "")
            parts.append(f"<td{kind}{label}>{text}</td>")
        parts.append("</tr>")
    parts.append("</tbody></table>")
    return "".join(parts)


def level_chance(row: TableRow, level: str) -> float | None:
    """The chance of hitting an obstacle of ``level``, whatever the chance's name."""
    for key in (f"collision.{level}", level, f"hit_{level}"):
        if key in row.chances:
            return row.chances[key]
    matches = [value for key, value in row.chances.items() if key.endswith(level)]
    return matches[0] if len(matches) == 1 else None


def header_html(data: ReportData) -> str:
    h = data.header
    title = f"Campaign {h.campaign_name or '(unnamed)'}: verification report"
    rulebook = f"{h.rulebook_name} {h.rulebook_version}".strip() or "(unknown rulebook)"
    return (f"<header><h1>{escape(title)}</h1><div class=\"sub\">Rulebook "
            f"<b>{escape(rulebook)}</b> · rulebook sha256 <span class=\"hash\">"
            f"{escape(h.rulebook_sha256[:16] or '–')}…</span> · campaign sha256 "
            f"<span class=\"hash\">{escape(h.campaign_sha256[:16] or '–')}…</span> · FMU "
            f"sha256 <span class=\"hash\">{escape(h.fmu_sha256[:16] or '–')}…</span></div>"
            f"</header><main>")


def provenance_html(data: ReportData) -> str:
    """Files, hashes, runs and times the results came from."""
    h = data.header
    rulebook = f"{h.rulebook_name} {h.rulebook_version}".strip() or "(unknown rulebook)"
    rows = [
        ("Rulebook", f"{escape(rulebook)} · sha256 <span class=\"hash\">"
                     f"{escape(h.rulebook_sha256 or '–')}</span>"),
        ("Campaign", f"{escape(h.campaign_path or h.campaign_name)} · sha256 "
                     f"<span class=\"hash\">{escape(h.campaign_sha256 or '–')}</span>"),
        ("FMU", f"{escape(h.fmu_path or '–')} · sha256 <span class=\"hash\">"
                f"{escape(h.fmu_sha256 or '–')}</span>"),
        ("Runs", escape(f"{h.runs} per path · seed {h.seed} · sampling {h.sampling}")),
        ("Results", escape(h.results or "–")),
        ("Time", escape(f"started {h.started or '–'} · finished {h.finished or '–'} · "
                        f"state {h.state or '–'} · evaluated {h.evaluated or '–'}")),
        ("Tool", escape(f"idefix-rules {h.package_version or '–'}")),
    ]
    return (f"<section><h2>Provenance</h2><div class=\"scroll\">{_table((), rows, raw=True)}"
            "</div></section>")


def _titled(name: str | None, titles: Mapping[str, str]) -> str:
    if not name:
        return "–"
    return f"{name} ({titles[name]})" if titles.get(name) else name


def table_one_html(data: ReportData, titles: Mapping[str, str] | None = None,
                   reasons: Mapping[str, list[str]] | None = None) -> str:
    titles = titles or {}
    label = bounds_label(data.confidence)
    head = ("Rank", "Path", "Risk [%]", f"{label} [%]", "L1 hit [%]", "L2 hit [%]",
            "L3 hit [%]", "Final local error [m]", "Final heading error [deg]",
            "Energy [mAs]", "Time [s]", "Verdict", "Runs (failed)", "Dominant index")
    rows = []
    for path in ranked(data.paths):
        row = path.row
        ci = (f"{_number(row.risk_ci95[0], 1, 100)} – {_number(row.risk_ci95[1], 1, 100)}"
              if row.risk_ci95 else "–")
        verdict = escape(row.verdict or path.status or "–")
        if row.undecided:
            verdict += " <span class=\"muted\">(not decided at this number of runs)</span>"
        rows.append((
            str(row.rank) if row.rank is not None else "–",
            f"<b>{escape(path.name)}</b>", _number(row.mean_risk, 1, 100), ci,
            *(_number(level_chance(row, level), 1, 100) for level in LEVELS),
            _mean(path.final_local_error, 3), _mean(path.final_heading_error, 2,
                                                     180.0 / math.pi),
            _number(row.energy_mAs, 1), _number(row.time_s, 1),
            f"<span class=\"{_verdict_class(row.verdict)}\">{verdict}</span>",
            f"{row.completed_runs} ({row.failed_runs})",
            escape(_titled(row.dominant_index, titles)),
        ))
    table = _table(head, rows, numeric={0, 2, 3, 4, 5, 6, 7, 8, 9, 10}, raw=True,
                   css="stack table-one", labels=True)
    explained = []
    for path in data.paths:
        lines = (list((reasons or {}).get(path.name, [])) or list(path.row.verdict_reasons)
                 or ([path.reason] if path.reason else []))
        row = path.row
        lines += [f"Waived {item.get('kind', 'rule')} rule {item.get('rule', '')}: "
                  f"{item.get('reason', '')} (approved by {item.get('approved_by', '')} until "
                  f"{item.get('until', '')})" for item in row.waivers]
        if row.unfinished_runs and row.stop_time_s is not None:
            lines.insert(0, unfinished_text(path.name, row.unfinished_runs,
                                            row.completed_runs, row.stop_time_s))
        if row.stop_reason:
            lines.insert(0, f"Runs: {row.stop_reason}")
        if row.spread_warning:
            lines.append(f"Warning: {row.spread_warning}")
        if lines:
            items = "".join(f"<li>{escape(line)}</li>" for line in lines)
            explained.append(f"<h3>{escape(path.name)}</h3><ul>{items}</ul>")
    ranking = " → ".join(escape(name) for name in data.ranking) or "–"
    return (f"<section><h2>Table 1: path evaluation</h2>{table}"
            f"<p>Rows in rank order, best first: {ranking}. Risk is the mean run risk I_max "
            f"(eq. 2) with its {label}: the rulebook's confidence holds for every bound of "
            f"every path and comparison at once, so each bound alone is at a higher level; "
            f"hit chances are the share of runs "
            f"that hit an obstacle of that level; final errors are means of the absolute "
            f"values at the end of the runs (distributions in the box plots below).</p>"
            f"{pairs_html(data)}{''.join(explained)}</section>")


def pairs_html(data: ReportData) -> str:
    """The ranking's neighbours compared in the same drawn worlds (a paired campaign), and
    every other pair the decision depends on: who was safer in how many worlds, the risk
    difference and its interval, and what it decides."""
    neighbours = pairwise.shown(data.ranking, data.pairs)
    if not neighbours:
        return ""
    head = ("Pair (higher rank first)", "Safer in the same worlds", "Risk difference [%]",
            "Interval [%]", "Outcome")
    rows = []
    for above, pair in neighbours:
        below, safer, difference, low, high = pairwise.seen_from(pair, above)
        outcome = {pairwise.TIED: f"tied (within ±{100 * pair.margin:.3g} %)",
                   pairwise.OPEN: "not settled" if pair.needed else
                   "not compared further (no decision depends on it)"}.get(
            pair.outcome, "safer" if high < 0 else "riskier")
        rows.append((f"{above} vs {below}", f"{safer} of {pair.shared}",
                     f"{100 * difference:+.1f}",
                     f"{100 * low:+.1f} … {100 * high:+.1f} ({percent_text(pair.confidence)})",
                     outcome))
    sentences = "".join(f"<li>{escape(pairwise.describe(pair, above))}</li>"
                        for above, pair in neighbours)
    return (f'<h3 id="pairs">Paired comparisons</h3>'
            f"{_table(head, rows, numeric={2}, css='stack', labels=True)}"
            f"<p>Run j of every path was simulated in the same drawn world (initial pose, "
            f"soil): each row compares two neighbours of the ranking world by world (and, "
            f"below them, any other pair the decision waits on). The "
            f"interval is an anytime-valid confidence sequence of the mean risk difference, "
            f"at the confidence the campaign's α leaves each comparison.</p><ul>{sentences}</ul>")


def figures_html(title: str, images: Sequence[Image], text: str = "", wide: bool = False) -> str:
    """A section of figures, two a row (``wide``: one a row, at the page's width)."""
    if not images:
        return ""
    body = "".join(image.tag() for image in images)
    css = "grid wide" if wide else "grid"
    return f"<section><h2>{escape(title)}</h2>{text}<div class=\"{css}\">{body}</div></section>"


def worst_runs_html(path: PathReport, context: WhyContext) -> str:
    """The worst runs of a path (clickable: the run panel opens), parameters in the
    campaign's units."""
    worst = path.worst_runs(WORST_RUNS, context.limits, context.weights)
    if not worst:
        return ""
    rows = []
    for run in worst:
        top = sorted(run.indices.items(), key=lambda item: -item[1])[:3]
        params = "; ".join(
            f"{name} = "
            + parameter_text(name, value, path.parameter_units.get(name, ""), context.units)
            for name, value in run.parameters.items())
        over = (f"{run.excess:.2f}× ({run.excess_index})"
                if run.excess is not None and run.excess_index else "–")
        rows.append(f'<tr class="run" data-path="{escape(path.name)}" data-run="{run.run}" '
                    f'title="open run {run.run} in the map and its time series">'
                    f'<td class="num">{run.run}</td><td class="num">{run.i_max:.3f}</td>'
                    f"<td class=\"num\">{escape(over)}</td>"
                    f"<td>{escape(_titled(run.dominant, context.titles))}</td>"
                    f"<td>{escape(', '.join(f'{n} {v:.2f}' for n, v in top))}</td>"
                    f"<td>{escape(params or '–')}</td></tr>")
    head = "".join(f"<th>{escape(h)}</th>" for h in (
        "Run", "I_max", "Furthest over its limit", "Dominant index", "Highest indices (0…1)",
        "Sampled parameters"))
    return ("<p>Worst runs, ranked by I_max, then by how far over its limit the furthest "
            "index goes (weight × value / limit, not clipped at 1), then by the sum of the "
            "normalised indices, then by run number. Click a row to see the run on the map "
            "and its time series.</p><div class=\"scroll\"><table><thead><tr>" + head +
            "</tr></thead><tbody>" + "".join(rows) + "</tbody></table></div>")


def why_html(data: ReportData, dominance_image: Image | None,
             context: WhyContext | None = None) -> str:
    context = context or WhyContext()
    parts = ["<section><h2>Why: what drove the risk</h2>"]
    if dominance_image is not None:
        parts.append(dominance_image.tag())
    for path in data.evaluated_paths:
        parts.append(f"<h3>{escape(path.name)}</h3>")
        dominance = path.dominance()
        total = sum(count for _, count in dominance) or 1
        parts.append("<p>Index that set I_max: " + ", ".join(
            f"<b>{escape(_titled(name, context.titles))}</b> in {count} of {total} runs "
            # one decimal, as the console's percentages: halves are not rounded to even
            f"({100 * count / total:.1f} %)" for name, count in dominance) + ".</p>")
        parts.append(worst_runs_html(path, context))
    coverage = data.coverage()
    if coverage:
        rows = []
        for item in coverage:
            if item.kind == "index":
                value = f"{100 * item.highest:.0f} % of its limit"
                state = "came near its limit" if item.near else \
                    f"never came near its limit (below {100 * NEAR_LIMIT:.0f} %)"
            else:
                value = f"held in {100 * item.highest:.1f} % of runs"
                state = "occurred" if item.near else "never occurred"
            rows.append((item.name, item.kind, value, item.where or "–", state))
        parts.append("<h3>Rule coverage in this campaign</h3>")
        parts.append(_table(("Rule", "Kind", "Highest", "On path", "Coverage"), rows))
        silent = [item.name for item in coverage if not item.near]
        if silent:
            parts.append("<p>Rules this campaign did not bring near their limits: " +
                         ", ".join(f"<code>{escape(name)}</code>" for name in silent) +
                         ". These results say little about them: a small change of their "
                         "limits would not show here, but a limit moved down towards the "
                         "values these runs reached would still change them. The rulebook's "
                         "example cases (<code>idefix-verify test --coverage</code>) show "
                         "which cases exercise each rule.</p>")
    parts.append("</section>")
    return "".join(parts)


def expectations_html(expectations: Sequence[Mapping[str, object]]) -> str:
    if not expectations:
        return ""
    rows = []
    for item in expectations:
        held = bool(item.get("held"))
        rows.append((escape(str(item.get("description", ""))),
                     f"<span class=\"{'pass' if held else 'fail'}\">"
                     f"{'holds' if held else 'does not hold'}</span>",
                     escape(str(item.get("message", "")))))
    return ("<section><h2>Expectations</h2>" +
            _table(("Expectation", "Result", "Message"), rows, raw=True) + "</section>")


def slip_html(records: Sequence[Mapping[str, object]]) -> str:
    """Assumed vs simulated slip per path (campaign/evaluation/slip.py), warnings below the
    table."""
    if not records:
        return ""

    def percent(value: object) -> str:
        return "n/a" if not isinstance(value, int | float) else f"{100.0 * value:.1f}"

    rows = []
    unmeasured: dict[str, list[str]] = {}  # reason → paths
    for record in records:
        disagrees = bool(record.get("disagrees"))
        path = str(record.get("path", ""))
        if isinstance(record.get("measured"), int | float):
            judged = (f"<span class=\"{'fail' if disagrees else 'pass'}\">"
                      f"{'disagree' if disagrees else 'agree'}</span>")
        else:  # nothing to compare: neither agreeing nor disagreeing
            judged = "<span class=\"muted\">not measured</span>"
            reason = str(record.get("not_measured") or "the results file does not say why")
            unmeasured.setdefault(reason, []).append(path)
        rows.append((escape(path), percent(record.get("assumed")),
                     percent(record.get("measured")), percent(record.get("wheel_slip")),
                     judged))
    margin = percent(records[0].get("margin"))
    warnings = "".join(f"<div class=\"note\">{escape(str(record['warning']))}</div>"
                       for record in records if record.get("warning"))
    why_not = "".join(f"<p class=\"muted\">Not measured ({escape(', '.join(paths))}): "
                      f"{escape(reason)}.</p>" for reason, paths in unmeasured.items())
    return ("<section><h2>Assumed vs simulated slip</h2><p>The theoretical path (local error) "
            "assumes the rulebook's <code>theoretical_slip</code>; <em>measured</em> is each "
            "reference run's effective slip along the path (1 − travelled / commanded), "
            "<em>wheel slip</em> its mean longitudinal wheel slip while driving. They should "
            f"agree within {margin} percentage points.</p>"
            + _table(("Path", "assumed %", "measured %", "wheel slip %", "assumed vs measured"),
                     rows, numeric={1, 2, 3}, raw=True) + why_not + warnings + "</section>")


def notes_html(notes: Sequence[str]) -> str:
    if not notes:
        return ""
    return "<section><h2>Notes</h2>" + "".join(
        f"<div class=\"note\">{escape(note)}</div>" for note in notes) + "</section>"


# Nothing may be fetched: no URL is allowed, so an accidental request fails loudly (a console
# error the browser tests catch) instead of leaking or breaking offline.
CSP = ("default-src 'none'; img-src data:; style-src 'unsafe-inline'; "
       "script-src 'unsafe-inline'; base-uri 'none'; form-action 'none'")


def page(data: ReportData, parts: Sequence[str], script: str = "", css: str = "") -> str:
    """The whole report page: header, then ``parts`` (already HTML) in order, then the
    page's own script."""
    title = f"{data.header.campaign_name or 'campaign'} · idefix-verify report"
    body = header_html(data) + "".join(parts) + "</main>"
    code = f"<script>{script}</script>" if script else ""
    return (f"<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<meta http-equiv=\"Content-Security-Policy\" content=\"{CSP}\">"
            f"<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
            f"<title>{escape(title)}</title><style>{CSS}{css}</style></head><body>{body}"
            f"{code}</body></html>\n")
