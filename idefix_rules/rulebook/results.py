"""Result records of a compiled rulebook: per-run evaluations, findings, path statistics, verdicts.

All records are plain data with ``to_dict()`` (JSON-ready: lists, floats, non-finite → None).
Arrays in :class:`RunEvaluation` are vectorised across runs (axis 0).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from idefix_rules.errors import Span


def _plain(value: Any) -> Any:
    """JSON-ready copy: numpy → Python, non-finite floats → None."""
    if isinstance(value, np.ndarray):
        return [_plain(v) for v in value.tolist()] if value.ndim else _plain(value.item())
    if isinstance(value, np.generic):
        return _plain(value.item())
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, Span):
        return str(value)
    return value


def _plain_dict(data: Mapping[str, Any]) -> dict[str, Any]:
    plain: dict[str, Any] = _plain(data)
    return plain


@dataclass(frozen=True)
class RunRow:
    """One run of a :class:`RunEvaluation`, as plain Python values (for reports)."""

    run: int
    values: dict[str, float]
    raw: dict[str, float]
    weighted: dict[str, float]
    i_max: float
    dominant: str
    dominant_sample: int
    chances: dict[str, bool]
    time: float
    energy: float

    def to_dict(self) -> dict[str, Any]:
        return _plain_dict(self.__dict__)


@dataclass(frozen=True)
class RunEvaluation:
    """Per-run results of ``CompiledRulebook.evaluate``, arrays over runs.

    ``values[name]`` (runs,) normalised and clamped to [0, 1]; ``raw[name]`` (runs,) the SI
    value before normalisation (NaN when the run's signals held NaN); ``per_sample[name]``
    (runs, samples) normalised per-sample value; ``weighted[name]`` weight × value; ``i_max``
    (runs,); ``dominant`` (runs,) position in ``index_names`` of the index that set I_max (the
    first on ties); ``dominant_sample`` (runs,) the sample where the dominant index's per-sample
    value peaks; ``chances[name]`` (runs,) bool; ``time`` (runs,) s; ``energy`` (runs,) A·s.
    """

    index_names: tuple[str, ...]
    values: dict[str, np.ndarray]
    raw: dict[str, np.ndarray]
    per_sample: dict[str, np.ndarray]
    weighted: dict[str, np.ndarray]
    i_max: np.ndarray
    dominant: np.ndarray
    dominant_sample: np.ndarray
    chance_names: tuple[str, ...]
    chances: dict[str, np.ndarray]
    time: np.ndarray
    energy: np.ndarray

    @property
    def runs(self) -> int:
        return int(self.i_max.shape[0])

    @classmethod
    def concat(cls, parts: Sequence[RunEvaluation]) -> RunEvaluation:
        """Join evaluations of chunks of runs of the same chain (same indices and time grid)."""
        if not parts:
            raise ValueError("concat needs at least one RunEvaluation")
        first = parts[0]
        for part in parts[1:]:
            if part.index_names != first.index_names or part.chance_names != first.chance_names:
                raise ValueError("cannot join evaluations of different rulebooks")

        def join(getter: Any) -> np.ndarray:
            return np.concatenate([getter(p) for p in parts], axis=0)

        def join_map(attribute: str, names: tuple[str, ...]) -> dict[str, np.ndarray]:
            return {n: join(lambda p, n=n: getattr(p, attribute)[n]) for n in names}

        names, chance_names = first.index_names, first.chance_names
        return cls(
            index_names=names,
            values=join_map("values", names),
            raw=join_map("raw", names),
            per_sample=join_map("per_sample", names),
            weighted=join_map("weighted", names),
            i_max=join(lambda p: p.i_max),
            dominant=join(lambda p: p.dominant),
            dominant_sample=join(lambda p: p.dominant_sample),
            chance_names=chance_names,
            chances=join_map("chances", chance_names),
            time=join(lambda p: p.time),
            energy=join(lambda p: p.energy),
        )

    def row(self, run: int) -> RunRow:
        """Run ``run`` as plain values; ``dominant`` by name."""
        return RunRow(
            run=run,
            values={n: float(self.values[n][run]) for n in self.index_names},
            raw={n: float(self.raw[n][run]) for n in self.index_names},
            weighted={n: float(self.weighted[n][run]) for n in self.index_names},
            i_max=float(self.i_max[run]),
            dominant=self.index_names[int(self.dominant[run])],
            dominant_sample=int(self.dominant_sample[run]),
            chances={n: bool(self.chances[n][run]) for n in self.chance_names},
            time=float(self.time[run]),
            energy=float(self.energy[run]),
        )

    def to_dict(self, per_sample: bool = False) -> dict[str, Any]:
        """Arrays as lists; ``per_sample`` (large) only when asked."""
        data: dict[str, Any] = {
            "index_names": list(self.index_names),
            "values": self.values,
            "raw": self.raw,
            "weighted": self.weighted,
            "i_max": self.i_max,
            "dominant": [self.index_names[int(d)] for d in self.dominant],
            "dominant_sample": self.dominant_sample,
            "chances": self.chances,
            "time": self.time,
            "energy": self.energy,
        }
        if per_sample:
            data["per_sample"] = self.per_sample
        return _plain_dict(data)


@dataclass(frozen=True)
class CommandViolation:
    """A command rule that does not hold for one command of a chain."""

    rule: str
    command_number: int  # 1-based
    values: dict[str, float]  # the command quantities the rule reads, SI
    rationale: str | None
    message: str
    span: Span | None = None

    def to_dict(self) -> dict[str, Any]:
        return _plain_dict(self.__dict__)


@dataclass(frozen=True)
class PrescreenFinding:
    """A prescreen rule the reference run fails: the chain is excluded before Monte Carlo."""

    rule: str
    values: dict[str, float]  # the indices, chances and risk the rule reads
    rationale: str | None
    message: str
    span: Span | None = None

    def to_dict(self) -> dict[str, Any]:
        return _plain_dict(self.__dict__)


@dataclass(frozen=True)
class Estimate:
    """A path statistic with its confidence interval (``low`` ≤ ``value`` ≤ ``high``)."""

    value: float
    low: float
    high: float

    def to_dict(self) -> dict[str, Any]:
        return _plain_dict(self.__dict__)


@dataclass(frozen=True)
class PathStatistics:
    """Statistics of one path (chain) over its Monte Carlo runs.

    ``runs`` evaluated runs, ``failed_runs`` runs whose simulation failed (not evaluated);
    ``risk`` mean I_max with a Student-t interval at ``confidence``; ``index_mean`` with the
    same kind of interval, ``index_max``; ``chances`` fractions with Wilson intervals;
    ``time`` / ``energy`` means with Student-t intervals; ``dominant_counts`` how many runs each
    index dominated.
    """

    runs: int
    failed_runs: int
    confidence: float
    risk: Estimate
    risk_std: float
    index_mean: dict[str, Estimate]
    index_max: dict[str, float]
    chances: dict[str, Estimate]
    time: Estimate
    energy: Estimate
    dominant_counts: dict[str, int]
    # the share of failed runs with bounds (a campaign's); None: judged as the exact share
    failed: Estimate | None = None

    @property
    def failed_fraction(self) -> float:
        total = self.runs + self.failed_runs
        return self.failed_runs / total if total else 0.0

    def to_dict(self) -> dict[str, Any]:
        data = {k: (v.to_dict() if isinstance(v, Estimate) else v)
                for k, v in self.__dict__.items()}
        data["failed_fraction"] = self.failed_fraction
        return _plain_dict(data)


@dataclass(frozen=True)
class RuleResult:
    """One verdict rule on one path."""

    name: str
    passed: bool
    decided: bool  # False: a threshold lies inside the statistic's confidence interval
    statistic: str | None  # e.g. "risk", "chance(hit_L3)"; None for compound conditions
    value: float | None  # the statistic's point estimate
    interval: tuple[float, float] | None
    threshold: float | None
    rationale: str | None
    message: str
    span: Span | None = None
    # within the rule's indifference margin of its limit (then neither passed nor failed:
    # ``passed`` is False, ``decided`` True); the margin in SI, 0 when the rule has none
    near: bool = False
    margin: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return _plain_dict(self.__dict__)


@dataclass(frozen=True)
class Verdict:
    """Pass/fail of a path: every rule passes. ``decided`` is True when every rule is decided,
    or when at least one rule fails decidedly or lies within its margin of the limit (the path
    does not pass whatever the undecided rules say); otherwise the verdict is not decided at
    this number of runs (a threshold lies inside a confidence interval)."""

    passed: bool
    decided: bool
    rules: tuple[RuleResult, ...] = field(default=())

    @property
    def failed_rules(self) -> tuple[RuleResult, ...]:
        return tuple(r for r in self.rules if not r.passed)

    @property
    def marginal(self) -> bool:
        """Not passed because some rule is within its margin of the limit, none failing
        decidedly: the path is neither shown to pass nor to fail."""
        return (not self.passed and any(r.near for r in self.rules)
                and not any(not r.passed and r.decided and not r.near for r in self.rules))

    def to_dict(self) -> dict[str, Any]:
        return {"passed": self.passed, "decided": self.decided, "marginal": self.marginal,
                "rules": [r.to_dict() for r in self.rules]}
