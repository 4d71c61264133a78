"""Every figure of the report, drawn with matplotlib's object API on the Agg canvas.

Drawing only: the data arrive prepared (:mod:`idefix_rules.report.riskmap`,
:mod:`idefix_rules.report.prepare`). No pyplot, so no global figure state and no GUI backend.
"""

from __future__ import annotations

import io
import multiprocessing
import os
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse, Polygon
from PIL import Image
from PIL.PngImagePlugin import PngInfo

from idefix_rules.files import write_atomic
from idefix_rules.report.environment import MapEnvironment, buffer_mask
from idefix_rules.report.riskmap import RiskGrid

RISK_COLOURS = "RdYlGn_r"  # green = safe, red = critical, like the paper's Fig. 8
LEVEL_COLOURS = {"L1": "#1f77b4", "L2": "#ff7f0e", "L3": "#d62728", "?": "#7f7f7f"}
PATH_COLOURS = ("#1f4e9c", "#6a3d9a", "#00897b", "#c2185b", "#5d4037", "#455a64")
DPI = 110


def path_colour(position: int) -> str:
    return PATH_COLOURS[position % len(PATH_COLOURS)]


def _figure(width: float, height: float) -> Figure:
    figure = Figure(figsize=(width, height), dpi=DPI, layout="constrained")
    FigureCanvasAgg(figure)
    return figure


# PNG as drawn on the Agg canvas, without its alpha channel (every figure is opaque), at zlib
# level 3: smaller than matplotlib's RGBA at level 6 and encoded in half the time.
PNG_COMPRESSION = 3
PNG_SOFTWARE = f"Matplotlib version{matplotlib.__version__}, https://matplotlib.org/"


def png_bytes(figure: Figure) -> bytes:
    """The figure as PNG. Drawn once on its canvas (the layout is done within that draw;
    ``savefig`` lays out in a dry draw first and draws again), then encoded as RGB."""
    canvas = figure.canvas
    assert isinstance(canvas, FigureCanvasAgg)
    canvas.draw()  # type: ignore[no-untyped-call]
    pixels = canvas.buffer_rgba()  # type: ignore[no-untyped-call]
    image = Image.frombuffer("RGBA", canvas.get_width_height(), pixels, "raw", "RGBA", 0,
                             1).convert("RGB")
    info = PngInfo()
    info.add_text("Software", PNG_SOFTWARE)
    buffer = io.BytesIO()
    image.save(buffer, format="png", compress_level=PNG_COMPRESSION, pnginfo=info,
               dpi=(DPI, DPI))
    return buffer.getvalue()


def save_png(figure: Figure, target: Path) -> bytes:
    """Write the figure as PNG and return the bytes (for embedding)."""
    data = png_bytes(figure)
    write_atomic(target, data)
    return data


def _draw_to(target: Path, make: Callable[..., Figure], arguments: tuple[Any, ...],
             keywords: dict[str, Any]) -> bytes:
    return save_png(make(*arguments, **keywords), target)


def _started() -> None:
    """Nothing: handed to the drawing processes so that they are forked at once."""


class FigureProcesses:
    """Figures drawn to PNG files while the caller goes on: each figure handed to
    :meth:`draw` (a function of this module and its arguments) is made and drawn in one of
    ``workers`` forked processes, so drawing runs on the other cores while the report
    prepares the next path's data. The processes are forked when this is made, before the
    report reads any run (they inherit no reading thread and little memory), and draw every
    figure (their font and text caches stay warm). Where ``fork`` is missing, or with one
    worker, :meth:`draw` draws at once. :meth:`wait` gives every file's bytes, in the order
    handed over.

    >>> drawing = FigureProcesses()  # doctest: +SKIP
    >>> drawing.draw(out / "box.png", box_plot_figure, series, order, "m", "t")  # doctest: +SKIP
    >>> pngs = drawing.wait()  # doctest: +SKIP
    """

    def __init__(self, workers: int | None = None) -> None:
        self.workers = max(1, workers or os.cpu_count() or 1)
        self._pool: ProcessPoolExecutor | None = None
        if self.workers > 1 and "fork" in multiprocessing.get_all_start_methods():
            self._pool = ProcessPoolExecutor(self.workers,
                                             mp_context=multiprocessing.get_context("fork"))
            self._pool.submit(_started)  # a forking pool starts all its processes at once
        self._drawn: list[Future[bytes]] = []

    def draw(self, target: Path, make: Callable[..., Figure], *arguments: Any,
             **keywords: Any) -> None:
        """Draw the figure ``make(*arguments, **keywords)`` returns into ``target``."""
        if self._pool is None:
            done: Future[bytes] = Future()
            done.set_result(_draw_to(target, make, arguments, keywords))
            self._drawn.append(done)
            return
        self._drawn.append(self._pool.submit(_draw_to, target, make, arguments, keywords))

    def wait(self) -> list[bytes]:
        """Every figure's PNG, in the order handed to :meth:`draw`, once all are drawn."""
        return [future.result() for future in self._drawn]

    def close(self) -> None:
        """End the drawing processes (those still drawing when the report failed too)."""
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)
            self._pool = None


def _add_patch(axes: Any, patch: Any) -> None:
    """Add a patch without growing the data limits: the maps set their limits themselves,
    and matplotlib's limit update walks every vertex of a polygon (a wheel band has
    thousands) as Bézier segments."""
    axes.add_artist(patch)


def _draw_environment(axes: object, environment: MapEnvironment, step: float) -> None:
    from matplotlib.axes import Axes

    assert isinstance(axes, Axes)
    for area in environment.areas:
        colour = LEVEL_COLOURS.get(area.level, LEVEL_COLOURS["?"])
        _add_patch(axes, Polygon(area.polygon, closed=True, facecolor=colour, alpha=0.25,
                               edgecolor=colour, hatch="//", linewidth=1.2, zorder=3))
        if area.buffer > 0:
            xs, ys, mask = buffer_mask(area, step)
            axes.contour(xs, ys, mask, levels=[0.5], colors=[colour], linestyles="--",
                         linewidths=1.0, zorder=3)
        if area.name:
            axes.annotate(f"{area.name} ({area.level})", area.polygon.mean(axis=0),
                          fontsize=10, ha="center", color=colour, zorder=6)
    for rock in environment.rocks:
        colour = LEVEL_COLOURS.get(rock.level, LEVEL_COLOURS["?"])
        _add_patch(axes, Ellipse((rock.x, rock.y), 2 * rock.a, 2 * rock.b, facecolor="#8d8d8d",
                               edgecolor=colour, linewidth=1.5, zorder=4))
        if rock.buffer > 0:
            _add_patch(axes, Ellipse((rock.x, rock.y), 2 * (rock.a + rock.buffer),
                                   2 * (rock.b + rock.buffer), fill=False, edgecolor=colour,
                                   linestyle="--", linewidth=1.0, zorder=4))
        buffer = f", buffer {rock.buffer * 100:.0f} cm" if rock.buffer > 0 else ""
        axes.annotate(f"{rock.name} ({rock.level}{buffer})",
                      (rock.x, rock.y + rock.b + rock.buffer), fontsize=10, ha="center",
                      va="bottom", color=colour, zorder=6)


@dataclass(frozen=True)
class MapOverlay:
    """What is drawn over the risk cells besides obstacles (all per path, metres)."""

    references: Mapping[str, tuple[np.ndarray, np.ndarray]]
    ideal: Mapping[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    wheels: Mapping[str, Mapping[str, tuple[np.ndarray, np.ndarray]]] = field(
        default_factory=dict)
    contacts: Mapping[str, Sequence[Mapping[str, Any]]] = field(default_factory=dict)
    bands: Mapping[str, Mapping[str, np.ndarray]] = field(default_factory=dict)
    # a worst-case search's worst run per path (docs/worst-case.md)
    worst: Mapping[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)


def risk_map_figure(values: np.ndarray, grid: RiskGrid, environment: MapEnvironment,
                    overlay: MapOverlay, path_order: Sequence[str], title: str,
                    cell_note: str, highlight: str | None = None) -> Figure:
    """The result map (paper Fig. 8): risk per cell, obstacles with level and buffer, per
    path the ideal (commanded) path dashed, the reference run and its four wheel tracks, and
    the first contacts marked where they happened. Sized to be read at page width (fonts
    ≥ 9 pt at 100 %), the legend below the map."""
    figure = _figure(9.0, 7.4)
    axes = figure.add_subplot()
    cmap = colormaps[RISK_COLOURS].with_extremes(bad=(1.0, 1.0, 1.0, 0.0))
    image = axes.imshow(np.ma.masked_invalid(values), origin="lower", extent=grid.extent,
                        cmap=cmap, norm=Normalize(0.0, 1.0), interpolation="nearest", zorder=2)
    _draw_environment(axes, environment, grid.cell / 4)
    contacts_drawn = False
    for position, name in enumerate(path_order):
        strong = highlight is None or name == highlight
        colour = path_colour(position)
        alpha = 1.0 if strong else 0.35
        if name == highlight:
            for band in (overlay.bands.get(name) or {}).values():
                _add_patch(axes, Polygon(band, closed=True, facecolor=colour, alpha=0.18,
                                       edgecolor="none", zorder=4))
        # footprints of the highlighted path only: every path's at once hide the map
        for wheel in (overlay.wheels.get(name) or {}).values() if name == highlight else ():
            axes.plot(wheel[0], wheel[1], color=colour, linewidth=0.8, alpha=0.6 * alpha,
                      zorder=5)
        ideal = overlay.ideal.get(name)
        if ideal is not None and strong:
            axes.plot(ideal[0], ideal[1], color=colour, linestyle=(0, (5, 3)), linewidth=1.5,
                      zorder=6)
        track = overlay.references.get(name)
        if track is not None:
            axes.plot(track[0], track[1], color=colour, linewidth=2.2 if strong else 0.9,
                      alpha=alpha, label=name, zorder=6)
        worst = overlay.worst.get(name)
        if worst is not None and strong:
            axes.plot(worst[0], worst[1], color=colour, linestyle=(0, (1, 1.5)), linewidth=2.0,
                      zorder=6)
        points = overlay.contacts.get(name) or ()
        if points and strong:
            axes.scatter([p["x"] for p in points], [p["y"] for p in points], marker="x",
                         s=28, color="black", linewidths=1.2, zorder=7)
            contacts_drawn = True
    axes.plot([0.0], [0.0], marker="o", color="black", markersize=5, zorder=7, label="start")
    grey = "#555555"
    axes.plot([], [], color=grey, linewidth=2.2, label="reference run (body centre)")
    axes.plot([], [], color=grey, linestyle=(0, (5, 3)), linewidth=1.5,
              label="ideal (commanded) path")
    if overlay.worst:
        axes.plot([], [], color=grey, linestyle=(0, (1, 1.5)), linewidth=2.0,
                  label="worst world found (body centre)")
    if highlight is not None and overlay.wheels.get(highlight):
        axes.plot([], [], color=grey, linewidth=0.8, label="wheel tracks (reference run)")
    _add_patch(axes, Polygon(np.zeros((3, 2)), facecolor=grey, alpha=0.25, edgecolor="none",
                           label="wheel footprints (6 cm wide)"
                           if highlight is not None and overlay.bands.get(highlight) else None))
    if contacts_drawn:
        axes.scatter([], [], marker="x", color="black", label="first contact (at the wheel)")
    left, right, bottom, top = grid.extent
    axes.set_xlim(left, right)
    axes.set_ylim(bottom, top)
    axes.set_aspect("equal")
    # the terrain's frame, that of the FMU's x/y and the DEM (the rover's start frame only
    # when it starts at the origin heading +x)
    axes.set_xlabel(f"x [m] (terrain frame)\ngrid: {cell_note}", fontsize=10)
    axes.set_ylabel("y [m] (terrain frame)", fontsize=10)
    axes.tick_params(labelsize=10)
    # At the top of the map, as matplotlib would place it: given, it is not placed again at
    # every draw (which measures the tick labels of the map and its colour bar once more;
    # the map has no ticks or offset text at its top that it would have to clear).
    axes.set_title(title, fontsize=13, y=1.0)
    axes.grid(True, linewidth=0.3, alpha=0.5, zorder=1)
    axes.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=3, fontsize=9.5,
                framealpha=0.9)
    # The colour bar sits in an inset, so it is exactly as tall as the map whatever its aspect.
    bar = figure.colorbar(image, cax=axes.inset_axes((1.03, 0.0, 0.035, 1.0)))
    bar.set_label("risk (0 safe … 1 critical)", fontsize=10)
    return figure


def sensitivity_figure(sensitivity: Mapping[str, Mapping[str, Any]],
                       path_order: Sequence[str]) -> Figure:
    """A bar chart per path: each parameter's Spearman ρ with I_max and its 95 % interval
    (filled when the interval excludes 0), parameters in the same order in every panel."""
    names = [name for name in path_order if sensitivity.get(name, {}).get("risk")]
    parameters: list[str] = []
    for name in names:
        parameters += [item["parameter"] for item in sensitivity[name]["risk"]
                       if item["parameter"] not in parameters]
    rows = max(1, len(names))
    figure = _figure(9.0, 0.9 + rows * (0.55 + 0.3 * max(1, len(parameters))))
    panels = figure.subplots(rows, 1, sharex=True, squeeze=False)[:, 0]
    for axes, name in zip(panels, names, strict=False):
        items = {item["parameter"]: item for item in sensitivity[name]["risk"]}
        shown = [p for p in parameters if p in items]
        ys = np.arange(len(shown))
        rho = np.array([items[p]["rho"] for p in shown])
        low = rho - np.array([items[p]["ci95"][0] for p in shown])
        high = np.array([items[p]["ci95"][1] for p in shown]) - rho
        colour = path_colour(list(path_order).index(name))
        significant = [bool(items[p]["significant"]) for p in shown]
        axes.barh(ys, rho, height=0.7, xerr=[low, high], capsize=3,
                  color=[colour if s else "white" for s in significant], edgecolor=colour,
                  linewidth=1.2, error_kw={"linewidth": 0.9})
        axes.set_yticks(ys, shown, fontsize=10)
        axes.invert_yaxis()
        axes.axvline(0.0, color="black", linewidth=0.8)
        # placed as matplotlib would (nothing numbered at a panel's top): see risk_map_figure
        axes.set_title(f"{name} ({sensitivity[name].get('runs', 0)} runs)", fontsize=11,
                       loc="left", y=1.0)
        axes.grid(True, axis="x", linewidth=0.3, alpha=0.6)
    panels[-1].set_xlim(-1.0, 1.0)
    panels[-1].set_xlabel("Spearman ρ with the run risk I_max, 95 % interval "
                          "(filled: the interval excludes 0)", fontsize=10)
    return figure


def box_plot_figure(series: Mapping[str, np.ndarray], path_order: Sequence[str],
                    ylabel: str, title: str, scale: float = 1.0) -> Figure:
    """A box plot per path (paper Fig. 9): median, quartiles, whiskers at 1.5 IQR, outliers."""
    figure = _figure(7.0, 4.2)
    axes = figure.add_subplot()
    names = [name for name in path_order if name in series and np.isfinite(series[name]).any()]
    data = [np.asarray(series[name])[np.isfinite(series[name])] * scale for name in names]
    if data:
        # the run count under each name, not inside the plot where outliers lie
        labels = [f"{name}\nn={values.size}" for name, values in zip(names, data, strict=True)]
        boxes = axes.boxplot(data, tick_labels=labels, patch_artist=True, showmeans=True,
                             meanprops={"marker": "^", "markerfacecolor": "white",
                                        "markeredgecolor": "black", "markersize": 5})
        for position, patch in enumerate(boxes["boxes"]):
            patch.set_facecolor(path_colour(path_order.index(names[position])))
            patch.set_alpha(0.55)
    else:
        axes.text(0.5, 0.5, "no complete runs", ha="center", va="center",
                  transform=axes.transAxes)
    axes.set_ylabel(ylabel)
    axes.set_title(title, fontsize=11)
    axes.grid(True, axis="y", linewidth=0.3, alpha=0.6)
    return figure


def dominance_figure(counts: Mapping[str, Sequence[tuple[str, int]]],
                     path_order: Sequence[str]) -> Figure:
    """Stacked bars: per path, the share of runs each index dominated I_max."""
    figure = _figure(7.0, 3.6)
    axes = figure.add_subplot()
    names = [name for name in path_order if counts.get(name)]
    indices: list[str] = []
    for name in names:
        indices += [index for index, _ in counts[name] if index not in indices]
    bottom = np.zeros(len(names))
    palette = colormaps["tab10"]
    for position, index in enumerate(indices):
        shares = np.array([dict(counts[name]).get(index, 0) / max(1, sum(
            c for _, c in counts[name])) for name in names]) * 100.0
        axes.barh(names, shares, left=bottom, color=palette(position % 10), label=index)
        bottom += shares
    axes.set_xlim(0, 100)
    axes.set_xlabel("runs in which the index set I_max [%]")
    axes.invert_yaxis()
    axes.set_title("Which index dominated the run risk", fontsize=11, y=1.0)  # see the maps
    if indices:
        axes.legend(loc="upper center", bbox_to_anchor=(0.5, -0.25), ncol=min(6, len(indices)),
                    fontsize=8)
    return figure
