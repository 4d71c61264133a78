"""End to end: a small real campaign writes its report, which renders in headless Chromium."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_report_browser import check_page, render

from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.cli import main
from idefix_rules.report import prepare_report
from idefix_rules.report.reading import row_from_arrays

# No pre-screen and no command rule: every path gets its Monte Carlo runs, whatever the rover
# model's current tuning makes of the reference runs.
RULEBOOK = """\
rulebook "report-e2e" version "0.2.0"
purpose "Rules for the report's end-to-end test"

const f_obs = {L1: 0.2, L2: 0.6, L3: 1}

settings {
  theoretical_slip = 20 %
  tolerance_growth = 5 cm/rad
}

obstacles {
  level L1 below 3 cm  buffer 2 cm
  level L2 below 10 cm buffer 5 cm
  level L3             buffer 10 cm
}

index I_pos "position drift" {
  value  = final over time (global_error / tolerance_radius)
  limit  = 1
  weight = 0.5
}

index I_s "wheel slip ratio" {
  value  = max over time (max over wheels (abs(wheel.slip)))
  limit  = 70 %
  weight = 1
}

index I_obs "obstacle collisions" {
  value  = sum over parts (sum over levels (collision.hits * f_obs))
  limit  = 1
  weight = 1
  map    = max over parts (max over levels (collision.contact * f_obs))
}

chance hit_L2 = any over parts (collision.hits[L2] > 0)

verdict acceptable_risk: require risk <= 70 %
"""

CAMPAIGN = """\
name: report-e2e
rulebook: report-e2e.rules
runs: 4
output: out
environment:
  terrain:
    synthetic: {size: "3 m", cell: "2 cm", slope: "2 deg", slope_direction: "0 deg"}
  rocks:
    - {x: "0.45 m", y: "-0.30 m", radius: "4 cm", level: L2}
  keep_out:
    - name: soft-patch
      polygon: [["0.2 m", "0.7 m"], ["0.45 m", "0.7 m"], ["0.45 m", "0.9 m"],
                ["0.2 m", "0.9 m"]]
uncertainty:
  method: monte_carlo
  seed: 3
  parameters:
    initial.y: {distribution: normal, mean: "0 m", std: "1 cm"}
    soil.cohesion: {distribution: uniform, low: "100 Pa", high: "400 Pa"}
paths:
  straight:
    - {max_wheel_rate: "0.09 rad/s", delta_position: "0.6 m", delta_heading: "0 deg"}
  detour:
    - {max_wheel_rate: "0.09 rad/s", delta_position: "0.3 m", delta_heading: "20 deg"}
    - {max_wheel_rate: "0.09 rad/s", delta_position: "0.3 m", delta_heading: "-20 deg"}
"""


@pytest.mark.slow
def test_a_campaign_run_writes_a_report_that_renders(tmp_path: Path) -> None:
    campaign = tmp_path / "small.yaml"
    campaign.write_text(CAMPAIGN, encoding="utf-8")
    (tmp_path / "report-e2e.rules").write_text(RULEBOOK, encoding="utf-8")
    code = main(["run", str(campaign), "--quiet", "--workers", "2"])
    # straight hits the L2 rock in every run (risk 100 % > 70 %): it fails acceptable_risk
    # (not decided at 4 runs), so not every path passes: exit 1
    assert code == 1
    out = tmp_path / "out"
    page = out / "report.html"
    assert page.exists() and (out / "risk_map_all.png").exists()
    text = page.read_text(encoding="utf-8")
    assert "report-e2e 0.2.0" in text and "Notes" not in text
    assert "Assumed vs simulated slip" in text  # the reference runs' slip beside the rulebook's
    data, setup, maps = prepare_report(out / "results.h5")
    assert maps.per_sample and setup.notes == []
    # The rock near the straight path and the keep-out area are drawn, with their levels.
    assert [rock.level for rock in setup.environment.rocks] == ["L2"]
    assert [area.name for area in setup.environment.areas] == ["soft-patch"]
    for path in data.evaluated_paths:
        accumulator = maps.per_path[path.name]
        values = accumulator.values()
        # Per-sample values may exceed a run's I_max where an index reduces with `final`
        # (a transient the final value no longer shows): only the scale is bounded.
        assert np.nanmin(values) >= 0.0 and np.nanmax(values) <= 1.0
        complete = int(path.complete.sum())
        assert accumulator.runs == complete
        # Each run crosses cells along its track (0.6 m commanded; a straight run held at the
        # rock still covers 0.3 m: more than 10 cells of 2.5 cm).
        assert accumulator.counts().max() <= complete
        assert accumulator.counts().sum() >= 10 * complete
        assert path.final_local_error is not None
        assert path.final_local_error.size == int(path.complete.sum())
    # The rock beside the right wheels of 'straight': where they touch it (body centre near
    # x = 0.45 m), the per-sample obstacle risk of the L2 contact (factor 0.6) is on the map.
    # The rock overlaps the right wheels' track (y = -0.26 m ± 3 cm), so runs hit it.
    straight = next(p for p in data.paths if p.name == "straight")
    assert straight.chances["hit_L2"][straight.complete].any()
    xs, _ = maps.grid.centres()
    near_rock = maps.per_path["straight"].values()[(xs > 0.35) & (xs < 0.55)]
    assert np.nanmax(near_rock) >= 0.6 - 1e-9
    # Without summary.json in the file, Table 1 comes from each path's stored statistics.
    store = ResultStore.open(out / "results.h5")
    try:
        rows = {p.name: row_from_arrays(p.name, store.path_group(p.name), p)
                for p in data.evaluated_paths}
    finally:
        store.close()
    for path in data.evaluated_paths:
        row = rows[path.name]
        # summary.json rounds: risks to 4 decimals, energy to 0.1 mAs, time to 0.01 s.
        assert row.mean_risk == pytest.approx(path.row.mean_risk, abs=5e-5)
        assert row.risk_ci95 == pytest.approx(path.row.risk_ci95, abs=5e-5)
        assert row.energy_mAs == pytest.approx(path.row.energy_mAs, abs=0.05)
        assert row.time_s == pytest.approx(path.row.time_s, abs=0.005)
        assert (row.verdict, row.undecided) == (path.row.verdict, path.row.undecided)
    # What explains the map: contacts where the right wheels met the rock, the ideal path,
    # the reference run's wheel tracks, and the decision above everything.
    contacts = maps.contacts["straight"]
    assert contacts and all(c["body"] in ("FR", "RR") for c in contacts if c["part"] == "wheel")
    assert all(abs(c["y"] - (-0.30)) < 0.04 + 0.06 for c in contacts)  # at the rock's side
    ideal_x, ideal_y = maps.ideal_tracks["straight"]
    assert ideal_x[-1] == pytest.approx(0.6) and np.allclose(ideal_y, 0.0)
    assert set(maps.wheel_tracks["straight"]) == {"FL", "FR", "RL", "RR"}
    assert text.index('id="decision"') < text.index("Table 1") < text.index('id="imap"')
    # The page as a person sees it: the report again from the CLI, then a screenshot.
    assert main(["report", str(out / "results.h5"), "-o", str(tmp_path / "again")]) == 0
    assert render(tmp_path / "again" / "report.html", tmp_path / "screen.png") == []
    for width in (800, 1400):
        found = check_page(tmp_path / "again" / "report.html", width, tmp_path)
        assert found["errors"] == [] and found["overflowing"] == []
        assert found["resources"] == []
        assert found["openedFromRow"] == found["row"]
