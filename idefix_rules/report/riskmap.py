"""The result map of paper Fig. 8 as data: a grid over the xy-plane with a risk per cell.

Definition (paper, section 4): a run's value in a cell is the **maximum** of the run's
per-sample risk over the run's samples in that cell; a cell's value is the **mean over the runs
that crossed it** of those run values. With a single run the map shows that run's maxima; where
several runs cross, their run-specific maxima are averaged. The per-sample risk is the run risk
of eq. 1 before the time reduction: ``max over indices of weight × per-sample index value``.

Positions are the body centre ``(x, y)`` in the terrain's frame (the frame of the FMU's
``x``/``y`` signals and of the DEM; the rover's start frame only when it starts at the origin
heading +x). Between two samples the body centre moves along a straight segment; the
segment is **rasterised** by sub-sampling it at most half a cell apart, so a fast segment never
leaves a gap of untouched cells. Each sub-sample carries the risk of the nearer of the two
samples (the first half of a segment the first sample's risk, the second half the second's), so
every value on the map is a value that actually occurred in the run, never an interpolation.

Everything here is plain numpy, drawing happens in :mod:`idefix_rules.report.figures`.

>>> grid = RiskGrid(x0=0.0, y0=0.0, cell=1.0, nx=3, ny=1)
>>> acc = RiskAccumulator(grid)
>>> acc.add(np.array([[0.5, 1.5, 2.5]]), np.array([[0.5, 0.5, 0.5]]),
...         np.array([[0.2, 0.9, 0.1]]))
>>> acc.values().tolist()
[[0.2, 0.9, 0.1]]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from idefix_rules.commands import RoverGeometry

# A cell is this fraction of the rover's track width (wheel centre to wheel centre).
CELLS_PER_TRACK = 20
# The grid never gets more cells than this along an axis (the cell grows instead).
MAX_CELLS_PER_AXIS = 400
# Segments are sub-sampled this many times per cell length at least.
SUBSAMPLES_PER_CELL = 2
# Upper bound of sub-samples per segment (a teleporting run is not worth a billion points).
MAX_SUBSAMPLES = 256


@dataclass(frozen=True)
class RiskGrid:
    """A regular grid: cell ``(i, j)`` spans ``x0 + i·cell … x0 + (i+1)·cell`` (same in y)."""

    x0: float
    y0: float
    cell: float
    nx: int
    ny: int

    @property
    def shape(self) -> tuple[int, int]:
        """Array shape of a map on this grid: (ny, nx), rows are y."""
        return (self.ny, self.nx)

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(left, right, bottom, top) in m, as matplotlib's ``imshow`` wants it."""
        return (self.x0, self.x0 + self.nx * self.cell, self.y0, self.y0 + self.ny * self.cell)

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """Cell-centre coordinates, each shaped (ny, nx)."""
        xs = self.x0 + (np.arange(self.nx) + 0.5) * self.cell
        ys = self.y0 + (np.arange(self.ny) + 0.5) * self.cell
        return np.meshgrid(xs, ys)

    def cell_index(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Flat cell index ``row · nx + column`` of each point; -1 outside the grid."""
        col = np.floor((x - self.x0) / self.cell)
        row = np.floor((y - self.y0) / self.cell)
        inside = (col >= 0) & (col < self.nx) & (row >= 0) & (row < self.ny)
        flat = np.where(inside, row * self.nx + col, -1.0)
        return flat.astype(np.int64)


def cell_size_for(rover: RoverGeometry) -> float:
    """Cell edge from the rover size: 1/20 of the track width, rounded to 5 mm (≥ 5 mm).

    >>> cell_size_for(RoverGeometry())
    0.025
    """
    track = 2.0 * rover.half_track
    return max(0.005, round(track / CELLS_PER_TRACK / 0.005) * 0.005)


def grid_covering(xmin: float, xmax: float, ymin: float, ymax: float, cell: float,
                  margin: float = 0.0) -> RiskGrid:
    """A grid aligned to multiples of ``cell`` that covers the box plus ``margin``.

    The cell grows (doubling) when the box would need more than ``MAX_CELLS_PER_AXIS`` cells.

    >>> grid_covering(0.0, 1.0, -0.1, 0.1, 0.25)
    RiskGrid(x0=0.0, y0=-0.25, cell=0.25, nx=5, ny=2)
    """
    if not all(math.isfinite(v) for v in (xmin, xmax, ymin, ymax)):
        xmin, xmax, ymin, ymax = -0.5, 0.5, -0.5, 0.5
    xmin, xmax, ymin, ymax = xmin - margin, xmax + margin, ymin - margin, ymax + margin
    while True:
        x0 = math.floor(xmin / cell) * cell
        y0 = math.floor(ymin / cell) * cell
        nx = max(1, math.floor((xmax - x0) / cell) + 1)
        ny = max(1, math.floor((ymax - y0) / cell) + 1)
        if max(nx, ny) <= MAX_CELLS_PER_AXIS:
            return RiskGrid(x0=x0, y0=y0, cell=cell, nx=nx, ny=ny)
        cell *= 2.0


def rasterise(x: np.ndarray, y: np.ndarray, risk: np.ndarray,
              spacing: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Sub-sample each run's polyline at most ``spacing`` apart: flat (run, x, y, risk) points,
    each run's in driving order.

    Each segment gets its own number of sub-samples (``ceil(length / spacing)``), so the result
    does not depend on which other runs are processed together. Non-finite samples (a run's NaN
    tail) are dropped, and a segment touching one is not filled in. The risk of a sub-sample is
    that of the nearer end of its segment.

    >>> run, px, py, pr = rasterise(np.array([[0.0, 1.0]]), np.zeros((1, 2)),
    ...                             np.array([[0.1, 0.7]]), 0.25)
    >>> px.tolist(), pr.tolist()
    ([0.0, 0.25, 0.5, 0.75, 1.0], [0.1, 0.1, 0.7, 0.7, 0.7])
    """
    x = np.atleast_2d(np.asarray(x, dtype=float))
    y = np.atleast_2d(np.asarray(y, dtype=float))
    risk = np.atleast_2d(np.asarray(risk, dtype=float))
    runs, samples = x.shape
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(risk)
    # Per sample: the sample itself (when valid) and the points strictly inside the segment
    # to the next one; each sample's points are written at its offset in the output, so the
    # points come out in driving order without sorting.
    inner = np.zeros((runs, samples), dtype=np.int64)
    if samples >= 2:
        dx, dy = np.diff(x, axis=1), np.diff(y, axis=1)
        segment_ok = ok[:, :-1] & ok[:, 1:]
        length = np.where(segment_ok, np.hypot(dx, dy), 0.0)
        steps = np.clip(np.ceil(length / spacing - 1e-9), 1, MAX_SUBSAMPLES).astype(np.int64)
        inner[:, :-1] = np.where(segment_ok, steps - 1, 0)
    flat_ok = ok.ravel()
    count = flat_ok + inner.ravel()
    offset = np.cumsum(count) - count
    total = int(count.sum())
    run_ids = np.empty(total, dtype=np.int64)
    px, py, pr = np.empty(total), np.empty(total), np.empty(total)
    at = offset[flat_ok]
    run_ids[at] = np.repeat(np.arange(runs), samples)[flat_ok]
    px[at], py[at], pr[at] = x.ravel()[flat_ok], y.ravel()[flat_ok], risk.ravel()[flat_ok]
    per_sample = inner.ravel()
    if per_sample.any():
        sample = np.repeat(np.arange(per_sample.size), per_sample)  # flat (run, sample)
        first = np.cumsum(per_sample) - per_sample
        j = np.arange(sample.size) - first[sample] + 1  # 1 … steps - 1 along the segment
        fraction = j / (per_sample[sample] + 1)
        after = sample + 1  # the segment's end (a segment never ends a run's row)
        flat_x, flat_y, flat_risk = x.ravel(), y.ravel(), risk.ravel()
        at = offset[sample] + j  # after the segment's first sample
        run_ids[at] = sample // samples
        px[at] = flat_x[sample] + fraction * (flat_x[after] - flat_x[sample])
        py[at] = flat_y[sample] + fraction * (flat_y[after] - flat_y[sample])
        pr[at] = np.where(fraction >= 0.5, flat_risk[after], flat_risk[sample])
    return run_ids, px, py, pr


def run_cell_maxima(grid: RiskGrid, x: np.ndarray, y: np.ndarray,
                    risk: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For every (run, cell) a run visited: the run index, the flat cell and the run's maximum,
    ordered by run, then cell.

    Inputs are (runs, samples) arrays; segments are rasterised first (:func:`rasterise`).
    """
    run_of, px, py, pr = rasterise(x, y, risk, grid.cell / SUBSAMPLES_PER_CELL)
    cells = grid.cell_index(px, py)
    keep = cells >= 0
    cells, run_of, values = cells[keep], run_of[keep], np.clip(pr[keep], 0.0, 1.0)
    if cells.size == 0:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty, np.zeros(0)
    size = grid.nx * grid.ny
    key = run_of * size + cells
    # A run stays in a cell for many points in a row (a cell is several samples long, and a
    # run holds its last pose after its chain): each stretch is reduced to its maximum first,
    # so only the stretches are sorted.
    stretch = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    key, values = key[stretch], np.maximum.reduceat(values, stretch)
    order = np.argsort(key, kind="stable")
    key, values = key[order], values[order]
    first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    key, values = key[first], np.maximum.reduceat(values, first)
    return key // size, key % size, values


class RiskAccumulator:
    """Sums of run maxima and counts of runs per cell; add runs in chunks, read the mean."""

    def __init__(self, grid: RiskGrid) -> None:
        self.grid = grid
        self.total = np.zeros(grid.nx * grid.ny)
        self.count = np.zeros(grid.nx * grid.ny, dtype=np.int64)
        self.runs = 0

    def add(self, x: np.ndarray, y: np.ndarray, risk: np.ndarray) -> None:
        """Add runs: body-centre ``x``, ``y`` and per-sample risk, each (runs, samples)."""
        self.add_maxima(run_cell_maxima(self.grid, x, y, risk), int(np.atleast_2d(x).shape[0]))

    def add_maxima(self, maxima: tuple[np.ndarray, np.ndarray, np.ndarray], runs: int) -> None:
        """Add ``runs`` runs by their :func:`run_cell_maxima` on this grid."""
        _, cells, values = maxima
        size = self.grid.nx * self.grid.ny
        self.total += np.bincount(cells, weights=values, minlength=size)
        self.count += np.bincount(cells, minlength=size)
        self.runs += runs

    def merge(self, other: RiskAccumulator) -> None:
        """Add another accumulator on the same grid (the combined map of several paths)."""
        if other.grid != self.grid:
            raise ValueError("risk maps on different grids cannot be merged")
        self.total += other.total
        self.count += other.count
        self.runs += other.runs

    def values(self) -> np.ndarray:
        """Mean of run maxima per cell, (ny, nx); NaN where no run passed."""
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.where(self.count > 0, self.total / np.maximum(self.count, 1), np.nan)
        return mean.reshape(self.grid.shape)

    def counts(self) -> np.ndarray:
        """Number of runs that crossed each cell, (ny, nx)."""
        return self.count.reshape(self.grid.shape)


def per_sample_risk(per_sample: dict[str, np.ndarray], weights: dict[str, float]) -> np.ndarray:
    """Per-sample run risk: max over indices of weight × per-sample value, (runs, samples).

    >>> per_sample_risk({"a": np.array([[0.2, 0.8]]), "b": np.array([[0.5, 0.1]])},
    ...                 {"a": 0.5, "b": 1.0}).tolist()
    [[0.5, 0.4]]
    """
    if not per_sample:
        raise ValueError("no per-sample index values")
    risk: np.ndarray | None = None
    for name, values in per_sample.items():  # a running maximum: no stack of every index
        weighted = weights[name] * np.asarray(values, dtype=float)
        if risk is None:
            risk = np.array(weighted, dtype=float)  # writable, whatever broadcast it came from
        else:
            np.maximum(risk, weighted, out=risk)
    assert risk is not None
    np.clip(risk, 0.0, 1.0, out=risk)
    return risk
