"""Shared builders for the obstacle tests: simple drives as pose arrays."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from idefix_rules.obstacles import RoverBodies

Poses = dict[str, np.ndarray]


def straight_drive(x0: float = 0.0, x1: float = 1.5, y0: float = 0.0, samples: int = 1501,
                   duration: float = 300.0, yaw: float = 0.0) -> Poses:
    """One run driving straight along the heading ``yaw`` from (x0, y0), flat ground."""
    t = np.linspace(0.0, duration, samples)
    s = np.linspace(x0, x1, samples)
    zero = np.zeros(samples)
    poses = {"t": t, "x": s * np.cos(yaw), "y": y0 + s * np.sin(yaw),
             "z": zero + RoverBodies().body_centre_height, "roll": zero, "pitch": zero,
             "yaw": zero + yaw}
    return {name: array[None, :] for name, array in poses.items()}


@pytest.fixture
def drive() -> Callable[..., Poses]:
    return straight_drive
