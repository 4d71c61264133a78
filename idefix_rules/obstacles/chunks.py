"""What the collision checkers share: poses checked, runs in chunks, tracks turned into signals."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from idefix_rules.errors import UserInputError, error
from idefix_rules.obstacles.bodies import PARTS, Body, RoverBodies
from idefix_rules.obstacles.obstacles import LEVELS, ObstacleSet, Piece
from idefix_rules.obstacles.result import (
    CheckSettings,
    CollisionResult,
    FirstContact,
    RunCollisions,
)

POSE_NAMES = ("t", "x", "y", "z", "roll", "pitch", "yaw")


def check_poses(poses: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Pose arrays as float64 (runs, samples); ``UserInputError`` naming what is wrong."""
    problems = []
    missing = [name for name in POSE_NAMES if name not in poses]
    if missing:
        raise UserInputError(error("E630", f"poses lack {', '.join(missing)}",
                                   hint=f"collision checks need {', '.join(POSE_NAMES)}"))
    arrays = {name: np.asarray(poses[name], float) for name in POSE_NAMES}
    shape = arrays["x"].shape
    if len(shape) != 2 or shape[1] < 1:
        problems.append(error("E631", f"poses must be shaped (runs, samples), x has {shape}"))
    for name, array in arrays.items():
        if array.shape != shape:
            problems.append(error("E631", f"pose {name} has shape {array.shape}, x has {shape}"))
        elif not np.all(np.isfinite(array)):
            problems.append(error("E632", f"pose {name} contains NaN or infinite values"))
    if problems:
        raise UserInputError(problems)
    return arrays


@dataclass
class Tracks:
    """What a chunk checker accumulates for the runs of one chunk."""

    clearance: np.ndarray  # (runs, samples, bodies)
    contact: np.ndarray  # (runs, samples, part, level) int8
    hit: np.ndarray  # (runs, bodies, obstacles) bool
    nearest: np.ndarray  # (runs, bodies, obstacles) min clearance over the run
    first: dict[tuple[int, int, int], FirstContact]  # (run, part, level) →

    @classmethod
    def empty(cls, runs: int, samples: int, bodies: int, obstacles: int, cap: float) -> Tracks:
        return cls(clearance=np.full((runs, samples, bodies), cap),
                   contact=np.zeros((runs, samples, len(PARTS), len(LEVELS)), np.int8),
                   hit=np.zeros((runs, bodies, obstacles), bool),
                   nearest=np.full((runs, bodies, obstacles), cap),
                   first={})

    def note_contact(self, contact: FirstContact, run: int) -> None:
        """Keep ``contact`` if it is the earliest of its run, part and level."""
        key = (run, PARTS.index(contact.part), LEVELS.index(contact.level))
        known = self.first.get(key)
        if known is None or contact.time < known.time:
            self.first[key] = contact


ChunkChecker = Callable[[dict[str, np.ndarray], ObstacleSet, tuple[Body, ...], list[Piece],
                         np.ndarray, CheckSettings, float], "Tracks"]


def collect(arrays: dict[str, np.ndarray], obstacles: ObstacleSet, bodies: RoverBodies,
            settings: CheckSettings, first_run: int, checker: ChunkChecker) -> CollisionResult:
    """Run ``checker`` chunk by chunk and turn its :class:`Tracks` into the signals."""
    runs, samples = arrays["x"].shape
    body_list = bodies.bodies()
    n_obstacles = len(obstacles.obstacles)
    cap = settings.cap(obstacles.buffer_margins)
    clearance = np.full((runs, samples, len(PARTS)), cap)
    contact = np.zeros((runs, samples, len(PARTS), len(LEVELS)), np.int8)
    hits = np.zeros((runs, len(PARTS), len(LEVELS)), np.int64)
    buffers = np.zeros_like(hits)
    details: list[RunCollisions] = []
    pieces, piece_owner = _pieces(obstacles)
    levels = np.array([o.level for o in obstacles.obstacles], int)
    margins = np.array(obstacles.buffer_margins)[levels] if n_obstacles else np.zeros(0)
    runs_per_chunk = max(1, settings.chunk_poses // samples)
    for start in range(0, runs, runs_per_chunk):
        stop = min(runs, start + runs_per_chunk)
        chunk = {name: array[start:stop] for name, array in arrays.items()}
        tracks = checker(chunk, obstacles, body_list, pieces, piece_owner, settings, cap)
        part_hit = np.zeros((stop - start, len(PARTS), n_obstacles), bool)
        part_nearest = np.full(part_hit.shape, cap)
        for part in range(len(PARTS)):
            members = [i for i, b in enumerate(body_list) if b.part == part]
            clearance[start:stop, :, part] = tracks.clearance[:, :, members].min(axis=2)
            part_hit[:, part] = tracks.hit[:, members].any(axis=1)
            part_nearest[:, part] = tracks.nearest[:, members].min(axis=1)
        contact[start:stop] = tracks.contact
        entered = (part_nearest < margins[None, None, :]) & ~part_hit
        for level in range(len(LEVELS)):
            of_level = levels == level
            hits[start:stop, :, level] = part_hit[:, :, of_level].sum(axis=2)
            buffers[start:stop, :, level] = entered[:, :, of_level].sum(axis=2)
        details.extend(_details(tracks, part_hit, entered, body_list, obstacles, start,
                                first_run, cap))
    signals: dict[str, np.ndarray] = {
        "collision.hits": hits, "collision.buffer": buffers, "collision.contact": contact,
        "collision.clearance": clearance}
    return CollisionResult(signals, details, cap)


def _pieces(obstacles: ObstacleSet) -> tuple[list[Piece], np.ndarray]:
    pieces: list[Piece] = []
    owner: list[int] = []
    for index, obstacle in enumerate(obstacles.obstacles):
        pieces.extend(obstacle.pieces)
        owner.extend([index] * len(obstacle.pieces))
    return pieces, np.array(owner, int)


def _details(tracks: Tracks, part_hit: np.ndarray, entered: np.ndarray,
             body_list: tuple[Body, ...], obstacles: ObstacleSet, start: int, first_run: int,
             cap: float) -> list[RunCollisions]:
    names = obstacles.names

    def named(flags: np.ndarray) -> tuple[str, ...]:
        return tuple(names[o] for o in np.flatnonzero(flags))

    out = []
    for local in range(part_hit.shape[0]):
        contacts = tuple(tracks.first[key] for key in sorted(tracks.first) if key[0] == local)
        nearest = tracks.nearest[local].min(axis=0)
        out.append(RunCollisions(
            run=first_run + start + local,
            first_contacts=contacts,
            hits={PARTS[p]: named(part_hit[local, p]) for p in range(len(PARTS))},
            buffers={PARTS[p]: named(entered[local, p]) for p in range(len(PARTS))},
            min_clearance={name: float(v) for name, v in zip(names, nearest, strict=True)},
            clearance_cap=cap,
            body_hits={body.name: named(tracks.hit[local, b])
                       for b, body in enumerate(body_list)},
        ))
    return out
