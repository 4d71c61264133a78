"""Terrain files: round trip, generator, user DEMs, and errors that name file and line."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from idefix_rules.errors import UserInputError
from idefix_rules.fmu.terrain import (
    Rock,
    Terrain,
    highest_ground_under,
    load_dem,
    read_terrain,
    synthetic_terrain,
    write_terrain,
)


def test_round_trip_keeps_heights_and_rocks(tmp_path: Path) -> None:
    terrain = synthetic_terrain(size=(2.0, 1.0), cell=0.1, roughness=0.01, seed=4,
                                rocks=[Rock(0.2, 0.1, 0.05, 0.04, 0.03, level="L2")])
    back = read_terrain(write_terrain(tmp_path / "t.terrain", terrain))
    assert back.heights.shape == (11, 21)
    np.testing.assert_array_equal(back.heights, terrain.heights)
    assert back.origin == terrain.origin and back.cell == terrain.cell
    assert back.rocks == terrain.rocks


def test_rock_without_height_rests_on_the_ground_sunk_by_its_embedding() -> None:
    terrain = synthetic_terrain(size=2.0, cell=0.05, slope=0.2, slope_direction=0.0,
                                rocks=[Rock(0.5, 0.0, 0.1, 0.1, 0.05, embed=0.02)])
    rock = terrain.rocks[0]
    assert rock.z == pytest.approx(-math.tan(0.2) * 0.5 + 0.05 - 0.02)
    assert rock.top == pytest.approx(rock.z + 0.05)


def test_slope_descends_towards_its_direction_and_roughness_is_seeded() -> None:
    down_y = synthetic_terrain(size=2.0, cell=0.05, slope=0.1, slope_direction=-math.pi / 2)
    assert down_y.height_at(0.0, -0.5) < down_y.height_at(0.0, 0.5)
    a = synthetic_terrain(size=2.0, cell=0.05, roughness=0.01, seed=1)
    b = synthetic_terrain(size=2.0, cell=0.05, roughness=0.01, seed=1)
    c = synthetic_terrain(size=2.0, cell=0.05, roughness=0.01, seed=2)
    np.testing.assert_array_equal(a.heights, b.heights)
    assert not np.array_equal(a.heights, c.heights)
    assert float(a.heights.std()) == pytest.approx(0.01, rel=1e-6)


def test_bad_header_names_file_and_line(tmp_path: Path) -> None:
    path = tmp_path / "bad.terrain"
    path.write_bytes(b"IDEFIX-TERRAIN 1\nnx 2\nny 2\nwidth 3\nheights\n")
    with pytest.raises(UserInputError) as caught:
        read_terrain(path)
    span = caught.value.diagnostics[0].span
    assert span is not None and span.path == str(path) and span.line == 4
    assert "width" in caught.value.diagnostics[0].message


def test_short_height_grid_is_reported(tmp_path: Path) -> None:
    path = tmp_path / "short.terrain"
    path.write_bytes(b"IDEFIX-TERRAIN 1\nnx 3\nny 2\norigin 0 0\ncell 0.1\nrocks 0\nheights\n"
                     + np.zeros(5).tobytes())
    with pytest.raises(UserInputError, match="expected 48"):
        read_terrain(path)


def test_csv_dem_error_points_at_line_and_column(tmp_path: Path) -> None:
    path = tmp_path / "dem.csv"
    path.write_text("0.0,0.1,0.2\n0.0,x,0.2\n", encoding="utf-8")
    with pytest.raises(UserInputError) as caught:
        load_dem(path, cell=0.1)
    span = caught.value.diagnostics[0].span
    assert span is not None and (span.line, span.column) == (2, 5)


@pytest.mark.parametrize(("text", "expected"), [
    ("0.01,0.02,0.03\n0.04,0.05,0.06\n", [[0.01, 0.02, 0.03], [0.04, 0.05, 0.06]]),
    # semicolons and decimal commas (the CSV of locales that write 0,01): 3 heights a row,
    # never 0, 1, 0, 2, 0, 3
    ("0,01;0,02;0,03\r\n0,04;0,05;0,06\r\n", [[0.01, 0.02, 0.03], [0.04, 0.05, 0.06]]),
    ("1.5;2.5\n3.5;4.5\n", [[1.5, 2.5], [3.5, 4.5]]),  # semicolons, decimal points
    ("\ufeff1.0,2.0\n3.0,4.0\n", [[1.0, 2.0], [3.0, 4.0]]),  # Excel's byte-order mark
    ("1.0,2.0,\n3.0,4.0,\n", [[1.0, 2.0], [3.0, 4.0]]),  # a separator ending each row
    # a semicolon in a comment says nothing about the rows' separator
    ("# survey 2026; heights in m\n0.00,0.01\n0.02,0.03\n", [[0.0, 0.01], [0.02, 0.03]]),
])
def test_csv_dialects_are_read_as_the_grid_they_write(
        tmp_path: Path, text: str, expected: list[list[float]]) -> None:
    path = tmp_path / "dem.csv"
    path.write_bytes(text.encode("utf-8"))
    np.testing.assert_array_equal(load_dem(path, cell=0.1).heights, expected)


@pytest.mark.parametrize(("text", "where"), [
    ("1,000.5;2\n3;4\n", (1, 1)),        # a thousands separator is not a number
    ("1.0,2.0,\n3.0,4.0,,\n", (2, 9)),  # one separator ends a row, two leave a cell empty
])
def test_csv_cells_that_are_no_number_are_named(tmp_path: Path, text: str,
                                                where: tuple[int, int]) -> None:
    path = tmp_path / "dem.csv"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(UserInputError) as caught:
        load_dem(path, cell=0.1)
    span = caught.value.diagnostics[0].span
    assert span is not None and (span.line, span.column) == where


def test_npy_and_csv_dems_load_with_their_cell(tmp_path: Path) -> None:
    grid = np.arange(12, dtype=float).reshape(3, 4) * 0.01
    np.save(tmp_path / "dem.npy", grid)
    (tmp_path / "dem.csv").write_text("\n".join(",".join(str(v) for v in row) for row in grid),
                                      encoding="utf-8")
    for name in ("dem.npy", "dem.csv"):
        terrain = load_dem(tmp_path / name, cell=0.5)
        np.testing.assert_allclose(terrain.heights, grid)
        assert terrain.extent == (-0.75, 0.75, -0.5, 0.5)
    with pytest.raises(UserInputError, match="cell"):
        load_dem(tmp_path / "dem.npy")


@pytest.mark.parametrize("dtype", [np.int16, np.uint8, np.float32, np.bool_])
def test_an_npy_dem_of_whole_or_single_precision_numbers_loads(tmp_path: Path, dtype) -> None:
    grid = (np.arange(12).reshape(3, 4) % 2).astype(dtype)
    np.save(tmp_path / "dem.npy", grid)
    terrain = load_dem(tmp_path / "dem.npy", cell=0.5)
    assert terrain.heights.dtype == np.float64
    np.testing.assert_array_equal(terrain.heights, grid.astype(float))


def test_height_at_interpolates_bilinearly() -> None:
    terrain = Terrain(np.array([[0.0, 1.0], [2.0, 3.0]]), (0.0, 0.0), 1.0)
    assert float(terrain.height_at(0.5, 0.5)) == pytest.approx(1.5)
    assert float(terrain.height_at(5.0, -5.0)) == pytest.approx(1.0)  # edge continues


@pytest.mark.parametrize(("x", "refused"), [(0.9, False), (0.95, False), (0.951, True)])
def test_a_rock_of_a_terrain_file_outside_its_grid_is_named_at_its_line(
        tmp_path: Path, x: float, refused: bool) -> None:
    from idefix_rules.fmu.terrain import Rock, Terrain, write_terrain

    path = tmp_path / "site.dem"
    heights = np.zeros((20, 20))  # cell 0.05 m from (0, 0): x and y up to 0.95 m
    write_terrain(path, Terrain(heights, (0.0, 0.0), 0.05, (Rock(x, 0.5, 0.02, 0.02, 0.02),)))
    if not refused:
        assert load_dem(path).rocks[0].x == x
        return
    with pytest.raises(UserInputError) as caught:
        load_dem(path)
    found = caught.value.diagnostics[0]
    assert found.code == "F204" and "lies outside the grid (x 0 … 0.95 m" in found.message
    assert found.span is not None and path.read_bytes().split(b"\n")[found.span.line - 1] \
        .startswith(b"rock ")


@pytest.mark.parametrize(("height", "refused"), [(100_000.0, False), (-100_000.0, False),
                                                 (100_000.001, True), (-100_000.001, True)])
def test_heights_lie_within_100_km_of_the_datum_in_every_dem_format(
        tmp_path: Path, height: float, refused: bool) -> None:
    grid = np.zeros((3, 4))
    grid[2, 1] = height
    np.save(tmp_path / "dem.npy", grid)
    (tmp_path / "dem.csv").write_text(
        "\n".join(",".join(str(float(v)) for v in row) for row in grid), encoding="utf-8")
    write_terrain(tmp_path / "site.dem", Terrain(grid, (0.0, 0.0), 0.5))
    for name, code, where in (("dem.npy", "F206", None), ("dem.csv", "F207", (3, 5)),
                              ("site.dem", "F204", (7, 1))):
        if not refused:
            assert load_dem(tmp_path / name, cell=0.5).heights[2, 1] == height
            continue
        with pytest.raises(UserInputError) as caught:
            load_dem(tmp_path / name, cell=0.5)
        found = caught.value.diagnostics[0]
        assert found.code == code and "beyond ±100000 m of the datum" in found.message
        assert found.span is not None and found.span.path == str(tmp_path / name)
        if where is None:  # a .npy has no lines: the cell is named by row and column
            assert "row 2, column 1 (0-based)" in found.message
        else:
            assert (found.span.line, found.span.column) == where


@pytest.mark.parametrize(("rock", "ground", "refused"), [
    ("rock 0.5 0.5 0 1000 1 1", 0.0, None),
    ("rock 0.5 0.5 0 1 1 1000.001", 0.0, "rock semi-axis 1000.001 m: at most 1000 m"),
    ("rock 0.5 0.5 0 1 0.0009 1", 0.0, "rock semi-axis 0.0009 m: at least 0.001 m"),
    ("rock 0.5 0.5 101000 1 1000 1000", 1e5, None),  # a 1 km rock on ground 100 km high
    ("rock 0.5 0.5 -101000.001 1 1 1", 0.0,
     "rock centre height -101000.001 m: at most 101000 m"),
])
def test_a_rock_of_a_terrain_file_is_at_most_1_km_and_near_the_ground(
        tmp_path: Path, rock: str, ground: float, refused: str | None) -> None:
    path = tmp_path / "site.dem"
    path.write_bytes(f"IDEFIX-TERRAIN 1\nnx 2\nny 2\norigin 0 0\ncell 1\nrocks 1\n{rock}\n"
                     "heights\n".encode() + np.full(4, ground).tobytes())
    if refused is None:
        assert len(read_terrain(path).rocks) == 1
        return
    with pytest.raises(UserInputError) as caught:
        read_terrain(path)
    found = caught.value.diagnostics[0]
    assert found.code == "F204" and found.message.startswith(refused)
    assert found.span is not None and found.span.line == 7


def test_a_synthetic_slope_over_its_size_is_plausible_up_to_100_km() -> None:
    """45 deg over 200 km reaches 100 km at its edges: just inside; 200.002 km just beyond
    (the campaign says so at its synthetic section, C100)."""
    import math

    from idefix_rules.fmu.terrain import beyond_heights, synthetic_terrain

    inside = synthetic_terrain(size=200e3, cell=100e3, slope=math.pi / 4)
    assert beyond_heights(inside.heights) == ""
    outside = synthetic_terrain(size=200.002e3, cell=100.001e3, slope=math.pi / 4)
    assert beyond_heights(outside.heights).startswith("height 100001 m at row 0, column 0")


def _with_rock(tmp_path: Path, terrain: Terrain, z: float, x: float = 0.5, r: float = 0.1) -> Path:
    return write_terrain(tmp_path / "site.dem", replace(terrain, rocks=(Rock(x, 0.0, r, r, r,
                                                                             z=z),)))


def test_a_rock_resting_on_a_slope_rests_and_one_above_the_ground_under_it_floats(
        tmp_path: Path) -> None:
    """A ball of radius r resting on a 30 deg slope has its lowest point r (1/cos 30° - 1) =
    1.5 cm above the ground at its centre, and touches the slope uphill of it: it rests. Its
    lowest point may lie up to 1 mm above the highest ground under its outline (a z written to
    the millimetre); beyond, it floats (a rock 1 km up was simulated as a tower)."""
    slope, r = math.radians(30), 0.1
    terrain = synthetic_terrain(size=2.0, cell=0.05, slope=slope)
    ground = float(terrain.height_at(0.5, 0.0))
    resting = ground + r / math.cos(slope)
    assert read_terrain(_with_rock(tmp_path, terrain, resting)).rocks[0].z == resting
    highest = ground + r * math.tan(slope)  # uphill edge of the outline, x = 0.4 m
    for gap, floats in ((0.0009, False), (0.0011, True), (1000.0, True)):
        path = _with_rock(tmp_path, terrain, highest + gap + r)
        if not floats:
            assert len(read_terrain(path).rocks) == 1
            continue
        with pytest.raises(UserInputError) as caught:
            read_terrain(path)
        found = caught.value.diagnostics[0]
        assert found.code == "F204" and found.span is not None and found.span.line == 7
        assert found.message == (
            f"rock at (0.5 m, 0 m) floats: its lowest point (z - c = {highest + gap:.6g} m) is "
            f"{gap:.6g} m above the highest ground under it ({highest:.6g} m)")


def test_the_highest_ground_under_a_rock_is_found_between_the_grid_nodes() -> None:
    """Bilinear ground is linear along grid lines: its highest point under a rock's outline
    is a node inside it or where the outline's edges cross a grid line."""
    heights = np.zeros((5, 5))
    heights[2, 2] = 1.0  # a peak at (2, 2)
    terrain = Terrain(heights, (0.0, 0.0), 1.0)
    assert float(highest_ground_under(terrain, Rock(2.0, 2.0, 0.5, 0.5, 0.1))) == 1.0
    assert float(highest_ground_under(terrain, Rock(1.2, 2.0, 0.5, 0.1, 0.1))) == \
        pytest.approx(0.7)  # the outline's edge x = 1.7 m, on the grid line y = 2 m
    assert float(highest_ground_under(terrain, Rock(0.2, 0.2, 0.1, 0.1, 0.1))) == 0.0


def test_a_header_line_the_rover_model_would_read_as_two_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "site.dem"
    path.write_bytes(b"IDEFIX-TERRAIN 1\nnx 2\nny 2\norigin 0 " + b"0" * 505 + b"\ncell 1\n"
                     b"heights\n" + np.zeros(4).tobytes())
    with pytest.raises(UserInputError) as caught:
        read_terrain(path)
    found = caught.value.diagnostics[0]
    assert found.message == ("header line of 514 characters: at most 510 (the rover model reads "
                             "a longer line as two)")
    assert found.span is not None and (found.span.line, found.span.column) == (4, 511)
