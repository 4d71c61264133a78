"""Building the FMU: cache keyed by the sources, CLI prints the path last."""

from __future__ import annotations

import zipfile
from pathlib import Path

import pytest

from idefix_rules.cli import main
from idefix_rules.fmu import build


def test_build_is_cached_by_source_hash(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("IDEFIX_CACHE", str(tmp_path))
    first = build.default_fmu_path()
    stamp = first.stat().st_mtime_ns
    again = build.default_fmu_path()
    assert again == first and again.stat().st_mtime_ns == stamp
    assert build.source_hash()[:16] in first.name
    with zipfile.ZipFile(first) as archive:
        names = set(archive.namelist())
    assert "modelDescription.xml" in names
    assert any(n.startswith("binaries/") and "idefix_rover" in n for n in names)
    assert "sources/rover.c" in names and "signal_map.json" in names


def test_cli_build_fmu_prints_the_path_as_last_line(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv("IDEFIX_CACHE", str(tmp_path))
    assert main(["build-fmu"]) == 0
    last = Path(capsys.readouterr().out.strip().splitlines()[-1])
    assert last.is_file() and last.suffix == ".fmu" and last.is_relative_to(tmp_path)
    stamp = last.stat().st_mtime_ns
    assert main(["build-fmu", "--cached"]) == 0
    assert Path(capsys.readouterr().out.strip().splitlines()[-1]) == last
    assert last.stat().st_mtime_ns == stamp
