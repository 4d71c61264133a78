"""The FMU a Dask worker's run processes share: extracted once into the worker's scratch
folder; a scratch folder gone or an extraction that fails leaves nothing half-made behind and
lets the runner extract its own copy."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from idefix_rules.campaign.simulation.simulate import UNPACKED_FMU
from idefix_rules.campaign.simulation.worker import shared_extraction
from idefix_rules.errors import UserInputError


def test_the_fmu_is_extracted_once_and_found_again(tmp_path: Path, toy_fmu: Path) -> None:
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    first = shared_extraction(str(toy_fmu), str(scratch))
    assert first is not None and (Path(first) / "modelDescription.xml").is_file()
    stamp = os.stat(Path(first) / "modelDescription.xml").st_mtime_ns
    assert shared_extraction(str(toy_fmu), str(scratch)) == first  # not extracted again
    assert os.stat(Path(first) / "modelDescription.xml").st_mtime_ns == stamp
    assert [p.name for p in scratch.iterdir()] == [Path(first).name]  # nothing set aside left


def test_a_scratch_folder_gone_lets_the_runner_extract_its_own(tmp_path: Path,
                                                              toy_fmu: Path) -> None:
    assert shared_extraction(str(toy_fmu), str(tmp_path / "gone")) is None
    assert shared_extraction(str(tmp_path / "no.fmu"), str(tmp_path)) is None  # runner: F101


def test_a_failed_extraction_leaves_no_half_made_folder(tmp_path: Path) -> None:
    broken = tmp_path / "broken.fmu"
    broken.write_bytes(b"not a zip")
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    with pytest.raises(UserInputError):  # F102, as the runner would say
        shared_extraction(str(broken), str(scratch))
    assert list(scratch.iterdir()) == []


def test_a_process_that_lost_the_race_keeps_the_winners_folder(tmp_path: Path,
                                                              toy_fmu: Path,
                                                              monkeypatch: pytest.MonkeyPatch
                                                              ) -> None:
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    winner = shared_extraction(str(toy_fmu), str(scratch))
    assert winner is not None
    real_isdir = os.path.isdir
    calls = {"n": 0}

    def not_yet(path: str) -> bool:  # the first look misses it, as if another process won
        calls["n"] += 1
        return False if calls["n"] == 1 else real_isdir(path)

    monkeypatch.setattr(os.path, "isdir", not_yet)
    assert shared_extraction(str(toy_fmu), str(scratch)) == winner
    monkeypatch.undo()
    assert [p.name for p in scratch.iterdir()] == [Path(winner).name]
    shutil.rmtree(scratch)


KILLED_WHILE_SIMULATING = textwrap.dedent("""\
    import os, signal, sys
    from idefix_rules.campaign.input.load import load_campaign
    from idefix_rules.campaign.runner import run_campaign

    class KillAtFirstPath:  # the FMU is extracted by the time the first path starts
        def message(self, text): pass
        def note(self, text): pass
        def start_path(self, name, total, done, failed=0, up_to=False):
            os.kill(os.getpid(), signal.SIGKILL)
        def run_finished(self, name, ok): pass

    run_campaign(load_campaign(sys.argv[1]), progress=KillAtFirstPath())
""")


@pytest.mark.slow
def test_a_killed_campaign_leaves_its_extracted_fmu_in_its_output_folder_only(
        campaign_dir: Path, tmp_path: Path) -> None:
    """A campaign extracts the FMU once for its workers into its own output folder (it owns
    it), not the system's temporary folder: killed on its way, it leaves the extraction
    there, and the next campaign in that folder replaces it and removes it when it ends.
    Before, every killed campaign left a folder of its own in the temporary folder."""
    temporary = tmp_path / "temporary"
    temporary.mkdir()
    script = tmp_path / "killed.py"
    script.write_text(KILLED_WHILE_SIMULATING)
    killed = subprocess.run([sys.executable, str(script), str(campaign_dir / "campaign.yaml")],
                            capture_output=True, text=True, timeout=300,
                            env={**os.environ, "TMPDIR": str(temporary)})
    assert killed.returncode == -signal.SIGKILL, killed.stderr
    out = campaign_dir / "out"
    left = out / UNPACKED_FMU
    assert (left / "modelDescription.xml").is_file()
    assert list(temporary.iterdir()) == []
    stale = left / "stale-marker"
    stale.write_text("from the killed campaign")
    finished = subprocess.run([sys.executable, "-m", "idefix_rules", str(campaign_dir /
                                                                         "campaign.yaml"),
                               "--quiet"], capture_output=True, text=True, timeout=300,
                              env={**os.environ, "TMPDIR": str(temporary)})
    assert finished.returncode == 1, finished.stdout + finished.stderr  # a command rule breaks
    assert not left.exists()
    assert list(temporary.iterdir()) == []


def test_a_full_disk_while_extracting_is_a_full_disk_not_a_bad_fmu(
        tmp_path: Path, toy_fmu: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The extraction writes into the output folder: a disk that fills there reaches the
    campaign's disk guard (exit 3, 'disk full'), not F102 'not a readable FMU'; another
    failure to write is still F102."""
    import errno

    import fmpy

    from idefix_rules.campaign.storage import diskspace
    from idefix_rules.fmu import extract_fmu

    def full(*args: object, **kwargs: object) -> str:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(fmpy, "extract", full)
    with pytest.raises(diskspace.DiskFull, match=r"disk full: .* to simulate"), \
            diskspace.guard(tmp_path, "simulate"):
        extract_fmu(toy_fmu, tmp_path / "x")
    monkeypatch.setattr(fmpy, "extract", lambda *a, **k: (_ for _ in ()).throw(
        PermissionError(errno.EACCES, "Permission denied")))
    with pytest.raises(UserInputError, match="not a readable FMU"):
        extract_fmu(toy_fmu, tmp_path / "x")


def test_a_process_keeps_its_runner_only_while_the_fmu_file_is_the_same(
        tmp_path: Path, toy_fmu: Path) -> None:
    """A Dask worker outlives campaigns: an FMU replaced at the same path was still run from
    the runner made for the old file (the results labelled with the new file's hash)."""
    from idefix_rules.campaign.simulation.worker import RunTask, runner_key

    fmu = tmp_path / "rover.fmu"
    shutil.copy(toy_fmu, fmu)
    task = RunTask(str(fmu), None, None, (), (), 1.0, 0.1, 2)
    first = runner_key(task)
    assert runner_key(task) == first  # the same file: the same runner
    replacement = tmp_path / "other.fmu"
    replacement.write_bytes(toy_fmu.read_bytes() + b"\0")  # another file, moved into place
    os.replace(replacement, fmu)
    assert runner_key(task) != first
