"""Per-run values of a compiled rulebook: normalised, runs with non-finite data, time and energy."""

from __future__ import annotations

import numpy as np

from idefix_rules.rulebook.derived import DerivedSignals

FINITE = ("finite runs per signal",)  # key of the shared dict that no expression key equals


def bad_runs(source: DerivedSignals, names: tuple[str, ...],
             finite: dict[str, np.ndarray]) -> np.ndarray:
    """The runs in which one of the signals ``names`` holds NaN or ±inf (``finite``: which runs
    hold only finite values, per signal, filled as signals are read)."""
    flags = np.zeros(source.runs, dtype=bool)
    for name in names:
        if name not in finite:
            array = np.asarray(source.get(name))
            if array.dtype == bool:
                finite[name] = np.ones(array.shape[0], dtype=bool)
            else:  # elementwise: a sum of finite values near the largest double overflows
                finite[name] = np.isfinite(array.reshape(array.shape[0], -1)).all(axis=1)
        flags |= ~finite[name]
    return flags


def normalise(value: np.ndarray, limit: float, nominal: float | None) -> np.ndarray:
    """``clamp(value / limit, 0, 1)``, or through (nominal, 0.5) when there is a nominal, NaN → 1
    (``fmin`` returns 1 for NaN): :func:`.semantics.normalised`, element-wise, the same
    operations in the same order."""
    if nominal is None:
        normalised = np.asarray(np.divide(value, limit))
    else:
        below = 0.5 * value / nominal
        above = 0.5 + 0.5 * (value - nominal) / (limit - nominal)
        normalised = np.asarray(np.where(value <= nominal, below, above), dtype=float)
    np.fmin(normalised, 1.0, out=normalised)
    return np.asarray(np.fmax(normalised, 0.0, out=normalised))


def time_energy(source: DerivedSignals, runs: int) -> tuple[np.ndarray, np.ndarray]:
    """Each run's time and energy, at the sample where it ends."""
    # The run ends where the chain is complete (chain_done, idefix_rules.chain_end) when the
    # runs say so ('command' or 'done'), else at the last sample; without 'energy' the run's
    # energy is unknown (NaN).
    if source.provides("command") or source.provides("done"):
        done = np.broadcast_to(source.get("chain_done") > 0, (runs, source.samples))
    else:
        done = np.zeros((runs, source.samples), dtype=bool)
    sample = np.where(done.any(axis=1), np.argmax(done, axis=1), source.samples - 1)
    if not source.provides("energy"):
        return source.t[sample], np.full(runs, np.nan)
    energy = np.broadcast_to(source.get("energy"), (runs, source.samples))
    return source.t[sample], energy[np.arange(runs), sample]
