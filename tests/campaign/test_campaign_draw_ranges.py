"""An uncertain parameter whose draws leave the range the FMU allows is refused before any
Monte Carlo run (F110 at its distribution, naming the run that draws it); one whose draws all
lie inside runs."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from idefix_rules.cli import main

ROOT = Path(__file__).parents[2]
LAST = '    initial.y: {distribution: normal, mean: "0 m", std: "1 cm"}\n'


def _campaign(tmp_path: Path, friction: str) -> Path:
    text = (ROOT / "campaigns" / "flat-control.yaml").read_text()
    assert LAST in text
    text = text.replace("../rulebooks/", f"{ROOT / 'rulebooks'}/").replace(
        "output: ../results/flat-control", f"output: {tmp_path / 'out'}")
    text = text.replace(LAST, LAST + f"    soil.friction_angle: {friction}\n")
    text = text[:text.index("  wide-detour:")] + text[text.index("simulation:"):]
    path = tmp_path / "campaign.yaml"
    path.write_text(text)
    return path


def test_a_distribution_reaching_beyond_the_fmus_range_stops_before_any_run(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _campaign(tmp_path, '{distribution: normal, mean: "35 deg", std: "30 deg"}')
    assert main([str(path), "--runs", "8", "--workers", "1", "--quiet", "--no-report"]) == 2
    output = " ".join("".join(capsys.readouterr()).split())
    assert "Traceback" not in output
    line = 1 + path.read_text().splitlines().index(
        '    soil.friction_angle: {distribution: normal, mean: "35 deg", std: "30 deg"}')
    assert f"{path}:{line}:26: error[F110]: parameter soil.friction_angle = " in output
    assert "out of range: allowed [0, 80 deg]: run " in output
    assert "of path straight draws it (of 8 planned), before any run was simulated" in output
    import h5py

    with h5py.File(tmp_path / "out" / "results.h5") as results:  # no Monte Carlo run stored
        assert "runs" not in results["paths/straight"]


@pytest.mark.parametrize(("friction", "code"), [
    ('{distribution: uniform, low: "79.9 deg", high: "80 deg"}', 1),    # inside, at the edge
    ('{distribution: uniform, low: "79.9 deg", high: "80.1 deg"}', 2),  # some draws beyond
])
def test_the_range_edge(tmp_path: Path, friction: str, code: int,
                        capsys: pytest.CaptureFixture[str]) -> None:
    path = _campaign(tmp_path, friction)
    # without expectations met at 2 runs the campaign exits 1 when it runs at all
    got = main([str(path), "--runs", "2", "--workers", "1", "--quiet", "--no-report"])
    output = "".join(capsys.readouterr())
    assert got == code, output
    assert ("error[F110]" in output) is (code == 2)


def test_a_drawn_pressure_beyond_the_range_is_said_in_the_unit_of_its_distribution(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A compound unit (Pa, whose SI is kg/(m·s^2)) converts as a degree does: the drawn
    value and the range in Pa, the value to 6 significant digits."""
    path = _campaign(tmp_path, '{distribution: normal, mean: "250 Pa", std: "1 kPa"}')
    text = path.read_text().replace("    soil.friction_angle:", "    soil.cohesion:")
    path.write_text(text)
    assert main([str(path), "--runs", "8", "--workers", "1", "--quiet", "--no-report"]) == 2
    output = " ".join("".join(capsys.readouterr()).split())
    line = 1 + text.splitlines().index(
        '    soil.cohesion: {distribution: normal, mean: "250 Pa", std: "1 kPa"}')
    found = re.search(rf"{re.escape(str(path))}:{line}:20: error\[F110\]: parameter "
                      r"soil\.cohesion = (\S+) Pa out of range: allowed \[0, 1e\+06 Pa\]: run "
                      r"\d+ of path straight draws it \(of 8 planned\)", output)
    assert found, output
    assert len(found[1].lstrip("-").replace(".", "")) <= 6, found[1]


def test_refused_runs_in_a_row_keep_the_last_good_results(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A run refused for a drawn value (F110, found beside the reference runs, after the
    last results were set aside) puts them back: a second refused run replaced them with the
    first one's stub, and the good results were gone."""
    import h5py

    good = _campaign(tmp_path, '{distribution: uniform, low: "30 deg", high: "40 deg"}')
    argv = ["--runs", "2", "--workers", "1", "--quiet", "--no-report"]
    assert main([str(good), *argv]) == 1
    results = tmp_path / "out" / "results.h5"
    with h5py.File(results) as stored:
        planned = stored.attrs["started"]
    for _ in range(2):
        refused = _campaign(tmp_path, '{distribution: uniform, low: "85 deg", high: "95 deg"}')
        assert main([str(refused), *argv]) == 2
        assert "error[F110]" in "".join(capsys.readouterr())
        with h5py.File(results) as stored:
            assert stored.attrs["state"] == "complete" and stored.attrs["started"] == planned
            assert "runs" in stored["paths/straight"]
    assert not (tmp_path / "out" / "results.previous.h5").exists()
