"""A digest of the simulated datasets of a results file, to prove a campaign simulates the
same numbers as before a change (``tests/campaign/test_campaign_same_datasets.py``).

Only what the simulation stage writes per path is hashed (chain, reference signals and
parameters, Monte Carlo signals, parameters and status): not the provenance (times, paths)
nor the evaluation (which follows the rulebook).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import h5py
import numpy as np

ROVER_CAMPAIGN = """\
name: digest-rover
rulebook: rover.rules
output: out
runs: 3
workers: 1
environment:
  terrain:
    synthetic: {size: "3 m", cell: "2 cm", slope: "2 deg", roughness: "3 mm", seed: 11}
  rocks:
    - {x: "0.3 m", y: "-0.26 m", radius: "4 cm", embed: "1 cm", level: L2}
  regolith: {k_c: "1400 N/m^2", k_phi: "820000 N/m^3", n: 1.0}
uncertainty:
  method: latin_hypercube
  seed: 2026
  parameters:
    initial.x: {distribution: normal, mean: "0 m", std: "1 cm"}
    initial.y: {distribution: normal, mean: "0 m", std: "1 cm"}
    soil.cohesion: {distribution: log_normal, median: "250 Pa", sigma: 0.4}
paths:
  straight:
    - {max_wheel_rate: "0.05 rad/s", delta_position: "0.4 m", delta_heading: "0 deg"}
  turn:
    - {max_wheel_rate: "0.05 rad/s", delta_position: "0 m", delta_heading: "20 deg"}
    - {max_wheel_rate: "0.05 rad/s", delta_position: "0.2 m", delta_heading: "-10 deg"}
simulation:
  output_interval: "0.5 s"
  extra_time: "2 s"
"""

ROVER_RULEBOOK = """\
rulebook "digest" version "1.0.0"
purpose "Scores the digest campaign"

index I_s "slip" {
  value  = max over time (max over wheels (abs(wheel.slip)))
  limit  = 70 %
  weight = 1
  because "Slip"
}

verdict acceptable: require risk <= 50 %
  because "Mean risk limit"
"""


def results_digest(results: Path) -> str:
    """sha256 over the names, dtypes, shapes and bytes of every simulated dataset."""
    digest = hashlib.sha256()
    with h5py.File(results, "r") as file:
        for path in sorted(file["paths"]):
            group = file["paths"][path]
            names: list[str] = []
            group.visit(names.append)
            for name in sorted(names):
                item = group[name]
                if not isinstance(item, h5py.Dataset) or name.startswith("evaluation"):
                    continue
                if name == "runs/failure":
                    continue  # text of failures, none expected; platform-worded
                data = np.ascontiguousarray(item[()])
                digest.update(f"{path}/{name}:{data.dtype.str}:{data.shape}".encode())
                digest.update(data.tobytes())
            for key in sorted(group["reference/parameters"].attrs) \
                    if "reference/parameters" in group else ():
                value = float(group["reference/parameters"].attrs[key])
                digest.update(f"{path}/ref.{key}={value!r}".encode())
    return digest.hexdigest()
