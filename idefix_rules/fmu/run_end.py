"""Where a run's chain ends, when the rover is at rest, and the samples held after the end."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from idefix_rules.chain_end import ended

# A rover is at rest when its pose moved by at most this (m, rad) over a sample: far below
# the creep the contact laws' regularisation allows (10 µm/s, 1 µm per 0.1 s sample).
REST_SIGNALS = ("x", "y", "yaw")
REST_MOTION = 1e-9


def moved(before: float, after: float) -> bool:
    """Whether a pose coordinate moved over a sample. A non-finite one did not: the run is
    failed by its non-finite output (campaign.worker), simulating on would show nothing more."""
    return math.isfinite(before) and math.isfinite(after) and abs(after - before) > REST_MOTION


def end_sample(command: np.ndarray | None, done: np.ndarray | None,
               done_at: float = 1.0, started: bool = False,
               commands: int | None = None) -> int | None:
    """The first sample where the chain is complete, or None (not within the run).

    Complete (:func:`idefix_rules.chain_end.ended`): ``command`` (the raw output, index of the
    active command) rounds to -1 after a sample that ran a command; without ``command``, the
    raw ``done`` output reaches ``done_at`` after a sample below it (the evaluator reads a
    run's time the same way, docs/derived-signals.md). ``started``: a chain with nothing to
    execute, complete wherever the output says so; ``commands``: the chain's length.

    >>> end_sample(np.array([0.0, 1.0, -1.0, -1.0]), None)
    2
    >>> end_sample(None, np.array([0, 1, 2]), done_at=2)
    2
    >>> end_sample(np.array([-1.0, 0.0]), None) is None  # waiting to start is no end
    True
    """
    complete = ended(command, done, done_at, started, commands)
    return int(np.argmax(complete)) if complete.any() else None


def hold_after_end(columns: Sequence[np.ndarray], held: int) -> None:
    """Hold every column's value of sample ``held`` in all later samples, in place."""
    for column in columns:
        column[held + 1:] = column[held]
