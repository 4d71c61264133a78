"""Monte Carlo tasks are made as the pool takes them and a bounded number is held at once,
whatever the number of runs: the parent's memory does not grow with the campaign."""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import campaign_pool_tasks as tasks
import numpy as np
import pytest

from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.runner import run_campaign
from idefix_rules.campaign.simulation import monte_carlo, run_tasks
from idefix_rules.campaign.simulation.dask_pool import DaskPool
from idefix_rules.campaign.simulation.monte_carlo import PlannedRuns
from idefix_rules.campaign.simulation.pool import LocalPool
from idefix_rules.campaign.simulation.run_stage import SimulationOptions


class Drawn:
    """The tasks of ``tasks`` counted as they are taken, and the most taken but not yet
    answered at any time (``answered`` is counted by the caller)."""

    def __init__(self, tasks: Iterable[Any]) -> None:
        self.tasks = iter(tasks)
        self.taken = 0
        self.answered = 0
        self.most_held = 0

    def __iter__(self) -> Iterator[Any]:
        for task in self.tasks:
            self.taken += 1
            yield task

    def answer(self) -> None:
        self.most_held = max(self.most_held, self.taken - self.answered)
        self.answered += 1


def test_planned_runs_make_a_task_only_when_it_is_taken() -> None:
    made: list[tuple[str, int]] = []

    def make(name: str, run: int) -> str:
        made.append((name, run))
        return f"{name}:{run}"

    rows = {"straight": np.arange(10**6), "arc": np.arange(10**6)}
    planned = PlannedRuns(rows, make)
    first = list(itertools.islice(planned, 5))
    assert made == [("arc", 0), ("straight", 0), ("arc", 1), ("straight", 1), ("arc", 2)]
    assert [key for key, _ in first] == made
    assert planned.counts() == {"straight": 10**6, "arc": 10**6}


def test_planned_runs_come_in_the_order_a_sorted_list_of_every_task_had() -> None:
    rows = {"b": np.array([0, 3, 4]), "a": np.array([1, 3]), "c": np.array([], dtype=int)}
    keys = [key for key, _ in PlannedRuns(rows, lambda name, run: None)]
    listed = sorted(((name, int(run)) for name, runs in rows.items() for run in runs),
                    key=lambda key: (key[1], key[0]))
    assert keys == listed


def test_the_local_pool_holds_one_task_per_worker_whatever_the_number_of_tasks() -> None:
    drawn = Drawn((i, i) for i in range(200))
    for _ in LocalPool(tasks.square, workers=2).map(drawn):
        drawn.answer()
    assert drawn.answered == 200
    # per worker one task running and, while the caller stores it, one finished: a worker
    # that finished has its next task before the caller sees the finished one
    assert 3 <= drawn.most_held <= 4


@pytest.mark.slow
def test_dask_holds_a_bounded_window_of_runs_whatever_the_number_of_tasks() -> None:
    drawn = Drawn((i, i) for i in range(120))
    pool = DaskPool(tasks.square, workers=2)
    for _ in pool.map(drawn):
        drawn.answer()
    assert drawn.answered == 120
    assert drawn.most_held <= 2 * 2  # IN_FLIGHT_PER_THREAD per worker thread


def test_a_campaign_makes_its_run_tasks_as_the_workers_take_them(
        campaign_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # Counted where the tasks are made (run_task) and where outcomes come back (the pool's
    # map): a campaign that listed its runs up front would have made all of them before the
    # first outcome.
    made = [0]
    answered = [0]
    most_held = [0]
    real_task = monte_carlo.run_task

    def counted_task(*args: Any, **kwargs: Any) -> Any:
        if kwargs.get("encode"):  # a Monte Carlo run (reference runs are one per path)
            made[0] += 1
        return real_task(*args, **kwargs)

    class Counted(run_tasks.LocalPool):
        def map(self, work: Any) -> Iterator[Any]:
            for key, outcome in super().map(work):
                if isinstance(key, tuple):  # (path, run): a Monte Carlo run's outcome
                    most_held[0] = max(most_held[0], made[0] - answered[0])
                    answered[0] += 1
                yield key, outcome

    monkeypatch.setattr(monte_carlo, "run_task", counted_task)
    monkeypatch.setattr(run_tasks, "LocalPool", Counted)
    text = (campaign_dir / "campaign.yaml").read_text().replace("runs: 6", "runs: 40")
    (campaign_dir / "campaign.yaml").write_text(text)
    result = run_campaign(load_campaign(campaign_dir / "campaign.yaml"),
                          SimulationOptions(workers=2), report=False)
    simulated = [p for p in result.evaluation.paths if p.status == "simulated"]
    assert simulated and all(p.completed == 40 for p in simulated)
    assert made[0] == 40 * len(simulated)
    assert 3 <= most_held[0] <= 4  # per worker one running, one finished being stored
