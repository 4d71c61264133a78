"""The HTML report of a campaign: Table 1, the result map, the error box plots and the why.

``write_report(results_h5, out_dir)`` reads a results file and writes ``report.html`` (one
self-contained page: figures and data embedded, its own small script, no request of any kind)
plus every figure as PNG into ``out_dir``. The campaign run calls it at its end;
``idefix-verify report`` calls it on demand.
Stages: read the data (:mod:`.data`), evaluate per-sample risk and bin it (:mod:`.prepare`,
:mod:`.riskmap`, :mod:`.runs`), draw (:mod:`.figures`), assemble the page (:mod:`.html`,
:mod:`.sections`, the interactive map's data :mod:`.interactive` and script :mod:`.script`).
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable, Mapping
from html import escape
from pathlib import Path
from typing import Any

from idefix_rules.campaign.evaluation.sensitivity import store_sensitivity
from idefix_rules.campaign.input.wording import DisplayUnits
from idefix_rules.files import write_atomic
from idefix_rules.report import figures, html, interactive, script, sections
from idefix_rules.report.data import ReportData
from idefix_rules.report.prepare import MapSet, Setup, prepare, setup_from_store
from idefix_rules.report.reading import read_report_data
from idefix_rules.report.worst import NOTE as WORST_NOTE
from idefix_rules.report.worst import read_worst, worst_html, worst_rows, worst_tracks
from idefix_rules.results.reader import StoredResults

REPORT_FILE = "report.html"


def _safe(name: str) -> str:
    """A path's name as part of a figure's file name: lower-case letters, digits, '-', '_'
    and '.' as they are; a name with anything else (upper case, or longer than 60
    characters, or ``all``, the map of all paths) keeps its first characters, with others as
    '_', and a digest of the whole name, so two paths never share a figure's file (``arc
    left`` and ``arc_left``, ``Detour`` and ``detour`` where case is ignored).

    >>> _safe("smooth-detour"), _safe("arc left"), _safe("arc_left")
    ('smooth-detour', 'arc_left-b447339e', 'arc_left')
    """
    kept = "".join(c if c.isascii() and (c.isalnum() or c in "-_.") else "_" for c in name)
    # upper case too: 'Detour' and 'detour' are one file on macOS's and Windows' file systems
    if kept == name and len(name) <= 60 and name != "all" and name == name.lower():
        return name
    return f"{kept[:60]}-{hashlib.sha256(name.encode('utf-8')).hexdigest()[:8]}"


# A figure: its file name, the function of :mod:`.figures` that makes it and its arguments,
# its caption.
Drawing = tuple[str, Callable[..., Any], tuple[Any, ...], dict[str, Any], str]


def _what(maps: MapSet, runs: int) -> str:
    """What a map of ``runs`` runs shows (its title)."""
    if runs == 0:
        return "no evaluated runs (reference runs only)"
    return "per-sample risk" if maps.per_sample else "run risk I_max (per-sample values missing)"


def _overlay(maps: MapSet, worst: Mapping[str, tuple[Any, Any]] | None,
             highlight: str | None) -> figures.MapOverlay:
    """What the map drawn for ``highlight`` (None: all paths) shows over its cells: every
    path's reference run and ideal path, and the wheel tracks and footprints of the path it
    highlights, the contacts of those it draws strong (only these are handed to the drawing
    process)."""
    strong = maps.contacts if highlight is None else \
        {name: points for name, points in maps.contacts.items() if name == highlight}
    shown = () if highlight is None else (highlight,)
    return figures.MapOverlay(
        maps.reference_tracks, maps.ideal_tracks,
        {name: maps.wheel_tracks[name] for name in shown if name in maps.wheel_tracks},
        strong, {name: maps.wheel_bands[name] for name in shown if name in maps.wheel_bands},
        worst or {})


def _path_map(data: ReportData, maps: MapSet, setup: Setup, name: str,
              worst: Mapping[str, tuple[Any, Any]] | None = None) -> Drawing:
    """The result map of path ``name`` (its data complete)."""
    accumulator = maps.per_path[name]
    return (f"risk_map_{_safe(name)}.png", figures.risk_map_figure,
            (accumulator.values(), maps.grid, setup.environment,
             _overlay(maps, worst, name), [path.name for path in data.paths],
             f"{name}: {_what(maps, accumulator.runs)}", maps.cell_reason),
            {"highlight": name}, f"Result map of path {name} ({accumulator.runs} runs).")


def _combined_map(data: ReportData, maps: MapSet, setup: Setup,
                  worst: Mapping[str, tuple[Any, Any]] | None = None) -> Drawing:
    """The result map of all paths together (every path's data complete)."""
    return ("risk_map_all.png", figures.risk_map_figure,
            (maps.combined.values(), maps.grid, setup.environment,
             _overlay(maps, worst, None), [path.name for path in data.paths],
             f"All paths: {_what(maps, maps.combined.runs)}", maps.cell_reason), {},
            f"Result map, all paths together ({maps.combined.runs} runs).")


def _box_images(data: ReportData) -> list[Drawing]:
    order = [path.name for path in data.paths]
    local = {p.name: p.final_local_error for p in data.paths if p.final_local_error is not None}
    heading = {p.name: p.final_heading_error for p in data.paths
               if p.final_heading_error is not None}
    images: list[Drawing] = []
    if local:
        images.append(("box_local_error.png", figures.box_plot_figure,
                       (local, order, "final local error [m]", "Final local error per path"),
                       {}, "Final local error (distance to the theoretical path at the "
                           "end of the run) per path; triangle = mean."))
    if heading:
        images.append(("box_heading_error.png", figures.box_plot_figure,
                       (heading, order, "final heading error [deg]",
                        "Final heading error per path"), {"scale": 180.0 / math.pi},
                       "Final heading error (yaw minus the reference run's yaw at "
                       "the end) per path; triangle = mean."))
    return images


Advance = Callable[[float, str], None]
# Shares of the report's time (measured on the example): the per-sample pass over the runs
# (the paths' maps drawn meanwhile), then the rest (the map of all paths, box plots,
# sensitivity, the page).
PREPARE_SHARE = 0.8


def _quiet(fraction: float, stage: str) -> None:
    pass


def prepare_report(results_h5: Path, advance: Advance = _quiet,
                   embed: Mapping[str, int] | None = None
                   ) -> tuple[ReportData, Setup, MapSet]:
    """Everything the report shows, as data: read, evaluate per sample, bin (no drawing).
    ``embed``: a run per path the interactive map holds besides the worst ones."""
    store = StoredResults.open(results_h5)
    try:
        data = read_report_data(store)
        setup = setup_from_store(store)
        return data, setup, _maps(store, data, setup, advance, embed)
    finally:
        store.close()


def _maps(store: StoredResults, data: ReportData, setup: Setup, advance: Advance,
          embed: Mapping[str, int] | None,
          mapped: Callable[[MapSet, str], None] | None = None) -> MapSet:
    return prepare(store, data, setup,
                   lambda share, name: advance(PREPARE_SHARE * share,
                                               f"per-sample risk of {name}"), embed, mapped)


def _limit_texts(setup: Setup) -> dict[str, str]:
    """Each index's limit as the rulebook wrote it (a constant shows its value: ``70 %``)."""
    from idefix_rules.rulebook.format import format_expr
    from idefix_rules.rulebook.model import Name

    rulebook = getattr(setup.checked, "rulebook", None)
    if rulebook is None:
        return {}
    constants = {c.name: c.value for c in rulebook.constants}
    texts = {}
    for index in rulebook.indices:
        expr = index.limit
        shown = format_expr(expr)
        if isinstance(expr, Name) and expr.name in constants:
            shown = f"{expr.name} = {format_expr(constants[expr.name])}"
        texts[index.name] = shown
    return texts


def write_report(results_h5: Path, out_dir: Path, advance: Advance | None = None) -> Path:
    """Write ``report.html`` and the figures as PNG into ``out_dir``; returns the HTML path.
    ``advance(fraction, stage)`` hears how far it is (for an ETA).

    A missing or foreign results file raises :class:`~idefix_rules.errors.UserInputError`.
    """
    advance = advance or _quiet
    searched = read_worst(Path(results_h5))  # a worst-case search's outcome, if it is one
    searched_rows = worst_rows(searched) if searched is not None else {}
    tracks = worst_tracks(Path(results_h5), searched) if searched is not None else {}
    store = StoredResults.open(Path(results_h5))
    try:
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        # Figures are drawn in forked processes as their data are ready: each path's map
        # while the next path is evaluated, the rest while the page is put together. The
        # processes start now, before any run is read.
        drawing = figures.FigureProcesses()
        try:
            return _write_report(store, out_dir, advance, searched, searched_rows, tracks,
                                 drawing)
        finally:
            drawing.close()
    finally:
        store.close()


def _write_report(store: StoredResults, out_dir: Path, advance: Advance, searched: Any,
                  searched_rows: Mapping[str, int], tracks: Mapping[str, tuple[Any, Any]],
                  drawing: figures.FigureProcesses) -> Path:
    drawings: dict[str, Drawing] = {}

    def draw(key: str, drawn: Drawing) -> None:
        drawings[key] = drawn
        file, make, arguments, keywords, _ = drawn
        drawing.draw(out_dir / file, make, *arguments, **keywords)

    data = read_report_data(store)
    order = [path.name for path in data.paths]
    # the figures whose data are read already, drawn while the runs are evaluated
    counts = {path.name: path.dominance() for path in data.evaluated_paths}
    if any(counts.values()):
        draw("dominance", ("dominant_index.png", figures.dominance_figure, (counts, order), {},
                           "Share of runs in which each index set the run risk I_max."))
    sensitivity = store_sensitivity(store.file)
    if any(record.get("risk") for record in sensitivity.values()):
        draw("sensitivity", (
            "sensitivity.png", figures.sensitivity_figure, (sensitivity, order), {},
            "Per path, Spearman rank correlation of each sampled parameter with the run "
            "risk I_max and its 95 % interval; filled bars: the interval excludes 0."))
    setup = setup_from_store(store)

    def mapped(maps: MapSet, name: str) -> None:
        draw(f"map {name}", _path_map(data, maps, setup, name, tracks))

    maps = _maps(store, data, setup, advance, searched_rows, mapped)
    advance(PREPARE_SHARE, "the map of all paths, box plots, the page")
    draw("map", _combined_map(data, maps, setup, tracks))
    for position, drawn in enumerate(_box_images(data)):
        draw(f"box {position}", drawn)
    notes = list(setup.notes)
    if searched is not None:
        notes.insert(0, WORST_NOTE)
    if not data.evaluated_paths:
        notes.append("no path has an evaluation: run `idefix-verify evaluate` first")
    map_text = (f"<p>Grid: {escape(maps.cell_reason)}. A cell crossed by one run shows "
                "the maximum per-sample risk of that run there; a cell crossed by several runs "
                "the mean of the run-specific maxima (body-centre positions; segments between "
                "samples are rasterised so fast segments leave no gap). Dashed: the ideal "
                "(commanded) path; solid: the reference run's body centre, thin: its wheel "
                "tracks; ✕: first contacts, at the touching wheel; dashed rings: buffer zones. "
                "These are the printable figures of the interactive map above.</p>")
    info = interactive.index_info(setup)
    titles = {name: entry["title"] for name, entry in info.items() if entry["title"]}
    units = DisplayUnits.from_campaign_text(setup.campaign_text)
    context = html.WhyContext(units, dict(getattr(setup.checked, "limits", {}) or {}),
                              dict(getattr(setup.checked, "weights", {}) or {}), titles)
    colours = {name: figures.path_colour(position) for position, name in enumerate(order)}
    payload = interactive.payload_json(interactive.payload(data, setup, maps, units,
                                                           searched_rows))
    slip = html.slip_html(_slip_records(store))
    limit_texts = _limit_texts(setup)
    # the page's figures, once drawn
    pngs = dict(zip([drawn[0] for drawn in drawings.values()], drawing.wait(), strict=True))
    images = {key: html.Image(file, pngs[file], caption)
              for key, (file, _, _, _, caption) in drawings.items()}
    map_images = [images[key] for key in ["map", *(f"map {name}" for name in maps.per_path)]
                  if key in images]
    box_images = [images[key] for key in sorted(images) if key.startswith("box ")]
    sensitivity_images = [images["sensitivity"]] if "sensitivity" in images else []
    parts = [
        sections.decision_html(data) if searched is None else worst_html(
            searched, units, (data.header.rulebook_name, data.header.rulebook_version,
                              data.header.rulebook_sha256),
            {path.name: path.i_max for path in data.paths}),
        html.notes_html(notes),
        html.table_one_html(data, titles, sections.path_reasons(data)),
        slip,
        sections.interactive_html(payload, order, colours, worst=bool(searched_rows)),
        html.figures_html("Result maps (printable)", map_images, map_text, wide=True),
        html.figures_html("Final errors (paper Fig. 9)", box_images),
        sections.sensitivity_html(sensitivity, sensitivity_images, titles),
        html.why_html(data, images.get("dominance"), context),
        sections.indices_html(info, limit_texts),
        html.expectations_html(data.expectations),
        html.provenance_html(data),
    ]
    page = html.page(data, parts, script.SCRIPT, script.CSS)
    target = out_dir / REPORT_FILE
    write_atomic(target, page)
    return target


def _slip_records(store: StoredResults) -> list[dict[str, object]]:
    """Assumed vs simulated slip per path from the stored summary (campaign/evaluation/slip.py)."""
    from idefix_rules.campaign.evaluation.slip import stored_records

    return stored_records(store.file)


__all__ = ["REPORT_FILE", "prepare_report", "write_report"]
