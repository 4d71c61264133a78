"""An FMU that returns fmi2Fatal in one run. FMI 2.0.x section 2.1.3: "the model computations
are irreparably corrupted for all FMU instances … It is not possible to call any other
function for any of the FMU instances": that run fails with the FMU's own message, and the
process it ran in runs nothing more (the toy FMU corrupts what its instances share, so a later
run there would slip more than asked). Every other run gives the same numbers with one worker
as with two, and the numbers its parameters ask for."""

from __future__ import annotations

import re
from pathlib import Path

import h5py
import numpy as np
import pytest
from campaign_texts import CAMPAIGN
from test_campaign_robustness import assert_same_datasets, copy_campaign

from idefix_rules.campaign.storage.store import STATUS_COMPLETE, STATUS_FAILED
from idefix_rules.cli import main

pytestmark = pytest.mark.slow

TOO_FAST = ("  too-fast:\n    - {max_wheel_rate: \"0.5 rad/s\", delta_position: \"0.1 m\", "
            "delta_heading: \"0 deg\"}\n")
# Seed 55: of 8 paired runs only run 1 draws a fatal time within what is simulated of a path,
# and only of arc's (about 34 s; straight's runs end after about 11 s). Runs go to the workers
# in the order (0, arc), (0, straight), (1, arc) …: the worker of the fatal run would take
# later runs.
FATAL = CAMPAIGN.replace("runs: 6", "runs: 8").replace("seed: 5", "seed: 55") \
    .replace(TOO_FAST, "") \
    .replace("    toy.slip:", '    toy.fatal_at: {distribution: uniform, low: "1 s", '
                               'high: "300 s"}\n    toy.slip:')
FATAL_RUN = ("arc", 1)
REASON = re.compile(r"InfrastructureError: toy\.fmu: fmi2DoStep failed at t = (?P<step>[\d.]+) "
                    r"s \(status 4\): toy: slip table corrupted at t = (?P<at>[\d.]+) s")


def outcomes(results: Path) -> dict[tuple[str, int], tuple[int, str]]:
    """``(path, run) → (status, failure reason)`` of every Monte Carlo run."""
    found = {}
    with h5py.File(results) as stored:
        for name in ("straight", "arc"):
            runs = stored[f"paths/{name}/runs"]
            reasons = [r.rstrip(b"\0").decode() for r in runs["failure"][()]]
            for run, state in enumerate(runs["status"][()]):
                found[(name, run)] = (int(state), reasons[run])
    return found


def run_on_one_and_two_workers(campaign_dir: Path, tmp_path: Path, text: str,
                               exit_code: int) -> tuple[Path, Path]:
    """The campaign ``text`` run with one worker and with two (each must exit ``exit_code``);
    their results files."""
    found = []
    for workers in (1, 2):
        path = copy_campaign(campaign_dir, tmp_path / f"workers-{workers}",
                             text.replace("workers: 2", f"workers: {workers}"))
        assert main([str(path), "--quiet", "--no-report"]) == exit_code
        found.append(path.parent / "out" / "results.h5")
    return found[0], found[1]


def test_a_fatal_run_fails_alone_and_its_worker_runs_nothing_more(
        campaign_dir: Path, tmp_path: Path) -> None:
    # the fatal run is a failed run of arc, and a path with failed runs cannot pass
    one, two = run_on_one_and_two_workers(campaign_dir, tmp_path, FATAL, exit_code=1)
    for results in (one, two):
        found = outcomes(results)
        status, reason = found.pop(FATAL_RUN)
        assert status == STATUS_FAILED
        match = REASON.fullmatch(reason)
        assert match is not None, reason
        with h5py.File(results) as stored:
            fatal_at = float(stored["paths/arc/runs/parameters/toy.fatal_at"][FATAL_RUN[1]])
            # no other run crashed or failed, and each slipped as its parameter says
            for (name, run), (status, reason) in found.items():
                assert status == STATUS_COMPLETE, (name, run, reason)
                runs = stored[f"paths/{name}/runs"]
                slip = float(runs["parameters/toy.slip"][run])
                assert float(np.max(runs["signals/wheel.slip"][run])) == \
                    pytest.approx(slip, rel=1e-6), (name, run)
        assert float(match["step"]) < fatal_at <= float(match["at"])
    assert_same_datasets(one, two)



# Every run complete: the toy's reset fails after a run that slipped more than 0.2 (about
# one run in four of toy.slip's 0.05 … 0.25), which is what that run left, not the next run's
# doing: the next run is simulated all the same (Error: by a fresh instance in the process;
# Fatal: by a fresh process), and which worker ran what changes nothing.
RESET_FAILS = CAMPAIGN.replace("runs: 6", "runs: 8").replace(TOO_FAST, "") \
    .replace("    toy.slip:", "    toy.reset_fails_above: {distribution: fixed, value: 0.2}\n"
                               "    toy.slip:")


@pytest.mark.parametrize("status", ["3", "4"])
def test_a_reset_failing_after_a_run_is_not_the_next_run_s_failure(
        campaign_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        status: str) -> None:
    monkeypatch.setenv("TOY_RESET_STATUS", status)
    # 8 runs decide no verdict of this rulebook: exit 1, as without the failing resets
    one, two = run_on_one_and_two_workers(campaign_dir, tmp_path, RESET_FAILS, exit_code=1)
    for results in (one, two):
        found = outcomes(results)
        assert {state for state, _ in found.values()} == {STATUS_COMPLETE}, found
        with h5py.File(results) as stored:
            slips = np.concatenate([stored[f"paths/{name}/runs/parameters/toy.slip"][()]
                                    for name in ("straight", "arc")])
            assert (slips > 0.2).sum() >= 2  # the precondition: resets do fail
            for name in ("straight", "arc"):
                runs = stored[f"paths/{name}/runs"]
                for run in range(8):  # each slipped as its parameter says, none corrupted
                    assert float(np.max(runs["signals/wheel.slip"][run])) == pytest.approx(
                        float(runs["parameters/toy.slip"][run]), rel=1e-6), (name, run)
    assert_same_datasets(one, two)
