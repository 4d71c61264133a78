"""A run's collisions checked by the worker that simulated it: the pieces the evaluation stores
of a check of the run as stored (its poses at their stored precision), whatever the precision
the FMU gave them with."""

from __future__ import annotations

import numpy as np

from idefix_rules.campaign.evaluation.remembered import collision_pieces, run_collisions
from idefix_rules.commands import RoverGeometry
from idefix_rules.obstacles import ObstacleSet, RoverBodies
from idefix_rules.results.collisions import POSE_SIGNALS, ObstacleCheck
from idefix_rules.results.format import storage_dtype


def wobbly_drive(samples: int = 801) -> dict[str, np.ndarray]:
    """One run past a rock, its tilt and height with more digits than float32 keeps."""
    rng = np.random.default_rng(5)
    t = np.linspace(0.0, 200.0, samples)
    return {"t": t, "x": np.linspace(0.0, 1.2, samples), "y": np.full(samples, -0.01),
            "z": RoverBodies().body_centre_height + 0.003 * rng.standard_normal(samples),
            "roll": 0.02 * rng.standard_normal(samples),
            "pitch": 0.02 * rng.standard_normal(samples),
            "yaw": 0.001 * rng.standard_normal(samples)}


def test_a_worker_checks_its_run_as_the_evaluation_checks_the_stored_run() -> None:
    rock = {"name": "rock", "x": 0.8, "y": -0.26, "z": 0.0, "radius": 0.08, "level": "L2"}
    checker = ObstacleCheck(ObstacleSet.from_rocks([rock], buffer_margins=[0.05] * 3), {},
                            RoverGeometry())
    signals = wobbly_drive()
    assert any(storage_dtype(key) == np.float32 for key in POSE_SIGNALS)
    rows = np.array([11])
    stored = {key: np.asarray(values, dtype=storage_dtype(key)).astype(np.float64)[None]
              for key, values in signals.items()}
    expected = collision_pieces(rows, *checker(stored, rows), stored["t"])
    found = run_collisions(checker, signals, 11)
    assert int(np.sum(expected["hits"])) > 0 and len(expected["contact"]) > 0
    for key in ("hits", "buffer", "contact", "clearance_profile"):
        assert np.array_equal(found[key], expected[key], equal_nan=True), key
    assert [texts.tolist() for _, texts in found["details"]] == \
        [texts.tolist() for _, texts in expected["details"]]
    assert b'"run": 11' in found["details"][0][1][0]
    # checked at the FMU's float64 instead, the clearance is another one
    raw = collision_pieces(rows, *checker({k: v[None] for k, v in signals.items()}, rows),
                           signals["t"][None])
    assert not np.array_equal(raw["clearance_profile"], expected["clearance_profile"])
