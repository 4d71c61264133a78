"""One campaign at a time per output folder: the lock file, its owner, stale locks."""

from __future__ import annotations

import errno
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path

import h5py
import pytest

from idefix_rules.campaign.storage import ownership
from idefix_rules.campaign.storage.ownership import (
    LOCK_FILE,
    Owner,
    own_folder,
    process_start,
    this_process,
)
from idefix_rules.errors import UserInputError


@pytest.fixture
def sleeper() -> Iterator[subprocess.Popen[bytes]]:
    """A live process of this host that is not this one."""
    process = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"])
    try:
        yield process
    finally:
        process.kill()
        process.wait()


def dead_pid() -> int:
    process = subprocess.Popen([sys.executable, "-c", "pass"])
    process.wait()
    return process.pid


def write_lock(folder: Path, pid: int, host: str | None = None,
               started: str | None = None) -> Owner:
    owner = Owner(pid, host or socket.gethostname(), "2025-05-01T12:00:03+02:00",
                  "idefix-verify run campaign.yaml",
                  process_start(pid) if started is None else started)
    (folder / LOCK_FILE).write_text(owner.to_json())
    return owner


def test_the_lock_names_its_owner_and_goes_with_the_block(tmp_path: Path) -> None:
    with own_folder(tmp_path, "idefix-verify run c.yaml") as lock:
        owner = Owner.from_json((tmp_path / LOCK_FILE).read_bytes())
        assert owner is not None and lock.note is None
        assert (owner.pid, owner.host, owner.command) == (os.getpid(), socket.gethostname(),
                                                          "idefix-verify run c.yaml")
        assert owner.started and owner.process_start == process_start(os.getpid())
    assert not (tmp_path / LOCK_FILE).exists()
    assert list(tmp_path.iterdir()) == []  # no temporary left either


@pytest.mark.parametrize("failure", [RuntimeError, KeyboardInterrupt, SystemExit])
def test_the_lock_goes_on_every_way_out(tmp_path: Path, failure: type[BaseException]) -> None:
    with pytest.raises(failure), own_folder(tmp_path):
        raise failure()
    assert not (tmp_path / LOCK_FILE).exists()


def test_one_process_may_own_a_folder_twice_and_keeps_it_until_the_outer_block(
        tmp_path: Path) -> None:
    with own_folder(tmp_path):
        with own_folder(tmp_path) as inner:
            assert inner.note is None
        assert (tmp_path / LOCK_FILE).exists()
    assert not (tmp_path / LOCK_FILE).exists()


def test_a_live_owner_is_refused_with_its_pid_host_and_start_time(
        tmp_path: Path, sleeper: subprocess.Popen[bytes]) -> None:
    owner = write_lock(tmp_path, sleeper.pid)
    before = (tmp_path / LOCK_FILE).read_bytes()
    with pytest.raises(UserInputError) as caught, own_folder(tmp_path):
        pass
    [diagnostic] = caught.value.diagnostics
    assert diagnostic.code == "C208"
    assert diagnostic.span is not None and diagnostic.span.path == str(tmp_path / LOCK_FILE)
    assert f"pid {sleeper.pid} on host {owner.host}, started 2025-05-01 12:00:03+02:00 " \
           "(idefix-verify run campaign.yaml)" in diagnostic.message
    assert diagnostic.hint is not None and "--out" in diagnostic.hint
    assert (tmp_path / LOCK_FILE).read_bytes() == before  # untouched


def test_the_lock_of_a_process_that_no_longer_runs_is_taken_over_with_a_note(
        tmp_path: Path) -> None:
    pid = dead_pid()
    write_lock(tmp_path, pid, started="")
    with own_folder(tmp_path) as lock:
        assert lock.note is not None
        assert f"took over the lock of pid {pid} on host" in lock.note
        assert "that process no longer runs" in lock.note and "\n" not in lock.note
        assert Owner.from_json((tmp_path / LOCK_FILE).read_bytes()).pid == os.getpid()  # type: ignore[union-attr]
    assert sorted(tmp_path.iterdir()) == []


def test_a_pid_reused_by_a_later_process_does_not_hold_the_lock(
        tmp_path: Path, sleeper: subprocess.Popen[bytes]) -> None:
    if process_start(sleeper.pid) is None:
        pytest.skip("process start times are read from /proc")
    write_lock(tmp_path, sleeper.pid, started="another-boot:12345")
    with own_folder(tmp_path) as lock:
        assert lock.note is not None and "its pid now belongs to another process" in lock.note


def test_a_lock_from_another_host_is_refused_and_names_the_file_to_delete(
        tmp_path: Path) -> None:
    write_lock(tmp_path, dead_pid(), host="node-that-is-not-this-one", started="")
    with pytest.raises(UserInputError) as caught, own_folder(tmp_path):
        pass
    [diagnostic] = caught.value.diagnostics
    assert diagnostic.code == "C208" and "node-that-is-not-this-one" in diagnostic.message
    assert diagnostic.hint is not None and f"delete {tmp_path / LOCK_FILE}" in diagnostic.hint


def test_a_damaged_lock_file_is_taken_over_once_it_is_old(tmp_path: Path) -> None:
    (tmp_path / LOCK_FILE).write_text("{\"pid\": ")
    os.utime(tmp_path / LOCK_FILE, (0, 0))
    with own_folder(tmp_path) as lock:
        assert lock.note is not None and "not a complete lock file" in lock.note


def test_a_lock_file_being_written_is_waited_for_before_it_counts_as_damaged(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(ownership, "UNREADABLE_GRACE_SECONDS", 0.3)
    (tmp_path / LOCK_FILE).write_text("")  # created, not yet filled (no hard links here)
    # written just now, whatever the machine's load between here and the check (an age
    # measured against the file's time could end the wait early)
    future = time.time() + 60
    os.utime(tmp_path / LOCK_FILE, (future, future))
    waits: list[float] = []
    sleep = time.sleep
    monkeypatch.setattr(ownership.time, "sleep", lambda seconds: (waits.append(seconds),
                                                                   sleep(seconds)))
    with own_folder(tmp_path) as lock:
        assert waits  # it waited for the file to be written before it took it over
        assert lock.note is not None and "an unknown owner" in lock.note


def test_a_forked_child_never_frees_its_parents_folder(tmp_path: Path) -> None:
    with own_folder(tmp_path) as lock:
        pid = os.fork()
        if pid == 0:  # the child: a worker forked while the campaign runs, ending normally
            lock.release()
            os._exit(0)
        os.waitpid(pid, 0)
        assert (tmp_path / LOCK_FILE).exists()


def test_a_folder_that_cannot_take_a_lock_is_a_user_error(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def read_only(*args: object, **kwargs: object) -> None:
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(tempfile, "mkstemp", read_only)
    with pytest.raises(UserInputError) as caught, own_folder(tmp_path):
        pass
    [diagnostic] = caught.value.diagnostics
    assert diagnostic.code == "C205"
    assert "cannot be used: cannot create .idefix.lock: Read-only file system" in \
        diagnostic.message


def test_this_process_is_described_for_a_person() -> None:
    owner = this_process("idefix-verify run c.yaml")
    assert owner.describe().startswith(f"pid {os.getpid()} on host {socket.gethostname()}, "
                                       "started ")
    assert Owner.from_json(owner.to_json().encode()) == owner
    assert Owner.from_json(b"not json") is None


# ----------------------------------------------------------------------------- campaigns

# Slow enough (one worker, thousands of runs of the toy FMU) to be running when the second
# campaign starts.
SLOW_RUNS = {"overlap": 600, "long": 2500}
# A campaign interrupted after a second: far more runs than a second simulates on an idle
# machine (2 × 2500 once finished before the interrupt came, which then met the interpreter's
# clean-up), which costs nothing since it never gets far.
INTERRUPTED_RUNS = 100_000


def slow_campaign(campaign_dir: Path, runs: int) -> Path:
    text = (campaign_dir / "campaign.yaml").read_text()
    text = text.replace("runs: 6", f"runs: {runs}").replace("workers: 2", "workers: 1")
    path = campaign_dir / f"slow-{runs}.yaml"
    path.write_text(text)
    return path


# `idefix-verify` as its console script runs it. Not `python -m idefix_rules`: under -m,
# CPython ends a process by SIGINT (exit -2, not the 130 returned) whenever a KeyboardInterrupt
# ended a string exec (a dataclass or scipy being imported as Ctrl-C came), even one caught
# later (bpo-41602); the shell's $? is 130 either way.
COMMAND = [sys.executable, "-c",
           "import sys; from idefix_rules.cli import process_main; sys.exit(process_main())"]


def start(*argv: str | Path) -> subprocess.Popen[str]:
    environment = {**os.environ, "COLUMNS": "400"}  # one message, one line
    return subprocess.Popen([*COMMAND, *map(str, argv)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=environment)


def finish(process: subprocess.Popen[str]) -> tuple[int, str]:
    out, err = process.communicate(timeout=600)
    assert "Traceback" not in out + err, out + err
    return process.returncode, out + err


def wait_for(path: Path, seconds: float = 120.0) -> None:
    deadline = time.monotonic() + seconds
    while not path.exists():
        assert time.monotonic() < deadline, f"{path} never appeared"
        time.sleep(0.005)


def stored_seed(out: Path) -> int:
    with h5py.File(out / "results.h5") as results:
        return int(results.attrs["seed"])


@pytest.mark.slow
def test_two_campaigns_started_0_1_s_apart_one_runs_and_the_other_is_refused(
        campaign_dir: Path) -> None:
    campaign = slow_campaign(campaign_dir, SLOW_RUNS["overlap"])
    out = campaign_dir / "out"
    first = start(campaign, "--quiet", "--no-report", "--seed", "1")
    time.sleep(0.1)
    second = start(campaign, "--quiet", "--no-report", "--seed", "2")
    (first_code, first_text), (second_code, second_text) = finish(first), finish(second)
    # Whichever took the folder first runs; the other is refused before touching anything.
    assert sorted([first_code == 2, second_code == 2]) == [False, True], (first_text,
                                                                          second_text)
    winner, seed, refused = (first, 1, second_text) if second_code == 2 else \
        (second, 2, first_text)
    # Either process may win the race; the winner is told from the loser by the loser's
    # exit 2 (C208) above. Whichever it is, it runs the same paths, and too-fast breaks the
    # command rule wheel_rate_limit (0.5 rad/s): rejected, so exit 1 whatever the seed.
    assert winner.returncode == 1
    assert "error[C208]" in refused and "is in use by another campaign" in refused
    assert f"pid {winner.pid} on host {socket.gethostname()}, started " in refused
    assert stored_seed(out) == seed
    assert json.loads((out / "summary.json").read_text())["seed"] == seed
    assert not list(out.glob("*.previous.*"))  # nothing of the winner was set aside
    assert not (out / LOCK_FILE).exists()


@pytest.mark.slow
def test_campaigns_and_evaluate_started_5_s_after_a_running_campaign_are_refused(
        campaign_dir: Path) -> None:
    campaign = slow_campaign(campaign_dir, SLOW_RUNS["long"])
    out = campaign_dir / "out"
    started = time.monotonic()
    first = start(campaign, "--quiet", "--no-report", "--seed", "1")
    wait_for(out / LOCK_FILE)
    time.sleep(max(0.0, started + 5.0 - time.monotonic()))
    others = {"run": start(campaign, "--quiet", "--no-report", "--seed", "2"),
              "resume": start(campaign, "--quiet", "--no-report", "--seed", "1", "--resume"),
              "evaluate": start("evaluate", out / "results.h5")}
    for name, process in others.items():
        code, text = finish(process)
        assert code == 2, (name, text)
        assert f"{out / LOCK_FILE}: error[C208]: output folder {out} is in use by another " \
               f"campaign: pid {first.pid} on host {socket.gethostname()}, started " in text
        assert "hint: wait until it ends" in text
    assert first.poll() is None, "the first campaign ended before the others were refused"
    code, text = finish(first)
    assert code == 1, text  # too-fast breaks the command rule wheel_rate_limit: exit 1
    assert stored_seed(out) == 1
    assert json.loads((out / "summary.json").read_text())["seed"] == 1
    assert not list(out.glob("*.previous.*"))
    assert not (out / LOCK_FILE).exists()


@pytest.mark.slow
def test_a_campaign_killed_early_leaves_no_old_output_and_its_lock_is_taken_over(
        campaign_dir: Path) -> None:
    out = campaign_dir / "out"
    code, _ = finish(start(campaign_dir / "campaign.yaml", "--quiet", "--seed", "4242"))
    assert code == 1  # too-fast breaks the command rule wheel_rate_limit: exit 1
    assert (out / "summary.json").is_file() and (out / "report.html").is_file()

    killed = start(slow_campaign(campaign_dir, SLOW_RUNS["long"]), "--quiet", "--seed", "777")
    wait_for(out / LOCK_FILE)
    time.sleep(0.2)  # compiling the rulebook, checking the FMU: the first moments of the run
    killed.kill()
    finish(killed)
    # Nothing in place speaks for the last run; it is kept aside.
    for name in ("summary.json", "report.html"):
        assert not (out / name).exists(), name
    assert json.loads((out / "summary.previous.json").read_text())["seed"] == 4242
    assert (out / "report.previous.html").is_file()
    with h5py.File(out / "results.previous.h5") as previous:
        assert int(previous.attrs["seed"]) == 4242
    owner = Owner.from_json((out / LOCK_FILE).read_bytes())  # a kill -9 leaves the lock
    assert owner is not None and owner.pid == killed.pid

    code, text = finish(start(campaign_dir / "campaign.yaml", "--quiet", "--no-report",
                              "--seed", "5"))
    assert code == 1, text  # too-fast breaks the command rule wheel_rate_limit: exit 1
    [note] = [line for line in text.splitlines() if line.startswith("note:")]
    assert f"note: {out / LOCK_FILE}: took over the lock of pid {killed.pid} on host " in note
    assert note.endswith("that process no longer runs")
    assert json.loads((out / "summary.json").read_text())["seed"] == 5
    assert not (out / LOCK_FILE).exists()


def test_evaluate_takes_over_a_killed_campaigns_lock_with_a_note_and_calls_it_interrupted(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A campaign killed mid-run leaves its lock and its results file `running`: evaluate
    takes the lock over (a note, as for a run) and, owning the folder, knows no campaign
    writes the file: it is interrupted, and so the file says from then on."""
    from idefix_rules.cli import main

    assert main([str(campaign_dir / "campaign.yaml"), "--quiet", "--no-report"]) == 1
    capsys.readouterr()
    out = campaign_dir / "out"
    results = out / "results.h5"
    with h5py.File(results, "r+") as file:  # as a kill -9 midway leaves it
        file.attrs["state"], file.attrs["finished"] = "running", ""
        status = file["paths/arc/runs/status"]
        status[3:] = 0
    pid = dead_pid()
    write_lock(out, pid)
    assert main(["evaluate", str(results)]) == 1
    captured = capsys.readouterr()
    words = " ".join(captured.out.split())
    assert f"note: {out / LOCK_FILE}: took over the lock of pid {pid} on host" in words
    assert "warning: " + str(out / LOCK_FILE) not in words
    assert f"{results} holds a campaign that is interrupted: runs never simulated count as " \
           "failed" in words
    assert "that is running" not in words
    with h5py.File(results) as file:
        assert file.attrs["state"] == "interrupted"
    assert not (out / LOCK_FILE).exists()


@pytest.mark.slow
def test_ctrl_c_releases_the_folder(campaign_dir: Path) -> None:
    out = campaign_dir / "out"
    process = start(slow_campaign(campaign_dir, INTERRUPTED_RUNS), "--quiet", "--no-report")
    wait_for(out / LOCK_FILE)
    time.sleep(1.0)
    process.send_signal(signal.SIGINT)
    code, text = finish(process)
    assert code == 130, text
    assert not (out / LOCK_FILE).exists()



@pytest.mark.slow
@pytest.mark.parametrize("after", [0.3, 1.5, 8.0])
def test_ctrl_c_on_a_local_dask_cluster_says_only_how_to_continue(campaign_dir: Path,
                                                                   after: float) -> None:
    """Ctrl-C as a terminal sends it, to the whole process group (the cluster's starting or
    running workers get it too): while the cluster starts (a start it failed made it an
    internal error, exit 3) or while its workers hang in runs (what they log about the runs
    cancelled under them is Dask's business, not the operator's). The campaign's own line
    says what happened and how to continue, exit 130."""
    out = campaign_dir / "out"
    campaign = slow_campaign(campaign_dir, INTERRUPTED_RUNS)
    # runs that hang (the reference's, at the mean, does not): the workers are busy with one
    # when the operator presses Ctrl-C
    campaign.write_text(campaign.read_text().replace("    toy.slip:", """\
    toy.hang_at: {distribution: uniform, low: "1 s", high: "1000 s"}
    toy.slip:"""))
    process = subprocess.Popen(
        [*COMMAND, str(campaign), "--no-report", "--dask-local",
         "--workers", "2", "--run-timeout", "600"], stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True, env={**os.environ, "COLUMNS": "400"},
        start_new_session=True)
    wait_for(out / "results.h5")
    time.sleep(after)
    os.killpg(process.pid, signal.SIGINT)
    code, text = finish(process)
    assert code == 130, text
    assert "distributed" not in text and "CancelledError" not in text, text
    # the command continues the campaign as it ran: on a local cluster of 2, its timeout
    assert f"interrupted: continue with `idefix-verify {campaign} --resume --workers 2 " \
           "--dask-local --run-timeout 600 --no-report`" in text, text
    assert not (out / LOCK_FILE).exists()

KILLED_AT_FIRST_STEP = textwrap.dedent("""\
    import os, signal, sys
    from idefix_rules.campaign.input.load import load_campaign
    from idefix_rules.campaign.runner import run_campaign

    class KillAtFirstStep:  # the first thing a campaign says: "compiling the rulebook …"
        def message(self, text):
            os.kill(os.getpid(), signal.SIGKILL)
        def note(self, text): pass
        def start_path(self, name, total, done, failed=0, up_to=False): pass
        def run_finished(self, name, ok): pass

    campaign = load_campaign(sys.argv[1]).with_overrides(seed=int(sys.argv[2]))
    run_campaign(campaign, progress=KillAtFirstStep())
""")


@pytest.mark.slow
def test_a_campaign_killed_at_its_first_step_has_set_every_old_output_aside(
        campaign_dir: Path, tmp_path: Path) -> None:
    out = campaign_dir / "out"
    code, _ = finish(start(campaign_dir / "campaign.yaml", "--quiet", "--seed", "4242"))
    assert code == 1  # too-fast breaks the command rule wheel_rate_limit: exit 1
    script = tmp_path / "killed.py"
    script.write_text(KILLED_AT_FIRST_STEP)
    killed = subprocess.run([sys.executable, str(script), str(campaign_dir / "campaign.yaml"),
                             "777"], capture_output=True, text=True, timeout=300)
    assert killed.returncode == -signal.SIGKILL, killed.stderr
    # Before the rulebook was even compiled, nothing in place speaks for the last run.
    for name in ("summary.json", "report.html", "results.h5"):
        assert not (out / name).exists(), name
    for name in ("summary.previous.json", "report.previous.html", "results.previous.h5",
                 LOCK_FILE):
        assert (out / name).is_file(), name
    assert json.loads((out / "summary.previous.json").read_text())["seed"] == 4242


def test_the_write_probe_of_one_campaign_leaves_another_campaigns_probe_alone(
        campaign_dir: Path) -> None:
    """Two campaigns started together both probe the folder: each removes only its own (with
    one shared name the second found its probe gone: C205 'No such file or directory')."""
    from idefix_rules.campaign.input.load import load_campaign
    from idefix_rules.campaign.input.validate import prepare_output

    campaign = load_campaign(campaign_dir / "campaign.yaml")
    campaign.output.mkdir(parents=True, exist_ok=True)
    in_flight = campaign.output / ".idefix-write-test"  # another campaign's, mid-probe
    in_flight.write_bytes(b"")
    prepare_output(campaign)
    assert in_flight.is_file()
    assert [p.name for p in campaign.output.iterdir()] == [in_flight.name]
