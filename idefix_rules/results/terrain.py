"""The terrain a campaign was simulated on, stored in its results file (group ``/terrain``).

A results file is then enough to score its runs again as the campaign did: the obstacle
checker's rocks (their heights resolved on the ground), the ground under them and the steep
areas all come from the stored terrain, never from the campaign's DEM file or a ``terrain.dem``
next to the results, which may have changed or be gone (docs/results-format.md, "Terrain").

Written when the results file is created, and by a ``--resume`` of a file written before
results held their terrain; read by every re-scoring path (``evaluate``, ``diff --results``,
``report``) and by ``--resume``, which simulates the runs still missing on it.

>>> from idefix_rules.fmu.terrain import synthetic_terrain
>>> a = synthetic_terrain(size=1.0, cell=0.1, slope=0.1)
>>> terrain_differences(a, a)
[]
>>> terrain_differences(a, synthetic_terrain(size=1.0, cell=0.1))
['heights differ by up to 0.0502 m (of 11 x 11 nodes)']
"""

from __future__ import annotations

import contextlib
import hashlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from idefix_rules.fmu.terrain import Rock, Terrain
from idefix_rules.results.format import attribute_text

GROUP = "terrain"
ROCK_COLUMNS = ("x", "y", "z", "a", "b", "c")
# Heights are stored in chunks of at most this many nodes a side, shuffled and gzip-compressed
# (HDF5's built-in filters: readable by any HDF5 tool).
CHUNK_NODES = 256
COMPRESSION_LEVEL = 4
# Header, attributes and chunk index of the group and its datasets, for the free-space check.
HEADER_BYTES = 16 * 1024
FIRST_FORMAT_WITH_TERRAIN = 4


@dataclass(frozen=True)
class TerrainSource:
    """Where a campaign's terrain came from: its DEM file (absolute path and the sha256 of its
    bytes when the campaign was simulated), or the campaign's synthetic terrain (no file)."""

    kind: str  # "dem" or "synthetic"
    path: str = ""
    sha256: str = ""

    @classmethod
    def of(cls, dem: Path | None) -> TerrainSource:
        """The source of a campaign whose DEM is ``dem`` (None: synthetic terrain)."""
        if dem is None:
            return cls("synthetic")
        return cls("dem", str(Path(dem).resolve()), file_sha256(Path(dem)))

    def describe(self) -> str:
        """``'the DEM /site/dem.npy'`` or ``'the campaign's synthetic terrain'``."""
        return f"the DEM {self.path}" if self.kind == "dem" else \
            "the campaign's synthetic terrain"


def file_sha256(path: Path) -> str:
    with path.open("rb") as handle:
        return hashlib.file_digest(handle, "sha256").hexdigest()


def terrain_sha256(terrain: Terrain) -> str:
    """A digest of everything the checks read from a terrain: the height grid (shape and
    little-endian float64 values), its origin and cell, and every rock with its level."""
    digest = hashlib.sha256()
    digest.update(np.asarray(terrain.heights.shape, dtype="<i8").tobytes())
    digest.update(np.asarray([*terrain.origin, terrain.cell], dtype="<f8").tobytes())
    digest.update(np.ascontiguousarray(terrain.heights, dtype="<f8").tobytes())
    digest.update(_rock_table(terrain).astype("<f8").tobytes())
    digest.update("\0".join(rock.level or "" for rock in terrain.rocks).encode("utf-8"))
    return digest.hexdigest()


def _rock_table(terrain: Terrain) -> np.ndarray:
    """(rocks, 6): x, y, z, a, b, c of every rock (z resolved on the ground by the terrain)."""
    return np.array([_rock_row(rock) for rock in terrain.rocks],
                    dtype=np.float64).reshape(-1, 6)


def _rock_row(rock: Rock) -> tuple[float, ...]:
    z = rock.z if rock.z is not None else float("nan")
    return rock.x, rock.y, z, rock.a, rock.b, rock.c


def stored_bytes(terrain: Terrain) -> int:
    """At most what storing ``terrain`` takes (uncompressed), for the free-space check."""
    return terrain.heights.size * 8 + len(terrain.rocks) * 64 + HEADER_BYTES


# --- writing ----------------------------------------------------------------------------------

def write_terrain(file: h5py.File, terrain: Terrain, source: TerrainSource) -> None:
    """Store ``terrain`` as the file's ``/terrain`` (replacing one a kill left incomplete).

    Its ``sha256`` attribute is written last: a group without it is incomplete and read as
    absent."""
    if GROUP in file:
        del file[GROUP]
    group = file.create_group(GROUP)
    ny, nx = terrain.heights.shape
    heights = group.create_dataset(
        "heights", data=np.ascontiguousarray(terrain.heights, dtype=np.float64),
        chunks=(min(ny, CHUNK_NODES), min(nx, CHUNK_NODES)), compression="gzip",
        compression_opts=COMPRESSION_LEVEL, shuffle=True)
    heights.attrs["unit"] = "m"
    heights.attrs["axes"] = '["y", "x"]'
    rocks = group.create_dataset("rocks", data=_rock_table(terrain))
    rocks.attrs["columns"] = list(ROCK_COLUMNS)
    rocks.attrs["units"] = ["m"] * len(ROCK_COLUMNS)
    group.create_dataset("rock_levels", data=[rock.level or "" for rock in terrain.rocks],
                         dtype=h5py.string_dtype("utf-8"))
    group.attrs["origin"] = np.asarray(terrain.origin, dtype=np.float64)
    group.attrs["cell"] = float(terrain.cell)
    group.attrs["source"] = source.kind
    group.attrs["source_path"] = source.path
    group.attrs["source_sha256"] = source.sha256
    group.attrs["sha256"] = terrain_sha256(terrain)


# --- reading ----------------------------------------------------------------------------------

def has_terrain(file: h5py.File) -> bool:
    """Whether the file holds a complete stored terrain."""
    group = file.get(GROUP)
    return isinstance(group, h5py.Group) and "sha256" in group.attrs


def read_terrain(file: h5py.File) -> Terrain | None:
    """The stored terrain (None when the file holds none, or an incomplete one)."""
    if not has_terrain(file):
        return None
    group = file[GROUP]
    table = np.asarray(group["rocks"][()], dtype=np.float64).reshape(-1, 6)
    levels = [attribute_text(level) for level in group["rock_levels"][()]]
    rocks = tuple(Rock(x=float(x), y=float(y), a=float(a), b=float(b), c=float(c), z=float(z),
                       level=level or None)
                  for (x, y, z, a, b, c), level in zip(table, levels, strict=True))
    origin = np.asarray(group.attrs["origin"], dtype=np.float64)
    return Terrain(np.asarray(group["heights"][()], dtype=np.float64),
                   (float(origin[0]), float(origin[1])), float(group.attrs["cell"]), rocks)


def read_source(file: h5py.File) -> TerrainSource | None:
    """Where the stored terrain came from (None when the file holds none)."""
    if not has_terrain(file):
        return None
    attrs = file[GROUP].attrs
    return TerrainSource(attribute_text(attrs.get("source", "")),
                         attribute_text(attrs.get("source_path", "")),
                         attribute_text(attrs.get("source_sha256", "")))


# --- comparing --------------------------------------------------------------------------------

def terrain_differences(stored: Terrain, current: Terrain) -> list[str]:
    """What differs between two terrains, in words (empty when they are the same)."""
    found = []
    if stored.heights.shape != current.heights.shape:
        found.append(f"the height grid is {_shape(current)} nodes, {_shape(stored)} stored")
    elif not np.array_equal(stored.heights, current.heights):
        change = float(np.max(np.abs(stored.heights - current.heights)))
        found.append(f"heights differ by up to {change:.3g} m (of {_shape(stored)} nodes)")
    if stored.origin != current.origin or stored.cell != current.cell:
        found.append(f"origin {_point(current.origin)} and cell {current.cell:g} m, "
                     f"{_point(stored.origin)} and {stored.cell:g} m stored")
    if len(stored.rocks) != len(current.rocks):
        found.append(f"{len(current.rocks)} rock(s), {len(stored.rocks)} stored")
        return found
    moved = sum((_rock_row(a), a.level) != (_rock_row(b), b.level)
                for a, b in zip(stored.rocks, current.rocks, strict=True))
    if moved:
        found.append(f"{moved} of {len(stored.rocks)} rock(s) differ (place, size, height or "
                     "level)")
    return found


def _shape(terrain: Terrain) -> str:
    ny, nx = terrain.heights.shape
    return f"{nx} x {ny}"


def _point(point: tuple[float, float]) -> str:
    return f"({point[0]:g} m, {point[1]:g} m)"


# --- choosing the terrain of a stored campaign -------------------------------------------------

@dataclass(frozen=True)
class StoredTerrain:
    """The terrain to check a stored campaign's runs on (None: the campaign's rocks resting on
    the flat datum, for files that hold none and have no ``terrain.dem`` beside them), and what
    the user should know about that choice."""

    terrain: Terrain | None
    warnings: tuple[str, ...] = ()


def terrain_for_rescoring(file: h5py.File, results: Path) -> StoredTerrain:
    """The terrain the runs of ``results`` were simulated on, for scoring them again.

    The stored one whenever the file holds it; a warning says when the campaign's DEM file
    has changed since (the runs are still scored on the stored terrain: they were simulated on
    it). A file written before results held their terrain (format 3 and older) is scored on
    the ``terrain.dem`` the campaign wrote beside it when that is still there, else with the
    rocks on the flat datum; a warning names what is missing either way.
    """
    terrain = read_terrain(file)
    if terrain is not None:
        source = read_source(file)
        return StoredTerrain(terrain, tuple(_changed_dem(source, results)))
    from idefix_rules.campaign.input.environment import TERRAIN_FILE
    from idefix_rules.campaign.input.environment import read_terrain as read_terrain_file

    version = attribute_text(file.attrs.get("format_version", "?"))
    missing = (f"{results} holds no terrain (results format {version}; the terrain is "
               f"stored from format {FIRST_FORMAT_WITH_TERRAIN} on)")
    beside = results.parent / TERRAIN_FILE
    try:
        found = read_terrain_file(results.parent)
    except Exception as failure:  # a damaged file: say so, rather than fail the scoring
        found = None
        missing += f", and the {TERRAIN_FILE} beside it cannot be read ({failure})"
    if found is not None:
        return StoredTerrain(found, (
            f"{missing}: the collision and area checks use the {TERRAIN_FILE} beside it, "
            "which the campaign wrote for its FMU (if it was replaced since, so is the "
            "ground the runs are checked on)",))
    if beside.exists():
        return StoredTerrain(None, (
            f"{missing}: the rocks are placed on the flat datum (z = 0) and no ground is "
            "steep; collision and area results differ from the campaign's unless its ground "
            "was flat",))
    return StoredTerrain(None, (
        f"{missing} and no {TERRAIN_FILE} is beside it: the rocks are placed on the flat "
        "datum (z = 0) and no ground is steep; collision and area results differ from the "
        f"campaign's unless its ground was flat (copy its {TERRAIN_FILE} beside the results, "
        "or simulate the campaign again)",))


def _changed_dem(source: TerrainSource | None, results: Path) -> Iterator[str]:
    """A warning when the campaign's DEM file is still there but no longer the one the
    campaign was simulated on (nothing when it is gone: the stored terrain stands alone)."""
    if source is None or source.kind != "dem" or not source.path:
        return
    path = Path(source.path)
    with contextlib.suppress(OSError):
        if path.is_file() and file_sha256(path) != source.sha256:
            yield (f"the campaign's DEM {path} has changed since the campaign was simulated: "
                   f"its runs are scored on the terrain stored in {results}, the one they "
                   "were simulated on")


def terrain_for_resume(file: h5py.File, campaign_terrain: Terrain, source: TerrainSource,
                       results: Path) -> tuple[Terrain, list[str]]:
    """The terrain a ``--resume`` simulates the missing runs on, and what to say about it:
    the stored one (the runs simulated so far saw it), with a warning when the campaign's
    terrain now differs; the campaign's own when the file holds none (it is stored then)."""
    stored = read_terrain(file)
    if stored is None:
        version = attribute_text(file.attrs.get("format_version", "?"))
        return campaign_terrain, [
            f"{results} held no terrain (results format {version}): {source.describe()} is "
            "stored in it now, and the runs simulated before this resume are taken to have "
            "been simulated on it"]
    if terrain_sha256(stored) == terrain_sha256(campaign_terrain):
        return stored, []
    differences = "; ".join(terrain_differences(stored, campaign_terrain)) or "its digest"
    return stored, [
        f"{source.describe()} now gives another terrain than the one stored in {results} "
        f"({differences}): the runs still missing are simulated on the stored terrain, as "
        "the runs before them were; to use the new terrain, run the campaign again without "
        "--resume"]
