"""Which uncertain parameter drives a path's risk: rank correlations over the stored runs.

No new simulation: the Monte Carlo runs already stored are a given-data sample of the
parameters (``runs/parameters``) and of what the rulebook made of them (``evaluation/i_max`` and
the index values). For each path and parameter we report Spearman's rank correlation ρ with

- the run risk ``I_max`` (what the verdict and the ranking read), and
- the raw value of the path's **dominant index** (the index that set I_max in most runs; raw,
  so runs where the index saturates at its limit still differ),

each with a 95 % confidence interval from Fisher's z transform with the Bonett–Wright standard
error ``sqrt((1 + ρ²/2) / (n − 3))`` for Spearman's ρ. Rank correlation is chosen over a
variance-based index because it needs no model, works with any sampling method, reads the
sign (more cohesion → less risk), is robust to the saturation of I_max at 1 (ties get average
ranks), and its interval says when a sample is too small to tell. It measures monotonic
influence only: a parameter whose effect goes up and down shows a small ρ.

>>> rng = np.random.default_rng(1)
>>> a, b = rng.uniform(size=200), rng.uniform(size=200)
>>> found = correlations({"a": a, "b": b}, 3 * a + 0.1 * rng.normal(size=200))
>>> [(c.parameter, round(c.rho, 2)) for c in found]
[('a', 0.99), ('b', 0.0)]
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import stats

from idefix_rules.campaign.storage.store import STATUS_COMPLETE
from idefix_rules.results.format import attribute_text

CONFIDENCE = 0.95
MIN_RUNS = 8  # fewer complete runs: no correlation is reported


@dataclass(frozen=True)
class Correlation:
    """Spearman's ρ of one parameter with one target, with its confidence interval."""

    parameter: str
    rho: float
    low: float
    high: float
    runs: int

    @property
    def significant(self) -> bool:
        """The interval excludes 0."""
        return self.low > 0.0 or self.high < 0.0

    def to_dict(self) -> dict[str, Any]:
        return {"parameter": self.parameter, "rho": round(self.rho, 3),
                "ci95": [round(self.low, 3), round(self.high, 3)], "runs": self.runs,
                "significant": self.significant}


def spearman_interval(rho: float, runs: int, confidence: float = CONFIDENCE
                      ) -> tuple[float, float]:
    """Confidence interval of Spearman's ρ (Fisher z, Bonett–Wright standard error).

    >>> low, high = spearman_interval(0.5, 100)
    >>> round(low, 3), round(high, 3)
    (0.326, 0.641)
    """
    if runs <= 3:
        return -1.0, 1.0
    r = min(max(rho, -0.999999), 0.999999)
    z = math.atanh(r)
    se = math.sqrt((1.0 + r * r / 2.0) / (runs - 3))
    q = float(stats.norm.ppf(0.5 + confidence / 2.0))
    return math.tanh(z - q * se), math.tanh(z + q * se)


def correlations(parameters: dict[str, np.ndarray], target: np.ndarray) -> list[Correlation]:
    """ρ of every parameter with ``target`` over the runs where both are finite, strongest
    first; parameters or targets without spread are left out (ρ undefined)."""
    target = np.asarray(target, dtype=float)
    found = []
    for name, values in parameters.items():
        values = np.asarray(values, dtype=float)
        ok = np.isfinite(values) & np.isfinite(target)
        n = int(ok.sum())
        if n < MIN_RUNS or np.ptp(values[ok]) == 0 or np.ptp(target[ok]) == 0:
            continue
        rho = float(stats.spearmanr(values[ok], target[ok]).statistic)
        if not math.isfinite(rho):
            continue
        low, high = spearman_interval(rho, n)
        found.append(Correlation(name, rho, low, high, n))
    return sorted(found, key=lambda c: (-abs(c.rho), c.parameter))


def why_none(parameters: dict[str, np.ndarray], target: np.ndarray, what: str) -> str | None:
    """Why :func:`correlations` finds nothing for ``target`` (None when it finds something or
    there is no simple reason), in words for the report.

    >>> why_none({"a": np.arange(10.0)}, np.full(10, 0.25), "run risk I_max")
    'every run has the same run risk I_max (0.25): a rank correlation needs a spread'
    """
    target = np.asarray(target, dtype=float)
    finite = target[np.isfinite(target)]
    if finite.size < MIN_RUNS:
        return (f"{finite.size} complete run(s): a rank correlation needs at least "
                f"{MIN_RUNS}")
    if np.ptp(finite) == 0:
        return (f"every run has the same {what} ({float(finite[0]):.4g}): a rank "
                "correlation needs a spread")
    if not any(np.ptp(np.asarray(v, dtype=float)[np.isfinite(v)]) > 0
               for v in parameters.values() if np.isfinite(v).any()):
        return "no sampled parameter varies between the runs"
    return None


def path_sensitivity(group: Any) -> dict[str, Any] | None:
    """Sensitivity of one stored path (an h5py group ``/paths/<name>``); None when the path
    has no evaluated runs."""
    runs, evaluation = group.get("runs"), group.get("evaluation")
    if runs is None or evaluation is None or "i_max" not in evaluation:
        return None
    complete = np.asarray(runs["status"][()]) == STATUS_COMPLETE
    i_max = np.asarray(evaluation["i_max"][()], dtype=float)
    if complete.size != i_max.size:
        return None
    parameters = {key: np.asarray(data[()], dtype=float)[complete]
                  for key, data in runs.get("parameters", {}).items()}
    names = list(json.loads(attribute_text(evaluation.attrs.get("index_names", "[]"))))
    dominant_codes = np.asarray(evaluation["dominant"][()])[complete] \
        if "dominant" in evaluation else np.zeros(0, dtype=int)
    valid = dominant_codes[(dominant_codes >= 0) & (dominant_codes < len(names))]
    dominant = names[int(np.bincount(valid.astype(int)).argmax())] if valid.size else None
    record: dict[str, Any] = {
        "runs": int(complete.sum()),
        "risk": [c.to_dict() for c in correlations(parameters, i_max[complete])],
        "dominant_index": dominant,
        "dominant": [],
        "note": None,  # why no correlation could be computed, when none could
    }
    if not record["risk"]:
        record["note"] = why_none(parameters, i_max[complete], "run risk I_max")
    if dominant is not None:
        source = evaluation.get("raw") if "raw" in evaluation else evaluation.get("indices")
        if source is not None and dominant in source:
            values = np.asarray(source[dominant][()], dtype=float)[complete]
            record["dominant"] = [c.to_dict() for c in correlations(parameters, values)]
    return record


def store_sensitivity(file: Any) -> dict[str, Any]:
    """``{path: sensitivity}`` of every evaluated path of a results file (h5py.File)."""
    paths = file.get("paths")
    if paths is None:
        return {}
    found = {}
    for name in paths:
        record = path_sensitivity(paths[name])
        if record is not None:
            found[str(name)] = record
    return found
