"""What the collision check returns: the ``collision.*`` signals and per-run details as data."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from idefix_rules.obstacles.bodies import PARTS
from idefix_rules.obstacles.obstacles import LEVELS


@dataclass(frozen=True)
class CheckSettings:
    """Tolerances of the collision check, in metres.

    ``contact_tolerance``: a body closer than this to an obstacle touches it (a wheel the rover
    model has lifted onto a rock rests *on* it, at distance ≈ 0, and must count).
    ``clearance_cutoff``: clearance is exact below it and reported as the cutoff above it (raised
    to the largest buffer margin when smaller). ``clearance_resolution`` and
    ``clearance_relative``: per-sample clearance below the cutoff is within
    ``max(clearance_resolution, clearance_relative × clearance)`` of the exact value (relative to
    the clearance reported); contact and buffer flags do not depend on them. ``min_step``:
    flags can differ from the exact ones only where the distance is within ``min_step`` of the
    contact tolerance or a buffer margin (fcl's GJK distances are certified to it as well).
    ``chunk_poses``: poses handled at once (memory bound).
    """

    contact_tolerance: float = 0.005
    clearance_cutoff: float = 0.3
    clearance_resolution: float = 0.005
    clearance_relative: float = 0.1
    min_step: float = 1e-4
    chunk_poses: int = 300_000

    def cap(self, buffer_margins: tuple[float, float, float]) -> float:
        """The clearance cap actually used: at least every margin and the contact tolerance."""
        return max(self.clearance_cutoff, *buffer_margins, self.contact_tolerance)


@dataclass(frozen=True)
class FirstContact:
    """Where and when a part first touched an obstacle of a level (body centre pose)."""

    part: str
    level: str
    time: float
    x: float
    y: float
    z: float
    body: str
    obstacle: str

    def to_dict(self) -> dict[str, Any]:
        return {"part": self.part, "level": self.level, "time": self.time, "x": self.x,
                "y": self.y, "z": self.z, "body": self.body, "obstacle": self.obstacle}


@dataclass(frozen=True)
class RunCollisions:
    """Details of one run: first contacts per part and level, obstacles hit and buffer zones
    entered per part, obstacles hit per body (FL … panel_right), the minimum clearance (m) to
    each obstacle over the run and all bodies (the clearance cap means "at least the cap")."""

    run: int
    first_contacts: tuple[FirstContact, ...]
    hits: dict[str, tuple[str, ...]]
    buffers: dict[str, tuple[str, ...]]
    min_clearance: dict[str, float]
    clearance_cap: float = math.inf
    body_hits: dict[str, tuple[str, ...]] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"run": self.run,
                "first_contacts": [c.to_dict() for c in self.first_contacts],
                "hits": {part: list(names) for part, names in self.hits.items()},
                "buffers": {part: list(names) for part, names in self.buffers.items()},
                "min_clearance": dict(self.min_clearance),
                "clearance_cap": self.clearance_cap,
                "body_hits": {body: list(names) for body, names in self.body_hits.items()}}


@dataclass
class CollisionResult:
    """``signals``: the ``collision.*`` arrays of the signal contract, axis 0 = run.

    * ``collision.hits`` int64 (runs, part, level): distinct obstacles hit (n_obs,k,l);
    * ``collision.buffer`` int64 (runs, part, level): distinct buffer zones entered without
      hitting their obstacle;
    * ``collision.contact`` int8 (runs, samples, part, level): 1 where the part touches an
      obstacle of that level (contacts between two samples mark the nearer sample);
    * ``collision.clearance`` float64 (runs, samples, part): smallest distance to any obstacle,
      0 in contact, capped at ``clearance_cap``.

    ``details``: one :class:`RunCollisions` per run.
    """

    signals: dict[str, np.ndarray]
    details: list[RunCollisions]
    clearance_cap: float
    parts: tuple[str, ...] = PARTS
    levels: tuple[str, ...] = LEVELS

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (details and per-run counts, not the per-sample arrays)."""
        return {"clearance_cap": self.clearance_cap, "parts": list(self.parts),
                "levels": list(self.levels),
                "hits": self.signals["collision.hits"].tolist(),
                "buffer": self.signals["collision.buffer"].tolist(),
                "details": [d.to_dict() for d in self.details]}
