"""Does a path's run risk discriminate? Its runs at the limit and the spread of their I_max.

A mean risk says little when most runs sit at I_max = 1 (the rulebook then calls them
critical, not how critical) or when every run scores the same. Per path, over its complete runs:

* ``critical`` — the share of runs at ``I_max >= CRITICAL`` (0.99) of the largest I_max the
  rulebook can give (its largest index weight; 0.99 when that is 1);
* ``quartiles`` — the 25th, 50th and 75th percentiles of I_max, and ``iqr`` their spread;
* ``at_limit`` — per index, the share of runs where that index is at ``CRITICAL`` or above.

A path with at least ``MIN_RUNS`` runs whose runs are critical in half or more
(``saturated``), or whose runs all score the same to ``SAME`` (``uniform``), gets a warning
(console, ``summary.json`` under each path's ``risk_spread``), naming the indices at their limit.

>>> spread = risk_spread("a", np.array([1.0, 1.0, 0.995, 0.6]),
...                      {"I_s": np.array([1.0, 0.5, 0.995, 0.6]),
...                       "I_pos": np.array([1.0, 1.0, 0.3, 0.2])})
>>> spread.critical, spread.saturated, spread.at_limit
(0.75, False, {'I_s': 0.5, 'I_pos': 0.5})
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

CRITICAL = 0.99  # a run at or above this I_max is at the limit
MIN_RUNS = 8     # fewer complete runs say nothing about a spread
SAME = 1e-6      # run risks closer than this are the same (the same physics rounds apart)


@dataclass(frozen=True)
class RiskSpread:
    """One path's run risks: how many are at the limit and how far apart the rest lie."""

    path: str
    runs: int
    critical: float
    quartiles: tuple[float, float, float]
    lowest: float
    highest: float
    at_limit: dict[str, float] = field(default_factory=dict)
    critical_at: float = CRITICAL  # CRITICAL × the largest index weight: I_max's own ceiling

    @property
    def iqr(self) -> float:
        return self.quartiles[2] - self.quartiles[0]

    @property
    def saturated(self) -> bool:
        """Half the runs or more at the limit: the risk cannot tell them apart."""
        return self.runs >= MIN_RUNS and self.critical >= 0.5

    @property
    def uniform(self) -> bool:
        """Every run scores the same I_max (to ``SAME``).

        Runs that differ only by a translation on homogeneous ground score the same up to
        rounding (the flat control's straight chain: 4.7e-9 apart over 200 runs).
        """
        return self.runs >= MIN_RUNS and self.highest - self.lowest <= SAME

    @property
    def warning(self) -> str | None:
        if self.saturated:
            limits = ", ".join(f"{name} in {100 * share:.1f} %"
                               for name, share in self.at_limit.items())
            at = f" (at its limit: {limits})" if limits else ""
            return (f"{self.path}: {100 * self.critical:.1f} % of its {self.runs} runs are at "
                    f"I_max >= {self.critical_at:g}{at}; its risk says these runs are critical, "
                    "not how critical, so it does not tell them apart")
        if self.uniform:
            return (f"{self.path}: every one of its {self.runs} runs scores I_max "
                    f"{100 * self.lowest:.1f} %; the uncertainty moves nothing the rulebook "
                    "reads")
        return None

    def to_dict(self) -> dict[str, Any]:
        """The JSON record: a path without complete runs has null quartiles and extremes."""
        return {"runs": self.runs, "critical": round(self.critical, 4),
                "critical_at": round(self.critical_at, 6),
                "quartiles": [_rounded(q) for q in self.quartiles],
                "iqr": _rounded(self.iqr), "lowest": _rounded(self.lowest),
                "highest": _rounded(self.highest),
                "at_limit": {name: round(share, 4) for name, share in self.at_limit.items()},
                "saturated": self.saturated, "uniform": self.uniform, "warning": self.warning}


def _rounded(value: float) -> float | None:
    return round(value, 4) if np.isfinite(value) else None


def risk_spread(path: str, i_max: np.ndarray, indices: Mapping[str, np.ndarray],
                ceiling: float = 1.0) -> RiskSpread:
    """The spread of ``i_max`` over the runs where it is a number (complete runs); ``indices``
    the per-run normalised index values (same rows), in the rulebook's order; ``ceiling`` the
    largest I_max the rulebook can give (its largest index weight): a run is at the limit from
    ``CRITICAL`` of it on (with every weight 0.5, at I_max 0.495)."""
    values = np.asarray(i_max, dtype=float)
    done = np.isfinite(values)
    risks = values[done]
    critical_at = CRITICAL * ceiling
    if risks.size == 0:
        return RiskSpread(path, 0, 0.0, (float("nan"),) * 3, float("nan"), float("nan"),
                          critical_at=critical_at)
    q1, q2, q3 = (float(q) for q in np.percentile(risks, [25, 50, 75]))
    at_limit: dict[str, float] = {}
    for name, index in indices.items():
        column = np.asarray(index, dtype=float)
        if column.shape != values.shape:
            continue
        share = float(np.mean(column[done] >= CRITICAL))
        if share > 0.0:
            at_limit[str(name)] = share
    at_limit = dict(sorted(at_limit.items(), key=lambda item: -item[1]))
    critical = float(np.mean(risks >= critical_at)) if ceiling > 0.0 else 0.0
    return RiskSpread(path, int(risks.size), critical, (q1, q2, q3), float(risks.min()),
                      float(risks.max()), at_limit, critical_at)


def spread_warnings(spreads: Sequence[RiskSpread | None]) -> list[str]:
    """The warning of every path whose run risk does not discriminate, in the paths' order."""
    return [spread.warning for spread in spreads if spread is not None and spread.warning]
