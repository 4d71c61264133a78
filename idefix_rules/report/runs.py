"""Per-run data the interactive report shows: thinned tracks and time series, map cells, contacts.

Filled during the report's one chunked pass over the stored runs (:mod:`.prepare`):

- :class:`CellRuns` per path: for each map cell, how many runs crossed it, how often each index
  was the run's dominant one among them, and the worst of the runs embedded in the page (the
  one a click on the cell opens).
- :func:`run_series`: a run's track and time series thinned to at most ``POINTS`` points for the
  page. Time is cut into equal buckets; position and heading take the bucket's last sample, and
  every series against a limit keeps its bucket **extreme** (maximum; minimum for clearance), so
  a peak over a limit never disappears in the thinning.
- :func:`contact_points`: where contacts happened, from ``evaluation/collisions/details`` (first
  contact per part and level: time, body, obstacle) and the run's own pose at that time: a wheel
  contact is marked at that wheel's centre, a chassis or panel contact at the body centre.

Values are in display units (cm, deg, %), chosen in :data:`SERIES`; files stay SI.
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from idefix_rules.commands import RoverGeometry
from idefix_rules.report.riskmap import RiskGrid, run_cell_maxima
from idefix_rules.results.collisions import profile_edges
from idefix_rules.results.format import CLEARANCE_POINTS

POINTS = CLEARANCE_POINTS  # 120
# Contacts per path the page draws (the first ones by run number; all are in results.h5).
MAX_CONTACTS = 1000
# Runs per path whose track and time series the page holds (the worst first).
EMBEDDED_RUNS = 24


@dataclass(frozen=True)
class Series:
    """A time series the run panel draws: which signal, how it is reduced, its unit."""

    key: str
    title: str
    signal: str
    unit: str
    scale: float  # SI → unit
    reduce: str  # "max" (of |value| over wheels and bucket), "min", "dev" (|run − ref|)


SERIES = (
    Series("slip", "wheel slip ratio (largest wheel)", "wheel.slip", "%", 100.0, "max"),
    Series("slip_angle", "wheel slip angle (largest wheel)", "wheel.slip_angle", "deg",
           180.0 / math.pi, "max"),
    Series("sinkage", "wheel sinkage (deepest wheel)", "wheel.sinkage", "cm", 100.0, "max"),
    Series("roll", "roll deviation from the reference run", "roll", "deg", 180.0 / math.pi,
           "dev"),
    Series("pitch", "pitch deviation from the reference run", "pitch", "deg",
           180.0 / math.pi, "dev"),
    Series("clearance", "clearance to the nearest obstacle (any body)", "collision.clearance",
           "cm", 100.0, "min"),
)


def wheel_offsets(rover: RoverGeometry) -> dict[str, tuple[float, float]]:
    """Wheel centres in the body frame (x forward, y left), as the FMU and the checker use."""
    a, b = rover.half_wheelbase, rover.half_track
    return {"FL": (a, b), "FR": (a, -b), "RL": (-a, b), "RR": (-a, -b)}


def wheel_tracks(x: np.ndarray, y: np.ndarray, yaw: np.ndarray,
                 rover: RoverGeometry) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each wheel centre's track from the body-centre track and heading."""
    cos, sin = np.cos(yaw), np.sin(yaw)
    return {name: (x + dx * cos - dy * sin, y + dx * sin + dy * cos)
            for name, (dx, dy) in wheel_offsets(rover).items()}


def wheel_bands(x: np.ndarray, y: np.ndarray, yaw: np.ndarray, rover: RoverGeometry,
                width: float) -> dict[str, np.ndarray]:
    """Each wheel's footprint over the run: the band its ``width`` sweeps, as a polygon
    (edges offset ±width/2 along the wheel axle, i.e. across the body heading)."""
    half = width / 2.0
    keep = np.isfinite(x) & np.isfinite(y) & np.isfinite(yaw)
    x, y, yaw = x[keep], y[keep], yaw[keep]
    across = np.stack([-np.sin(yaw), np.cos(yaw)], axis=1) * half
    bands = {}
    for name, (wx, wy) in wheel_tracks(x, y, yaw, rover).items():
        centre = np.stack([wx, wy], axis=1)
        bands[name] = np.vstack([centre + across, (centre - across)[::-1]])
    return bands


def _buckets(valid: int, points: int = POINTS) -> np.ndarray:
    """Bucket edges over ``valid`` samples (at most ``points`` buckets): the stretches of
    the clearance profile the evaluation stores."""
    return profile_edges(valid, points)


def _reduce(values: np.ndarray, edges: np.ndarray, how: str) -> list[float]:
    """The extreme (``how``: "min", else the maximum) of the finite values of each stretch
    between two edges (a stretch of no sample: the sample at its start; none finite: NaN)."""
    starts = edges[:-1]
    if values.ndim == 1 and starts.size and starts[0] == 0 and edges[-1] == values.size \
            and np.all(np.diff(edges) > 0):
        # contiguous stretches covering the values: one reduction over all of them
        finite = np.where(np.isfinite(values), values, np.nan)
        with np.errstate(invalid="ignore"):
            extremes = (np.fmin if how == "min" else np.fmax).reduceat(finite, starts)
        return [float(value) for value in extremes]
    out = []
    for start, stop in itertools.pairwise(edges):
        chunk = values[start:max(stop, start + 1)]
        finite = chunk[np.isfinite(chunk)]
        if finite.size == 0:
            out.append(math.nan)
        else:
            out.append(float(finite.min() if how == "min" else finite.max()))
    return out


def _across(values: np.ndarray, how: str) -> np.ndarray:
    """Per sample the minimum (``how`` "min") or maximum over the wheels, (samples, wheels)
    → (samples,); NaN where a wheel is NaN, as ``np.min``/``np.max`` over the axis, whose
    reduction of four columns is several times slower than combining them."""
    combine = np.minimum if how == "min" else np.maximum
    out = np.array(values[:, 0], dtype=float)
    for column in range(1, values.shape[1]):
        combine(out, values[:, column], out=out)
    return out


def _rounded(values: list[float], digits: int = 3) -> list[float | None]:
    return [None if not math.isfinite(v) else float(f"{v:.{digits}g}") for v in values]


def run_series(signals: Mapping[str, np.ndarray], row: int, risk: np.ndarray,
               reference: Mapping[str, np.ndarray] | None,
               profiles: Mapping[str, np.ndarray] | None = None) -> dict[str, Any]:
    """One run (row ``row`` of a chunk) thinned for the page: ``t, x, y, yaw, risk`` and each
    :data:`SERIES` entry the stored signals hold. ``profiles``: a series the evaluation
    stored already thinned (the clearance profile, by signal name), for a signal the chunk
    does not hold."""
    t = np.asarray(signals["t"][row], dtype=float)
    valid = int(np.flatnonzero(np.isfinite(t))[-1] + 1) if np.isfinite(t).any() else 0
    edges = _buckets(valid)
    last = np.clip(edges[1:] - 1, 0, max(valid - 1, 0))
    out: dict[str, Any] = {
        "t": _rounded([float(v) for v in t[last]], 5),
        "x": _rounded([float(v) for v in signals["x"][row][last]], 4),
        "y": _rounded([float(v) for v in signals["y"][row][last]], 4),
        "yaw": _rounded([float(v) for v in signals["yaw"][row][last]], 4)
        if "yaw" in signals else None,
        "risk": _rounded(_reduce(np.asarray(risk[row], dtype=float)[:valid], edges, "max")),
        "series": {},
    }
    for spec in SERIES:
        data = signals.get(spec.signal)
        if data is None:
            profile = (profiles or {}).get(spec.signal)
            if profile is not None:  # the same minima per stretch, stored
                thinned = np.asarray(profile, dtype=float)[:len(edges) - 1] * spec.scale
                out["series"][spec.key] = _rounded([float(v) for v in thinned])
            continue
        values = np.asarray(data[row], dtype=float)[:valid]
        if spec.reduce == "dev":
            if reference is None or spec.signal not in reference:
                continue
            base = np.asarray(reference[spec.signal], dtype=float)[:valid]
            values = np.abs(values - base)
        elif values.ndim > 1:
            values = _across(values if spec.reduce == "min" else np.abs(values), spec.reduce)
        elif spec.reduce == "max":
            values = np.abs(values)
        out["series"][spec.key] = _rounded(_reduce(values * spec.scale, edges, spec.reduce))
    return out


class CellRuns:
    """Per cell of a path's map: runs that crossed it, dominant-index counts, worst embedded run."""

    def __init__(self, grid: RiskGrid, index_count: int) -> None:
        size = grid.nx * grid.ny
        self.grid = grid
        self.runs = np.zeros(size, dtype=np.int64)
        self.dominant = np.zeros((size, max(1, index_count + 1)), dtype=np.int64)
        self.worst_value = np.full(size, -1.0)
        self.worst_run = np.full(size, -1, dtype=np.int64)

    def add(self, rows: np.ndarray, x: np.ndarray, y: np.ndarray, risk: np.ndarray,
            dominant: np.ndarray, embedded: set[int]) -> None:
        """Add a chunk: ``rows`` its path run numbers, ``dominant`` each run's dominant index
        (-1 none)."""
        self.add_maxima(rows, run_cell_maxima(self.grid, x, y, risk), dominant, embedded)

    def add_maxima(self, rows: np.ndarray, maxima: tuple[np.ndarray, np.ndarray, np.ndarray],
                   dominant: np.ndarray, embedded: set[int]) -> None:
        """Add a chunk by its :func:`run_cell_maxima` on this grid (as :meth:`add`)."""
        local, cells, values = maxima
        if cells.size == 0:
            return
        runs = rows[local]
        np.add.at(self.runs, cells, 1)
        codes = np.asarray(dominant)[runs]
        codes = np.where((codes >= 0) & (codes < self.dominant.shape[1] - 1), codes,
                         self.dominant.shape[1] - 1)
        np.add.at(self.dominant, (cells, codes), 1)
        keep = np.isin(runs, np.fromiter(embedded, dtype=np.int64, count=len(embedded)))
        if keep.any():
            cells, runs, values = cells[keep], runs[keep], values[keep]
            order = np.lexsort((-runs, values))  # ascending value; on ties the lower run wins
            cells, runs, values = cells[order], runs[order], values[order]
            better = values > self.worst_value[cells]
            # Later (larger) entries of a cell overwrite earlier ones: the last is the maximum.
            self.worst_value[cells[better]] = values[better]
            self.worst_run[cells[better]] = runs[better]

    def cells(self, index_names: list[str]) -> list[list[Any]]:
        """``[cell, runs, dominant index name or None, its count, worst embedded run]`` for
        every crossed cell."""
        crossed = np.flatnonzero(self.runs > 0)
        out = []
        for cell in crossed:
            counts = self.dominant[cell]
            code = int(np.argmax(counts))
            name = index_names[code] if code < len(index_names) else None
            out.append([int(cell), int(self.runs[cell]), name, int(counts[code]),
                        int(self.worst_run[cell])])
        return out


def contact_points(details: Any, rows: np.ndarray, signals: Mapping[str, np.ndarray],
                   rover: RoverGeometry) -> list[dict[str, Any]]:
    """First contacts of the chunk's runs, placed at the touching wheel (or body centre)."""
    offsets = wheel_offsets(rover)
    points = []
    for position, run in enumerate(rows):
        text = details[int(run)] if int(run) < len(details) else ""
        if isinstance(text, bytes):
            text = text.decode("utf-8")
        if not text:
            continue
        try:
            record = json.loads(text)
        except ValueError:
            continue
        for contact in record.get("first_contacts", []):
            t = np.asarray(signals["t"][position], dtype=float)
            sample = int(np.nanargmin(np.abs(t - float(contact.get("time", 0.0)))))
            x = float(signals["x"][position][sample])
            y = float(signals["y"][position][sample])
            body = str(contact.get("body", ""))
            if body in offsets and "yaw" in signals:
                yaw = float(signals["yaw"][position][sample])
                dx, dy = offsets[body]
                x, y = x + dx * math.cos(yaw) - dy * math.sin(yaw), \
                    y + dx * math.sin(yaw) + dy * math.cos(yaw)
            if not (math.isfinite(x) and math.isfinite(y)):
                continue
            points.append({"run": int(run), "t": round(float(t[sample]), 2),
                           "x": round(x, 4), "y": round(y, 4), "body": body,
                           "part": str(contact.get("part", "")),
                           "level": str(contact.get("level", "")),
                           "obstacle": str(contact.get("obstacle", ""))})
    return points
