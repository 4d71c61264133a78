"""A digest of the simulated datasets of a results file, to prove a campaign simulates the
same numbers as before a change (``tests/campaign/test_campaign_same_datasets.py``).

Only what the simulation stage writes per path is hashed (chain, reference signals and
parameters, Monte Carlo signals, parameters and status): not the provenance (times, paths)
nor the evaluation (which follows the rulebook).
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterator
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


def simulated(file: h5py.File) -> Iterator[tuple[str, np.ndarray | float]]:
    """Every simulated dataset (``PATH/NAME``, its data) and reference parameter
    (``PATH/ref.KEY``, its value), path by path in a fixed order: what the simulation stage
    writes, not the evaluation nor the failures' platform-worded texts."""
    for path in sorted(file["paths"]):
        group = file["paths"][path]
        names: list[str] = []
        group.visit(names.append)
        for name in sorted(names):
            item = group[name]
            if not isinstance(item, h5py.Dataset) or name.startswith("evaluation") \
                    or name == "runs/failure":  # text of failures, none expected
                continue
            yield f"{path}/{name}", np.ascontiguousarray(item[()])
        for key in sorted(group["reference/parameters"].attrs) \
                if "reference/parameters" in group else ():
            yield f"{path}/ref.{key}", float(group["reference/parameters"].attrs[key])


def results_digest(results: Path) -> str:
    """sha256 over the names, dtypes, shapes and bytes of every simulated dataset."""
    digest = hashlib.sha256()
    with h5py.File(results, "r") as file:
        for label, data in simulated(file):
            if isinstance(data, float):
                digest.update(f"{label}={data!r}".encode())
            else:
                digest.update(f"{label}:{data.dtype.str}:{data.shape}".encode())
                digest.update(data.tobytes())
    return digest.hexdigest()


# --- a fingerprint that holds across platforms ------------------------------------------------
#
# The digest above is bit-exact, and so only holds on one platform: glibc picks its libm
# functions by processor (FMA, AVX, SSE2 variants) and numpy its SIMD math by processor too, and
# they differ in the last bits. Measured on the rover campaign below between glibc's FMA and AVX
# variants on one machine: at most 6e-14 on the reference run's float64 signals and one float32
# ulp on the stored Monte Carlo signals (the model is not chaotic there: no contact decision
# flips). The fingerprint keeps every dataset's dtype and shape exactly and its values at a
# tolerance far above that and far below any change of the physics: its sum, extremes and
# values at 32 evenly spaced places.

RTOL = 1e-6
ATOL = 1e-9
PLACES = 32


def results_fingerprint(results: Path) -> dict[str, object]:
    """Per simulated dataset (as :func:`results_digest` selects them): dtype, shape, and the
    sum, minimum, maximum and 32 values of it (NaN kept as None); per reference parameter its
    value."""
    found: dict[str, object] = {}
    with h5py.File(results, "r") as file:
        for label, data in simulated(file):
            if isinstance(data, float):
                found[label] = {"values": [_plain(data)]}
                continue
            entry: dict[str, object] = {"dtype": data.dtype.str, "shape": list(data.shape)}
            if data.dtype.kind in "fiub" and data.size:
                flat = data.astype(np.float64).reshape(-1)
                places = np.unique(np.linspace(0, flat.size - 1, PLACES).astype(int))
                finite = bool(np.isfinite(flat).any())
                entry["values"] = [_plain(v) for v in (
                    np.nansum(flat) if finite else np.nan,
                    np.nanmin(flat) if finite else np.nan,
                    np.nanmax(flat) if finite else np.nan,
                    *flat[places])]
            found[label] = entry
    return found


def _plain(value: float) -> float | None:
    return None if not np.isfinite(value) else float(value)


def fingerprint_differences(found: dict[str, object], expected: dict[str, object]
                            ) -> list[str]:
    """What differs, dataset by dataset: a dataset added or gone, another dtype or shape, or a
    value beyond ``RTOL`` / ``ATOL`` (a NaN against a number included)."""
    problems = [f"{name}: {'added' if name in found else 'gone'}"
                for name in sorted(set(found) ^ set(expected))]
    for name in sorted(set(found) & set(expected)):
        mine, theirs = found[name], expected[name]
        assert isinstance(mine, dict) and isinstance(theirs, dict)
        for key in ("dtype", "shape"):
            if mine.get(key) != theirs.get(key):
                problems.append(f"{name}: {key} {mine.get(key)} against {theirs.get(key)}")
        a, b = mine.get("values", []), theirs.get("values", [])
        assert isinstance(a, list) and isinstance(b, list)
        if len(a) != len(b):
            problems.append(f"{name}: {len(a)} values against {len(b)}")
            continue
        for index, (x, y) in enumerate(zip(a, b, strict=True)):
            if (x is None) != (y is None) or (x is not None and y is not None and not
                                              np.isclose(x, y, rtol=RTOL, atol=ATOL)):
                problems.append(f"{name}: value {index}: {x!r} against {y!r}")
                break
    return problems


FINGERPRINTS = Path(__file__).parent / "fingerprints"


def record(name: str, results: Path) -> Path:
    """Write the fingerprint of ``results`` as the expected one of ``name`` (on purpose only:
    ``IDEFIX_RECORD_FINGERPRINTS=1 pytest tests/campaign/test_campaign_same_datasets.py``)."""
    import json

    FINGERPRINTS.mkdir(exist_ok=True)
    target = FINGERPRINTS / f"{name}.json"
    target.write_text(json.dumps(results_fingerprint(results), indent=1, sort_keys=True) + "\n")
    return target


def expected_fingerprint(name: str) -> dict[str, object]:
    import json

    loaded: dict[str, object] = json.loads((FINGERPRINTS / f"{name}.json").read_text())
    return loaded
