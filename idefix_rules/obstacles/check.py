"""The collision check: every run's poses against every obstacle, with python-fcl.

Three stages per chunk of runs (``docs/obstacles.md`` has the derivations):

1. **Motion bound.** Between two samples the pose is interpolated linearly (position and the
   three angles). A point of body ``b`` then moves at most
   ``|Δp| + (|Δroll| + |Δpitch| + |Δyaw|) · reach_b`` per step, ``reach_b`` bounding the body
   about the rover centre. Its running sum ``u_b`` is a distance-like coordinate along the run:
   the fcl distance of ``b`` to any obstacle changes by at most ``|Δu_b|``.
2. **Broad phase (numpy, all poses at once).** On blocks of 32 samples, each body's bounding
   sphere, grown by how far the body can move within the block, against each obstacle piece's
   axis-aligned box. Only (run, body, piece) stretches of blocks whose lower bound is within the
   clearance cap go on.
3. **Narrow phase (fcl, conservative advancement).** Along each stretch, fcl's exact distance
   ``d`` at an anchor sample holds within ``±Δu`` for the samples that follow. fcl's GJK answers
   are certified first (:func:`~idefix_rules.obstacles.distances.certified_distance`: a
   support-function lower bound, a retry with the objects swapped when it disagrees, the
   remaining uncertainty taken off the allowance), since GJK now and then reports a distance
   far too large. The next anchor is
   the last sample before ``Δu`` reaches an allowance chosen so that no contact or buffer
   decision can flip (``|d - tolerance|``, ``|d - margin|``, in overlap how deep a witness point
   of the body lies inside the obstacle)
   and the clearance error stays within the resolution. When the next sample is beyond the
   allowance it is measured too, and the gap between the two is filled with interpolated poses
   only if a contact or buffer entry could hide in it. So no obstacle is skipped between samples
   however fast the rover moves, and slow drives (sub-millimetre steps) need one fcl call per few
   millimetres near an obstacle.

Stage 2 is :mod:`~idefix_rules.obstacles.broad_phase`, stage 3
:mod:`~idefix_rules.obstacles.narrow_phase` (fcl's distances, certified:
:mod:`~idefix_rules.obstacles.distances`); what this checker shares with the exhaustive one
(:mod:`~idefix_rules.obstacles.reference`) is :mod:`~idefix_rules.obstacles.chunks`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from idefix_rules.obstacles.bodies import Body, RoverBodies, rotation_matrices
from idefix_rules.obstacles.broad_phase import broad_phase
from idefix_rules.obstacles.chunks import Tracks, check_poses, collect
from idefix_rules.obstacles.narrow_phase import Walker
from idefix_rules.obstacles.obstacles import ObstacleSet, Piece
from idefix_rules.obstacles.result import CheckSettings, CollisionResult


def collision_signals(poses: Mapping[str, np.ndarray], obstacles: ObstacleSet,
                      bodies: RoverBodies = RoverBodies(),  # noqa: B008 - frozen, immutable
                      settings: CheckSettings = CheckSettings(),  # noqa: B008
                      first_run: int = 0) -> CollisionResult:
    """Collision signals of runs of poses against an obstacle set.

    ``poses``: ``t, x, y, z, roll, pitch, yaw`` shaped (runs, samples), SI. ``first_run`` numbers
    the runs in ``details`` (the campaign calls this per chunk of runs).

    >>> from idefix_rules.obstacles import ObstacleSet
    >>> t = np.linspace(0.0, 100.0, 201)[None, :]
    >>> poses = dict(t=t, x=0.005 * t, y=0 * t, z=0 * t + 0.3, roll=0 * t, pitch=0 * t,
    ...              yaw=0 * t)
    >>> rock = {"name": "r", "x": 0.4, "y": -0.26, "z": 0.0, "radius": 0.06, "level": "L2"}
    >>> result = collision_signals(poses, ObstacleSet.from_rocks([rock]))
    >>> result.signals["collision.hits"][0].tolist()  # part × level
    [[0, 1, 0], [0, 0, 0], [0, 0, 0]]
    """
    return collect(check_poses(poses), obstacles, bodies, settings, first_run, _check_chunk)


def _check_chunk(chunk: dict[str, np.ndarray], obstacles: ObstacleSet, body_list: tuple[Body, ...],
                 pieces: list[Piece], piece_owner: np.ndarray, settings: CheckSettings,
                 cap: float) -> Tracks:
    runs, samples = chunk["x"].shape
    n_obstacles = len(obstacles.obstacles)
    tracks = Tracks.empty(runs, samples, len(body_list), n_obstacles, cap)
    if not pieces:
        return tracks
    rotation = rotation_matrices(chunk["roll"], chunk["pitch"], chunk["yaw"])
    position = np.stack([chunk["x"], chunk["y"], chunk["z"]], axis=-1)
    reach = np.array([b.reach for b in body_list])
    step_move = np.linalg.norm(np.diff(position, axis=1), axis=2)
    step_turn = (np.abs(np.diff(chunk["roll"], axis=1)) + np.abs(np.diff(chunk["pitch"], axis=1))
                 + np.abs(np.diff(chunk["yaw"], axis=1)))
    cum = np.zeros((runs, samples, len(body_list)))
    cum[:, 1:] = np.cumsum(step_move[..., None] + step_turn[..., None] * reach, axis=1)
    candidates = broad_phase(position, rotation, cum, body_list, pieces, piece_owner,
                             obstacles, cap)
    walker = Walker(chunk, rotation, position, cum, body_list, pieces, piece_owner, obstacles,
                    settings, cap, tracks)
    for run, body, piece, first, last in candidates:
        walker.walk(run, body, piece, first, last)
    return tracks
