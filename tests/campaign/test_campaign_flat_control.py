"""The no-obstacle control campaign on the built-in rover FMU: on flat ground, nominal soil and
only the initial position uncertain, no chain is critical on position: the default rulebook's
I_pos reads the drift each run's drive adds to its start offset, and its path-level statement the
runs' average position; read per run against the reference (rulebook 1.0.0) the same runs
saturate from the initial spread alone."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from idefix_rules.campaign.evaluation.evaluate import evaluate_path
from idefix_rules.campaign.input.campaign_values import initial_position_sigma, rover_geometry
from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.cli import main
from idefix_rules.results.campaign import rebuilt_campaign
from idefix_rules.rulebook import check_text, compile_rulebook

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
POSITION_ONLY = """rulebook "position" version "1.0.0"
purpose "the default rulebook's position index alone"
settings {
  theoretical_slip = 20 %
  tolerance_growth = 5 cm/rad
}
index I_pos {
  value  = final over time (hypot(mean over runs (x - ref.x), mean over runs (y - ref.y))
                            / tolerance_radius)
  limit  = 1
  weight = 1
}
verdict ok: require risk <= 70 %
"""


def _paths(summary_file: Path) -> dict[str, dict]:
    return {p["name"]: p for p in json.loads(summary_file.read_text())["paths"]}


def test_the_flat_control_is_not_critical_on_position(tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]
                                                      ) -> None:
    out = tmp_path / "flat"
    code = main([str(ROOT / "campaigns" / "flat-control.yaml"), "--runs", "24", "--out",
                 str(out), "--workers", "2", "--quiet", "--no-report"])
    console = capsys.readouterr().out
    assert code == 0, console
    paths = _paths(out / "summary.json")
    # The rulebook assumes 20 % slip; on flat nominal soil the reference runs slip far less:
    # the campaign says so, per path, naming the setting.
    slip = json.loads((out / "summary.json").read_text())["slip"]
    assert slip["setting"] == "theoretical_slip" and slip["margin"] == 0.05
    assert {record["path"] for record in slip["paths"]} == set(paths)
    straight = next(r for r in slip["paths"] if r["path"] == "straight")
    assert straight["assumed"] == pytest.approx(0.2)
    assert 0.0 <= straight["measured"] < 0.1 and straight["disagrees"]
    # one warning for every path that disagrees (the assumption is the rulebook's), said once;
    # and one for the straight chain, whose runs are the same drive shifted on homogeneous
    # ground: every run scores the same (its slip index), which the campaign says
    words = " ".join(console.split())
    assert words.count("warning:") == 2
    spread = paths["straight"]["risk_spread"]
    assert spread["uniform"] and not spread["saturated"] and spread["iqr"] == 0.0
    assert f"warning: {spread['warning']}" in words
    assert spread["warning"].startswith("straight: every one of its 24 runs scores I_max 4.0 %")
    # the detours' turns cross their own ruts, which the 1 cm rut grid resolves a little
    # differently from each shifted start (64 runs: 6e-4 and 1e-2 apart): no warning
    for name in ("wide-detour", "smooth-detour"):
        assert paths[name]["risk_spread"]["warning"] is None, name
    assert f"warning: {' '.join(slip['warning'].split())}" in words  # its JSON form
    assert "warning: the reference runs slipped straight" in words
    assert "set `theoretical_slip =" in words
    assert f"straight {100 * straight['measured']:.1f} %" in words
    assert set(paths) == {"straight", "wide-detour", "smooth-detour"}
    for name, record in paths.items():
        statistics = record["statistics"]
        assert record["completed_runs"] == 24, name
        assert statistics["index_max"]["I_pos"] < 0.5, name
        assert statistics["index_mean"]["I_pos"]["value"] < 0.5, name
        assert record["collision_chance"] == {"L1": 0.0, "L2": 0.0, "L3": 0.0}
    assert paths["straight"]["mean_risk"] <= 0.3

    # Chunk by chunk (a first pass over every run for the path-level mean), the position index
    # is the same value in every run, and the same whatever the chunk size.
    store = ResultStore.open(out / "results.h5")
    try:
        campaign = rebuilt_campaign(store)
        evaluator = compile_rulebook(check_text(POSITION_ONLY).checked)
        rover, sigma = rover_geometry(campaign), initial_position_sigma(campaign)
        whole, _ = evaluate_path(store, "straight", evaluator, rover, sigma, None, chunk_runs=100)
        chunked, _ = evaluate_path(store, "straight", evaluator, rover, sigma, None, chunk_runs=5)
    finally:
        store.close()
    assert whole.raw["I_pos"].shape == (24,) and np.ptp(whole.raw["I_pos"]) == 0.0
    np.testing.assert_allclose(chunked.raw["I_pos"], whole.raw["I_pos"], rtol=1e-12)
    # the runs' average position sits far inside the tolerance: the default rulebook's
    # path-level chance that reads it holds in no run
    assert whole.raw["I_pos"][0] < 0.1
    for record in paths.values():
        assert record["statistics"]["chances"]["average_off_course"]["value"] == 0.0

    # The same runs scored by the per-run position rule of rulebook 1.0.0: on the straight chain
    # (its tolerance stays at 1 sigma) the initial spread alone, about 1.25 sigma per run, makes
    # I_pos near critical. (The turning chains' tolerance grows with the turns.)
    earlier = ROOT / "rulebooks" / "history" / "idefix-ops-1.0.0.rules"
    assert main(["evaluate", str(out / "results.h5"), "--rulebook", str(earlier), "--out",
                 str(tmp_path / "earlier")]) == 1  # straight's mean risk is above 30 %
    straight = _paths(tmp_path / "earlier" / "summary.json")["straight"]
    assert straight["statistics"]["index_mean"]["I_pos"]["value"] > 0.5
