"""The default run timeout: derived from the simulated duration and the measured reference
cost, rounded to 1-2-5 steps, overridable, 0 disables; and the Dask watch that stops a stuck
campaign instead of waiting forever."""

from __future__ import annotations

import time
from types import SimpleNamespace

import pytest

from idefix_rules.campaign.simulation import dask_pool, timeouts
from idefix_rules.campaign.simulation.dask_pool import ClusterError, _Watch


@pytest.mark.parametrize(("seconds", "expected"), [
    (0.3, 1.0), (1.0, 1.0), (1.01, 2.0), (2.0, 2.0), (2.5, 5.0), (5.0, 5.0), (5.1, 10.0),
    (20.0, 20.0), (20.001, 50.0), (99.9, 100.0), (101.0, 200.0), (4999.0, 5000.0)])
def test_nice_ceiling_rounds_up_to_1_2_5_steps(seconds: float, expected: float) -> None:
    assert timeouts.nice_ceiling(seconds) == expected


def test_a_cheap_fmu_gets_the_floor_and_a_slow_one_a_multiple_of_its_cost() -> None:
    stop = 300.0
    at_floor = timeouts.FLOOR / (timeouts.FACTOR * stop)  # cost where the product is the floor
    assert timeouts.monte_carlo_timeout(stop, at_floor, None) == timeouts.FLOOR
    assert timeouts.monte_carlo_timeout(stop, at_floor * 0.999, None) == timeouts.FLOOR
    assert timeouts.monte_carlo_timeout(stop, at_floor * 1.001, None) == 50.0
    # a longer path gets a longer timeout at the same cost
    assert timeouts.monte_carlo_timeout(3 * stop, at_floor * 2, None) == 200.0


def test_an_explicit_timeout_wins_and_zero_disables_it() -> None:
    assert timeouts.monte_carlo_timeout(300.0, 0.5, 7.0) == 7.0
    assert timeouts.monte_carlo_timeout(300.0, 0.5, 0.0) is None
    assert timeouts.reference_timeout(300.0, 7.0) == 7.0
    assert timeouts.reference_timeout(300.0, 0.0) is None


def test_reference_runs_get_real_time_and_at_least_the_reference_floor() -> None:
    assert timeouts.REFERENCE_FLOOR == 50.0
    assert timeouts.reference_timeout(10.0, None) == 50.0
    assert timeouts.reference_timeout(50.0, None) == 50.0
    assert timeouts.reference_timeout(50.5, None) == 100.0
    # not measured (results of an older version): the reference rule applies to the runs too
    assert timeouts.monte_carlo_timeout(50.5, None, None) == 100.0


def test_the_measured_cost_is_seconds_per_simulated_second_over_all_paths() -> None:
    assert timeouts.measured_cost([(1.0, 100.0), (3.0, 100.0)]) == pytest.approx(0.02)
    assert timeouts.measured_cost([]) is None


def test_monte_carlo_timeouts_read_the_stored_reference_costs() -> None:
    groups = {"a": SimpleNamespace(attrs={timeouts.COST_ATTRIBUTE: 30.0}),
              "b": SimpleNamespace(attrs={})}
    store = SimpleNamespace(has_path=lambda name: True, path_group=lambda name: groups[name])
    plans = {"a": SimpleNamespace(stop_time=10.0), "b": SimpleNamespace(stop_time=40.0)}
    timeout = timeouts.monte_carlo_timeouts(plans, store, None)
    # cost 30 s / 10 s = 3 s per simulated second: 20 x 3 x 10 = 600 s, 20 x 3 x 40 = 2400 s
    assert timeout(("a", 0)) == 1000.0 and timeout(("b", 5)) == 5000.0


class FakeClient:
    def __init__(self, workers: dict[str, object]) -> None:
        self.status = "running"
        self.workers = workers

    def scheduler_info(self, n_workers: int = -1) -> dict[str, object]:
        return {"workers": self.workers}


def test_the_watch_stops_a_cluster_without_workers(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(dask_pool, "HEALTH_CHECK", 0.0)
    monkeypatch.setattr(dask_pool, "NO_WORKER_GRACE", 0.2)
    watch = _Watch(FakeClient({}), stall=None)
    watch.check()  # no workers seen for the first time: not yet
    time.sleep(0.3)
    with pytest.raises(ClusterError, match="no worker for 0 s"):
        watch.check()
    healthy = _Watch(FakeClient({"tcp://w": {}}), stall=None)
    healthy.check()
    time.sleep(0.3)
    healthy.check()  # workers there: waiting is fine without a stall limit


def test_the_watch_stops_a_campaign_where_no_run_finishes() -> None:
    watch = _Watch(FakeClient({"tcp://w": {}}), stall=0.2)
    watch.check()
    watch.progress()
    time.sleep(0.3)
    with pytest.raises(ClusterError, match="no run finished on the Dask cluster"):
        watch.check()


def test_the_watch_stops_when_the_scheduler_is_lost(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(dask_pool, "HEALTH_CHECK", 0.0)
    client = FakeClient({"tcp://w": {}})
    client.status = "closed"
    with pytest.raises(ClusterError, match="lost the connection"):
        _Watch(client, stall=None).check()
