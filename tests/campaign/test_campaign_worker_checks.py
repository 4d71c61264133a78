"""A run's collisions checked by the worker that simulated it: the pieces the evaluation stores
of a check of the stored runs (their poses at their stored precision, read back in a chunk of
several runs), whatever the precision the FMU gave them with."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from idefix_rules.campaign.evaluation.remembered import collision_pieces, run_collisions
from idefix_rules.campaign.storage.encoded_chunks import decode_chunk, encode_chunk
from idefix_rules.commands import RoverGeometry
from idefix_rules.obstacles import ObstacleSet, RoverBodies
from idefix_rules.results.collisions import POSE_SIGNALS, ObstacleCheck
from idefix_rules.results.format import storage_dtype


def wobbly_drive(offset: float, seed: int, samples: int = 801) -> dict[str, np.ndarray]:
    """One run past a rock, ``offset`` to its side; its tilt and height with more digits than
    float32 keeps."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 200.0, samples)
    return {"t": t, "x": np.linspace(0.0, 1.2, samples), "y": np.full(samples, offset),
            "z": RoverBodies().body_centre_height + 0.003 * rng.standard_normal(samples),
            "roll": 0.02 * rng.standard_normal(samples),
            "pitch": 0.02 * rng.standard_normal(samples),
            "yaw": 0.001 * rng.standard_normal(samples)}


def test_a_worker_checks_its_run_as_the_evaluation_checks_the_stored_chunk() -> None:
    rock = {"name": "rock", "x": 0.8, "y": -0.26, "z": 0.0, "radius": 0.08, "level": "L2"}
    checker = ObstacleCheck(ObstacleSet.from_rocks([rock], buffer_margins=[0.05] * 3), {},
                            RoverGeometry())
    assert any(storage_dtype(key) == np.float32 for key in POSE_SIGNALS)
    rows = np.array([4, 9, 11])  # complete runs of a look, one failed between them
    runs = [wobbly_drive(offset, seed) for seed, offset in enumerate((-0.01, 0.12, 0.3))]
    # the chunk the evaluation reads back: each run's stored chunk, decoded, as float64
    stored = {key: np.stack([decode_chunk(encode_chunk(key, run[key])) for run in runs]
                            ).astype(np.float64) for key in POSE_SIGNALS}
    chunk = collision_pieces(rows, *checker(stored, rows), stored["t"])
    hits = np.asarray(chunk["hits"])
    assert int(np.sum(hits > 0)) > 0 and int(np.sum(hits[2])) == 0  # the third run misses
    contact = np.asarray(chunk["contact"])
    for index, row in enumerate(rows.tolist()):
        found = run_collisions(checker, runs[index], row)
        for key in ("hits", "buffer", "clearance_profile"):
            assert np.array_equal(found[key][0], chunk[key][index], equal_nan=True), key
        assert np.array_equal(found["contact"], contact[contact[:, 0] == row]), row
        assert found["details"][0][1][0] == chunk["details"][0][1][index]
        assert f'"run": {row}'.encode() in found["details"][0][1][0]
    # checked at the FMU's float64 instead, the clearance is another one
    raw = collision_pieces(rows[:1], *checker({k: v[None] for k, v in runs[0].items()},
                                              rows[:1]), runs[0]["t"][None])
    assert not np.array_equal(raw["clearance_profile"][0], chunk["clearance_profile"][0])


def test_the_wheels_are_checked_where_the_campaigns_geometry_puts_them() -> None:
    """A campaign that sets `rover.half_track` drives its wheels there: a rock in their track
    is hit, one in the default track (0.26 m) passes between them; the defaults the other way
    round."""
    def wheel_hits(half_track: float | None, rock_y: float) -> int:
        rock = {"name": "rock", "x": 0.8, "y": rock_y, "z": 0.0, "radius": 0.04, "level": "L2"}
        geometry = RoverGeometry() if half_track is None else RoverGeometry(
            half_track=half_track)
        checker = ObstacleCheck(ObstacleSet.from_rocks([rock]), {}, geometry)
        run = {key: value[None] for key, value in wobbly_drive(0.0, 1).items()}
        for key in ("roll", "pitch", "yaw"):
            run[key] = np.zeros_like(run[key])
        run["z"] = np.full_like(run["z"], RoverBodies().body_centre_height)
        signals, _ = checker(run)
        return int(np.asarray(signals["collision.hits"])[0, 0].sum())  # the wheels, any level

    assert wheel_hits(0.4, -0.4) > 0 and wheel_hits(0.4, -0.26) == 0
    assert wheel_hits(None, -0.4) == 0 and wheel_hits(None, -0.26) > 0


def test_a_campaign_checks_collisions_with_its_own_geometry(tmp_path: Path) -> None:
    """The checker a campaign simulates with takes `rover.half_track` from its regolith (the
    one `evaluate` rebuilds from the stored campaign takes the stored campaign's geometry,
    `StoredCampaign.rover`, the same way)."""
    from idefix_rules.campaign.input.load import load_campaign
    from idefix_rules.campaign.preparation import prepare_simulation

    root = Path(__file__).parents[2]
    text = (root / "campaigns" / "rock-detour.yaml").read_text().replace(
        "../rulebooks/", f"{root / 'rulebooks'}/").replace(
        '  regolith:\n', '  regolith:\n    rover.half_track: "0.3 m"\n', 1)
    assert 'rover.half_track: "0.3 m"' in text
    source = tmp_path / "wide.yaml"
    source.write_text(text.replace("../", f"{root}/"))
    campaign = load_campaign(source).with_overrides(output=tmp_path / "out")
    prepared = prepare_simulation(campaign, lambda said: None, "again")
    assert isinstance(prepared.collisions, ObstacleCheck)
    assert prepared.collisions.bodies.half_track == 0.3
