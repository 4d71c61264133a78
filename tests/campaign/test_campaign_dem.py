"""User DEMs in a campaign: our terrain format, ``.npy`` and ``.csv`` heights (cell and origin
from the campaign file), and the mistakes around them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from campaign_texts import CAMPAIGN

from idefix_rules.campaign.input.environment import build_terrain
from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.cli import main
from idefix_rules.errors import UserInputError
from idefix_rules.fmu.terrain import Terrain, read_terrain, write_terrain

GRID = np.array([[0.0, 0.01, 0.02, 0.03],
                 [0.0, 0.02, 0.04, 0.06],
                 [0.0, 0.03, 0.06, 0.09]])


def with_terrain(campaign_dir: Path, terrain: str) -> Path:
    path = campaign_dir / "campaign.yaml"
    path.write_text(CAMPAIGN + "environment:\n  terrain:\n" + terrain)
    return path


def write_csv(path: Path, grid: np.ndarray) -> None:
    path.write_text("# heights in m, one grid row per line\n"
                    + "\n".join(",".join(f"{v:g}" for v in row) for row in grid) + "\n")


@pytest.mark.parametrize("name", ["dem.npy", "dem.csv"])
def test_height_grid_dems_take_cell_and_origin_from_the_campaign(campaign_dir: Path,
                                                                 name: str) -> None:
    if name.endswith(".npy"):
        np.save(campaign_dir / name, GRID)
    else:
        write_csv(campaign_dir / name, GRID)
    campaign = load_campaign(with_terrain(
        campaign_dir, f'    dem: {name}\n    cell: "5 cm"\n    origin: ["-1 m", "50 cm"]\n'))
    terrain = build_terrain(campaign.model.environment, campaign.dem)
    assert np.array_equal(terrain.heights, GRID)
    assert terrain.cell == pytest.approx(0.05)
    assert terrain.origin == pytest.approx((-1.0, 0.5))
    # without origin the grid is centred on (0, 0)
    centred = load_campaign(with_terrain(campaign_dir, f'    dem: {name}\n    cell: "5 cm"\n'))
    terrain = build_terrain(centred.model.environment, centred.dem)
    assert terrain.origin == pytest.approx((-0.075, -0.05))


def test_a_terrain_file_dem_keeps_its_own_grid(campaign_dir: Path) -> None:
    write_terrain(campaign_dir / "site.dem", Terrain(GRID, (2.0, 3.0), 0.1, ()))
    campaign = load_campaign(with_terrain(campaign_dir, "    dem: site.dem\n"))
    terrain = build_terrain(campaign.model.environment, campaign.dem)
    assert np.array_equal(terrain.heights, GRID)
    assert terrain.origin == pytest.approx((2.0, 3.0)) and terrain.cell == pytest.approx(0.1)


def test_a_height_grid_without_cell_is_a_campaign_error_at_its_line(campaign_dir: Path) -> None:
    np.save(campaign_dir / "dem.npy", GRID)
    path = with_terrain(campaign_dir, "    dem: dem.npy\n")
    with pytest.raises(UserInputError) as caught:
        load_campaign(path)
    [diagnostic] = caught.value.diagnostics
    assert diagnostic.code == "C203" and "environment.terrain.cell" in diagnostic.message
    line = path.read_text().splitlines().index("    dem: dem.npy") + 1
    assert diagnostic.span is not None and diagnostic.span.line == line


def test_cell_or_origin_next_to_a_terrain_file_is_a_campaign_error(campaign_dir: Path) -> None:
    write_terrain(campaign_dir / "site.dem", Terrain(GRID, (2.0, 3.0), 0.1, ()))
    path = with_terrain(campaign_dir, '    dem: site.dem\n    cell: "5 cm"\n')
    with pytest.raises(UserInputError) as caught:
        load_campaign(path)
    [diagnostic] = caught.value.diagnostics
    assert diagnostic.code == "C204" and "environment.terrain.cell" in diagnostic.message


@pytest.mark.slow
def test_a_csv_dem_reaches_the_fmu_and_a_bad_value_names_file_and_line(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    write_csv(campaign_dir / "dem.csv", GRID)
    path = with_terrain(campaign_dir, '    dem: dem.csv\n    cell: "5 cm"\n')
    # too-fast breaks the command rule wheel_rate_limit (0.5 rad/s): rejected, exit 1
    assert main([str(path), "--runs", "2", "--quiet", "--no-report"]) == 1
    written = read_terrain(campaign_dir / "out" / "terrain.dem")
    assert np.array_equal(written.heights, GRID) and written.cell == pytest.approx(0.05)
    (campaign_dir / "dem.csv").write_text("0,0.01,0.02,0.03\n0,0.02,O.04,0.06\n"
                                          "0,0.03,0.06,0.09\n")
    capsys.readouterr()
    assert main([str(path), "--runs", "2", "--quiet", "--no-report"]) == 2
    err = capsys.readouterr().err
    assert f"{campaign_dir / 'dem.csv'}:2:" in err and "'O.04'" in err


def _dem_mistake(campaign_dir: Path, name: str) -> str:
    campaign = load_campaign(with_terrain(campaign_dir, f'    dem: {name}\n    cell: "5 cm"\n'))
    with pytest.raises(UserInputError) as caught:
        build_terrain(campaign.model.environment, campaign.dem)
    return caught.value.diagnostics[0].format()


def test_an_empty_npy_dem_is_a_user_error_naming_it(campaign_dir: Path) -> None:
    (campaign_dir / "empty.npy").write_bytes(b"")  # numpy raised EOFError: a traceback
    said = _dem_mistake(campaign_dir, "empty.npy")
    assert "empty.npy: error[F203]: cannot read DEM: the file is empty" in said


def test_a_dem_with_too_many_heights_is_refused_naming_it(campaign_dir: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """A float32 grid of more heights than the FMU reads fits the .npy byte limit: it was
    prepared, written as terrain.dem and refused there, naming a file the user never wrote."""
    import idefix_rules.fmu.terrain as terrain_module
    monkeypatch.setattr(terrain_module, "MAX_NODES", 12)
    np.save(campaign_dir / "just.npy", GRID.astype(np.float32))  # 12 heights: accepted
    campaign = load_campaign(with_terrain(campaign_dir, '    dem: just.npy\n    cell: "5 cm"\n'))
    assert build_terrain(campaign.model.environment, campaign.dem).heights.size == 12
    np.save(campaign_dir / "big.npy", np.zeros((3, 5), np.float32))  # 15: one row too many
    said = _dem_mistake(campaign_dir, "big.npy")
    assert "big.npy: error[F204]: DEM has 15 heights (3 x 5); at most 12 are accepted" in said


def test_a_non_finite_height_is_named_by_row_and_column(campaign_dir: Path) -> None:
    grid = GRID.copy()
    grid[2, 1] = np.nan
    np.save(campaign_dir / "holes.npy", grid)
    said = _dem_mistake(campaign_dir, "holes.npy")
    assert "holes.npy: error[F206]: DEM must be a finite 2-D grid: row 2, column 1 (0-based) " \
        "holds nan" in said
