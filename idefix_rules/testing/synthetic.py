"""Synthetic runs from a case: the nominal run of the chain, shaped by keyframes.

The *nominal run* is the chain executed ideally (:func:`idefix_rules.commands.ideal_poses`, no
slip): ``x``, ``y``, ``yaw`` follow the commanded path, ``command`` steps through the commands at
their ideal durations and ends with ``-1``, ``wheel.rate`` is the commanded rate of each wheel;
every other signal is 0, the obstacle clearance 1 m. A case's ``signals`` replace a signal (or
one wheel or part of it) by keyframes, its ``offsets`` add keyframes to the nominal values, and
its ``collisions`` set ``collision.contact``/``hits``/``buffer``/``clearance``. The reference
run is the nominal run with the case's ``reference`` keyframes.

>>> from idefix_rules.commands import Command
>>> t, command = timeline((Command(0.1, 0.05, 0.0),), step=1.0, duration=None)
>>> float(t[-1]), command.tolist()[:2], int(command[-1])
(10.0, [0.0, 0.0], -1)
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np

from idefix_rules import signals
from idefix_rules.commands import Command, RoverGeometry, command_kinematics, ideal_poses
from idefix_rules.rulebook.derived import RunContext
from idefix_rules.testing.case_model import (
    DEFAULT_SETTLE,
    STEP_SIGNALS,
    Case,
    Collision,
    Keyframes,
    RunGroup,
)

FAR = 1.0  # m: clearance to every obstacle when the case gives no collision


def timeline(chain: tuple[Command, ...], step: float, duration: float | None,
             rover: RoverGeometry | None = None, last_keyframe: float = 0.0
             ) -> tuple[np.ndarray, np.ndarray]:
    """Time grid and ``command`` signal: each command for its ideal duration, then -1.

    Without ``duration`` the run lasts the chain plus a settling time (and at least to the last
    keyframe)."""
    rover = rover or RoverGeometry()
    durations = [command_kinematics(c, rover).duration for c in chain]
    ends = np.cumsum(durations) if durations else np.zeros(0)
    total = float(ends[-1]) if len(ends) else 0.0
    if duration is None:
        duration = max(total + DEFAULT_SETTLE, last_keyframe)
    samples = math.floor(duration / step + 1e-9) + 1
    t = np.arange(samples) * step
    command = np.full(samples, -1.0)
    start = 0.0
    for k, end in enumerate(ends):
        command[(t >= start) & (t < end)] = k
        start = float(end)
    return t, command


def _nominal(case: Case, t: np.ndarray, command: np.ndarray, rover: RoverGeometry
             ) -> dict[str, np.ndarray]:
    samples = len(t)
    out: dict[str, np.ndarray] = {}
    for name, spec in signals.FMU_SIGNALS.items():
        shape = (samples, 4) if "wheel" in spec.axes else (samples,)
        out[name] = np.zeros(shape)
    poses = ideal_poses(case.chain, rover, t)
    out["x"], out["y"], out["yaw"] = poses[:, 0].copy(), poses[:, 1].copy(), poses[:, 2].copy()
    out["t"], out["command"] = t.copy(), command.copy()
    rates = np.zeros((samples, 4))
    for k, item in enumerate(case.chain):
        rates[command == k] = command_kinematics(item, rover).wheel_rates
    out["wheel.rate"] = rates
    out["collision.clearance"] = np.full((samples, 3), FAR)
    return out


def _curve(frames: Keyframes, t: np.ndarray) -> np.ndarray:
    times, values = np.array(frames.times), np.array(frames.values)
    if frames.signal in STEP_SIGNALS or signals.area_signal(frames.signal) is not None:
        position = np.searchsorted(times, t, side="right") - 1
        return np.asarray(values[np.maximum(position, 0)], dtype=float)
    return np.asarray(np.interp(t, times, values), dtype=float)


def _shape(run: dict[str, np.ndarray], keyframes: tuple[Keyframes, ...], t: np.ndarray) -> None:
    for frames in keyframes:
        curve = _curve(frames, t)
        array = run[frames.signal]
        if frames.label is None:
            if array.ndim == 2:  # every wheel (or part) alike
                curve = curve[:, np.newaxis]
            if frames.offset:
                array += curve
            else:
                array[...] = curve
            continue
        spec = signals.lookup(frames.signal)
        assert spec is not None
        axis = next(a for a in spec.axes if a != "time")
        column = signals.AXIS_LABELS[axis].index(frames.label)
        if frames.offset:
            array[:, column] += curve
        else:
            array[:, column] = curve


def _collide(run: dict[str, np.ndarray], collisions: tuple[Collision, ...],
             t: np.ndarray) -> None:
    parts, levels = signals.AXIS_LABELS["part"], signals.AXIS_LABELS["level"]
    contact = np.zeros((len(t), 3, 3))
    hits = np.zeros((3, 3))
    buffer = np.zeros((3, 3))
    for item in collisions:
        p, lv = parts.index(item.part), levels.index(item.level)
        if item.buffer_only:
            buffer[p, lv] += 1
            continue
        hits[p, lv] += 1
        during = (t >= item.start - 1e-9) & (t <= item.end + 1e-9)
        if not during.any():  # shorter than a step: the nearest sample
            during[int(np.argmin(np.abs(t - item.start)))] = True
        contact[during, p, lv] = 1.0
        run["collision.clearance"][during, p] = 0.0
    run["collision.contact"], run["collision.hits"], run["collision.buffer"] = \
        contact, hits, buffer


def _last_keyframe(case: Case) -> float:
    times = [f.times[-1] for g in case.groups for f in g.keyframes]
    times += [c.end for g in case.groups for c in g.collisions]
    times += [f.times[-1] for f in case.reference]
    return max(times, default=0.0)


def build_runs(case: Case, rover: RoverGeometry | None = None, areas: Iterable[str] = ()
               ) -> tuple[dict[str, np.ndarray], RunContext]:
    """Every run of ``case`` (groups in order, each repeated ``count`` times) vectorised over
    runs, and the run context with the reference run. ``areas``: the signals of the rulebook's
    named areas, 0 (no wheel near the area) wherever the case does not shape them."""
    rover = rover or case.rover
    t, command = timeline(case.chain, case.step, case.duration, rover, _last_keyframe(case))
    shaped = {f.signal for g in case.groups for f in g.keyframes
              if signals.area_signal(f.signal) is not None}
    zero = sorted(shaped | set(areas))
    per_group = [_group(case, group, t, command, rover, zero) for group in case.groups]
    names = per_group[0].keys()
    batch = {name: np.concatenate([np.repeat(run[name][np.newaxis], group.count, axis=0)
                                   for run, group in zip(per_group, case.groups, strict=True)])
             for name in names}
    reference = _nominal(case, t, command, rover)
    _shape(reference, case.reference, t)
    reference_fmu = {k: v for k, v in reference.items() if k in signals.FMU_SIGNALS}
    context = RunContext(case.chain, rover, case.initial_position_sigma, reference_fmu)
    _hold_after_end(batch, context)
    return batch, context


def _hold_after_end(batch: dict[str, np.ndarray], context: RunContext) -> None:
    """Every signal of a run holds its last own sample's value after it (semantics: "A run's
    own samples"), as a campaign's runner holds an FMU's outputs once the chain is complete
    and the rover at rest: ``max`` and ``percentile 100`` then read the same."""
    from idefix_rules.rulebook.derived import DerivedSignals

    lengths = DerivedSignals(batch, context).run_lengths()
    if lengths is None:
        return
    samples = len(batch["t"][0])
    in_time = [name for name in batch if name != "t"
               and (spec := signals.lookup(name)) is not None and spec.axes[:1] == ("time",)]
    for run, length in enumerate(lengths.tolist()):
        if 0 < length < samples:
            for name in in_time:
                batch[name][run, length:] = batch[name][run, length - 1]


def _group(case: Case, group: RunGroup, t: np.ndarray, command: np.ndarray,
           rover: RoverGeometry, zero: Sequence[str] = ()) -> dict[str, np.ndarray]:
    run = _nominal(case, t, command, rover)
    for name in zero:
        run[name] = np.zeros(len(t))
    if group.unfinished:
        # still executing its last command at the end of the grid: 'command' never reads -1
        started = np.maximum.accumulate(command >= 0)
        run["command"] = np.where(started & (command < 0), float(len(case.chain) - 1),
                                  run["command"])
    _shape(run, group.keyframes, t)
    _collide(run, group.collisions, t)
    run["energy"] = np.maximum.accumulate(run["energy"])  # cumulative charge never falls
    return run
