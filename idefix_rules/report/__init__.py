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

import math
from collections.abc import Callable, Mapping
from html import escape
from pathlib import Path
from typing import Any

from idefix_rules.campaign.sensitivity import store_sensitivity
from idefix_rules.campaign.wording import DisplayUnits
from idefix_rules.files import write_atomic
from idefix_rules.report import figures, html, interactive, script, sections
from idefix_rules.report.data import ReportData, read_report_data
from idefix_rules.report.prepare import MapSet, Setup, prepare, setup_from_store
from idefix_rules.report.worst import NOTE as WORST_NOTE
from idefix_rules.report.worst import read_worst, worst_html, worst_rows, worst_tracks
from idefix_rules.results.reader import StoredResults

REPORT_FILE = "report.html"


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)


Drawing = tuple[str, Any, str]  # file name, matplotlib figure, caption


def _map_images(data: ReportData, maps: MapSet, setup: Setup,
                done: Callable[[float], None] = lambda share: None,
                worst: Mapping[str, tuple[Any, Any]] | None = None) -> list[Drawing]:
    order = [path.name for path in data.paths]
    images = []
    what = "per-sample risk" if maps.per_sample else "run risk I_max (per-sample values missing)"
    if maps.combined.runs == 0:
        what = "no evaluated runs (reference runs only)"
    overlay = figures.MapOverlay(maps.reference_tracks, maps.ideal_tracks, maps.wheel_tracks,
                                 maps.contacts, maps.wheel_bands, worst or {})
    combined = figures.risk_map_figure(
        maps.combined.values(), maps.grid, setup.environment, overlay, order,
        f"All paths: {what}", maps.cell_reason)
    images.append(("risk_map_all.png", combined,
                   f"Result map, all paths together ({maps.combined.runs} runs)."))
    for position, (name, accumulator) in enumerate(maps.per_path.items(), start=1):
        done(position / (len(maps.per_path) + 1))
        file = f"risk_map_{_safe(name)}.png"
        figure = figures.risk_map_figure(accumulator.values(), maps.grid, setup.environment,
                                         overlay, order, f"{name}: {what}",
                                         maps.cell_reason, highlight=name)
        images.append((file, figure, f"Result map of path {name} ({accumulator.runs} runs)."))
    return images


def _box_images(data: ReportData) -> list[Drawing]:
    order = [path.name for path in data.paths]
    local = {p.name: p.final_local_error for p in data.paths if p.final_local_error is not None}
    heading = {p.name: p.final_heading_error for p in data.paths
               if p.final_heading_error is not None}
    images = []
    if local:
        figure = figures.box_plot_figure(local, order, "final local error [m]",
                                         "Final local error per path")
        images.append(("box_local_error.png", figure,
                       "Final local error (distance to the theoretical path at the "
                       "end of the run) per path; triangle = mean."))
    if heading:
        figure = figures.box_plot_figure(heading, order, "final heading error [deg]",
                                         "Final heading error per path", scale=180.0 / math.pi)
        images.append(("box_heading_error.png", figure,
                       "Final heading error (yaw minus the reference run's yaw at "
                       "the end) per path; triangle = mean."))
    return images


Advance = Callable[[float, str], None]
# Shares of the report's time (measured on the example): the per-sample pass over the runs, then
# the printable maps, then the rest (box plots, sensitivity, the page).
PREPARE_SHARE, MAPS_SHARE = 0.25, 0.65


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
        return data, setup, prepare(store, data, setup,
                                    lambda share, name: advance(PREPARE_SHARE * share,
                                                                f"per-sample risk of {name}"),
                                    embed)
    finally:
        store.close()


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


def _sensitivity(results_h5: Path) -> dict[str, Any]:
    store = StoredResults.open(results_h5)
    try:
        return store_sensitivity(store.file)
    finally:
        store.close()


def write_report(results_h5: Path, out_dir: Path, advance: Advance | None = None) -> Path:
    """Write ``report.html`` and the figures as PNG into ``out_dir``; returns the HTML path.
    ``advance(fraction, stage)`` hears how far it is (for an ETA).

    A missing or foreign results file raises :class:`~idefix_rules.errors.UserInputError`.
    """
    advance = advance or _quiet
    searched = read_worst(Path(results_h5))  # a worst-case search's outcome, if it is one
    searched_rows = worst_rows(searched) if searched is not None else {}
    data, setup, maps = prepare_report(Path(results_h5), advance, searched_rows)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    order = [path.name for path in data.paths]
    tracks = worst_tracks(Path(results_h5), searched) if searched is not None else {}
    advance(PREPARE_SHARE, "result maps")
    map_drawings = _map_images(data, maps, setup,
                               lambda share: advance(PREPARE_SHARE + MAPS_SHARE * share,
                                                     "result maps"), tracks)
    advance(PREPARE_SHARE + MAPS_SHARE, "box plots, sensitivity, the page")
    box_drawings = _box_images(data)
    other: dict[str, Drawing] = {}
    counts = {path.name: path.dominance() for path in data.evaluated_paths}
    if any(counts.values()):
        other["dominance"] = ("dominant_index.png", figures.dominance_figure(counts, order),
                              "Share of runs in which each index set the run risk I_max.")
    sensitivity = _sensitivity(Path(results_h5))
    if any(record.get("risk") for record in sensitivity.values()):
        other["sensitivity"] = (
            "sensitivity.png", figures.sensitivity_figure(sensitivity, order),
            "Per path, Spearman rank correlation of each sampled parameter with the run "
            "risk I_max and its 95 % interval; filled bars: the interval excludes 0.")
    # every figure drawn at once, on the cores there are (figures.png_files)
    drawings = [*map_drawings, *box_drawings, *other.values()]
    pngs = figures.png_files([(figure, out_dir / file) for file, figure, _ in drawings])
    images = {file: html.Image(file, png, caption)
              for (file, _, caption), png in zip(drawings, pngs, strict=True)}
    map_images = [images[file] for file, _, _ in map_drawings]
    box_images = [images[file] for file, _, _ in box_drawings]
    dominance = images[other["dominance"][0]] if "dominance" in other else None
    sensitivity_images = [images[other["sensitivity"][0]]] if "sensitivity" in other else []
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
    parts = [
        sections.decision_html(data) if searched is None else worst_html(searched, units),
        html.notes_html(notes),
        html.table_one_html(data, titles, sections.path_reasons(data)),
        html.slip_html(_slip_records(Path(results_h5))),
        sections.interactive_html(payload, order, colours, worst=bool(searched_rows)),
        html.figures_html("Result maps (printable)", map_images, map_text, wide=True),
        html.figures_html("Final errors (paper Fig. 9)", box_images),
        sections.sensitivity_html(sensitivity, sensitivity_images, titles),
        html.why_html(data, dominance, context),
        sections.indices_html(info, _limit_texts(setup)),
        html.expectations_html(data.expectations),
        html.provenance_html(data),
    ]
    page = html.page(data, parts, script.SCRIPT, script.CSS)
    target = out_dir / REPORT_FILE
    write_atomic(target, page)
    return target


def _slip_records(results_h5: Path) -> list[dict[str, object]]:
    """Assumed vs simulated slip per path from the stored summary (campaign/slip.py)."""
    import h5py

    from idefix_rules.campaign.slip import stored_records

    with h5py.File(results_h5, "r") as file:
        return stored_records(file)


__all__ = ["REPORT_FILE", "prepare_report", "write_report"]
