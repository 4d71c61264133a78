"""Inputs too large are refused at once with exit 2 (subprocess timeouts are guards only, no
time is asserted); diagnostics never quote a foreign file; re-scored spans point into the
results file."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import h5py
import pytest
from campaign_texts import CAMPAIGN, RULEBOOK

from idefix_rules import limits
from idefix_rules.cli import main

SECRET = "zanzibar:x:0:0:secret-password-line:/home/zanzibar:/bin/bash\n"


def cli(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """The CLI in a subprocess; the timeout only guards against a hang (never a measurement)."""
    return subprocess.run([sys.executable, "-m", "idefix_rules", *args], cwd=cwd,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          timeout=120)


def sparse(path: Path, size: int, start: bytes = b"") -> Path:
    """A file of ``size`` bytes that takes no disk space (zeros after ``start``)."""
    with path.open("wb") as handle:
        handle.write(start)
        handle.truncate(size)
    return path


def test_a_50_mb_rulebook_is_refused_before_it_is_read(tmp_path: Path) -> None:
    sparse(tmp_path / "huge.rules", 50 * 1024 * 1024, RULEBOOK.encode())
    done = cli("check", "huge.rules", cwd=tmp_path)
    assert done.returncode == 2, done.stdout
    assert "huge.rules: error[E900]: rulebook file huge.rules is 50 MiB; at most 128 KiB " \
           "is accepted" in done.stdout
    assert "Traceback" not in done.stdout


def test_a_rulebook_just_inside_the_size_limit_is_parsed(tmp_path: Path) -> None:
    padding = "# padding\n" * ((limits.MAX_RULEBOOK_BYTES - len(RULEBOOK)) // 10)
    (tmp_path / "big.rules").write_text(RULEBOOK + padding)
    assert (tmp_path / "big.rules").stat().st_size <= limits.MAX_RULEBOOK_BYTES
    assert cli("check", "big.rules", cwd=tmp_path).returncode == 0
    (tmp_path / "big.rules").write_text(RULEBOOK + padding + "#" * 11)
    assert (tmp_path / "big.rules").stat().st_size > limits.MAX_RULEBOOK_BYTES
    assert cli("check", "big.rules", cwd=tmp_path).returncode == 2


def test_one_overlong_expression_line_is_refused_with_its_line(tmp_path: Path) -> None:
    line = "const c = " + "1 + " * (limits.MAX_RULEBOOK_LINE // 4) + "1\n"
    (tmp_path / "long.rules").write_text(RULEBOOK + line)
    done = cli("check", "long.rules", cwd=tmp_path)
    assert done.returncode == 2
    number = RULEBOOK.count("\n") + 1
    assert f"long.rules:{number}:1: error[E901]: line {number} has {len(line) - 1} characters; " \
           f"a rulebook line may have at most {limits.MAX_RULEBOOK_LINE}" in done.stdout
    assert max(map(len, done.stdout.splitlines())) < 200  # a window of the line, not all


def test_an_expression_line_just_inside_the_line_limit_is_parsed(tmp_path: Path) -> None:
    line = "const c = " + "1" * (limits.MAX_RULEBOOK_LINE - 10) + "\n"
    (tmp_path / "long.rules").write_text(RULEBOOK + line)
    assert len(line) - 1 == limits.MAX_RULEBOOK_LINE
    done = cli("check", "long.rules", cwd=tmp_path)
    assert "E901" not in done.stdout


def test_a_huge_campaign_file_is_refused(campaign_dir: Path) -> None:
    sparse(campaign_dir / "campaign.yaml", 20 * 1024 * 1024, CAMPAIGN.encode())
    done = cli("campaign.yaml", "--quiet", "--no-report", cwd=campaign_dir)
    assert done.returncode == 2
    assert "error[C600]: campaign file campaign.yaml is 20 MiB; at most 256 KiB" in done.stdout


@pytest.mark.parametrize(("name", "size"), [
    ("site.dem", limits.MAX_TERRAIN_HEADER_BYTES + 8 * 16_000_000 + 1),
    ("site.csv", limits.MAX_CSV_DEM_BYTES + 1),
    ("site.npy", limits.MAX_NPY_DEM_BYTES + 1),
])
def test_a_huge_terrain_file_is_refused(campaign_dir: Path, name: str, size: int) -> None:
    sparse(campaign_dir / name, size, b"IDEFIX-TERRAIN 1\n")
    cell = "" if name.endswith(".dem") else '    cell: "1 m"\n'
    (campaign_dir / "campaign.yaml").write_text(CAMPAIGN.replace(
        "paths:", f"environment:\n  terrain:\n    dem: {name}\n{cell}paths:"))
    done = cli("campaign.yaml", "--quiet", "--no-report", cwd=campaign_dir)
    assert done.returncode == 2, done.stdout
    assert f"error[C601]: {'terrain' if name.endswith('.dem') else 'DEM'} file" in done.stdout
    assert "is accepted" in done.stdout


def test_a_rulebook_path_naming_another_kind_of_file_quotes_none_of_it(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (campaign_dir / "passwd").write_text(SECRET)
    (campaign_dir / "campaign.yaml").write_text(
        CAMPAIGN.replace("rulebook: test.rules", "rulebook: passwd"))
    assert main([str(campaign_dir / "campaign.yaml"), "--quiet", "--no-report"]) == 2
    err = capsys.readouterr().err
    assert "error[E902]" in err and "is not a rulebook: it begins with 'zanzibar'" in err
    assert "secret" not in err


@pytest.mark.parametrize("name", ["site.dem", "site.csv"])
def test_a_dem_path_naming_another_kind_of_file_quotes_none_of_it(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str], name: str) -> None:
    (campaign_dir / name).write_text(SECRET)
    cell = "" if name.endswith(".dem") else '    cell: "1 m"\n'
    (campaign_dir / "campaign.yaml").write_text(CAMPAIGN.replace(
        "paths:", f"environment:\n  terrain:\n    dem: {name}\n{cell}paths:"))
    assert main([str(campaign_dir / "campaign.yaml"), "--quiet", "--no-report"]) == 2
    err = capsys.readouterr().err
    assert f"{name}:1:1: error[" in err
    assert "secret" not in err and "zanzibar" not in err


def test_a_campaign_argument_naming_another_kind_of_file_quotes_none_of_it(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "passwd.yaml").write_text(SECRET)
    assert main([str(tmp_path / "passwd.yaml")]) == 2
    err = capsys.readouterr().err
    assert "error[C101]" in err and "secret" not in err


@pytest.mark.slow
def test_rescored_spans_point_at_the_rulebook_stored_in_the_results(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([str(campaign_dir / "campaign.yaml"), "--quiet", "--no-report"]) == 1
    results = campaign_dir / "out" / "results.h5"
    (campaign_dir / "test.rules").unlink()  # re-scoring needs only the results file
    assert main(["evaluate", str(results)]) == 1
    capsys.readouterr()
    line = RULEBOOK.splitlines().index(
        "verdict acceptable_risk: require risk <= 50 %") + 1
    with h5py.File(results) as stored:
        verdicts = json.loads(stored["paths/straight/evaluation"].attrs["verdict"])
    spans = {v["name"]: v["span"] for v in verdicts["rules"]}
    assert spans["acceptable_risk"] == f"{results}:/provenance/rulebook:{line}:34"
    summary = json.loads((campaign_dir / "out" / "summary.json").read_text())
    assert summary["rulebook"]["path"] == f"{results}:/provenance/rulebook"
