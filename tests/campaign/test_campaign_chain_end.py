"""Runs end with their chain; a run stopped at the limit before its chain was done is flagged,
counted and reported, and a rulebook can judge it (built-in rover)."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest
from test_campaign_robustness import assert_same_datasets

from idefix_rules.cli import main

pytestmark = pytest.mark.slow

# Stop limit = ideal duration + 12 s. The straight (ideal 20 s) ends after its ramps and slip,
# well before 32 s. The 60° point turn (ideal 54.5 s) needs at least its ramp time (3.3 s) more
# than the 2 s its margin leaves, and closed loop about 1.85 × its ideal time: every run is still
# turning at the limit, 66.5 s.
CAMPAIGN = """\
name: chain-end
rulebook: end.rules
output: out
runs: 3
workers: 1
uncertainty:
  method: monte_carlo
  seed: 3
  parameters:
    initial.x: {distribution: normal, mean: "0 m", std: "1 cm"}
    initial.y: {distribution: normal, mean: "0 m", std: "1 cm"}
paths:
  straight:
    - {max_wheel_rate: "0.05 rad/s", delta_position: "0.1 m", delta_heading: "0 deg"}
  turn:
    - {max_wheel_rate: "0.05 rad/s", delta_position: "0 m", delta_heading: "60 deg"}
simulation:
  output_interval: "0.5 s"
  duration_margin: 1.0
  extra_time: "12 s"
"""

# The rulebook language cannot name the 'command' signal ('command' starts a command rule):
# after its chain the rover stands with its motors off, so wheels still turning in the last
# sample say the run was stopped before its chain was done.
RULEBOOK = """\
rulebook "chain-end" version "1.0.0"
purpose "Judges runs stopped before their chain was done"

index I_s "slip" {
  value  = max over time (max over wheels (abs(wheel.slip)))
  limit  = 100 %
  weight = 1
  because "Slip"
}

chance still_driving = final over time (max over wheels (abs(wheel.rate))) > 0 rad/s
  because "A run stopped at the limit before its chain was done"

verdict chains_finish: require chance(still_driving) <= 0 %
  because "Every run must end its chain"
"""


@pytest.fixture
def chain_end_dir(tmp_path: Path) -> Path:
    (tmp_path / "campaign.yaml").write_text(CAMPAIGN)
    (tmp_path / "end.rules").write_text(RULEBOOK)
    return tmp_path


def run(folder: Path, out: str, monkeypatch: pytest.MonkeyPatch, *options: str) -> int:
    monkeypatch.setenv("COLUMNS", "200")
    return main([str(folder / "campaign.yaml"), "--out", str(folder / out), "--quiet",
                 "--no-report", *options])


def test_runs_stopped_at_the_limit_are_flagged_counted_and_judged(
        chain_end_dir: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    assert run(chain_end_dir, "out", monkeypatch) == 1  # the turn fails chains_finish
    console = capsys.readouterr().out
    assert ("turn: 3 of 3 runs were still driving at the stop limit (66.5 s): their time is the "
            "limit, not the chain's duration") in console
    assert "straight: 3 of 3" not in console and "straight: 0 of" not in console

    summary = json.loads((chain_end_dir / "out" / "summary.json").read_text())
    paths = {record["name"]: record for record in summary["paths"]}
    assert paths["straight"]["unfinished_runs"] == 0
    assert paths["straight"]["stop_time_s"] == 32.0
    assert paths["straight"]["time_s"] < 30.0
    assert paths["turn"]["unfinished_runs"] == 3
    assert paths["turn"]["stop_time_s"] == paths["turn"]["time_s"] == 66.5
    assert paths["turn"]["verdict"] == "fail"
    # the rulebook's chance counts the same runs
    assert paths["turn"]["chances"]["still_driving"] == 1.0
    assert paths["straight"]["chances"]["still_driving"] == 0.0

    with h5py.File(chain_end_dir / "out" / "results.h5") as results:
        straight = results["paths/straight"]
        turn = results["paths/turn"]
        np.testing.assert_array_equal(straight["evaluation/finished"][()], [1, 1, 1])
        np.testing.assert_array_equal(turn["evaluation/finished"][()], [0, 0, 0])
        np.testing.assert_array_equal(turn["evaluation/time"][()], 66.5)
        # a finished run's samples after the step past its chain's end hold that step
        command = straight["runs/signals/command"][0]
        x = straight["runs/signals/x"][0]
        held = int(np.argmax(command == -1)) + 1
        assert held < command.size - 1
        np.testing.assert_array_equal(x[held:], x[held])
        assert np.all(straight["runs/signals/wheel.rate"][0, held:] == 0.0)
        np.testing.assert_array_equal(straight["runs/signals/t"][0],
                                      straight["reference/signals/t"][()])
        assert straight["runs/signals/t"][0, -1] == pytest.approx(32.0)


def test_the_report_counts_the_runs_stopped_at_the_limit(
        chain_end_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from idefix_rules.campaign.storage.store import ResultStore
    from idefix_rules.report import write_report
    from idefix_rules.report.reading import read_path

    assert run(chain_end_dir, "out", monkeypatch) == 1
    results = chain_end_dir / "out" / "results.h5"
    page = write_report(results, chain_end_dir / "report").read_text(encoding="utf-8")
    assert "turn: 3 of 3 runs were still driving at the stop limit (66.5 s)" in page
    assert "straight: 0 of" not in page
    # without the stored summary the report counts them from the evaluation's datasets
    store = ResultStore.open(results)
    try:
        rows = {name: read_path(name, store.path_group(name), {}).row
                for name in ("straight", "turn")}
    finally:
        store.close()
    assert (rows["straight"].unfinished_runs, rows["turn"].unfinished_runs) == (0, 3)
    assert rows["turn"].stop_time_s == 66.5


def test_runs_ending_with_their_chain_store_the_same_datasets_on_one_and_two_workers(
        chain_end_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    assert run(chain_end_dir, "one", monkeypatch, "--workers", "1") == 1
    assert run(chain_end_dir, "two", monkeypatch, "--workers", "2") == 1
    assert_same_datasets(chain_end_dir / "one" / "results.h5",
                         chain_end_dir / "two" / "results.h5")


# The samples a finished run holds to the end of its grid are the rover standing still; the
# counting reducers count only the run's own samples, so a longer stop limit changes nothing a
# run scores (docs/rulebook-language.md, "A run's own samples").
COUNTING_RULEBOOK = """\
rulebook "own-samples" version "1.0.0"
purpose "Counting reducers over a run's own samples"

index I_s "sustained slip" {
  value  = percentile 90 over time (max over wheels (abs(wheel.slip)))
  limit  = 100 %
  weight = 1
  because "Slip"
}

index I_rate "mean wheel rate" {
  value  = mean over time (max over wheels (abs(wheel.rate)))
  limit  = 0.1 rad/s
  weight = 1
  because "Rate"
}

chance often_turning = fraction over time (max over wheels (abs(wheel.rate)) > 0.01 rad/s) > 50 %
  because "Wheels turning for most of the run"

verdict mostly_driving: require chance(often_turning) <= 100 %
  because "Always holds"
"""


def test_a_longer_stop_limit_changes_nothing_a_finished_run_scores(
        chain_end_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (chain_end_dir / "end.rules").write_text(COUNTING_RULEBOOK)
    text = CAMPAIGN.replace("  duration_margin: 1.0\n", "  duration_margin: 3.0\n")
    (chain_end_dir / "campaign.yaml").write_text(text)
    assert run(chain_end_dir, "short", monkeypatch) == 0
    (chain_end_dir / "campaign.yaml").write_text(text.replace("duration_margin: 3.0",
                                                              "duration_margin: 6.0"))
    assert run(chain_end_dir, "long", monkeypatch) == 0
    values = {}
    for out in ("short", "long"):
        with h5py.File(chain_end_dir / out / "results.h5", "r") as results:
            for path in ("straight", "turn"):
                evaluation = results[f"paths/{path}/evaluation"]
                assert evaluation["finished"][()].all()  # every run ended its chain
                samples = results[f"paths/{path}/runs/signals/t"].shape[1]
                values[out, path] = (samples, evaluation["raw/I_s"][()],
                                     evaluation["raw/I_rate"][()],
                                     evaluation["chances/often_turning"][()],
                                     evaluation["time"][()])
    for path in ("straight", "turn"):
        short, long = values["short", path], values["long", path]
        assert long[0] > 1.5 * short[0]  # the longer grid holds many more samples after the end
        for got, want in zip(long[1:], short[1:], strict=True):
            np.testing.assert_array_equal(got, want)
        assert np.all(short[2] > 0.01)  # the mean rate is not a trivial 0
