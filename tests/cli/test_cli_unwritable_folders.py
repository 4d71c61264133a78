"""Folders this user cannot write, and empty names for outputs: exit 2 with a message, never a
traceback, nothing set aside or changed. (The tests run as any user, root too, so the folder's
permission is what ``os.access`` says, as it says it for a read-only mount.)"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
from test_cli_damaged_results import stored  # noqa: F401 - the fixture

from idefix_rules.cli import main


def _read_only(monkeypatch: pytest.MonkeyPatch, folder: Path) -> None:
    real = os.access

    def access(path: object, mode: int, *args: object, **kwargs: object) -> bool:
        if Path(str(path)).resolve() == folder.resolve() and mode & os.W_OK:
            return False
        return real(path, mode, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(os, "access", access)


@pytest.mark.parametrize("command", ["evaluate", "report"])
def test_a_results_folder_this_user_cannot_write_is_exit_2(
        command: str, stored: Path, tmp_path: Path,  # noqa: F811 - the fixture
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "read-only"
    folder.mkdir()
    shutil.copy(stored, folder / "results.h5")
    shutil.copy(stored.parent / "summary.json", folder / "summary.json")
    before = sorted((p.name, p.read_bytes()) for p in folder.iterdir())
    _read_only(monkeypatch, folder)
    code = main([command, str(folder / "results.h5")])
    captured = capsys.readouterr()
    output = " ".join((captured.out + captured.err).split())
    assert "Traceback" not in output
    assert code == 2, output
    if command == "evaluate":
        assert f"error[H002]: cannot write the evaluation of {folder / 'results.h5'}: its " \
            f"folder {folder} is not writable" in output, output
    else:
        assert f"error[C205]: output folder {folder} cannot be used: cannot write {folder}: " \
            f"{folder} is not writable" in output, output
        assert "-o DIR" in output
    assert sorted((p.name, p.read_bytes()) for p in folder.iterdir()) == before


@pytest.mark.parametrize("argv", [
    ["run", "campaign.yaml", "--out", ""],
    ["run", "campaign.yaml", "--junit", " "],
    ["report", "results.h5", "-o", ""],
    ["evaluate", "results.h5", "--out", ""],
])
def test_an_empty_output_name_is_refused_not_read_as_the_current_folder(
        argv: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    assert "an empty name (is the variable that gives it unset?)" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
