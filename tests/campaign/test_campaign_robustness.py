"""Determinism, resume after a kill, and runs that crash, hang or fail inside the FMU."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import h5py
import numpy as np
import pytest
from campaign_texts import CAMPAIGN

from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.runner import run_campaign
from idefix_rules.campaign.simulation.run_stage import SimulationOptions
from idefix_rules.campaign.storage.store import STATUS_COMPLETE, STATUS_MISSING

pytestmark = pytest.mark.slow


def datasets(path: Path) -> dict[str, np.ndarray]:
    """Every dataset under /paths (simulation and evaluation), by its HDF5 name."""
    found: dict[str, np.ndarray] = {}
    with h5py.File(path) as results:
        def visit(name: str, item: object) -> None:
            if isinstance(item, h5py.Dataset):
                found[name] = item[()]
        results["paths"].visititems(visit)
    return found


def assert_same_datasets(first: Path, second: Path) -> None:
    a, b = datasets(first), datasets(second)
    assert a.keys() == b.keys()
    for name in a:
        if a[name].dtype.kind == "f":
            assert np.array_equal(a[name], b[name], equal_nan=True), name
        else:
            assert np.array_equal(a[name], b[name]), name


def copy_campaign(source: Path, target: Path, text: str = CAMPAIGN) -> Path:
    target.mkdir()
    for name in ("toy.fmu", "test.rules"):
        (target / name).write_bytes((source / name).read_bytes())
    (target / "campaign.yaml").write_text(text)
    return target / "campaign.yaml"


def test_one_worker_and_two_workers_give_identical_datasets(campaign_dir: Path,
                                                            tmp_path: Path) -> None:
    one = load_campaign(campaign_dir / "campaign.yaml").with_overrides(
        output=tmp_path / "one", workers=1)
    two = load_campaign(campaign_dir / "campaign.yaml").with_overrides(
        output=tmp_path / "two", workers=2)
    run_campaign(one, SimulationOptions(workers=1), report=False)
    run_campaign(two, SimulationOptions(workers=2), report=False)
    assert_same_datasets(tmp_path / "one" / "results.h5", tmp_path / "two" / "results.h5")
    # and the runs differ from each other: the parameters really were sampled
    x = datasets(tmp_path / "one" / "results.h5")["straight/runs/signals/x"]
    assert len({row[-1] for row in x}) == x.shape[0]


KILLER = textwrap.dedent("""\
    import os, signal, sys
    from pathlib import Path
    from idefix_rules.campaign.input.load import load_campaign
    from idefix_rules.campaign.runner import run_campaign
    from idefix_rules.campaign.simulation.run_stage import SimulationOptions

    class KillAfter:
        seen = 0
        def message(self, text): pass
        def note(self, text): pass
        def start_path(self, name, total, done, failed=0, up_to=False): pass
        def run_finished(self, name, ok):
            self.seen += 1
            if self.seen == int(sys.argv[2]):
                os.kill(os.getpid(), signal.SIGKILL)

    # optional: argv[3] another seed, argv[4] a JUnit file
    campaign = load_campaign(sys.argv[1])
    if len(sys.argv) > 3:
        campaign = campaign.with_overrides(seed=int(sys.argv[3]))
    junit = Path(sys.argv[4]) if len(sys.argv) > 4 else None
    run_campaign(campaign, SimulationOptions(workers=2), progress=KillAfter(), report=False,
                 junit=junit)
""")


def test_a_killed_campaign_resumes_to_the_same_result(campaign_dir: Path,
                                                      tmp_path: Path) -> None:
    text = CAMPAIGN.replace("runs: 6", "runs: 10")
    killed = copy_campaign(campaign_dir, tmp_path / "killed", text)
    whole = copy_campaign(campaign_dir, tmp_path / "whole", text)
    script = tmp_path / "killer.py"
    script.write_text(KILLER)
    # a killed campaign cannot remove its FMU extraction: keep it in the test's own folder
    process = subprocess.run([sys.executable, str(script), str(killed), "7"],
                             capture_output=True, text=True, timeout=120,
                             env={**os.environ, "TMPDIR": str(tmp_path)})
    assert process.returncode == -9, process.stderr
    results = killed.parent / "out" / "results.h5"
    with h5py.File(results) as partial:
        assert partial.attrs["state"] == "running"  # killed: never marked complete
        status = np.concatenate([partial[f"paths/{p}/runs/status"][()]
                                 for p in ("straight", "arc")])
        assert np.sum(status == STATUS_COMPLETE) == 7
        assert np.sum(status == STATUS_MISSING) == 13

    resumed = run_campaign(load_campaign(killed), SimulationOptions(resume=True), report=False)
    uninterrupted = run_campaign(load_campaign(whole), report=False)
    assert resumed.exit_code == uninterrupted.exit_code
    assert_same_datasets(results, whole.parent / "out" / "results.h5")
    with h5py.File(results) as finished:
        assert finished.attrs["state"] == "complete"
        assert len(json.loads(finished.attrs["resumed"])) == 1


def test_a_run_whose_status_is_not_complete_is_never_read_as_data(campaign_dir: Path) -> None:
    campaign = load_campaign(campaign_dir / "campaign.yaml")
    run_campaign(campaign, report=False)
    results = campaign.output / "results.h5"
    original = datasets(results)
    with h5py.File(results, "r+") as stored:
        # A run cut off mid-write: data half there, status never set.
        stored["paths/arc/runs/signals/x"][3, :5] = 1e9
        stored["paths/arc/runs/status"][3] = STATUS_MISSING
    run_campaign(campaign, SimulationOptions(resume=True), report=False)
    assert_same_datasets_dicts(original, datasets(results))


def assert_same_datasets_dicts(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> None:
    assert a.keys() == b.keys()
    for name in a:
        assert np.array_equal(a[name], b[name], equal_nan=a[name].dtype.kind == "f"), name


def test_resume_refuses_results_of_another_campaign(campaign_dir: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    from idefix_rules.cli import main

    path = campaign_dir / "campaign.yaml"
    assert main([str(path), "--quiet", "--no-report"]) == 1
    assert main([str(path), "--quiet", "--no-report", "--resume", "--runs", "7"]) == 2
    assert "cannot resume" in capsys.readouterr().err


def test_resume_refuses_a_rulebook_edited_since_the_campaign_started(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Its command rules and prescreen decided which paths were simulated: a tighter wheel-rate
    rule would forbid the chain that was simulated under the old one. Nothing is changed, and
    the message says how to score the stored runs with the new rulebook instead."""
    from idefix_rules.cli import main

    path = campaign_dir / "campaign.yaml"
    rulebook = campaign_dir / "test.rules"
    assert main([str(path), "--quiet", "--no-report"]) == 1
    results = campaign_dir / "out" / "results.h5"
    before = datasets(results)
    with h5py.File(results) as stored:
        resumed = stored.attrs["resumed"]
    capsys.readouterr()
    original = rulebook.read_text()
    rulebook.write_text(original.replace("<= 0.2 rad/s", "<= 0.01 rad/s"))
    assert main([str(path), "--quiet", "--no-report", "--resume"]) == 2
    err = capsys.readouterr().err
    assert "error[H010]: cannot resume" in err
    assert "started with rulebook campaign-test 0.1.0" in err
    assert "is campaign-test 0.1.0, edited since" in err
    assert f"idefix-verify evaluate {results} --rulebook {rulebook}" in err
    assert "Traceback" not in err
    after = datasets(results)
    assert after.keys() == before.keys()
    for name, values in before.items():
        assert np.array_equal(values, after[name], equal_nan=values.dtype.kind == "f"), name
    with h5py.File(results) as stored:
        assert stored.attrs["resumed"] == resumed  # the refused attempt left no trace
    # the rulebook it started with: resumed as before
    rulebook.write_text(original)
    assert main([str(path), "--quiet", "--no-report", "--resume"]) == 1


def simulated_until(group: h5py.Group) -> float:
    """How far the toy FMU's runs of a path are simulated: one step past the chain's end (the
    FMU is not stepped after it), read from the reference run, as the toy's timing does not
    depend on the sampled parameters. A fault at a later time never strikes."""
    command = group["reference/signals/command"][()]
    return float(group["reference/signals/t"][int(np.argmax(command == -1)) + 1])


# Seed 5 (the campaign's own): runs among the 16 crash, hang and fail before their chain ends
# (with paired draws both paths share them; seed 1 had all three only across unpaired paths).
FAULTS = CAMPAIGN.replace("runs: 6", "runs: 16") \
    .replace("  too-fast:\n    - {max_wheel_rate: \"0.5 rad/s\", delta_position: \"0.1 m\", "
             "delta_heading: \"0 deg\"}\n", "") \
    .replace("    toy.slip:", """\
    toy.crash_at: {distribution: uniform, low: "1 s", high: "100 s"}
    toy.hang_at: {distribution: uniform, low: "1 s", high: "100 s"}
    toy.error_at: {distribution: uniform, low: "1 s", high: "100 s"}
    toy.slip:""")


def test_crashing_hanging_and_failing_runs_are_recorded_and_the_campaign_goes_on(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from idefix_rules.cli import main

    (campaign_dir / "campaign.yaml").write_text(FAULTS)
    code = main([str(campaign_dir / "campaign.yaml"), "--quiet", "--no-report",
                 "--run-timeout", "2"])
    out = capsys.readouterr().out
    assert code == 1  # a path with failed runs cannot pass
    expected_kinds = set()
    with h5py.File(campaign_dir / "out" / "results.h5") as results:
        for name in ("straight", "arc"):
            group = results[f"paths/{name}"]
            stop = simulated_until(group)
            status = group["runs/status"][()]
            reasons = [r.rstrip(b"\0").decode() for r in group["runs/failure"][()]]
            params = {k: group[f"runs/parameters/toy.{k}_at"][()]
                      for k in ("crash", "hang", "error")}
            for run in range(16):
                times = {kind: float(values[run]) for kind, values in params.items()}
                first = min(times, key=lambda kind: times[kind])
                if times[first] > stop:
                    assert status[run] == STATUS_COMPLETE, (name, run, reasons[run])
                    continue
                expected_kinds.add(first)
                assert status[run] == 2, (name, run)
                fragment = {"crash": "SIGSEGV", "hang": "run timeout of 2 s",
                            "error": "fmi2DoStep failed"}[first]
                assert fragment in reasons[run], (name, run, reasons[run])
                assert np.all(np.isnan(group["runs/signals/x"][run]))
            assert np.any(status == STATUS_COMPLETE)
    assert expected_kinds == {"crash", "hang", "error"}
    summary = json.loads((campaign_dir / "out" / "summary.json").read_text())
    for record in summary["paths"]:
        assert record["failed_runs"] > 0
        assert record["verdict"] == "fail"
        assert len(record["failures"]) == record["failed_runs"]
    assert "failed" in out


def test_a_local_dask_cluster_gives_the_same_datasets_as_the_process_pool(
        campaign_dir: Path, tmp_path: Path) -> None:
    pooled = load_campaign(campaign_dir / "campaign.yaml").with_overrides(
        output=tmp_path / "pool")
    dask = load_campaign(campaign_dir / "campaign.yaml").with_overrides(
        output=tmp_path / "dask")
    run_campaign(pooled, report=False)
    run_campaign(dask, SimulationOptions(dask_local=True, workers=2), report=False)
    assert_same_datasets(tmp_path / "pool" / "results.h5", tmp_path / "dask" / "results.h5")


class InterruptAfter:
    """Progress that presses Ctrl-C (raises KeyboardInterrupt) after some finished runs."""

    def __init__(self, runs: int) -> None:
        self.runs = runs
        self.seen = 0

    def message(self, text: str) -> None:
        pass

    def note(self, text: str) -> None:
        pass

    def start_path(self, name: str, total: int, done: int, failed: int = 0,
                   up_to: bool = False) -> None:
        pass

    def run_finished(self, name: str, ok: bool) -> None:
        self.seen += 1
        if self.seen == self.runs:
            raise KeyboardInterrupt


def test_an_interrupted_campaign_is_marked_and_resumes_to_the_same_result(
        campaign_dir: Path, tmp_path: Path) -> None:
    whole = copy_campaign(campaign_dir, tmp_path / "whole")
    campaign = load_campaign(campaign_dir / "campaign.yaml")
    with pytest.raises(KeyboardInterrupt):
        run_campaign(campaign, progress=InterruptAfter(5), report=False)
    results = campaign.output / "results.h5"
    with h5py.File(results) as partial:
        assert partial.attrs["state"] == "interrupted"
        assert partial.attrs["finished"] == ""
    run_campaign(campaign, SimulationOptions(resume=True), report=False)
    run_campaign(load_campaign(whole), report=False)
    assert_same_datasets(results, whole.parent / "out" / "results.h5")



def test_a_resumed_campaign_counts_its_stored_failed_runs_in_its_progress(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Runs that failed before the interruption are kept (their own failure, not the
    infrastructure's): the progress says so, and its counts of failed runs are the file's."""
    from idefix_rules.cli import main

    failing = CAMPAIGN.replace("runs: 6", "runs: 16").replace("    toy.slip:", """\
    toy.error_at: {distribution: uniform, low: "1 s", high: "100 s"}
    toy.slip:""")
    (campaign_dir / "campaign.yaml").write_text(failing)
    campaign = load_campaign(campaign_dir / "campaign.yaml")
    with pytest.raises(KeyboardInterrupt):
        run_campaign(campaign, progress=InterruptAfter(20), report=False)
    results = campaign.output / "results.h5"
    with h5py.File(results) as partial:
        stored = {name: partial[f"paths/{name}/runs/status"][()] for name in ("straight", "arc")}
    kept = {name: int(np.sum(status == 2)) for name, status in stored.items()}
    assert sum(kept.values()) > 0, kept  # failures stored before the Ctrl-C
    capsys.readouterr()
    assert main([str(campaign_dir / "campaign.yaml"), "--no-report", "--resume"]) == 1
    out = capsys.readouterr().out
    with h5py.File(results) as whole:
        failed = {name: int(np.sum(whole[f"paths/{name}/runs/status"][()] == 2))
                  for name in ("straight", "arc")}
    assert all(failed[name] > kept[name] for name in failed), (kept, failed)  # some new, too
    for name, status in stored.items():
        done = int(np.sum(status != STATUS_MISSING))
        assert f"{name}: {done}/16 runs stored already ({kept[name]} failed), {16 - done} to " \
               "simulate" in out, out
        assert f"{name}: 16/16 runs (100 %), {failed[name]} failed, " in out, out
    assert f"Monte Carlo runs of 2 path(s): 32 runs, {sum(failed.values())} failed (" in out



def test_an_adaptive_resume_counts_as_failed_only_the_runs_it_keeps(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Runs lost to the infrastructure are simulated again, so they are neither stored
    nor failed when the progress starts; its counts end at the file's."""
    from idefix_rules.cli import main

    adaptive = CAMPAIGN.replace("runs: 6", "runs: auto\nmax_runs: 200\nmin_runs: 10\n"
                                "batch_runs: 16").replace("workers: 2", "workers: 1")
    (campaign_dir / "campaign.yaml").write_text(adaptive)
    campaign = load_campaign(campaign_dir / "campaign.yaml")
    with pytest.raises(KeyboardInterrupt):
        run_campaign(campaign, progress=InterruptAfter(20), report=False)
    results = campaign.output / "results.h5"
    with h5py.File(results, "r+") as stored:
        status = stored["paths/straight/runs/status"]
        lost = np.flatnonzero(status[()] == STATUS_COMPLETE)[:2]
        for run in lost:
            status[run] = 2
            stored["paths/straight/runs/failure"][run] = \
                b"infrastructure: killed by SIGKILL 3 times"
        kept = int(np.sum(status[()] != STATUS_MISSING)) - len(lost)
    capsys.readouterr()
    main([str(campaign_dir / "campaign.yaml"), "--no-report", "--resume"])
    out = capsys.readouterr().out
    assert f"straight: {kept}/200 runs stored already, up to {200 - kept} more as its looks " \
        "decide" in out, out
    with h5py.File(results) as stored:
        failed = int(np.sum(stored["paths/straight/runs/status"][()] == 2))
    assert failed == 0  # the lost runs ran again, and completed
    [summary] = [line for line in out.splitlines() if line.startswith("Monte Carlo runs of")]
    assert "failed" not in summary, summary


def test_a_rerun_without_resume_says_first_what_it_sets_aside_and_how_to_resume(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from idefix_rules.campaign.simulation.resume import interrupted_runs
    from idefix_rules.cli import main

    campaign = load_campaign(campaign_dir / "campaign.yaml")
    with pytest.raises(KeyboardInterrupt):
        run_campaign(campaign, progress=InterruptAfter(5), report=False)
    results = campaign.output / "results.h5"
    stored, planned = interrupted_runs(results) or (-1, -1)
    assert 0 < stored < planned
    capsys.readouterr()
    code = main([str(campaign_dir / "campaign.yaml"), "--no-report"])
    out = capsys.readouterr().out
    assert code == 1  # too-fast breaks the command rule wheel_rate_limit: rejected, exit 1
    words = " ".join(out.split())
    note = (f"note: {results} held an interrupted campaign ({stored} of {planned} Monte Carlo "
            "runs stored): it is set aside as results.previous.h5 and this run starts from "
            "zero; to continue it instead, stop now (Ctrl-C), rename it back to results.h5 "
            f"and run `idefix-verify {campaign_dir / 'campaign.yaml'} --resume --out "
            f"{campaign.output} --runs 6 --seed 5 --no-report`")  # and this command's options
    assert note in words
    assert words.index(note) < words.index("compiling the rulebook")  # before it starts
    assert (campaign.output / "results.previous.h5").is_file()
    assert interrupted_runs(results) is None  # complete now: a rerun says nothing
    code = main([str(campaign_dir / "campaign.yaml"), "--no-report", "--quiet"])
    assert code == 1  # too-fast rejected again
    assert "interrupted campaign" not in capsys.readouterr().out
    # with --resume nothing is set aside, so nothing is said
    with pytest.raises(KeyboardInterrupt):
        run_campaign(campaign, progress=InterruptAfter(5), report=False)
    assert main([str(campaign_dir / "campaign.yaml"), "--no-report", "--quiet",
                 "--resume"]) == 1  # too-fast rejected again
    assert "interrupted campaign" not in capsys.readouterr().out


def test_the_command_that_continues_an_interrupted_campaign_has_its_runs_and_seed(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A run with other --runs and --seed finds the interrupted campaign: the command it
    suggests continues that campaign (its 6 runs, seed 5), not this command's (H010)."""
    from idefix_rules.cli import main

    campaign = load_campaign(campaign_dir / "campaign.yaml")
    with pytest.raises(KeyboardInterrupt):
        run_campaign(campaign, progress=InterruptAfter(5), report=False)
    results = campaign.output / "results.h5"
    capsys.readouterr()
    assert main([str(campaign_dir / "campaign.yaml"), "--no-report", "--quiet",
                 "--runs", "4", "--seed", "9"]) == 1  # too-fast rejected
    words = " ".join(capsys.readouterr().out.split())
    again = (f"idefix-verify {campaign_dir / 'campaign.yaml'} --resume --out {campaign.output} "
             "--runs 6 --seed 5 --no-report")  # the stored runs and seed, this command's options
    assert f"rename it back to results.h5 and run `{again}`" in words, words
    (campaign.output / "results.previous.h5").replace(results)
    code = main([*again.split()[1:], "--quiet"])
    captured = capsys.readouterr()
    words = " ".join((captured.out + captured.err).split())
    assert code == 1 and "H010" not in words  # continued: too-fast is rejected, as before
    with h5py.File(results) as continued:
        assert continued.attrs["state"] == "complete" and continued.attrs["runs"] == 6


def test_diff_of_an_interrupted_campaign_warns_as_evaluate_does(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from diff_warnings import diff_warnings

    campaign = load_campaign(campaign_dir / "campaign.yaml")
    with pytest.raises(KeyboardInterrupt):
        run_campaign(campaign, progress=InterruptAfter(5), report=False)
    said = (f"{campaign.output / 'results.h5'} holds a campaign that is interrupted: runs never "
            f"simulated count as failed; continue it with `idefix-verify "
            f"{campaign_dir / 'campaign.yaml'} --resume --out {campaign.output} --runs 6 "
            "--seed 5`")
    words, warnings = diff_warnings(campaign_dir / "test.rules",
                                    campaign.output / "results.h5", capsys)
    assert f"warning: {said}" in words and said in warnings


def test_a_path_cut_off_before_its_runs_were_allocated_is_started_again(
        campaign_dir: Path) -> None:
    campaign = load_campaign(campaign_dir / "campaign.yaml")
    run_campaign(campaign, report=False)
    results = campaign.output / "results.h5"
    original = datasets(results)
    with h5py.File(results, "r+") as stored:
        arc = stored["paths/arc"]
        arc.attrs["status"] = "pending"  # killed between its reference run and the pre-screen
        del arc["runs"]
        straight = stored["paths/straight/runs"]
        del straight["status"]  # killed while its run datasets were being created
    run_campaign(campaign, SimulationOptions(resume=True), report=False)
    assert_same_datasets_dicts(original, datasets(results))


def test_when_every_reference_run_fails_it_is_an_infrastructure_error(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from idefix_rules.cli import main

    crash = '    toy.crash_at: {distribution: fixed, value: "1 s"}\n'
    text = CAMPAIGN.replace("    toy.slip:", crash + "    toy.slip:")
    (campaign_dir / "campaign.yaml").write_text(text)
    assert main([str(campaign_dir / "campaign.yaml"), "--quiet", "--no-report"]) == 3
    err = capsys.readouterr().err
    assert "every reference run failed" in err and "SIGSEGV" in err
    assert "Traceback" not in err
    # resumed, the stored campaign is in the same state: the same answer (it said exit 1)
    assert main([str(campaign_dir / "campaign.yaml"), "--quiet", "--no-report",
                 "--resume"]) == 3
    err = capsys.readouterr().err
    assert "every reference run failed" in err and "SIGSEGV" in err
    assert "Traceback" not in err


def test_an_fmu_that_never_finishes_its_set_up_stops_the_campaign_after_one_timeout(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    # The toy loops forever leaving initialisation. Every reference run (3) and every check of
    # an extreme draw (one per distinct bound: 5 here) would set it up and wait out its own
    # timeout, one after another (with the defaults 50 s or more each); the campaign sets the
    # FMU up once first, on its own, and stops when that set-up times out: exit 3, one set-up.
    from idefix_rules.cli import main

    log = campaign_dir / "setups.log"
    monkeypatch.setenv("TOY_SETUP_LOG", str(log))
    hang = '    toy.hang_setup: {distribution: fixed, value: 1}\n'
    text = CAMPAIGN.replace("    toy.slip:", hang + "    toy.slip:")
    (campaign_dir / "campaign.yaml").write_text(text)
    assert main([str(campaign_dir / "campaign.yaml"), "--quiet", "--no-report",
                 "--run-timeout", "1"]) == 3
    err = capsys.readouterr().err
    assert "the FMU did not finish setting up" in err and "within 1 s" in err
    assert "Traceback" not in err
    assert log.read_text().splitlines() == ["set up"]

