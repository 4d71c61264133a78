"""What a run stage is handed: the :class:`RunStage` protocol (the Monte Carlo stage, an
adaptive campaign's looks, the worst-case search) and the types of its arguments, which the
whole simulation shares: the options a campaign is simulated with, the progress it reports to,
each path's plan, the FMU the workers run and the summary of what was simulated."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from idefix_rules.campaign.input.campaign_values import stop_limit
from idefix_rules.campaign.input.load import Campaign, PathSpec
from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.commands import RoverGeometry


class Progress(Protocol):
    """What the simulation reports while it works (the CLI shows it; tests ignore it)."""

    def message(self, text: str) -> None: ...

    def note(self, text: str) -> None:
        """A line said while runs go on (a path stopped, a check given up): it ends nothing,
        unlike :meth:`message`, which starts a new phase."""
        ...

    def start_path(self, name: str, total: int, done: int, failed: int = 0,
                   up_to: bool = False) -> None:
        """Runs of path ``name`` begin: ``total`` planned (``up_to``: at most, an adaptive
        campaign's cap), ``done`` of them stored already (a resumed campaign's), ``failed`` of
        those failed."""
        ...

    def run_finished(self, name: str, ok: bool) -> None: ...


class SilentProgress:
    def message(self, text: str) -> None:
        pass

    def note(self, text: str) -> None:
        pass

    def start_path(self, name: str, total: int, done: int, failed: int = 0,
                   up_to: bool = False) -> None:
        pass

    def run_finished(self, name: str, ok: bool) -> None:
        pass


@dataclass(frozen=True)
class SimulationOptions:
    workers: int | None = None  # None: the campaign's, else all cores
    run_timeout: float | None = None  # None: the default (campaign/simulation/timeouts.py); 0: none
    resume: bool = False
    scheduler: str | None = None  # Dask scheduler address
    dask_local: bool = False


@dataclass
class PathPlan:
    spec: PathSpec
    stop_time: float
    samples: int
    ideal_duration: float
    status: str = "pending"
    reason: str = ""
    reference: dict[str, np.ndarray] | None = None


@dataclass
class SimulationSummary:
    results: Path
    plans: list[PathPlan] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    fmu_seconds: float = 0.0  # summed time workers spent inside FmuRunner.run
    write_seconds: float = 0.0  # time the parent spent storing Monte Carlo runs
    simulated_runs: int = 0
    path_seconds: dict[str, float] = field(default_factory=dict)  # the same, per path


class RunStage(Protocol):
    """What simulates a campaign's runs once the reference runs are stored (the Monte Carlo
    stage by default): it allocates and writes the runs of the ``simulated`` paths into
    ``store``, with :func:`~idefix_rules.campaign.simulation.monte_carlo.run_and_store`."""

    def __call__(self, campaign: Campaign, evaluator: Any, rover: RoverGeometry,
                 fmu: FmuSource, fmu_parameters: Mapping[str, float | str],
                 plans: list[PathPlan], store: ResultStore, options: SimulationOptions,
                 progress: Progress, summary: SimulationSummary, collisions: Any) -> None: ...


def plan_path(campaign: Campaign, spec: PathSpec, rover: RoverGeometry) -> PathPlan:
    return PathPlan(spec, *stop_limit(campaign, spec.chain, rover))


@dataclass(frozen=True)
class FmuSource:
    """The FMU the workers run: its file, the folder it was extracted to once (None: each
    worker extracts it), and the campaign's parameters it has no variable for (the tool's own
    geometry of a foreign FMU: never set in it)."""

    path: str
    unzipped: str | None
    tool_only: frozenset[str] = frozenset()
