"""Where a run's chain is complete, read one way by the runner (which holds a run after its
end), the evaluator (a run's time and energy, ``chain_done``) and the campaign (unfinished
runs): from the raw ``command`` output, else from ``done``.

A chain is complete where ``command`` (the index of the active command) rounds to -1 (or
below) *after* a sample that ran a command (``>= 0``), or to the chain's length or above (past
its last command): an FMU that reports -1 while it waits to start has not finished. Without
``command``, where ``done`` reaches its threshold *after* a sample below it: an output that
says "idle" before the chain as after it is not done at the start. A chain with nothing to
execute (no command, or only commands that neither move nor turn) is complete wherever the
output says so, from the first sample.

>>> ended(np.array([-1.0, 0.0, 1.0, -1.0, -1.0]), None)
array([False, False, False,  True,  True])
>>> ended(None, np.array([1.0, 0.0, 0.0, 1.0]))
array([False, False, False,  True])
>>> ended(np.array([-1.0, -1.0]), None).any()  # never started
np.False_
>>> ended(np.array([0.0, 1.0, 1.0]), None, commands=1).tolist()  # past its one command
[False, True, True]
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from idefix_rules.commands import Command


def nothing_to_execute(chain: Sequence[Command]) -> bool:
    """Whether ``chain`` asks for no motion at all: no command, or only commands that neither
    move nor turn (an FMU skips them: its ``command`` reads -1 from the start)."""
    return all(command.delta_position == 0 and command.delta_heading == 0 for command in chain)


def ended(command: np.ndarray | None, done: np.ndarray | None, done_at: float = 0.5,
          started: bool = False, commands: int | None = None) -> np.ndarray:
    """Per sample (last axis), whether the chain is complete at or before it: True from the
    first sample that ends it on (all False when it never does, or when neither output is
    given). ``started``: a chain with nothing to execute; ``commands``: the chain's length
    (a ``command`` at or above it is past the last command)."""
    if command is not None:
        values = np.rint(np.asarray(command, dtype=np.float64))
        ran, end = values >= 0, values <= -1
        if commands is not None:
            end = end | (values >= commands)
    elif done is not None:
        values = np.asarray(done, dtype=np.float64)
        ran, end = values < done_at, values >= done_at
    else:
        return np.zeros(0, dtype=bool)
    armed = np.maximum.accumulate(ran | started, axis=-1)
    return np.asarray(np.maximum.accumulate(end & armed, axis=-1))


class EndWatch:
    """:func:`ended` sample by sample, for a run being stepped: ``watch(value)`` for samples
    0, 1, 2 … in order says whether the chain is complete at that sample."""

    def __init__(self, is_done: bool, done_at: float, started: bool = False,
                 commands: int | None = None) -> None:
        self._is_done = is_done
        self._done_at = done_at
        self._armed = started
        self._commands = commands

    def __call__(self, value: float) -> bool:
        if not math.isfinite(value):
            return False  # the run fails for its non-finite output (campaign.worker)
        if self._is_done:
            ran, end = value < self._done_at, value >= self._done_at
        else:
            rounded = round(value)
            ran = rounded >= 0
            end = rounded <= -1 or (self._commands is not None and rounded >= self._commands)
        self._armed = self._armed or ran
        return self._armed and end
