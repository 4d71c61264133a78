"""Named areas end to end: the rulebook declares them, the campaign gives their polygons (or the
terrain its steep parts), every run's wheels are checked against them (built-in rover)."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest

from idefix_rules.cli import main

pytestmark = pytest.mark.slow

# A 30 cm straight drive from x = 0: the front wheels (20 cm ahead of the centre) reach
# x = 0.50 m. The keep-out square starts at x = 0.45 m (inside: entered) and the unknown
# surface at x = 0.55 m (5 cm beyond the wheels: in its 8 cm buffer, never inside).
CAMPAIGN = """\
name: areas
rulebook: areas.rules
output: out
runs: 3
workers: 1
environment:
  terrain:
    synthetic: {size: "3 m", cell: "2 cm", slope: "0 deg", roughness: "0 mm", seed: 1}
  areas:
    crater:
      polygons: [[["0.45 m", "-0.6 m"], ["1 m", "-0.6 m"], ["1 m", "0.6 m"], ["0.45 m", "0.6 m"]]]
    dark:
      polygons: [[["0.55 m", "0.5 m"], ["1 m", "0.5 m"], ["1 m", "1 m"]]]
uncertainty:
  method: monte_carlo
  seed: 3
  parameters:
    initial.y: {distribution: normal, mean: "0 m", std: "2 mm"}
paths:
  straight:
    - {max_wheel_rate: "0.05 rad/s", delta_position: "0.3 m", delta_heading: "0 deg"}
simulation:
  output_interval: "0.5 s"
  duration_margin: 1.5
  extra_time: "5 s"
"""

RULEBOOK = """\
rulebook "areas" version "1.0.0"
purpose "Named areas"

obstacles {
  level L1 below 3 cm  buffer 1 cm
  level L2 below 10 cm buffer 2 cm
  level L3             buffer 3 cm
  area crater keep_out level L3 buffer 10 cm because "Crater rim"
  area dark unknown level L2 buffer 30 cm because "Not seen by the navigation cameras"
  area scarp steep above 20 deg level L3 buffer 5 cm because "Too steep to climb"
}

index I_area "time in the crater" {
  value  = integral over time (area.crater.inside)
  limit  = 1000 s
  weight = 1
}

chance entered_crater = any over time (area.crater.inside > 0)
chance near_dark = any over time (area.dark.buffer > 0)
chance entered_dark = any over time (area.dark.inside > 0)
chance on_scarp = any over time (area.scarp.buffer > 0)
chance hit_L3 = any over parts (collision.hits[L3] > 0)

verdict crater_kept: require chance(entered_crater) <= 0 %
"""


@pytest.fixture
def areas_dir(tmp_path: Path) -> Path:
    (tmp_path / "campaign.yaml").write_text(CAMPAIGN)
    (tmp_path / "areas.rules").write_text(RULEBOOK)
    return tmp_path


def run(folder: Path, monkeypatch: pytest.MonkeyPatch, *options: str) -> int:
    monkeypatch.setenv("COLUMNS", "200")
    return main([str(folder / "campaign.yaml"), "--out", str(folder / "out"), "--quiet",
                 "--no-report", *options])


def test_areas_are_entered_approached_and_counted(areas_dir: Path, capsys,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    assert run(areas_dir, monkeypatch) == 1  # crater_kept fails
    out = capsys.readouterr().out
    assert "crater_kept" in out
    with h5py.File(areas_dir / "out" / "results.h5", "r") as results:
        chances = results["paths/straight/evaluation/chances"]
        assert np.all(chances["entered_crater"][()] == 1)
        assert np.all(chances["near_dark"][()] == 1)
        assert np.all(chances["entered_dark"][()] == 0)
        assert np.all(chances["on_scarp"][()] == 0)  # flat terrain: nothing steep
        assert np.all(chances["hit_L3"][()] == 1)  # the crater is an L3 obstacle
        raw = results["paths/straight/evaluation/raw/I_area"][()]
        # time in the crater: from the first sample with the front wheels (20 cm ahead of the
        # centre, yaw ~0) past x = 0.45 m to the run's end (its chain complete, the rover at
        # rest; the samples held after it to the end of the grid do not count), within one
        # output interval
        signals = results["paths/straight/runs/signals"]
        ended = 0
        for number, value in enumerate(raw):
            t, x = signals["t"][number], signals["x"][number]
            command = signals["command"][number]
            kept = np.isfinite(x)
            t, x, command = t[kept], x[kept], command[kept]
            entry = t[np.argmax(x + 0.2 * np.cos(signals["yaw"][number][kept]) > 0.45)]
            finished = bool(np.any(command == -1))
            ended += finished
            end = t[np.argmax(command == -1) + 1] if finished else t[-1]
            assert end < t[-1] or not finished  # samples were held after the run's end
            assert value == pytest.approx(end - entry, abs=0.5)
        assert ended >= 1
    summary = json.loads((areas_dir / "out" / "summary.json").read_text())
    paths = {record["name"]: record for record in summary["paths"]}
    assert paths["straight"]["verdict"] == "fail"


def test_an_area_the_rulebook_does_not_declare_is_an_error_at_its_line(
        areas_dir: Path, capsys, monkeypatch: pytest.MonkeyPatch) -> None:
    text = CAMPAIGN.replace("    crater:\n", "    craters:\n")
    (areas_dir / "campaign.yaml").write_text(text)
    assert run(areas_dir, monkeypatch) == 2
    err = capsys.readouterr().err
    line = text.splitlines().index("    craters:") + 1
    assert f"campaign.yaml:{line}:5: error[C209]" in err
    assert "did you mean 'crater'?" in err
    assert "Traceback" not in err
    assert not (areas_dir / "out" / "results.h5").exists()


def test_a_polygon_without_vertices_is_an_error_at_its_line(
        areas_dir: Path, capsys, monkeypatch: pytest.MonkeyPatch) -> None:
    """`polygons: [[]]`: C209 at the polygon (the check of polygons against the terrain's
    extent took the largest x of no vertex: a traceback, exit 3)."""
    old = ('      polygons: [[["0.45 m", "-0.6 m"], ["1 m", "-0.6 m"], ["1 m", "0.6 m"], '
           '["0.45 m", "0.6 m"]]]\n')
    assert old in CAMPAIGN
    text = CAMPAIGN.replace(old, "      polygons: [[]]\n")
    (areas_dir / "campaign.yaml").write_text(text)
    assert run(areas_dir, monkeypatch) == 2
    err = capsys.readouterr().err
    line = text.splitlines().index("      polygons: [[]]") + 1
    assert f"campaign.yaml:{line}:18: error[C209]: environment.areas.crater.polygons[0]: " \
           "area crater: a polygon needs at least 3 finite (x, y) vertices" in err, err
    assert "Traceback" not in err


def test_polygons_for_a_steep_area_are_refused(areas_dir: Path, capsys,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    text = CAMPAIGN.replace("    dark:\n", "    scarp:\n      polygons: [[[\"0 m\", \"0 m\"], "
                            "[\"1 m\", \"0 m\"], [\"1 m\", \"1 m\"]]]\n    dark:\n")
    (areas_dir / "campaign.yaml").write_text(text)
    assert run(areas_dir, monkeypatch) == 2
    err = capsys.readouterr().err
    assert "error[C209]" in err and "steep area" in err


def test_a_declared_area_without_polygons_is_a_warning(areas_dir: Path, capsys,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    text = CAMPAIGN.replace(
        '    dark:\n      polygons: [[["0.55 m", "0.5 m"], ["1 m", "0.5 m"], ["1 m", "1 m"]]]\n',
        "")
    (areas_dir / "campaign.yaml").write_text(text)
    assert run(areas_dir, monkeypatch) == 1
    captured = capsys.readouterr()
    assert "C210" in captured.out + captured.err
    assert "'dark'" in captured.out + captured.err


def test_a_declared_area_written_without_polygons_is_the_same_warning_at_its_entry(
        areas_dir: Path, capsys, monkeypatch: pytest.MonkeyPatch) -> None:
    """`dark: {}` (a template left unfilled) placed the area nowhere without a word: it is
    no entry, as `dark:` left out is; `dark: {polygons: []}` says the site has none."""
    for entry, warned in (("{}", True), ("{polygons: []}", False)):
        text = CAMPAIGN.replace('    dark:\n      polygons: [[["0.55 m", "0.5 m"], ["1 m", '
                                '"0.5 m"], ["1 m", "1 m"]]]\n', f"    dark: {entry}\n")
        (areas_dir / "campaign.yaml").write_text(text)
        assert run(areas_dir, monkeypatch) == 1
        output = " ".join("".join(capsys.readouterr()).split())
        line = text.splitlines().index(f"    dark: {entry}") + 1
        said = (f"campaign.yaml:{line}:5: [C210] the rulebook declares the unknown area "
                "'dark', which this campaign gives no polygons: its signals are 0 in every run")
        assert (said in output) is warned, output
        assert ("hint: give its polygons under environment.areas.dark.polygons, or `dark: "
                "{polygons: []}` to say the site has none" in output) is warned
        assert "Traceback" not in output


def test_scoring_stored_runs_with_a_rulebook_of_areas_the_campaign_never_placed_warns(
        areas_dir: Path, capsys, monkeypatch: pytest.MonkeyPatch) -> None:
    """evaluate --rulebook and diff --results say C210 as a run does: the new rulebook's
    keep-out rule holds in every run only because the campaign gave its area no polygons."""
    text = CAMPAIGN.replace(
        '    dark:\n      polygons: [[["0.55 m", "0.5 m"], ["1 m", "0.5 m"], ["1 m", "1 m"]]]\n',
        "")
    (areas_dir / "campaign.yaml").write_text(text)
    (areas_dir / "placed.rules").write_text(RULEBOOK.replace(
        '  area dark unknown level L2 buffer 30 cm because "Not seen by the navigation cameras"\n',
        "").replace("chance near_dark = any over time (area.dark.buffer > 0)\n", "").replace(
        "chance entered_dark = any over time (area.dark.inside > 0)\n", ""))
    (areas_dir / "campaign.yaml").write_text(text.replace("rulebook: areas.rules",
                                                          "rulebook: placed.rules"))
    assert run(areas_dir, monkeypatch) == 1
    assert "C210" not in "".join(capsys.readouterr())  # every area of its rulebook placed
    results = str(areas_dir / "out" / "results.h5")
    rulebooks = [str(areas_dir / "placed.rules"), str(areas_dir / "areas.rules")]
    # crater_kept fails under either rulebook: evaluate exits 1, diff 0 (no verdict changes)
    for argv, code in ((["evaluate", results, "--rulebook", rulebooks[1]], 1),
                       (["diff", *rulebooks, "--results", results], 0)):
        assert main(argv) == code
        output = "".join(capsys.readouterr())
        flat = " ".join(output.split())
        assert "[C210] the rulebook declares the unknown area 'dark', which this campaign " \
               "gives no polygons" in flat, output
        assert ("new rulebook: " in flat) == (argv[0] == "diff")
        assert "area 'crater'" not in flat


@pytest.mark.parametrize("elevation", [100.0, -30.0])
def test_areas_stay_where_the_rover_drives_on_a_dem_at_a_sites_elevation(
        areas_dir: Path, capsys, monkeypatch: pytest.MonkeyPatch, elevation: float) -> None:
    """A DEM in site elevation, 100 m up (or 30 m down): the areas' prisms were placed about
    height 0 and reached 20 m, so the rover drove through the crater without a hit."""
    np.save(areas_dir / "site.npy", np.full((151, 151), elevation))
    text = CAMPAIGN.replace(
        '    synthetic: {size: "3 m", cell: "2 cm", slope: "0 deg", roughness: "0 mm", seed: 1}',
        '    dem: site.npy\n    cell: "2 cm"\n    origin: ["-1.5 m", "-1.5 m"]')
    (areas_dir / "campaign.yaml").write_text(text)
    assert run(areas_dir, monkeypatch) == 1
    with h5py.File(areas_dir / "out" / "results.h5", "r") as results:
        chances = results["paths/straight/evaluation/chances"]
        assert np.all(chances["entered_crater"][()] == 1)
        assert np.all(chances["hit_L3"][()] == 1)  # the crater's prism is hit, L3


def test_a_steep_patch_reaches_from_its_lowest_to_its_highest_ground() -> None:
    """A ramp 100 m high is one steep patch: its box spans the ramp's heights (it was a box
    20 m above and below the patch's mean height, 50 m, above the ramp's foot)."""
    from idefix_rules.obstacles.named import steep_area

    heights = np.tile(np.linspace(0.0, 100.0, 60), (20, 1))  # 100 m over 59 cells of 2 m
    area = steep_area("scarp", "L3", 0.05, np.radians(20), heights, (0.0, 0.0), 2.0)
    (obstacle,) = area.obstacles(heights)
    for piece in obstacle.pieces:
        low = piece.centre[2] - piece.size[2] / 2
        high = piece.centre[2] + piece.size[2] / 2
        assert low <= -20.0 + 1e-9 and high >= 120.0 - 1e-9
