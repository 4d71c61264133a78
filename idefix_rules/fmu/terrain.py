"""Terrain for the rover FMU: a DEM heightmap plus rigid rocks, and the file the FMU reads.

The format is documented in ``docs/terrain-format.md``. The obstacle checker builds its
geometry from the same :class:`Rock` records, so both see identical rocks.

>>> t = synthetic_terrain(size=2.0, cell=0.05, slope=0.1, seed=1)
>>> t.heights.shape
(41, 41)
>>> round(float(t.height_at(0.5, 0.0) - t.height_at(-0.5, 0.0)), 3)  # downhill along +x
-0.1
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from idefix_rules.errors import Span, UserInputError, error, read_user_text
from idefix_rules.files import write_atomic
from idefix_rules.fmu.terrain_header import MAGIC, MAX_NODES, read_header
from idefix_rules.limits import (
    MAX_CSV_DEM_BYTES,
    MAX_NPY_DEM_BYTES,
    MAX_TERRAIN_EXTENT,
    MAX_TERRAIN_HEADER_BYTES,
    MAX_TERRAIN_HEIGHT,
    MAX_TERRAIN_ROCKS,
    TERRAIN_TOO_LARGE,
    check_file_size,
)
from idefix_rules.units import UnitError, plain_number

MAX_ROCKS = MAX_TERRAIN_ROCKS


@dataclass(frozen=True)
class Rock:
    """A rigid rock: an axis-aligned ellipsoid, SI units.

    ``z`` is the centre height above the terrain datum; ``None`` places the rock on the ground
    at (x, y) with its bottom ``embed`` metres deep (resolved by :class:`Terrain`). ``level`` is the
    obstacle level ("L1", "L2", "L3") when known.
    """

    x: float
    y: float
    a: float
    b: float
    c: float
    z: float | None = None
    embed: float = 0.0
    level: str | None = None

    @property
    def top(self) -> float:
        """Height of the rock's highest point (needs a resolved ``z``)."""
        if self.z is None:
            raise ValueError("rock height not resolved; build it through a Terrain")
        return self.z + self.c


@dataclass(frozen=True)
class Terrain:
    """Heights (ny, nx) in m on a regular grid, row j at ``origin[1] + j*cell``, plus rocks."""

    heights: np.ndarray
    origin: tuple[float, float] = (0.0, 0.0)
    cell: float = 0.02
    rocks: tuple[Rock, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        heights = np.ascontiguousarray(self.heights, dtype=np.float64)
        if heights.ndim != 2 or min(heights.shape) < 2:
            raise ValueError("heights must be a 2-D array of at least 2 x 2")
        object.__setattr__(self, "heights", heights)
        object.__setattr__(self, "origin", (float(self.origin[0]), float(self.origin[1])))
        resolved = tuple(
            rock if rock.z is not None else replace(
                rock, z=float(self.height_at(rock.x, rock.y)) + rock.c - rock.embed)
            for rock in self.rocks
        )
        object.__setattr__(self, "rocks", resolved)

    @property
    def shape(self) -> tuple[int, int]:
        ny, nx = self.heights.shape
        return ny, nx

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) of the grid."""
        ny, nx = self.heights.shape
        x0, y0 = self.origin
        return x0, x0 + (nx - 1) * self.cell, y0, y0 + (ny - 1) * self.cell

    def height_at(self, x: float | np.ndarray, y: float | np.ndarray) -> np.ndarray:
        """Bilinear ground height (rocks excluded); edge values continue outside the grid."""
        ny, nx = self.heights.shape
        fx = np.clip((np.asarray(x, dtype=float) - self.origin[0]) / self.cell, 0, nx - 1)
        fy = np.clip((np.asarray(y, dtype=float) - self.origin[1]) / self.cell, 0, ny - 1)
        i = np.minimum(fx.astype(int), nx - 2)
        j = np.minimum(fy.astype(int), ny - 2)
        tx, ty = fx - i, fy - j
        h = self.heights
        heights: np.ndarray = ((1 - ty) * ((1 - tx) * h[j, i] + tx * h[j, i + 1])
                               + ty * ((1 - tx) * h[j + 1, i] + tx * h[j + 1, i + 1]))
        return heights


def flat_terrain(size: float = 6.0, cell: float = 0.05) -> Terrain:
    """Level ground at z = 0 centred on the origin."""
    return synthetic_terrain(size=size, cell=cell)


def synthetic_terrain(size: float | tuple[float, float] = 6.0, cell: float = 0.02,
                      slope: float = 0.0, slope_direction: float = 0.0,
                      roughness: float = 0.0, seed: int = 0,
                      rocks: Iterable[Rock] = (), correlation_length: float = 0.1,
                      centre: tuple[float, float] = (0.0, 0.0)) -> Terrain:
    """A generated terrain centred on ``centre``.

    ``slope`` (rad) descends towards ``slope_direction`` (rad from +x); ``roughness`` is the
    RMS height (m) of Gaussian-correlated noise with ``correlation_length`` (m), reproducible
    from ``seed``. Rocks with ``z=None`` are placed on the generated ground.
    """
    sx, sy = (size, size) if isinstance(size, (int, float)) else size
    if cell <= 0 or sx <= cell or sy <= cell:
        raise UserInputError(error("F201", f"terrain size {size} and cell {cell} must be "
                                   "positive with size > cell"))
    nx, ny = round(sx / cell) + 1, round(sy / cell) + 1
    x0, y0 = centre[0] - (nx - 1) * cell / 2, centre[1] - (ny - 1) * cell / 2
    xs = x0 + cell * np.arange(nx)
    ys = y0 + cell * np.arange(ny)
    gx, gy = np.meshgrid(xs - centre[0], ys - centre[1])
    gradient = math.tan(slope)
    heights = -gradient * (gx * math.cos(slope_direction) + gy * math.sin(slope_direction))
    if roughness > 0.0:
        from scipy.ndimage import gaussian_filter

        noise = np.random.default_rng(seed).standard_normal((ny, nx))
        noise = gaussian_filter(noise, sigma=max(correlation_length / cell, 0.5), mode="wrap")
        noise *= roughness / max(float(noise.std()), 1e-12)
        heights = heights + noise
    return Terrain(heights, (x0, y0), cell, tuple(rocks))


def write_terrain(path: str | Path, terrain: Terrain) -> Path:
    """Write ``terrain`` in the FMU's format (text header, then little-endian float64 rows)."""
    path = Path(path)
    ny, nx = terrain.heights.shape
    if len(terrain.rocks) > MAX_ROCKS:
        raise UserInputError(error("F202", f"{len(terrain.rocks)} rocks; at most {MAX_ROCKS} "
                                   f"(the rover model holds {MAX_ROCKS})"))
    widest = (max(nx, ny) - 1) * terrain.cell
    if not widest <= MAX_TERRAIN_EXTENT:
        raise UserInputError(error("F201", f"terrain of {nx} x {ny} nodes {terrain.cell:.12g} m "
                                   f"apart is {widest:.6g} m wide; at most "
                                   f"{MAX_TERRAIN_EXTENT / 1000:g} km"))
    lines = [MAGIC, f"nx {nx}", f"ny {ny}",
             f"origin {terrain.origin[0]!r} {terrain.origin[1]!r}", f"cell {terrain.cell!r}",
             f"rocks {len(terrain.rocks)}"]
    for rock in terrain.rocks:
        lines.append(f"rock {rock.x!r} {rock.y!r} {rock.z!r} {rock.a!r} {rock.b!r} {rock.c!r}"
                     + (f" {rock.level}" if rock.level else ""))
    lines.append("heights")
    data = ("\n".join(lines) + "\n").encode("ascii")
    data += terrain.heights.astype("<f8").tobytes(order="C")
    write_atomic(path, data)  # a full disk leaves no part of it behind
    return path


def read_terrain(path: str | Path) -> Terrain:
    """Read a terrain file written by :func:`write_terrain` (or by hand, same format): its
    header as the rover model reads it (:mod:`~idefix_rules.fmu.terrain_header`), its grid,
    and every rock resting on or in the ground."""
    path = Path(path)
    check_file_size(path, MAX_TERRAIN_HEADER_BYTES + 8 * MAX_NODES, TERRAIN_TOO_LARGE,
                    "terrain file")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise UserInputError(error("F203", f"cannot read terrain file: {exc.strerror}",
                                   Span(str(path)))) from None
    header = read_header(data, str(path))
    sources = {str(path): header.text}  # the header's text only: never the grid's bytes

    def fail(message: str, line: int = header.end_line, hint: str | None = None
             ) -> UserInputError:
        return UserInputError(error("F204", message, Span(str(path), line, 1), hint=hint),
                              sources=sources)

    nx, ny, offset = header.nx, header.ny, header.grid_offset
    expected = nx * ny * 8
    if len(data) - offset != expected:
        raise fail(f"height grid holds {len(data) - offset} bytes, expected {expected} "
                   f"({nx} x {ny} float64)")
    heights = np.frombuffer(data, dtype="<f8", count=nx * ny, offset=offset).reshape(ny, nx)
    if not np.all(np.isfinite(heights)):
        raise fail("height grid holds NaN or infinite values")
    beyond = beyond_heights(heights)
    if beyond:
        raise fail(f"height grid: {beyond}")
    terrain = Terrain(heights.copy(), header.origin, header.cell)
    rocks = tuple(Rock(r.x, r.y, r.a, r.b, r.c, z=r.z, level=r.level) for r in header.rocks)
    centres = terrain.height_at(np.array([r.x for r in rocks]), np.array([r.y for r in rocks]))
    for rock, given, centre in zip(rocks, header.rocks, np.atleast_1d(centres), strict=True):
        base, line = given.z - given.c, given.line
        if base <= float(centre) + ROCK_REST_TOLERANCE:
            continue  # on or in the ground at its centre (every rock write_terrain writes)
        ground = highest_ground_under(terrain, rock)
        if base > ground + ROCK_REST_TOLERANCE:
            raise fail(f"rock at ({rock.x:g} m, {rock.y:g} m) floats: its lowest point "
                       f"(z - c = {base:.6g} m) is {base - ground:.6g} m above the highest "
                       f"ground under it ({ground:.6g} m)", line,
                       hint="a rock rests on or in the ground: z = the ground at its centre "
                            "+ c - the depth its bottom is buried")
    return replace(terrain, rocks=rocks)


# How far a rock's lowest point may lie above the ground under it and still rest there: a z
# written to the millimetre (a hand-made file, a survey's rounding) still rests; a file written
# by write_terrain has its rocks exactly on or in the ground, to rounding (1e-11 m at 100 km).
ROCK_REST_TOLERANCE = 0.001


def highest_ground_under(terrain: Terrain, rock: Rock) -> float:
    """The highest ground (bilinear, rocks excluded) within the rectangle x ± a, y ± b around
    ``rock``'s outline: a rock resting on a slope or a bump touches the ground there, above
    the ground at its centre (a sphere of radius r on a slope α by r·(1/cos α − 1)).

    The bilinear surface is linear along every grid line, so its highest point in the
    rectangle is a grid node inside it or a point where its edges cross a grid line (or a
    corner); the grid is clamped at its edges, as the heights continue there.

    >>> flat = Terrain(np.array([[0.0, 0.0], [1.0, 1.0]]), (0.0, 0.0), 1.0)
    >>> float(highest_ground_under(flat, Rock(0.5, 0.25, 0.1, 0.25, 0.1)))
    0.5
    """
    ny, nx = terrain.heights.shape
    x0, y0 = terrain.origin
    cell = terrain.cell

    def lines_across(low: float, high: float, origin: float, count: int) -> np.ndarray:
        """The rectangle's edges and the grid lines between them, in grid units, clamped."""
        lo = min(max((low - origin) / cell, 0.0), count - 1.0)
        hi = min(max((high - origin) / cell, 0.0), count - 1.0)
        inner = np.arange(math.floor(lo) + 1, math.ceil(hi), dtype=float)
        return np.concatenate(([lo], inner, [hi]))

    fx = lines_across(rock.x - rock.a, rock.x + rock.a, x0, nx)
    fy = lines_across(rock.y - rock.b, rock.y + rock.b, y0, ny)
    inner_x = fx[1:-1].astype(int)
    inner_y = fy[1:-1].astype(int)
    highest = -math.inf
    if inner_x.size and inner_y.size:  # the nodes inside: a slice, however many
        highest = float(terrain.heights[inner_y[0]:inner_y[-1] + 1,
                                        inner_x[0]:inner_x[-1] + 1].max())
    xs, ys = x0 + cell * fx, y0 + cell * fy
    for edge_x, edge_y in ((xs, ys[[0, -1]]), (xs[[0, -1]], ys)):  # the edges' crossings
        gx, gy = np.meshgrid(edge_x, edge_y)
        highest = max(highest, float(np.max(terrain.height_at(gx, gy))))
    return highest


HEIGHT_GRID_SUFFIXES = (".npy", ".csv")  # DEMs of bare heights: no cell size, no origin


def load_dem(path: str | Path, cell: float | None = None,
             origin: tuple[float, float] | None = None, rocks: Sequence[Rock] = ()) -> Terrain:
    """A user DEM: our terrain format, a ``.npy`` 2-D array, or a ``.csv`` grid of heights.

    For ``.npy`` and ``.csv`` row j is y = origin[1] + j*cell and column i is
    x = origin[0] + i*cell; ``cell`` is required, ``origin`` defaults to centring the grid on
    (0, 0). Rocks given here are added to the file's own.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in HEIGHT_GRID_SUFFIXES:
        terrain = read_terrain(path)
        return replace(terrain, rocks=terrain.rocks + tuple(rocks)) if rocks else terrain
    if cell is None or cell <= 0:
        raise UserInputError(error("F205", "a .npy or .csv DEM needs a positive cell size",
                                   Span(str(path))))
    check_file_size(path, MAX_NPY_DEM_BYTES if suffix == ".npy" else MAX_CSV_DEM_BYTES,
                    TERRAIN_TOO_LARGE, "DEM file")
    if suffix == ".npy":
        try:
            heights = np.load(path, allow_pickle=False)
        except EOFError:  # an empty file
            raise UserInputError(error("F203", "cannot read DEM: the file is empty",
                                       Span(str(path)))) from None
        except (OSError, ValueError) as exc:
            # numpy's words for a file of Python objects advise loading it unsafely: never;
            # numpy takes any file without its header for a pickle (a text file named .npy)
            reason = str(exc)
            if "pickle" in str(exc):
                reason = ("not an array of numbers: numpy reads it as pickled Python objects, "
                          "which are never loaded") if _has_npy_header(path) else \
                    "not a .npy file: it has no NumPy header (a .npy file starts with \\x93NUMPY)"
            raise UserInputError(error("F203", f"cannot read DEM: {reason}", Span(str(path)))) \
                from None
        if not isinstance(heights, np.ndarray):  # an .npz archive under an .npy name
            raise UserInputError(error("F203", "cannot read DEM: the file is an .npz archive "
                                       "of arrays, not one .npy array", Span(str(path))))
        # numbers only: text, bytes, records, dates, times or complex values are no heights
        # (a cast would fail, or take a date for its day count, or drop an imaginary part)
        if heights.dtype.kind not in "biuf":
            raise UserInputError(error(
                "F203", f"cannot read DEM: the array holds {_dtype_words(heights.dtype)}, "
                        "not numbers (heights in metres)", Span(str(path))))
    else:
        heights = _read_csv(path)
    if np.size(heights) > MAX_NODES:  # a float32 grid fits the byte limit with twice as many
        shape = " x ".join(map(str, np.shape(heights)))
        raise UserInputError(error(
            "F204", f"DEM has {np.size(heights):,} heights ({shape}); at most {MAX_NODES:,} "
                    "are accepted", Span(str(path)),
            hint="resample the DEM to a coarser cell, or cut it to the area the chains cross"))
    heights = np.asarray(heights, dtype=float)
    if heights.ndim != 2 or min(heights.shape) < 2:
        raise UserInputError(error("F206", "DEM must be a finite 2-D grid of at least 2 x 2",
                                   Span(str(path))))
    if not np.all(np.isfinite(heights)):
        row, column = (int(i) for i in np.argwhere(~np.isfinite(heights))[0])
        raise UserInputError(error(
            "F206", f"DEM must be a finite 2-D grid: row {row}, column {column} (0-based) holds "
                    f"{heights[row, column]}", Span(str(path)),
            hint="fill the no-data cells (interpolate them, or cut the DEM to the area with "
                 "data)"))
    beyond = beyond_heights(heights)
    if beyond:
        raise UserInputError(error("F206", f"DEM {beyond}", Span(str(path)), hint=HEIGHTS_HINT))
    ny, nx = heights.shape
    if origin is None:
        origin = (-(nx - 1) * cell / 2, -(ny - 1) * cell / 2)
    return Terrain(heights, origin, cell, tuple(rocks))


PLAIN_HEIGHTS = ("a height is a plain decimal number in metres: a sign, the digits 0-9, a point, "
                 "an exponent (-1.25e-3)")
HEIGHTS_HINT = ("heights are metres from a datum near the ground (every planet's surface lies "
                f"within {MAX_TERRAIN_HEIGHT / 1000:g} km of its reference); a no-data value "
                "(1e308, 3.4e38) marks cells to fill or cut away")


def beyond_heights(heights: np.ndarray) -> str:
    """Where the finite ``heights`` leave the plausible range (±:data:`MAX_TERRAIN_HEIGHT`),
    in words, or "" when they do not.

    >>> beyond_heights(np.array([[0.0, 1.0], [2e5, 0.0]]))
    'height 200000 m at row 1, column 0 (0-based) is beyond ±100000 m of the datum'
    """
    outside = np.abs(heights) > MAX_TERRAIN_HEIGHT
    if not outside.any():
        return ""
    row, column = (int(i) for i in np.argwhere(outside)[0])
    return (f"height {heights[row, column]:.6g} m at row {row}, column {column} (0-based) is "
            f"beyond ±{MAX_TERRAIN_HEIGHT:g} m of the datum")


def _has_npy_header(path: Path) -> bool:
    """Whether ``path`` starts as every .npy file does (``\\x93NUMPY``)."""
    try:
        with path.open("rb") as handle:
            return handle.read(6) == b"\x93NUMPY"
    except OSError:
        return False


def _dtype_words(dtype: np.dtype[Any]) -> str:
    """What an array of ``dtype`` holds, in words (``text (<U1)``)."""
    words = {"U": "text", "S": "bytes", "V": "records", "M": "dates", "m": "time spans",
             "c": "complex numbers", "O": "Python objects"}
    return f"{words.get(dtype.kind, 'values')} ({dtype.str})"


def _read_csv(path: Path) -> np.ndarray:
    # bytes that are not UTF-8 (a CSV saved as Latin-1): named at their line and column, with
    # the way out; a byte-order mark (Excel's "CSV UTF-8") is no part of the first height
    text = read_user_text(path, "F203", "DEM file").removeprefix("\ufeff")
    # Cells are separated by commas, or by semicolons in a file whose rows hold one (its
    # comment lines say nothing about it): there (as the
    # CSV of locales that write a decimal comma gives it) a comma is the decimal sign, read as
    # a point; splitting on both read '0,01;0,02' as four heights 0, 1, 0, 2.
    separator = ";" if any(";" in line for line in text.splitlines()
                           if not line.lstrip().startswith("#")) else ","
    rows: list[list[float]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        cells = line.rstrip().split(separator)
        if len(cells) > 1 and not cells[-1].strip():
            cells = cells[:-1]  # a separator ending the row (some tools write one)
        row = []
        for column, cell_text in enumerate(cells):
            # plain decimal numbers only: Python's float() reads 1_000 as 1000 and every
            # script's digits, and 1e-400 as 0
            refused = ""
            try:
                value: float | None = plain_number(cell_text.replace(",", ".")
                                                   if separator == ";" else cell_text)
            except UnitError as failure:
                value, refused = None, str(failure)
            token = cell_text.strip()
            if token.lstrip("+-").lower() in ("nan", "inf", "infinity"):
                value = math.nan  # a no-data value: said as one
            if value is not None and math.isfinite(value) and abs(value) <= MAX_TERRAIN_HEIGHT:
                row.append(value)
                continue
            col = sum(len(c) + 1 for c in cells[:column]) + 1
            col += len(cell_text) - len(cell_text.lstrip())  # at the number, not its blanks
            if value is None and not rows and refused.startswith("not a number"):
                # before any row of numbers it may be any file: quote none of it
                raise UserInputError(error(
                    "F207", "not a CSV grid of heights: this line is not a row of numbers",
                    Span(str(path), number, 1)), sources={str(path): ""}) from None
            shown = repr(token[:20]) + ("…" if len(token) > 20 else "")
            if value is None:  # 1_000, ٣, 1e-400: said why
                raise UserInputError(error(
                    "F207", f"not a number: {shown}" if refused.startswith("not a number")
                    else refused, Span(str(path), number, col), hint=PLAIN_HEIGHTS)) from None
            if not math.isfinite(value):  # nan, inf, 1e400
                raise UserInputError(error(
                    "F207", f"not a finite height: {shown}", Span(str(path), number, col))) \
                    from None
            raise UserInputError(error(
                "F207", f"height {shown} is beyond ±{MAX_TERRAIN_HEIGHT:g} m of the datum",
                Span(str(path), number, col), hint=HEIGHTS_HINT)) from None
        if rows and len(row) != len(rows[0]):
            raise UserInputError(error("F208", f"row has {len(row)} values, the first row has "
                                       f"{len(rows[0])}", Span(str(path), number, 1)))
        rows.append(row)
    return np.array(rows, dtype=float)
