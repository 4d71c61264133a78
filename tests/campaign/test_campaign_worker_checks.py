"""A run's collisions checked by the worker that simulated it: the pieces the evaluation stores
of a check of the stored runs (their poses at their stored precision, read back in a chunk of
several runs), whatever the precision the FMU gave them with."""

from __future__ import annotations

import numpy as np

from idefix_rules.campaign.evaluation.remembered import collision_pieces, run_collisions
from idefix_rules.campaign.storage.store import decode_chunk, encode_chunk
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
