"""The report of a worst-case search (``idefix-verify worst``): its section and the worst runs'
tracks on the result maps.

A search's results file holds, besides its runs, the search's outcome (``/worst/record``, the
JSON of ``worst.json``). The report then opens with a table per path of what the search found
in place of the decision (a search chooses its worlds, so no verdict on them decides anything),
and draws each path's worst run on the printable result maps (dotted) and on the interactive
one (dotted and labelled, opened by a click on its label or on its row of the table).
"""

from __future__ import annotations

from collections.abc import Mapping
from html import escape
from typing import Any

import numpy as np

from idefix_rules.campaign.input.wording import DisplayUnits, parameter_text, percent
from idefix_rules.campaign.worst.outcome import rarity, sigmas
from idefix_rules.results.reader import StoredResults

NOTE = ("This file holds a worst-case search (idefix-verify worst): its runs are the worlds "
        "the search chose, not draws of the campaign's distributions. Each run's risk holds; "
        "Table 1's mean risks, chances and verdicts below are over the searched worlds, not "
        "the campaign's, and decide nothing.")


def read_worst(results_h5: Any) -> dict[str, Any] | None:
    """The search's outcome stored in a results file (None: a campaign's file)."""
    from idefix_rules.campaign.worst.stage import read_record

    store = StoredResults.open(results_h5)
    try:
        return read_record(store.file)
    finally:
        store.close()


def worst_rows(record: Mapping[str, Any]) -> dict[str, int]:
    """Per searched path, the row of its worst run among the path's runs (none when the worst
    world is the nominal one: that is the reference run, drawn already)."""
    rows = {}
    for path in record.get("paths", []):
        row = (path.get("worst") or {}).get("run") if path.get("status") == "searched" \
            else None
        if row is not None:
            rows[str(path["name"])] = int(row)
    return rows


def worst_tracks(results_h5: Any, record: Mapping[str, Any]
                 ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per searched path, the body centre's track (x, y) of its worst run (:func:`worst_rows`)."""
    tracks = {}
    store = StoredResults.open(results_h5)
    try:
        for name, row in worst_rows(record).items():
            if not store.has_path(name) or not store.has_runs(name):
                continue
            signals = store.read_runs(name, np.array([row]), ["x", "y"])
            if "x" in signals and "y" in signals:
                tracks[name] = (signals["x"][0], signals["y"][0])
    finally:
        store.close()
    return tracks


def _world(world: Mapping[str, Any], units: DisplayUnits,
           stored_units: Mapping[str, str]) -> str:
    return "; ".join(
        f"{escape(name)} {escape(parameter_text(name, float(entry['value']), stored_units.get(name, ''), units))}"  # noqa: E501
        f" <span class=\"muted\">(q {entry['quantile']:.4g})</span>"
        for name, entry in world.get("parameters", {}).items())


def _change(path: Mapping[str, Any]) -> str:
    if path.get("nominal_critical"):
        return "none: the nominal world is critical already"
    change = path.get("smallest_change")
    if change is None:
        return ("no critical world found" if not path.get("critical")
                else "not found along the rays searched")
    return f"{sigmas(change['distance'])} ({escape(str(change['direction']))})"


def rescored_note(record: Mapping[str, Any], rulebook: tuple[str, str, str]) -> str:
    """A note when the runs were scored since under another rulebook than the search's
    (``rulebook``: the evaluation's name, version and sha256): the search's findings are
    its rulebook's, "" when it is the same."""
    searched = record.get("rulebook") or {}
    name, version, sha = rulebook
    if not searched.get("sha256") or not sha or searched.get("sha256") == sha:
        return ""
    return (f"<p class=\"note\"><b>Searched under another rulebook.</b> The search found these "
            f"worlds under rulebook {escape(str(searched.get('name', '?')))} "
            f"{escape(str(searched.get('version', '?')))}; its runs were scored since under "
            f"{escape(name)} {escape(version)} (Table 1 below, and <i>now</i> beside each worst "
            "I_max), which searched nothing: its own worst world may lie elsewhere, and the "
            "boundaries are the search's. Run <code>idefix-verify worst</code> with it to "
            "search under it.</p>")


def _now(note: str, now: Mapping[str, np.ndarray] | None, path: Mapping[str, Any],
         worst: Mapping[str, Any]) -> str:
    """The worst run's I_max under the rulebook the runs were scored with since ("" when it
    is the search's, or the worst world is the nominal one)."""
    if not note or now is None or worst.get("run") is None:
        return ""
    values = now.get(str(path["name"]))
    row = int(worst["run"])
    if values is None or not 0 <= row < len(values) or not np.isfinite(values[row]):
        return ""
    return f" (now {percent(float(values[row]))})"


def worst_html(record: Mapping[str, Any], units: DisplayUnits,
               rulebook: tuple[str, str, str] = ("", "", ""),
               now: Mapping[str, np.ndarray] | None = None) -> str:
    """The section: per path the nominal and worst run risk, how rare the worst world is, the
    smallest change to critical; then per path the worlds and the boundary along each ray.
    ``rulebook`` (name, version, sha256) of the stored evaluation and ``now`` its per-run I_max
    by path: where the runs were scored under another rulebook than the search's, it says so,
    and each worst run's I_max under it."""
    stored_units = {p["name"]: p.get("unit", "") for p in record.get("parameters", [])}
    threshold = percent(float(record.get("threshold", 1.0)), 0)
    note = rescored_note(record, rulebook)
    rows = []
    for path in record.get("paths", []):
        if path.get("status") != "searched":
            rows.append(f"<tr><td>{escape(path['name'])}</td><td colspan=\"5\">not searched: "
                        f"{escape(path.get('status', ''))} {escape(path.get('reason', ''))}"
                        "</td></tr>")
            continue
        worst = path["worst"]
        opens = ""  # a row with a worst run opens it on the interactive map, as Why's rows do
        if worst.get("run") is not None:
            opens = (f' class="run" data-path="{escape(path["name"])}" '
                     f'data-run="{int(worst["run"])}" title="open run {int(worst["run"])} in '
                     'the map and its time series"')
        rows.append(
            f"<tr{opens}><td>{escape(path['name'])}</td>"
            f"<td class=\"num\">{percent(path['nominal']['risk'])}</td>"
            f"<td class=\"num\">{percent(worst['risk'])}{_now(note, now, path, worst)}</td>"
            f"<td>{escape(str(worst.get('dominant_index') or '–'))}</td>"
            f"<td>{escape(rarity(worst['tail_probability']))} "
            f"({sigmas(worst['distance'])})</td>"
            f"<td>{_change(path)}</td></tr>")
    head = ("path", "nominal I_max", "worst I_max", "dominant", "as far out as",
            "smallest change to critical")
    parts = [
        '<section id="worst"><h2>Worst case per path</h2>'
        f"<p>{escape(str(record.get('method', '')))}; at most {record.get('runs')} runs per "
        f"path, critical at I_max ≥ {threshold}. <i>As far out as</i>: the share of the "
        "campaign's worlds at least as far from the median world (every parameter at its "
        "median) as the worst one, in standard-normal quantile coordinates; σ: its distance "
        "from the nominal world there (docs/worst-case.md). Each worst run is dotted and "
        "labelled on the interactive result map; click its row (or its label) to open it "
        f"there with its time series.</p>{note}",
        '<div class="scroll"><table><thead><tr>'
        + "".join(f"<th>{escape(h)}</th>" for h in head) + "</tr></thead><tbody>"
        + "".join(rows) + "</tbody></table></div>"]
    for path in record.get("paths", []):
        if path.get("status") != "searched":
            continue
        worst = path["worst"]
        where = "the nominal world" if worst.get("run") is None else f"run {worst['run']}"
        drawn = "" if worst.get("run") is None else " (dotted on the result maps)"
        items = [f"<li>worst: I_max {percent(worst['risk'])} in {where}{drawn}: "
                 f"{_world(worst, units, stored_units)}</li>"]
        for boundary in path.get("boundaries", []):
            label = escape(str(boundary["direction"]))
            if not boundary["found"]:
                items.append(f"<li>boundary {label}: none up to "
                             f"{sigmas(boundary['searched_to'])}</li>")
                continue
            low, high = boundary["bracket"]
            critical = boundary.get("critical_world") or {}
            items.append(f"<li>boundary {label}: between {sigmas(low)} and {sigmas(high)}, "
                         f"critical at {_world(critical, units, stored_units)}</li>")
        parts.append(f"<h3>{escape(path['name'])}</h3><p>{path['runs_used']} runs "
                     f"({path['search_runs']} searching, {path['boundary_runs']} on the "
                     f"boundary)</p><ul>{''.join(items)}</ul>")
    parts.append("</section>")
    return "".join(parts)
