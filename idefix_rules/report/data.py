"""What a report shows, read from ``results.h5`` (layout: ``docs/results-format.md``).

Plain data, no drawing: the header (provenance and hashes), one :class:`PathReport` per path with
its Table 1 row, per-run index values and sampled parameters, and the "why" sections derived from
them (dominant index counts, worst runs, rule coverage). Figures are drawn from these objects by
:mod:`idefix_rules.report.figures`; they are read by :mod:`idefix_rules.report.reading`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from idefix_rules.campaign.statistics.pairwise import PairComparison

LEVELS = ("L1", "L2", "L3")
# An index "came near its limit" in a campaign when some run reached this share of it.
NEAR_LIMIT = 0.5
# Worst runs listed per path.
WORST_RUNS = 5


@dataclass(frozen=True)
class Header:
    """Provenance printed at the top of every report."""

    campaign_name: str
    campaign_path: str
    campaign_sha256: str
    rulebook_name: str
    rulebook_version: str
    rulebook_sha256: str
    fmu_path: str
    fmu_sha256: str
    package_version: str
    runs: int
    seed: int
    sampling: str
    started: str
    finished: str
    state: str
    evaluated: str
    results: str = ""  # the results file the report was made from
    runs_mode: str = ""  # fixed, auto, or worst (a worst-case search's runs)


@dataclass(frozen=True)
class TableRow:
    """One row of Table 1 (paper): units are those of the table (%, mAs, s)."""

    path: str
    status: str
    runs: int
    completed_runs: int
    failed_runs: int
    mean_risk: float | None
    risk_ci95: tuple[float, float] | None
    chances: dict[str, float]
    energy_mAs: float | None
    time_s: float | None
    verdict: str
    undecided: bool
    rank: int | None
    dominant_index: str | None
    verdict_reasons: tuple[str, ...] = ()
    reason: str = ""
    stop_reason: str = ""  # how many runs were used and why the Monte Carlo part ended
    # complete runs still driving at the stop limit (None: not known), and that limit in s
    unfinished_runs: int | None = None
    stop_time_s: float | None = None
    # the campaign's waivers that covered a failure of the path (rule, kind, reason,
    # approved_by, until), as summary.json lists them
    waivers: tuple[dict[str, str], ...] = ()
    # the failing or undecided verdict rules in words, as the console says them (an
    # undecided one with the runs that would decide it): summary.json's `reasons`
    reasons: tuple[str, ...] = ()
    # summary.json's risk_spread warning: the run risks do not tell the runs apart
    spread_warning: str = ""


@dataclass(frozen=True)
class WorstRun:
    """A run with a high risk, and what it was made of."""

    run: int
    i_max: float
    dominant: str | None
    indices: dict[str, float]
    parameters: dict[str, float]
    # Unclipped weighted value / limit of the index furthest over its limit (None: unknown).
    excess: float | None = None
    excess_index: str | None = None


@dataclass
class PathReport:
    """One path's data for the report."""

    name: str
    index: int
    status: str
    reason: str
    row: TableRow
    index_names: list[str] = field(default_factory=list)
    status_codes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int8))
    complete: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    i_max: np.ndarray = field(default_factory=lambda: np.zeros(0))
    dominant: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int16))
    indices: dict[str, np.ndarray] = field(default_factory=dict)
    raw: dict[str, np.ndarray] = field(default_factory=dict)  # index values before / limit
    verdict: dict[str, Any] = field(default_factory=dict)  # the stored Verdict as a dict
    chances: dict[str, np.ndarray] = field(default_factory=dict)
    parameters: dict[str, np.ndarray] = field(default_factory=dict)
    parameter_units: dict[str, str] = field(default_factory=dict)
    # Filled by the preparation of the box plots (m and rad), complete runs only.
    final_local_error: np.ndarray | None = None
    final_heading_error: np.ndarray | None = None

    @property
    def evaluated(self) -> bool:
        return bool(self.index_names) and self.i_max.size > 0

    def dominance(self) -> list[tuple[str, int]]:
        """How often each index gave I_max among complete runs, most frequent first."""
        counts: dict[str, int] = {}
        for position in self.dominant[self.complete]:
            name = self.index_names[position] if 0 <= position < len(self.index_names) else "none"
            counts[name] = counts.get(name, 0) + 1
        return sorted(counts.items(), key=lambda item: (-item[1], item[0]))

    def excess(self, limits: Mapping[str, float], weights: Mapping[str, float]
               ) -> tuple[np.ndarray, list[str | None]]:
        """Per run: how far over its limit the furthest index goes (weight × raw / limit,
        not clipped at 1), and which index that is; NaN where no raw value is known."""
        ratios = []
        names = []
        for name, values in self.raw.items():
            limit = limits.get(name)
            if limit is None or limit == 0:
                continue
            ratios.append(weights.get(name, 1.0) * np.asarray(values, dtype=float) / limit)
            names.append(name)
        if not ratios:
            return np.full(self.i_max.size, np.nan), [None] * self.i_max.size
        stacked = np.vstack(ratios)
        filled = np.where(np.isfinite(stacked), stacked, -np.inf)
        best = np.argmax(filled, axis=0)
        value = filled[best, np.arange(stacked.shape[1])]
        return (np.where(np.isfinite(value), value, np.nan),
                [names[int(b)] if np.isfinite(v) else None for b, v in zip(best, value,
                                                                           strict=True)])

    def worst_order(self, limits: Mapping[str, float] | None = None,
                    weights: Mapping[str, float] | None = None) -> np.ndarray:
        """Complete runs, worst first: by I_max, then by how far over the limits the run
        goes (unclipped weight × value / limit of its furthest index), then by the sum of its
        normalised indices (more indices near their limits), then by run number."""
        runs = np.flatnonzero(self.complete)
        if runs.size == 0:
            return runs
        excess, _ = self.excess(limits or {}, weights or {})
        total = np.zeros(self.i_max.size)
        for values in self.indices.values():
            total += np.nan_to_num(np.asarray(values, dtype=float))
        keys = (runs, -total[runs], -np.nan_to_num(excess[runs], nan=-np.inf),
                -self.i_max[runs])
        return runs[np.lexsort(keys)]

    def worst_runs(self, count: int = WORST_RUNS, limits: Mapping[str, float] | None = None,
                   weights: Mapping[str, float] | None = None) -> list[WorstRun]:
        """The ``count`` worst complete runs (:meth:`worst_order`), indices and parameters."""
        excess, excess_names = self.excess(limits or {}, weights or {})
        worst = []
        for run in self.worst_order(limits, weights)[:count]:
            position = int(self.dominant[run])
            dominant = (self.index_names[position]
                        if 0 <= position < len(self.index_names) else None)
            worst.append(WorstRun(
                run=int(run), i_max=float(self.i_max[run]), dominant=dominant,
                indices={name: float(values[run]) for name, values in self.indices.items()},
                parameters={name: float(values[run]) for name, values in self.parameters.items()},
                excess=float(excess[run]) if np.isfinite(excess[run]) else None,
                excess_index=excess_names[int(run)],
            ))
        return worst


@dataclass(frozen=True)
class Coverage:
    """How close a rule came to its limit over the whole campaign."""

    name: str
    kind: str  # "index" or "chance"
    highest: float  # index: largest normalised value (1 = limit); chance: largest chance
    where: str  # path of the highest value ("" when nothing ran)
    near: bool


@dataclass
class ReportData:
    header: Header
    paths: list[PathReport]
    ranking: list[str]
    expectations: list[dict[str, Any]]
    decision: dict[str, Any] | None = None  # summary.json's decision (None: older files)
    exit_code: int | None = None
    pairs: list[PairComparison] = field(default_factory=list)  # summary.json's, paired runs
    confidence: float = 0.95  # the bounds' family-wise confidence (1 - summary's alpha.alpha)
    # summary.json's problems: the campaign's mistakes only its evaluation shows (exit 2)
    problems: list[dict[str, Any]] = field(default_factory=list)

    @property
    def evaluated_paths(self) -> list[PathReport]:
        return [path for path in self.paths if path.evaluated]

    def coverage(self) -> list[Coverage]:
        """Per index and chance: the largest value any complete run reached, and where."""
        def index_peak(values: np.ndarray) -> float:
            return float(np.nanmax(values))

        def chance_share(values: np.ndarray) -> float:
            return float(np.mean(values > 0))

        indices = self._highest("indices", "index", index_peak)
        chances = self._highest("chances", "chance", chance_share)
        return ([Coverage(n, "index", v, w, v >= NEAR_LIMIT) for n, v, w in indices]
                + [Coverage(n, "chance", v, w, v > 0.0) for n, v, w in chances])

    def _highest(self, attribute: str, kind: str,
                 measure: Callable[[np.ndarray], float]) -> list[tuple[str, float, str]]:
        """(name, highest measure over the paths' complete runs, path where) per name."""
        names: list[str] = []
        for path in self.evaluated_paths:
            names += [n for n in getattr(path, attribute) if n not in names]
        result = []
        for name in names:
            best, where = 0.0, ""
            for path in self.evaluated_paths:
                values = getattr(path, attribute).get(name)
                if values is None or not path.complete.any():
                    continue
                value = measure(values[path.complete])
                if value > best or not where:
                    best, where = value, path.name
            result.append((name, best, where))
        return result
