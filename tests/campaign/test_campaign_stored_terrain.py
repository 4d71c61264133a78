"""The terrain a campaign was simulated on travels in its results file: a results.h5 copied
alone re-scores exactly as the campaign scored it, a changed DEM is said and not used, an
older file without a terrain is scored with a warning naming what is missing, and a resume
simulates on the stored terrain."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from campaign_texts import CAMPAIGN, RULEBOOK

from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.cli import main
from idefix_rules.fmu.terrain import Rock, Terrain, synthetic_terrain
from idefix_rules.fmu.terrain import write_terrain as write_terrain_file
from idefix_rules.report.prepare import setup_from_store
from idefix_rules.results import terrain as stored_terrain
from idefix_rules.results.terrain import (
    TerrainSource,
    read_terrain,
    terrain_for_rescoring,
    terrain_for_resume,
    terrain_sha256,
    write_terrain,
)

SYNTHETIC = TerrainSource("synthetic")
ROCKY = synthetic_terrain(size=2.0, cell=0.05, slope=0.1, roughness=0.003, seed=4,
                          rocks=[Rock(0.3, -0.26, 0.04, 0.04, 0.04, embed=0.01, level="L2"),
                                 Rock(-0.5, 0.2, 0.02, 0.03, 0.02)])


def stored_file(tmp_path: Path, terrain: Terrain | None = ROCKY,
                source: TerrainSource = SYNTHETIC) -> h5py.File:
    file = h5py.File(tmp_path / "results.h5", "w")
    file.attrs["format_version"] = 4 if terrain is not None else 3
    if terrain is not None:
        write_terrain(file, terrain, source)
    return file


# --- the stored terrain ---------------------------------------------------------------------

def test_the_stored_terrain_reads_back_exactly(tmp_path: Path) -> None:
    with stored_file(tmp_path) as file:
        back = read_terrain(file)
    assert back is not None
    assert np.array_equal(back.heights, ROCKY.heights)
    assert back.origin == ROCKY.origin and back.cell == ROCKY.cell
    assert [(r.x, r.y, r.z, r.a, r.b, r.c, r.level) for r in back.rocks] == \
        [(r.x, r.y, r.z, r.a, r.b, r.c, r.level) for r in ROCKY.rocks]
    assert terrain_sha256(back) == terrain_sha256(ROCKY)


def test_the_stored_terrain_needs_no_filter_beyond_hdf5s_own(tmp_path: Path) -> None:
    # deflate (gzip) and shuffle are built into every HDF5 library: any tool reads the terrain
    with stored_file(tmp_path) as file:
        group = file["terrain"]
        for name in ("heights", "rocks", "rock_levels"):
            plist = group[name].id.get_create_plist()
            filters = {plist.get_filter(i)[0] for i in range(plist.get_nfilters())}
            assert filters <= {h5py.h5z.FILTER_DEFLATE, h5py.h5z.FILTER_SHUFFLE}, name
        assert group["heights"].compression == "gzip" and group["heights"].shuffle
        assert list(group["rocks"].attrs["columns"]) == ["x", "y", "z", "a", "b", "c"]


def test_a_terrain_cut_off_before_its_digest_reads_as_none(tmp_path: Path) -> None:
    with stored_file(tmp_path) as file:
        del file["terrain"].attrs["sha256"]  # a kill before its last write
        assert read_terrain(file) is None
        write_terrain(file, ROCKY, SYNTHETIC)  # a resume writes it again
        assert read_terrain(file) is not None


# --- re-scoring ------------------------------------------------------------------------------

def test_rescoring_uses_the_stored_terrain_without_a_word(tmp_path: Path) -> None:
    with stored_file(tmp_path) as file:
        ground = terrain_for_rescoring(file, tmp_path / "results.h5")
    assert ground.terrain is not None and ground.warnings == ()
    assert terrain_sha256(ground.terrain) == terrain_sha256(ROCKY)


def test_a_changed_dem_is_named_and_the_stored_terrain_is_used(tmp_path: Path) -> None:
    dem = tmp_path / "site.npy"
    np.save(dem, ROCKY.heights)
    source = TerrainSource.of(dem)
    with stored_file(tmp_path, source=source) as file:
        assert terrain_for_rescoring(file, tmp_path / "results.h5").warnings == ()
        np.save(dem, ROCKY.heights + 0.01)
        ground = terrain_for_rescoring(file, tmp_path / "results.h5")
        assert ground.terrain is not None
        assert np.array_equal(ground.terrain.heights, ROCKY.heights)
        (warning,) = ground.warnings
        assert str(dem) in warning and "has changed" in warning
        dem.unlink()  # gone: the stored terrain stands alone, nothing to say
        assert terrain_for_rescoring(file, tmp_path / "results.h5").warnings == ()


def test_an_older_file_uses_the_terrain_file_beside_it_and_says_so(tmp_path: Path) -> None:
    write_terrain_file(tmp_path / "terrain.dem", ROCKY)
    with stored_file(tmp_path, terrain=None) as file:
        ground = terrain_for_rescoring(file, tmp_path / "results.h5")
    assert ground.terrain is not None
    (warning,) = ground.warnings
    assert "holds no terrain (results format 3" in warning and "terrain.dem beside it" in warning


def test_an_older_file_alone_puts_the_rocks_on_the_datum_and_says_so(tmp_path: Path) -> None:
    with stored_file(tmp_path, terrain=None) as file:
        ground = terrain_for_rescoring(file, tmp_path / "results.h5")
    assert ground.terrain is None
    (warning,) = ground.warnings
    assert "holds no terrain" in warning and "no terrain.dem is beside it" in warning
    assert "flat datum" in warning


# --- resuming --------------------------------------------------------------------------------

def test_a_resume_keeps_the_stored_terrain_and_names_the_changed_one(tmp_path: Path) -> None:
    dem = tmp_path / "site.npy"
    np.save(dem, ROCKY.heights)
    source = TerrainSource.of(dem)
    results = tmp_path / "results.h5"
    with stored_file(tmp_path, source=source) as file:
        terrain, warnings = terrain_for_resume(file, ROCKY, source, results)
        assert terrain_sha256(terrain) == terrain_sha256(ROCKY) and warnings == []
        steeper = synthetic_terrain(size=2.0, cell=0.05, slope=0.2, rocks=ROCKY.rocks[:1])
        terrain, warnings = terrain_for_resume(file, steeper, source, results)
    assert terrain_sha256(terrain) == terrain_sha256(ROCKY)  # the runs so far saw this one
    (warning,) = warnings
    assert str(dem) in warning and "heights differ by up to" in warning
    assert "1 rock(s), 2 stored" in warning and "without --resume" in warning


def test_a_resume_of_an_older_file_stores_the_campaigns_terrain(tmp_path: Path) -> None:
    with stored_file(tmp_path, terrain=None) as file:
        terrain, warnings = terrain_for_resume(file, ROCKY, SYNTHETIC, tmp_path / "results.h5")
    assert terrain is ROCKY
    (warning,) = warnings
    assert "held no terrain (results format 3)" in warning
    assert "the campaign's synthetic terrain is stored in it now" in warning


# --- end to end (toy FMU) --------------------------------------------------------------------

COLLISION_CHANCE = ("chance hit_L2 = any over parts (collision.hits[L2] > 0)\n"
                    '  because "Runs touching an L2 rock"\n')
# A slope and a rough ground: a rock's height depends on the ground under it.
ENVIRONMENT = """environment:
  terrain:
    synthetic: {size: "2 m", cell: "2 cm", slope: "6 deg", roughness: "4 mm", seed: 3}
  rocks:
    - {x: "0.3 m", y: "-0.26 m", radius: "4 cm", level: L2}
    - {x: "0.15 m", y: "0.3 m", radius: "2 cm", embed: "5 mm"}
  rock_levels: {l1_max_size: "3 cm", l2_max_size: "10 cm"}
"""


def evaluation_of(results: Path) -> dict[str, object]:
    """Every array the evaluation wrote per path, and the ranking."""
    found: dict[str, object] = {}
    with h5py.File(results, "r") as file:
        for path in file["paths"]:
            group = file["paths"][path].get("evaluation")
            if group is None:
                continue

            def keep(name: str, item: object, prefix: str = path) -> None:
                if isinstance(item, h5py.Dataset):
                    found[f"{prefix}/{name}"] = item[()]

            group.visititems(keep)
        found["ranking"] = json.loads(file["evaluation"].attrs["ranking"])
    return found


def assert_same(got: dict[str, object], expected: dict[str, object]) -> None:
    assert got.keys() == expected.keys()
    for key, values in expected.items():
        assert np.array_equal(np.asarray(got[key]), np.asarray(values),
                              equal_nan=np.asarray(values).dtype.kind == "f"), key


@pytest.fixture
def rocky_campaign(campaign_dir: Path) -> Path:
    """The toy campaign on a rough slope with rocks, its rulebook counting L2 hits; run."""
    rulebook = RULEBOOK.replace("prescreen reference_not_critical", COLLISION_CHANCE
                                + "\nprescreen reference_not_critical")
    (campaign_dir / "test.rules").write_text(rulebook)
    path = campaign_dir / "campaign.yaml"
    path.write_text(CAMPAIGN + ENVIRONMENT)
    assert main([str(path), "--quiet", "--no-report"]) == 1
    return campaign_dir / "out" / "results.h5"


@pytest.mark.slow
def test_a_results_file_copied_alone_rescores_as_the_campaign_did(
        rocky_campaign: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    original = evaluation_of(rocky_campaign)
    assert any(key.endswith("collisions/details") for key in original)
    alone = tmp_path / "alone" / "results.h5"
    alone.parent.mkdir()
    shutil.copy(rocky_campaign, alone)  # without its terrain.dem
    capsys.readouterr()
    assert main(["evaluate", str(alone), "--quiet"]) == 1
    shown = capsys.readouterr().out
    assert "terrain" not in shown  # nothing to warn about
    assert_same(evaluation_of(alone), original)

    # The terrain matters here: the same file without it (as an older format wrote it) puts
    # the rocks on the flat datum, says so, and the clearances change.
    older = tmp_path / "older" / "results.h5"
    older.parent.mkdir()
    shutil.copy(rocky_campaign, older)
    with h5py.File(older, "r+") as file:
        del file["terrain"]
        file.attrs["format_version"] = 3
    assert main(["evaluate", str(older), "--quiet"]) == 1
    shown = " ".join(capsys.readouterr().out.split())
    assert f"{older} holds no terrain (results format 3" in shown
    assert "no terrain.dem is beside it" in shown
    changed = evaluation_of(older)
    assert any(not np.array_equal(np.asarray(changed[key]), np.asarray(values))
               for key, values in original.items() if key.endswith("collisions/details"))

    # The report's maps stand on the same terrain, and say the same when it is missing.
    for results, notes in ((alone, 0), (older, 1)):
        store = ResultStore.open(results)
        try:
            setup = setup_from_store(store)
        finally:
            store.close()
        assert setup.collisions is not None
        assert sum("holds no terrain" in note for note in setup.notes) == notes


@pytest.mark.slow
def test_a_changed_dem_is_named_by_evaluate_and_resume_and_never_used(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rulebook = RULEBOOK.replace("prescreen reference_not_critical", COLLISION_CHANCE
                                + "\nprescreen reference_not_critical")
    (campaign_dir / "test.rules").write_text(rulebook)
    dem = campaign_dir / "site.npy"
    np.save(dem, ROCKY.heights)
    path = campaign_dir / "campaign.yaml"
    path.write_text(CAMPAIGN + 'environment:\n  terrain: {dem: site.npy, cell: "5 cm"}\n'
                    '  rocks:\n    - {x: "0.3 m", y: "-0.26 m", radius: "4 cm", level: L2}\n')
    assert main([str(path), "--quiet", "--no-report"]) == 1
    results = campaign_dir / "out" / "results.h5"
    original = evaluation_of(results)
    with h5py.File(results, "r") as file:
        assert file["terrain"].attrs["source"] == "dem"
        assert file["terrain"].attrs["source_path"] == str(dem.resolve())

    np.save(dem, ROCKY.heights + 0.05)  # the site's DEM is replaced after the campaign ran
    capsys.readouterr()
    assert main(["evaluate", str(results), "--quiet"]) == 1
    shown = " ".join(capsys.readouterr().out.split())
    assert f"the campaign's DEM {dem.resolve()} has changed" in shown
    assert_same(evaluation_of(results), original)

    assert main([str(path), "--quiet", "--no-report", "--resume"]) == 1
    shown = " ".join(capsys.readouterr().out.split())
    assert f"the DEM {dem.resolve()} now gives another terrain" in shown
    assert "heights differ by up to 0.05 m" in shown
    with h5py.File(results, "r") as file:
        kept = stored_terrain.read_terrain(file)
    assert kept is not None and np.array_equal(kept.heights, ROCKY.heights)
    assert_same(evaluation_of(results), original)
