"""The result map's cell values against hand-computed small cases (paper Fig. 8 definition)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from idefix_rules.commands import RoverGeometry
from idefix_rules.report.riskmap import (
    MAX_SUBSAMPLES,
    RiskAccumulator,
    RiskGrid,
    cell_size_for,
    grid_covering,
    per_sample_risk,
    rasterise,
    run_cell_maxima,
)

NAN = float("nan")

# 4 × 2 cells of 1 m: columns x ∈ [0,1), [1,2), [2,3), [3,4); rows y ∈ [0,1), [1,2).
GRID = RiskGrid(x0=0.0, y0=0.0, cell=1.0, nx=4, ny=2)


def test_one_run_shows_its_maximum_per_cell() -> None:
    acc = RiskAccumulator(GRID)
    # Two samples in cell (row 0, col 0) with risks 0.2 and 0.6 → 0.6; one in col 1 → 0.3.
    # The segment (0.6 → 1.5) is 0.9 m: sub-sampled at 0.5 m, its second half (x = 1.05)
    # carries the second sample's 0.3 into column 1 as well, nothing else changes.
    acc.add(np.array([[0.5, 0.6, 1.5]]), np.array([[0.5, 0.5, 0.5]]),
            np.array([[0.2, 0.6, 0.3]]))
    np.testing.assert_array_equal(acc.values(), [[0.6, 0.3, NAN, NAN], [NAN] * 4])
    np.testing.assert_array_equal(acc.counts(), [[1, 1, 0, 0], [0, 0, 0, 0]])


def test_two_crossing_runs_average_their_maxima() -> None:
    acc = RiskAccumulator(GRID)
    # Run A drives along row 0 through columns 0, 1, 2 with risks 0.1, 0.8, 0.3.
    # Run B drives up column 1 from row 0 to row 1; in cell (0, 1) its samples are 0.2 and 0.4,
    # in cell (1, 1) 0.9. Crossing cell (0, 1): mean of A's 0.8 and B's max 0.4 = 0.6.
    x = np.array([[0.5, 1.5, 2.5], [1.5, 1.5, 1.5]])
    y = np.array([[0.5, 0.5, 0.5], [0.2, 0.8, 1.5]])
    risk = np.array([[0.1, 0.8, 0.3], [0.2, 0.4, 0.9]])
    acc.add(x, y, risk)
    np.testing.assert_allclose(acc.values(), [[0.1, 0.6, 0.3, NAN], [NAN, 0.9, NAN, NAN]])
    np.testing.assert_array_equal(acc.counts(), [[1, 2, 1, 0], [0, 1, 0, 0]])


def test_runs_added_in_chunks_equal_runs_added_at_once() -> None:
    rng = np.random.default_rng(3)
    x = rng.uniform(0, 4, (6, 30))
    y = rng.uniform(0, 2, (6, 30))
    risk = rng.uniform(0, 1, (6, 30))
    whole = RiskAccumulator(GRID)
    whole.add(x, y, risk)
    first, second = RiskAccumulator(GRID), RiskAccumulator(GRID)
    first.add(x[:2], y[:2], risk[:2])
    second.add(x[2:], y[2:], risk[2:])
    first.merge(second)
    np.testing.assert_allclose(first.values(), whole.values())
    assert first.runs == 6


def test_a_fast_segment_leaves_no_gap() -> None:
    acc = RiskAccumulator(GRID)
    # Two samples 3 m apart: every column between them is crossed.
    acc.add(np.array([[0.5, 3.5]]), np.array([[0.5, 0.5]]), np.array([[0.2, 0.7]]))
    np.testing.assert_array_equal(acc.values()[0], [0.2, 0.2, 0.7, 0.7])


def test_nan_samples_and_points_outside_are_ignored() -> None:
    acc = RiskAccumulator(GRID)
    # The NaN sample breaks the polyline: no segment runs from 0.5 to the outside point 9.0.
    acc.add(np.array([[0.5, NAN, 9.0]]), np.array([[0.5, NAN, 0.5]]),
            np.array([[0.4, 1.0, 1.0]]))
    assert acc.counts().sum() == 1
    assert acc.values()[0, 0] == pytest.approx(0.4)


def test_rasterise_carries_the_nearer_sample_risk() -> None:
    run, px, _, pr = rasterise(np.array([[0.0, 1.0], [5.0, 5.0]]), np.zeros((2, 2)),
                               np.array([[0.1, 0.7], [0.3, 0.3]]), 0.5)
    assert run.tolist() == [0, 0, 0, 1, 1]
    assert px.tolist() == [0.0, 0.5, 1.0, 5.0, 5.0]
    assert pr.tolist() == [0.1, 0.7, 0.7, 0.3, 0.3]


def _rasterised_run_by_run(x, y, risk, spacing):
    """The rasterising written out sample by sample: the definition the fast one keeps."""
    points = []
    for run in range(x.shape[0]):
        for i in range(x.shape[1]):
            ok = all(math.isfinite(v[run, i]) for v in (x, y, risk))
            if not ok:
                continue
            points.append((run, x[run, i], y[run, i], risk[run, i]))
            if i + 1 == x.shape[1] or not all(math.isfinite(v[run, i + 1])
                                              for v in (x, y, risk)):
                continue
            dx, dy = x[run, i + 1] - x[run, i], y[run, i + 1] - y[run, i]
            length = float(np.hypot(dx, dy))
            steps = min(max(math.ceil(length / spacing - 1e-9), 1), MAX_SUBSAMPLES)
            for j in range(1, steps):
                fraction = j / steps
                points.append((run, x[run, i] + fraction * dx, y[run, i] + fraction * dy,
                               risk[run, i + 1] if fraction >= 0.5 else risk[run, i]))
    return points


finite_or_not = st.one_of(st.floats(-3.0, 6.0), st.just(NAN))


@given(st.integers(1, 3).flatmap(lambda runs: st.integers(1, 12).flatmap(
    lambda samples: st.tuples(*(st.lists(st.lists(finite_or_not, min_size=samples,
                                                  max_size=samples),
                                         min_size=runs, max_size=runs)
                                for _ in range(3))))))
def test_rasterise_and_run_maxima_follow_their_definition(tracks) -> None:
    x, y, risk = (np.array(values, dtype=float) for values in tracks)
    risk = np.abs(risk) / 6.0
    run, px, py, pr = rasterise(x, y, risk, 0.5)
    assert list(zip(run.tolist(), px.tolist(), py.tolist(), pr.tolist(), strict=True)) == \
        [tuple(float(v) if i else int(v) for i, v in enumerate(point))
         for point in _rasterised_run_by_run(x, y, risk, 0.5)]
    # every (run, cell) the points visit once, with the run's largest risk there
    maxima: dict[tuple[int, int], float] = {}
    cells = GRID.cell_index(px, py)
    for r, cell, value in zip(run.tolist(), cells.tolist(), pr.tolist(), strict=True):
        if cell >= 0:
            maxima[(r, cell)] = max(maxima.get((r, cell), -1.0), min(max(value, 0.0), 1.0))
    runs, flat, values = run_cell_maxima(GRID, x, y, risk)
    assert list(zip(runs.tolist(), flat.tolist(), values.tolist(), strict=True)) == \
        [(r, cell, value) for (r, cell), value in sorted(maxima.items())]


def test_per_sample_risk_is_the_weighted_maximum() -> None:
    risk = per_sample_risk({"I_s": np.array([[0.5, 1.0]]), "I_obs": np.array([[0.9, 0.0]])},
                           {"I_s": 0.8, "I_obs": 1.0})
    np.testing.assert_allclose(risk, [[0.9, 0.8]])
    # a NaN stays NaN whatever the other indices say; a value the same for every sample
    # (broadcast, read only) is taken as it is
    risk = per_sample_risk({"I_a": np.broadcast_to(np.array([[0.3]]), (1, 3)),
                            "I_b": np.array([[NAN, 0.1, 2.0]])}, {"I_a": 1.0, "I_b": 1.0})
    np.testing.assert_array_equal(risk, [[NAN, 0.3, 1.0]])


def test_cell_size_follows_the_rover_and_the_grid_stays_bounded() -> None:
    assert cell_size_for(RoverGeometry()) == pytest.approx(0.025)
    assert cell_size_for(RoverGeometry(half_track=0.5)) == pytest.approx(0.05)
    grid = grid_covering(0.0, 100.0, 0.0, 1.0, 0.025)
    assert grid.nx <= 400 and grid.cell > 0.025
    assert grid.extent[1] >= 100.0
