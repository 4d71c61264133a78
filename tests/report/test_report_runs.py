"""The interactive page's per-run data: thinning keeps peaks, contacts sit at the wheel,
cells know their runs, and the worst runs are ranked past ties at I_max = 1."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from idefix_rules.commands import RoverGeometry
from idefix_rules.report.data import PathReport, TableRow
from idefix_rules.report.riskmap import RiskGrid
from idefix_rules.report.runs import POINTS, CellRuns, contact_points, run_series


def _signals(samples: int = 2000) -> dict[str, np.ndarray]:
    t = np.arange(samples) * 0.1
    slip = np.full((1, samples, 4), 0.2)
    slip[0, 1234, 2] = 0.93  # one sample of one wheel over the 70 % limit
    clearance = np.full((1, samples, 3), 0.3)
    clearance[0, 777, 1] = 0.0  # one contact
    return {"t": t[None, :], "x": (0.001 * t)[None, :], "y": np.zeros((1, samples)),
            "yaw": np.zeros((1, samples)), "wheel.slip": slip,
            "roll": np.full((1, samples), 0.01), "collision.clearance": clearance}


def test_thinning_keeps_every_peak_and_the_last_position() -> None:
    signals = _signals()
    reference = {"roll": np.zeros(2000)}
    out = run_series(signals, 0, np.full((1, 2000), 0.3), reference)
    assert len(out["t"]) == POINTS
    assert max(out["series"]["slip"]) == pytest.approx(93.0)  # % of the one-sample peak
    assert min(out["series"]["clearance"]) == 0.0
    assert out["series"]["roll"][0] == pytest.approx(math.degrees(0.01), rel=1e-3)
    assert out["x"][-1] == pytest.approx(0.001 * 199.9, rel=1e-3)
    assert "slip_angle" not in out["series"]  # not stored: not shown


def test_contacts_are_marked_at_the_touching_wheel() -> None:
    rover = RoverGeometry()
    signals = {"t": np.array([[0.0, 1.0, 2.0]]), "x": np.array([[0.0, 0.1, 0.2]]),
               "y": np.zeros((1, 3)), "yaw": np.array([[0.0, math.pi / 2, math.pi / 2]])}
    details = ["", json.dumps({"first_contacts": [
        {"part": "wheel", "level": "L2", "time": 1.02, "body": "FR", "obstacle": "rock1"},
        {"part": "chassis", "level": "L3", "time": 2.0, "body": "chassis", "obstacle": "r2"}]})]
    points = contact_points(details, np.array([1]), signals, rover)
    wheel, chassis = points
    # Facing +y at x = 0.1: the front-right wheel is at x + 0.26, y + 0.20.
    assert (wheel["x"], wheel["y"]) == pytest.approx((0.1 + rover.half_track,
                                                      rover.half_wheelbase))
    assert wheel["run"] == 1 and wheel["t"] == 1.0 and wheel["level"] == "L2"
    assert (chassis["x"], chassis["y"]) == (0.2, 0.0)


def test_cells_count_runs_and_keep_the_worst_embedded_run() -> None:
    grid = RiskGrid(x0=0.0, y0=0.0, cell=1.0, nx=3, ny=1)
    cells = CellRuns(grid, index_count=2)
    x = np.array([[0.5, 1.5], [0.5, 2.5], [0.5, 0.6]])
    y = np.full((3, 2), 0.5)
    risk = np.array([[0.2, 0.9], [0.4, 0.1], [0.95, 0.95]])
    cells.add(np.array([10, 11, 12]), x, y, risk, np.array([0] * 10 + [1, 0, 1]),
              embedded={10, 11})
    found = {row[0]: row for row in cells.cells(["I_a", "I_b"])}
    # Cell 0: three runs; run 12 is the worst but not embedded, so run 11 opens.
    assert found[0] == [0, 3, "I_b", 2, 11]
    # Cell 1: run 10 ends there, run 11 passes through (rasterised); its risk there is 0.1.
    assert found[1] == [1, 2, "I_a", 1, 10]
    assert found[2] == [2, 1, "I_a", 1, 11]


def _path(i_max: list[float], raw_ratio: list[float]) -> PathReport:
    row = TableRow("p", "simulated", 4, 4, 0, None, None, {}, None, None, "fail", False, None,
                   None)
    path = PathReport("p", 0, "simulated", "", row, index_names=["I_a", "I_b"])
    path.complete = np.ones(len(i_max), dtype=bool)
    path.i_max = np.array(i_max)
    path.dominant = np.zeros(len(i_max), dtype=np.int16)
    path.indices = {"I_a": np.minimum(np.array(raw_ratio), 1.0), "I_b": np.zeros(len(i_max))}
    path.raw = {"I_a": np.array(raw_ratio) * 0.7, "I_b": np.zeros(len(i_max))}
    return path


def test_worst_runs_break_ties_by_how_far_over_the_limit() -> None:
    path = _path([1.0, 1.0, 0.5, 1.0], [1.2, 3.0, 0.5, 1.000001])
    limits, weights = {"I_a": 0.7, "I_b": 1.0}, {"I_a": 1.0, "I_b": 1.0}
    assert path.worst_order(limits, weights).tolist() == [1, 0, 3, 2]
    worst = path.worst_runs(2, limits, weights)
    assert [(w.run, w.excess_index) for w in worst] == [(1, "I_a"), (0, "I_a")]
    assert worst[0].excess == pytest.approx(3.0)
    # Without limits, equal I_max keeps the run order.
    assert path.worst_order().tolist()[:3] == [0, 1, 3]


def test_wheel_footprints_are_as_wide_as_the_wheel_across_the_heading() -> None:
    from idefix_rules.report.runs import wheel_bands

    rover = RoverGeometry()
    x = np.linspace(0.0, 1.0, 11)
    bands = wheel_bands(x, np.zeros(11), np.zeros(11), rover, 0.06)
    front_right = bands["FR"]
    assert front_right.shape == (22, 2)
    # Driving along +x: the band spans y = -half_track ± 3 cm, x = half_wheelbase + 0 … 1 m.
    assert front_right[:, 1].min() == pytest.approx(-rover.half_track - 0.03)
    assert front_right[:, 1].max() == pytest.approx(-rover.half_track + 0.03)
    assert front_right[:, 0].max() == pytest.approx(1.0 + rover.half_wheelbase)
    # Facing +y, the band is 6 cm wide along x instead.
    turned = wheel_bands(np.zeros(3), np.linspace(0, 1, 3), np.full(3, math.pi / 2), rover,
                         0.06)["FL"]
    assert np.ptp(turned[:, 0]) == pytest.approx(0.06)
