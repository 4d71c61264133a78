"""The FMU a Dask worker's run processes share: extracted once into the worker's scratch
folder; a scratch folder gone or an extraction that fails leaves nothing half-made behind and
lets the runner extract its own copy."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

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
