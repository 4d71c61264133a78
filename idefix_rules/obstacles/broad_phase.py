"""The collision check's broad phase: the (run, body, piece) stretches that need fcl."""

from __future__ import annotations

import numpy as np

from idefix_rules.obstacles.bodies import PARTS, Body
from idefix_rules.obstacles.obstacles import ObstacleSet, Piece

_TIME_BLOCK = 32  # samples per block of the broad phase


def _aabb_gap(points: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Distance from points (..., 3) to boxes (lower/upper broadcastable)."""
    gap = np.maximum(np.maximum(lower - points, points - upper), 0.0)
    distance: np.ndarray = np.sqrt((gap * gap).sum(axis=-1))
    return distance


def broad_phase(position: np.ndarray, rotation: np.ndarray, cum: np.ndarray,
                 body_list: tuple[Body, ...], pieces: list[Piece], piece_owner: np.ndarray,
                 obstacles: ObstacleSet, cap: float) -> list[tuple[int, int, int, int, int]]:
    """Stretches ``(run, body, piece, first sample, last sample)`` that need fcl.

    Conservative, on blocks of ``_TIME_BLOCK`` samples: each body's bounding sphere at the
    block's first pose, grown by how far any point of the body can move within the block and the
    steps just outside it, against each piece's axis-aligned box. Consecutive blocks within the
    clearance cap form one stretch.
    """
    samples = position.shape[1]
    lower = np.array([p.lower for p in pieces])
    upper = np.array([p.upper for p in pieces])
    starts = np.arange(0, samples, _TIME_BLOCK)
    stops = np.minimum(starts + _TIME_BLOCK, samples) - 1
    offsets = np.array([body.offset for body in body_list])
    # Body centres at the first sample of each block: (runs, blocks, bodies, 3).
    centres = position[:, starts, None, :] + np.einsum("rkij,bj->rkbi", rotation[:, starts],
                                                       offsets)
    # How far any point of a body can move from there within the block and its outer steps.
    growth = (cum[:, np.minimum(stops + 1, samples - 1)] - cum[:, np.maximum(starts - 1, 0)])
    radius = np.array([body.radius for body in body_list])
    allowed = np.array([[PARTS[b.part] in o.parts for o in obstacles.obstacles]
                        for b in body_list])[:, piece_owner]  # (bodies, pieces)
    hits = []
    for m in range(len(pieces)):
        bound = _aabb_gap(centres, lower[m], upper[m]) - radius - growth  # (runs, blocks, bodies)
        run, block, body = np.nonzero((bound <= cap) & allowed[None, None, :, m])
        hits.append(((run * len(body_list) + body) * len(pieces) + m, block))
    key = np.concatenate([h[0] for h in hits])
    block = np.concatenate([h[1] for h in hits])
    if len(key) == 0:
        return []
    order = np.lexsort((block, key))
    key, block = key[order], block[order]
    # A new stretch where the track changes or blocks are not consecutive.
    breaks = np.flatnonzero((np.diff(key) != 0) | (np.diff(block) > 1)) + 1
    stretch_starts = np.concatenate([[0], breaks])
    stretch_ends = np.concatenate([breaks - 1, [len(key) - 1]])
    out = []
    for s, e in zip(stretch_starts.tolist(), stretch_ends.tolist(), strict=True):
        run_body, m = divmod(int(key[s]), len(pieces))
        r, b = divmod(run_body, len(body_list))
        # One sample of margin each side covers the motion into and out of the stretch.
        out.append((r, b, m, max(0, int(starts[block[s]]) - 1),
                    min(samples - 1, int(stops[block[e]]) + 1)))
    return out
