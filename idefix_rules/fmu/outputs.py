"""A runner's outputs: where each FMU output goes, which one ends a chain, signals in SI."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from idefix_rules.chain_end import EndWatch, nothing_to_execute
from idefix_rules.commands import Command
from idefix_rules.errors import Span, UserInputError, error
from idefix_rules.fmu.binding import OutputGroup
from idefix_rules.fmu.description import FmuVariable
from idefix_rules.fmu.mapping import DONE_SIGNAL, contract_column, missing_variable, si_scale
from idefix_rules.fmu.run_end import REST_SIGNALS, end_sample, moved
from idefix_rules.signals import AXIS_LABELS, FMU_SIGNALS


@dataclass(frozen=True)
class Slot:
    """Where an output goes: signal, wheel column (None: a time signal), SI factor, done."""

    signal: str
    index: int | None
    scale: float
    done: bool


class OutputPlan:
    """The outputs a runner reads, in slot order (each FMU variable with its :class:`Slot`),
    and the one that says the chain is complete; a ``done`` signal is 1 from ``done_at``."""

    def __init__(self, variables: Mapping[str, FmuVariable], signal_map: Mapping[str, str],
                 extra: list[str], fmu_path: Path, done_at: float) -> None:
        """Variable, destination (signal, column), SI scale and kind of every mapped output."""
        self.done_at = done_at
        outputs: list[tuple[FmuVariable, Slot]] = []
        for fmu_name, contract in signal_map.items():
            variable = variables.get(fmu_name)
            if variable is None:
                raise missing_variable(fmu_name, "mapped", fmu_path)
            base, index = contract_column(contract, Span(str(fmu_path)))
            if variable.reader not in ("real", "integer", "boolean"):
                raise UserInputError(error(
                    "F401", f"'{fmu_name}' is a {variable.type}; a signal needs a Real, Integer, "
                    "Boolean or Enumeration output", Span(str(fmu_path))))
            scale = 1.0 if base == DONE_SIGNAL else si_scale(
                variable, f"signal '{base}'", FMU_SIGNALS[base].unit, Span(str(fmu_path)))
            outputs.append((variable, Slot(base, index, scale, base == DONE_SIGNAL)))
        for name in extra:
            variable = variables.get(name)
            if variable is None:
                raise missing_variable(name, "requested", fmu_path)
            outputs.append((variable, Slot(name, None, 1.0, False)))
        self.outputs = outputs
        # The output that says the chain is complete: 'command' when mapped, else 'done'
        # (the evaluator's order), as (slot position, is 'done').
        ends = [(position, slot.done) for position, (_, slot) in enumerate(outputs)
                if slot.done or (slot.signal == "command" and slot.index is None)]
        ends.sort(key=lambda end: end[1])
        self.end_output: tuple[int, bool] | None = ends[0] if ends else None

    def end_watch(self, groups: Sequence[OutputGroup], buffers: list[np.ndarray],
                  chain: Sequence[Command]) -> Callable[[int], bool] | None:
        """Whether sample k of a co-simulation run says the chain is complete (None: the FMU
        maps no output that says so), for a run of ``chain``."""
        if self.end_output is None:
            return None
        position, is_done = self.end_output
        for group, buffer in zip(groups, buffers, strict=True):
            if position in group.positions:
                column = buffer[:, group.positions.index(position)]
                break
        else:  # pragma: no cover - every output belongs to a group
            return None
        item = column.item
        watch = EndWatch(is_done, self.done_at, nothing_to_execute(chain), len(chain))
        return lambda k: watch(float(item(k)))  # called for samples 0, 1, 2 … in order

    def pose_columns(self) -> list[int]:
        """Slot positions of the pose outputs (x, y, yaw) this runner reads."""
        return [position for position, (_, slot) in enumerate(self.outputs)
                if slot.signal in REST_SIGNALS and slot.index is None]

    def rest_watch(self, groups: Sequence[OutputGroup], buffers: list[np.ndarray]
                   ) -> Callable[[int], bool] | None:
        """Whether the rover is at rest at sample k: its pose (x, y, yaw) moved by at most
        REST_MOTION since sample k - 1 (None: the FMU maps no pose output). After its chain a
        rover may still slide (no balance on a slope its wheels cannot hold): the run goes on
        until it is at rest, so a hold never freezes a moving rover."""
        columns = []
        for position in self.pose_columns():
            for group, buffer in zip(groups, buffers, strict=True):
                if position in group.positions:
                    columns.append(buffer[:, group.positions.index(position)])
        if not columns:
            return None
        return lambda k: k > 0 and not any(moved(float(column.item(k - 1)),
                                                 float(column.item(k))) for column in columns)

    def end_of(self, columns: list[np.ndarray], chain: Sequence[Command]) -> int | None:
        """The first sample of read columns (slot order) where the chain is complete
        (a run of ``chain``)."""
        if self.end_output is None:
            return None
        position, is_done = self.end_output
        column = columns[position]
        started, commands = nothing_to_execute(chain), len(chain)
        end = end_sample(None, column, self.done_at, started) if is_done else \
            end_sample(column, None, started=started, commands=commands)
        poses = [columns[position] for position in self.pose_columns()]
        while end is not None and poses and end + 1 < len(column) and any(
                moved(float(pose[end]), float(pose[end + 1])) for pose in poses):
            end += 1  # still moving after the chain: hold only once at rest
        return end

    def collect(self, columns: list[np.ndarray], steps: int, interval: float,
                held: int | None = None) -> dict[str, np.ndarray]:
        """Signals by contract name from the outputs' columns (slot order), SI, float64;
        ``held``: the sample the columns hold after (``t`` then goes on along the grid)."""
        signals: dict[str, np.ndarray] = {}
        wheels: dict[str, np.ndarray] = {}
        for (_, slot), column in zip(self.outputs, columns, strict=True):
            values = column.astype(np.float64)  # always a copy, whatever the type read
            if slot.done:
                values = (values >= self.done_at).astype(np.float64)
            elif slot.scale != 1.0:
                values *= slot.scale
            if slot.index is None:
                signals[slot.signal] = values
            else:
                array = wheels.setdefault(slot.signal, np.full(
                    (steps + 1, len(AXIS_LABELS["wheel"])), np.nan))
                array[:, slot.index] = values
        signals.update(wheels)
        if "t" not in signals:
            signals["t"] = np.arange(steps + 1) * interval
        elif held is not None:
            # the time an FMU reports after each further step: communication point + step
            signals["t"][held + 1:] = np.arange(held, steps) * interval + interval
        return signals
