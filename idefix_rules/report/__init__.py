"""The HTML report of a campaign: Table 1, the result map, the error box plots and the why.

``write_report(results_h5, out_dir)`` reads a results file and writes ``report.html`` (one
self-contained page: figures embedded, no script, no network) plus every figure as PNG into
``out_dir``. The campaign run calls it at its end; ``idefix-verify report`` calls it on demand.
Stages: read the data (:mod:`.data`), evaluate per-sample risk and bin it (:mod:`.prepare`,
:mod:`.riskmap`), draw (:mod:`.figures`), assemble the page (:mod:`.html`).
"""

from __future__ import annotations

import math
from html import escape
from pathlib import Path

from idefix_rules.campaign.store import ResultStore
from idefix_rules.report import figures, html
from idefix_rules.report.data import ReportData, read_report_data
from idefix_rules.report.prepare import MapSet, Setup, prepare, setup_from_store

REPORT_FILE = "report.html"


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)


def _map_images(data: ReportData, maps: MapSet, setup: Setup, out_dir: Path) -> list[html.Image]:
    order = [path.name for path in data.paths]
    images = []
    what = "per-sample risk" if maps.per_sample else "run risk I_max (per-sample values missing)"
    if maps.combined.runs == 0:
        what = "no evaluated runs (reference runs only)"
    combined = figures.risk_map_figure(
        maps.combined.values(), maps.grid, setup.environment, maps.reference_tracks, order,
        f"All paths: {what}", maps.cell_reason)
    images.append(html.Image("risk_map_all.png",
                             figures.save_png(combined, out_dir / "risk_map_all.png"),
                             f"Result map, all paths together ({maps.combined.runs} runs)."))
    for name, accumulator in maps.per_path.items():
        file = f"risk_map_{_safe(name)}.png"
        figure = figures.risk_map_figure(accumulator.values(), maps.grid, setup.environment,
                                         maps.reference_tracks, order, f"{name}: {what}",
                                         maps.cell_reason, highlight=name)
        images.append(html.Image(file, figures.save_png(figure, out_dir / file),
                                 f"Result map of path {name} ({accumulator.runs} runs)."))
    return images


def _box_images(data: ReportData, out_dir: Path) -> list[html.Image]:
    order = [path.name for path in data.paths]
    local = {p.name: p.final_local_error for p in data.paths if p.final_local_error is not None}
    heading = {p.name: p.final_heading_error for p in data.paths
               if p.final_heading_error is not None}
    images = []
    if local:
        figure = figures.box_plot_figure(local, order, "final local error [m]",
                                         "Final local error per path")
        images.append(html.Image("box_local_error.png",
                                 figures.save_png(figure, out_dir / "box_local_error.png"),
                                 "Final local error (distance to the theoretical path at the "
                                 "end of the run) per path; triangle = mean."))
    if heading:
        figure = figures.box_plot_figure(heading, order, "final heading error [deg]",
                                         "Final heading error per path", scale=180.0 / math.pi)
        images.append(html.Image("box_heading_error.png",
                                 figures.save_png(figure, out_dir / "box_heading_error.png"),
                                 "Final heading error (yaw minus the reference run's yaw at "
                                 "the end) per path; triangle = mean."))
    return images


def prepare_report(results_h5: Path) -> tuple[ReportData, Setup, MapSet]:
    """Everything the report shows, as data: read, evaluate per sample, bin (no drawing)."""
    store = ResultStore.open(results_h5)
    try:
        data = read_report_data(store)
        setup = setup_from_store(store)
        return data, setup, prepare(store, data, setup)
    finally:
        store.close()


def write_report(results_h5: Path, out_dir: Path) -> Path:
    """Write ``report.html`` and the figures as PNG into ``out_dir``; returns the HTML path.

    A missing or foreign results file raises :class:`~idefix_rules.errors.UserInputError`.
    """
    data, setup, maps = prepare_report(Path(results_h5))
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    map_images = _map_images(data, maps, setup, out_dir)
    box_images = _box_images(data, out_dir)
    dominance = None
    counts = {path.name: path.dominance() for path in data.evaluated_paths}
    if any(counts.values()):
        figure = figures.dominance_figure(counts, [path.name for path in data.paths])
        dominance = html.Image("dominant_index.png",
                               figures.save_png(figure, out_dir / "dominant_index.png"),
                               "Share of runs in which each index set the run risk I_max.")
    notes = list(setup.notes)
    if not data.evaluated_paths:
        notes.append("no path has an evaluation: run `idefix-verify evaluate` first")
    map_text = (f"<p>Grid: {escape(maps.cell_reason)}. A cell crossed by one run shows "
                "the maximum per-sample risk of that run there; a cell crossed by several runs "
                "the mean of the run-specific maxima (body-centre positions; segments between "
                "samples are rasterised so fast segments leave no gap). Dashed outlines: buffer "
                "zones; lines: reference runs.</p>")
    page = html.page(data, map_images, box_images, dominance, notes, map_text,
                     _slip_records(Path(results_h5)))
    target = out_dir / REPORT_FILE
    target.write_text(page, encoding="utf-8")
    return target


def _slip_records(results_h5: Path) -> list[dict[str, object]]:
    """Assumed vs simulated slip per path from the stored summary (campaign/slip.py)."""
    import h5py

    from idefix_rules.campaign.slip import stored_records

    with h5py.File(results_h5, "r") as file:
        return stored_records(file)


__all__ = ["REPORT_FILE", "prepare_report", "write_report"]
