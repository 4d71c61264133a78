"""Rank correlations of sampled parameters with the stored risk (no simulation)."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
from hypothesis import event, given, settings
from hypothesis import strategies as st

from idefix_rules.campaign.evaluation.sensitivity import (
    correlations,
    spearman_interval,
    store_sensitivity,
)


def test_the_driving_parameter_comes_first_with_its_sign() -> None:
    rng = np.random.default_rng(4)
    cohesion = rng.uniform(100, 400, 300)
    noise = rng.uniform(0, 1, 300)
    # Risk falls with cohesion and saturates at 1 for the weakest soils (ties at the top).
    risk = np.minimum(1.0, 1.3 - cohesion / 400 + 0.05 * rng.normal(size=300))
    found = correlations({"noise": noise, "soil.cohesion": cohesion,
                          "constant": np.full(300, 2.0)}, risk)
    assert [c.parameter for c in found] == ["soil.cohesion", "noise"]  # constant: no ρ
    assert found[0].rho < -0.9 and found[0].significant
    assert found[0].low <= found[0].rho <= found[0].high
    assert not found[1].significant


def test_too_few_runs_give_no_correlation() -> None:
    assert correlations({"a": np.arange(7.0)}, np.arange(7.0)) == []
    assert len(correlations({"a": np.arange(8.0)}, np.arange(8.0))) == 1


@settings(max_examples=60, deadline=None)
@given(rho=st.floats(-0.99, 0.99), runs=st.integers(4, 5000))
def test_the_interval_holds_rho_and_narrows_with_runs(rho: float, runs: int) -> None:
    low, high = spearman_interval(rho, runs)
    event("strong" if abs(rho) > 0.5 else "weak")
    assert -1.0 <= low <= rho <= high <= 1.0
    more_low, more_high = spearman_interval(rho, runs * 4)
    assert more_high - more_low < high - low


def test_a_results_file_gives_risk_and_dominant_index_sensitivity(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    runs = 40
    slip = rng.uniform(0.05, 0.25, runs)
    with h5py.File(tmp_path / "r.h5", "w") as file:
        group = file.create_group("paths/p")
        status = np.ones(runs, dtype=np.int8)
        status[3] = 2  # a failed run: left out
        group.create_dataset("runs/status", data=status)
        group.create_dataset("runs/parameters/toy.slip", data=slip)
        group.create_dataset("runs/parameters/initial.y", data=rng.normal(0, 0.01, runs))
        evaluation = group.create_group("evaluation")
        evaluation.attrs["index_names"] = json.dumps(["I_s", "I_pos"])
        raw = slip * 4.0
        evaluation.create_dataset("i_max", data=np.minimum(raw / 0.7, 1.0))
        evaluation.create_dataset("dominant", data=np.zeros(runs, dtype=np.int16))
        evaluation.create_dataset("raw/I_s", data=raw)
        file.create_group("paths/rejected")  # never simulated: no entry
        found = store_sensitivity(file)
    assert list(found) == ["p"]
    record = found["p"]
    assert record["runs"] == runs - 1 and record["dominant_index"] == "I_s"
    assert record["risk"][0]["parameter"] == "toy.slip" and record["risk"][0]["rho"] > 0.9
    assert record["dominant"][0] == {**record["dominant"][0], "parameter": "toy.slip",
                                     "rho": 1.0}
