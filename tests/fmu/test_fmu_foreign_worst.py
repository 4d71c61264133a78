"""The worst-case search on an FMU another exporter built (pythonfmu's ``Unicycle``), whose
failure region is known in closed form, through the CLI.

The unicycle drives the chain's 1.2 m at its set-point speed times ``1 - slip`` and keeps its
start offset ``y0``: it ends ``1.2 m · (1 - slip)`` ahead and ``y0`` to the side. With the
rulebook below, a run is critical (I_max = 1) exactly when

- it ends 3 cm or more short of the reference run (slip 0.05): slip ≥ 0.075, the quantile 0.75
  of its uniform distribution on [0, 0.1], z = Φ⁻¹(0.75) = 0.674 in quantile coordinates; or
- it ends 1.5 cm or more to the left: y0 ≥ 1.5 cm, z = 1.5 for y0 ~ normal(0, 1 cm).

Tolerance: the search brackets each boundary to 1/64 of the ray searched (3 rounds, each
quartering the bracket: docs/worst-case.md), so the reported distance (the nearest critical
world simulated) lies within ``searched_to / 64`` above the true one — 0.058 σ along an axis
whose box ends at 3.72 σ — and the true boundary lies inside the reported bracket.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from scipy import stats

from idefix_rules.cli import main

RULEBOOK = """\
rulebook "closed-form" version "1.0.0"
purpose "A failure region known in closed form, for the worst-case search"

index I_short "shortfall against the reference run" {
  value  = final over time (ref.x - x)
  limit  = 3 cm
  weight = 1
  because "Ending 3 cm short of the reference run is critical"
}

index I_left "offset to the left" {
  value  = final over time (y)
  limit  = 1.5 cm
  weight = 1
  because "Ending 1.5 cm to the left is critical"
}

verdict acceptable_risk: require risk <= 50 %
  because "Mean risk limit"
"""

CAMPAIGN = """\
name: unicycle-worst
fmu:
  path: Unicycle.fmu
  signals:
    px: x
    py: y
  parameters:
    y0: initial.y
  chain:
    delivery: inputs
    inputs:
      v: body.speed
      w: body.yaw_rate
rulebook: closed-form.rules
output: out
workers: 2
uncertainty:
  seed: 3
  parameters:
    slip: {distribution: uniform, low: 0.0, high: 0.1}
    initial.y: {distribution: normal, mean: "0 m", std: "1 cm"}
paths:
  straight:
    - {max_wheel_rate: "0.05 rad/s", delta_position: "1.2 m", delta_heading: "0 deg"}
simulation:
  output_interval: "2 s"
  extra_time: "4 s"
"""

Z_SLIP = float(stats.norm.ppf(0.75))  # slip 0.075
Z_LEFT = 1.5  # y0 1.5 cm


def test_the_reported_boundary_is_the_closed_form_one_within_a_64th_of_the_ray(
        tmp_path: Path, unicycle_fmu: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "Unicycle.fmu").write_bytes(unicycle_fmu.read_bytes())
    (tmp_path / "closed-form.rules").write_text(RULEBOOK, encoding="utf-8")
    (tmp_path / "campaign.yaml").write_text(CAMPAIGN, encoding="utf-8")
    code = main(["worst", str(tmp_path / "campaign.yaml"), "--runs", "90", "--quiet",
                 "--no-report"])
    output = " ".join((capsys.readouterr().out).split())
    assert code == 0, output
    record = json.loads((tmp_path / "out" / "worst" / "worst.json").read_text())
    path = record["paths"][0]
    assert path["nominal"]["risk"] == 0.0 and path["critical"]
    assert path["runs_used"] <= 90 and path["failed_runs"] == 0
    # the most likely critical world is on the slip axis, slip 0.075
    worst = path["worst"]
    assert worst["risk"] == 1.0 and worst["dominant_index"] == "I_short"
    assert worst["parameters"]["slip"]["value"] == pytest.approx(0.075, abs=0.01)
    boundaries = {b["direction"]: b for b in path["boundaries"]}
    assert set(boundaries) == {"toward the worst world", "slip up", "initial.y up"}
    direction = boundaries["toward the worst world"]["unit_vector"]
    true_distance = {
        "slip up": Z_SLIP, "initial.y up": Z_LEFT,
        "toward the worst world": min(Z_SLIP / direction[0] if direction[0] > 0 else 99,
                                      Z_LEFT / direction[1] if direction[1] > 0 else 99)}
    for name, boundary in boundaries.items():
        low, high = boundary["bracket"]
        tolerance = boundary["searched_to"] / 64 + 1e-3
        assert low - 1e-3 <= true_distance[name] <= high + 1e-3, name
        assert boundary["distance"] == pytest.approx(true_distance[name], abs=tolerance), name
    critical = boundaries["slip up"]["critical_world"]["parameters"]
    assert critical["slip"]["value"] == pytest.approx(0.075, abs=0.1 * 3.72 / 64)
    left = boundaries["initial.y up"]["critical_world"]["parameters"]["initial.y"]["value"]
    assert 0.015 <= left <= 0.015 + 0.01 * 3.72 / 64 + 1e-6
    change = path["smallest_change"]
    assert change["distance"] == pytest.approx(Z_SLIP, abs=3.72 / 64)
    assert "straight" in output and "slip up" in output
