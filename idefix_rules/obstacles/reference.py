"""The obviously correct checker: fcl distance of every body to every piece at every sample.

No broad phase, no advancement, no interpolation between samples. It is the baseline of
``benchmarks/bench_collisions.py`` and the oracle the tests compare :func:`collision_signals`
with (on trajectories sampled finely enough that nothing happens between samples). Distances fcl
computes with GJK (every piece but spheres) go through the same certificate as in the fast
checker (:func:`~idefix_rules.obstacles.distances.certified_distance`), so both see fcl's best
answer.
"""

from __future__ import annotations

from collections.abc import Mapping

import fcl
import numpy as np

from idefix_rules.obstacles.bodies import PARTS, Body, RoverBodies, rotation_matrices
from idefix_rules.obstacles.chunks import Tracks, check_poses, collect
from idefix_rules.obstacles.distances import (
    certified_distance,
    fcl_body,
    fcl_piece,
    piece_support,
    support_function,
)
from idefix_rules.obstacles.obstacles import LEVELS, ObstacleSet, Piece
from idefix_rules.obstacles.result import CheckSettings, CollisionResult, FirstContact


def reference_collision_signals(poses: Mapping[str, np.ndarray], obstacles: ObstacleSet,
                                bodies: RoverBodies = RoverBodies(),  # noqa: B008 - frozen
                                settings: CheckSettings = CheckSettings(),  # noqa: B008
                                first_run: int = 0) -> CollisionResult:
    """Same result as :func:`~idefix_rules.obstacles.collision_signals`, computed the slow way
    (clearance exact at every sample, capped the same way)."""
    return collect(check_poses(poses), obstacles, bodies, settings, first_run, _exhaustive_chunk)


def _exhaustive_chunk(chunk: dict[str, np.ndarray], obstacles: ObstacleSet,
                      body_list: tuple[Body, ...], pieces: list[Piece], piece_owner: np.ndarray,
                      settings: CheckSettings, cap: float) -> Tracks:
    runs, samples = chunk["x"].shape
    tracks = Tracks.empty(runs, samples, len(body_list), len(obstacles.obstacles), cap)
    rotation = rotation_matrices(chunk["roll"], chunk["pitch"], chunk["yaw"])
    position = np.stack([chunk["x"], chunk["y"], chunk["z"]], axis=-1)
    body_objects = [fcl_body(b) for b in body_list]
    piece_objects = [fcl_piece(p) for p in pieces]
    body_supports = [support_function(b.shape, b.size) for b in body_list]
    piece_supports = [piece_support(p) for p in pieces]
    request = fcl.DistanceRequest()
    tol = settings.contact_tolerance
    for run in range(runs):
        for sample in range(samples):
            for b, body in enumerate(body_list):
                body_objects[b].setRotation(rotation[run, sample] @ body.rotation)
                body_objects[b].setTranslation(position[run, sample]
                                               + rotation[run, sample] @ body.offset)
                for m, piece_object in enumerate(piece_objects):
                    owner = int(piece_owner[m])
                    obstacle = obstacles.obstacles[owner]
                    if PARTS[body.part] not in obstacle.parts:
                        continue
                    if pieces[m].shape == "sphere":
                        distance = fcl.distance(body_objects[b], piece_object, request,
                                                fcl.DistanceResult())
                    else:
                        distance = certified_distance(body_objects[b], body_supports[b],
                                                      piece_object, piece_supports[m],
                                                      settings.min_step)[0]
                    value = 0.0 if distance <= tol else min(distance, cap)
                    tracks.clearance[run, sample, b] = min(tracks.clearance[run, sample, b],
                                                           value)
                    tracks.nearest[run, b, owner] = min(tracks.nearest[run, b, owner], value)
                    if distance <= tol:
                        tracks.contact[run, sample, body.part, obstacle.level] = 1
                        tracks.hit[run, b, owner] = True
                        tracks.note_contact(FirstContact(
                            PARTS[body.part], LEVELS[obstacle.level],
                            float(chunk["t"][run, sample]), float(chunk["x"][run, sample]),
                            float(chunk["y"][run, sample]), float(chunk["z"][run, sample]),
                            body.name, obstacle.name), run)
    return tracks
