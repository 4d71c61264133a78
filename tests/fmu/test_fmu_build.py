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


def test_the_built_fmu_is_readable_as_the_umask_lets_and_only_an_fmu_is_replaced(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import os

    target = tmp_path / "rover.fmu"
    previous = os.umask(0o022)
    try:
        assert main(["build-fmu", "-o", str(target)]) == 0
        assert target.stat().st_mode & 0o777 == 0o644  # not mkstemp's 0600
        os.umask(0o027)
        assert main(["build-fmu", "-o", str(target)]) == 0  # an FMU: replaced
        assert target.stat().st_mode & 0o777 == 0o640
    finally:
        os.umask(previous)
    rulebook = tmp_path / "ops.rules"
    rulebook.write_text('rulebook "x" version "1.0.0"\n')
    assert main(["build-fmu", "-o", str(rulebook)]) == 2  # a usage error
    assert rulebook.read_text() == 'rulebook "x" version "1.0.0"\n'
    assert "exists and is not an FMU" in capsys.readouterr().err


def test_a_cache_folder_that_cannot_be_made_is_said_without_a_traceback(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A cache this user cannot write (here a file where the folder should be): exit 3 with
    what to do, not "internal error" and an OSError's traceback."""
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("")
    monkeypatch.setenv("IDEFIX_CACHE", str(blocker / "cache"))
    assert main(["build-fmu"]) == 3
    err = capsys.readouterr().err
    assert "Traceback" not in err and "internal error" not in err, err
    assert f"building the rover FMU into {blocker / 'cache' / 'fmu'} failed: Not a directory; " \
           "the FMU needs a writable folder: point IDEFIX_CACHE at one" in err, err


def test_no_compiler_and_a_failing_cmake_build_is_said_without_a_traceback(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """No C compiler on PATH: fmpy's cmake build fails with a CalledProcessError (cmake
    finds no compiler either), said as the missing compiler, exit 3."""
    import subprocess

    import fmpy.build

    def cmake_fails(unzipdir: object) -> None:
        raise subprocess.CalledProcessError(1, ["cmake", "--build", "."])

    monkeypatch.setenv("IDEFIX_CACHE", str(tmp_path))
    monkeypatch.setattr(build, "_compiler", lambda: None)
    monkeypatch.setattr(fmpy.build, "build_platform_binary", cmake_fails)
    assert main(["build-fmu"]) == 3
    err = capsys.readouterr().err
    assert "Traceback" not in err and "internal error" not in err, err
    assert "building the rover FMU needs a C compiler (cc, gcc or clang; or $CC): none was " \
           "found, and fmpy's cmake build failed too" in err, err
