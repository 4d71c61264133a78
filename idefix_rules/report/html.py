"""The self-contained HTML page: inline CSS, figures as base64 PNG data URIs, no script, no URL.

It opens from disk in any browser, offline. Every text from the results file is escaped.
"""

from __future__ import annotations

import base64
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from html import escape

import numpy as np

from idefix_rules.report.data import LEVELS, NEAR_LIMIT, ReportData, TableRow

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
td.num { text-align: right; font-variant-numeric: tabular-nums; }
code, .hash { font-family: ui-monospace, "DejaVu Sans Mono", monospace; font-size: 0.88em;
              word-break: break-all; }
.pass { color: #1b7f3b; font-weight: 600; } .fail { color: #b3261e; font-weight: 600; }
.other { color: #8a5a00; font-weight: 600; } .muted { color: #66707a; }
.note { background: #fff7e0; border-left: 4px solid #e0a800; padding: 6px 10px; margin: 6px 0; }
figure { margin: 10px 0; } figure img { max-width: 100%; height: auto;
          border: 1px solid #e3e7ec; }
figcaption { font-size: 0.88em; color: #4a545e; }
.grid { display: flex; flex-wrap: wrap; gap: 14px; }
.grid figure { flex: 1 1 520px; max-width: calc(50% - 7px); }
@media (max-width: 1100px) { .grid figure { max-width: 100%; } }
"""


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


def _table(head: Sequence[str], rows: Iterable[Sequence[str]], numeric: set[int] | None = None,
           raw: bool = False) -> str:
    """A table; cells are escaped unless ``raw`` (then the caller escaped them)."""
    numeric = numeric or set()
    parts = ["<table>"]
    if any(head):
        parts += ["<thead><tr>", *(f"<th>{escape(h)}</th>" for h in head), "</tr></thead>"]
    parts.append("<tbody>")
    for row in rows:
        parts.append("<tr>")
        for position, cell in enumerate(row):
            text = cell if raw else escape(cell)
            css = ' class="num"' if position in numeric else ""
            parts.append(f"<td{css}>{text}</td>")
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
    rows = [
        ("Rulebook", f"{escape(rulebook)} · sha256 <span class=\"hash\">"
                     f"{escape(h.rulebook_sha256 or '–')}</span>"),
        ("Campaign", f"{escape(h.campaign_path or h.campaign_name)} · sha256 "
                     f"<span class=\"hash\">{escape(h.campaign_sha256 or '–')}</span>"),
        ("FMU", f"{escape(h.fmu_path or '–')} · sha256 <span class=\"hash\">"
                f"{escape(h.fmu_sha256 or '–')}</span>"),
        ("Runs", escape(f"{h.runs} per path · seed {h.seed} · sampling {h.sampling}")),
        ("Time", escape(f"started {h.started or '–'} · finished {h.finished or '–'} · "
                        f"state {h.state or '–'} · evaluated {h.evaluated or '–'}")),
        ("Tool", escape(f"idefix-rules {h.package_version or '–'}")),
    ]
    table = _table((), rows, raw=True)
    return (f"<header><h1>{escape(title)}</h1><div class=\"sub\">Rulebook "
            f"<b>{escape(rulebook)}</b> · rulebook sha256 <span class=\"hash\">"
            f"{escape(h.rulebook_sha256[:16] or '–')}…</span> · campaign sha256 "
            f"<span class=\"hash\">{escape(h.campaign_sha256[:16] or '–')}…</span> · FMU "
            f"sha256 <span class=\"hash\">{escape(h.fmu_sha256[:16] or '–')}…</span></div>"
            f"</header><main><section><h2>Provenance</h2>{table}</section>")


def table_one_html(data: ReportData) -> str:
    head = ("Path", "Risk [%]", "95 % CI of the risk [%]", "L1 hit [%]", "L2 hit [%]",
            "L3 hit [%]", "Final local error [m]", "Final heading error [deg]",
            "Energy [mAs]", "Time [s]", "Verdict", "Rank", "Runs (failed)")
    rows = []
    for path in data.paths:
        row = path.row
        ci = (f"{_number(row.risk_ci95[0], 1, 100)} – {_number(row.risk_ci95[1], 1, 100)}"
              if row.risk_ci95 else "–")
        verdict = escape(row.verdict or path.status or "–")
        if row.undecided:
            verdict += " <span class=\"muted\">(not decided at this number of runs)</span>"
        rows.append((
            escape(path.name), _number(row.mean_risk, 1, 100), ci,
            *(_number(level_chance(row, level), 1, 100) for level in LEVELS),
            _mean(path.final_local_error, 3), _mean(path.final_heading_error, 2,
                                                     180.0 / math.pi),
            _number(row.energy_mAs, 1), _number(row.time_s, 1),
            f"<span class=\"{_verdict_class(row.verdict)}\">{verdict}</span>",
            str(row.rank) if row.rank is not None else "–",
            f"{row.completed_runs} ({row.failed_runs})",
        ))
    table = _table(head, rows, numeric={1, 2, 3, 4, 5, 6, 7, 8, 9, 11}, raw=True)
    reasons = []
    for path in data.paths:
        lines = list(path.row.verdict_reasons) or ([path.reason] if path.reason else [])
        if path.row.stop_reason:
            lines.insert(0, f"Runs: {path.row.stop_reason}")
        if lines:
            items = "".join(f"<li>{escape(line)}</li>" for line in lines)
            reasons.append(f"<h3>{escape(path.name)}</h3><ul>{items}</ul>")
    ranking = " → ".join(escape(name) for name in data.ranking) or "–"
    return (f"<section><h2>Table 1: path evaluation</h2>{table}"
            f"<p>Ranking, best first: {ranking}. Risk is the mean run risk I_max (eq. 2) "
            f"with its 95 % confidence interval; hit chances are the share of runs that hit an "
            f"obstacle of that level; final errors are means of the absolute values at the end "
            f"of the runs (distributions in the box plots below).</p>{''.join(reasons)}</section>")


def figures_html(title: str, images: Sequence[Image], text: str = "") -> str:
    if not images:
        return ""
    body = "".join(image.tag() for image in images)
    return f"<section><h2>{escape(title)}</h2>{text}<div class=\"grid\">{body}</div></section>"


def _parameter_text(name: str, value: float, unit: str) -> str:
    return f"{name} = {value:.4g}{' ' + unit if unit and unit != '1' else ''}"


def why_html(data: ReportData, dominance_image: Image | None) -> str:
    parts = ["<section><h2>Why: what drove the risk</h2>"]
    if dominance_image is not None:
        parts.append(dominance_image.tag())
    for path in data.evaluated_paths:
        parts.append(f"<h3>{escape(path.name)}</h3>")
        dominance = path.dominance()
        total = sum(count for _, count in dominance) or 1
        parts.append("<p>Index that set I_max: " + ", ".join(
            f"<b>{escape(name)}</b> in {count} of {total} runs ({100 * count / total:.0f} %)"
            for name, count in dominance) + ".</p>")
        worst = path.worst_runs()
        if worst:
            rows = []
            for run in worst:
                top = sorted(run.indices.items(), key=lambda item: -item[1])[:3]
                params = "; ".join(_parameter_text(name, value, path.parameter_units.get(name, ""))
                                   for name, value in run.parameters.items())
                rows.append((str(run.run), f"{run.i_max:.3f}", run.dominant or "–",
                             ", ".join(f"{name} {value:.2f}" for name, value in top),
                             params or "–"))
            parts.append("<p>Worst runs and their sampled parameters:</p>")
            parts.append(_table(("Run", "I_max", "Dominant", "Highest indices",
                                 "Sampled parameters (SI)"), rows, numeric={0, 1}))
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
            parts.append("<p>Rules this campaign did not exercise: " +
                         ", ".join(f"<code>{escape(name)}</code>" for name in silent) +
                         ". A change to their limits would not change these results.</p>")
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


def notes_html(notes: Sequence[str]) -> str:
    if not notes:
        return ""
    return "<section><h2>Notes</h2>" + "".join(
        f"<div class=\"note\">{escape(note)}</div>" for note in notes) + "</section>"


def page(data: ReportData, maps: Sequence[Image], boxes: Sequence[Image],
         dominance: Image | None, notes: Sequence[str], map_text: str) -> str:
    """The whole report page."""
    title = f"{data.header.campaign_name or 'campaign'} · idefix-verify report"
    body = "".join([
        header_html(data),
        notes_html(notes),
        table_one_html(data),
        figures_html("Result map (paper Fig. 8)", maps, map_text),
        figures_html("Final errors (paper Fig. 9)", boxes),
        why_html(data, dominance),
        expectations_html(data.expectations),
        "</main>",
    ])
    return (f"<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
            f"<title>{escape(title)}</title><style>{CSS}</style></head><body>{body}"
            f"</body></html>\n")

