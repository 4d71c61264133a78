"""Derived signals: what the evaluator computes from a run's fmu signals and its context.

Rulebooks read these names like any other signal (``idefix_rules.signals.DERIVED_SIGNALS`` and
``ref.*``). Arrays are vectorised across runs: axis 0 is the run, axis 1 the sample. All runs of
a chain share one time grid ``t`` (row 0 of the ``t`` signal is used).

Formulas (``docs/derived-signals.md`` has the same list with figures of speech):

* ``ref.<s>`` — the reference run's signal ``<s>`` (``RunContext.reference``), same time grid,
  broadcast over the runs.
* ``theory.x``, ``theory.y``, ``theory.yaw`` — the commanded path with the fixed slip
  ``theoretical_slip`` (rulebook setting): :func:`idefix_rules.commands.ideal_poses` with
  ``scale = 1 - theoretical_slip``, one command at a time, command *k* (0-based) starting at the
  first sample where the run's own ``command`` signal equals *k*, so the theoretical timeline
  follows the run's command timing. Within a command the ideal progress runs at the ideal speed
  and stops at the command's end pose; once a later command (or the end, ``command == -1``) is
  reached, the command counts as complete. The path starts at the reference run's initial pose
  (``ref.x[0]``, ``ref.y[0]``, ``ref.yaw[0]``), or at each run's own initial pose when no
  reference is given.
* ``local_error`` = ``hypot(x - theory.x, y - theory.y)`` (accuracy, planar).
* ``global_error`` = ``sqrt((x - ref.x)² + (y - ref.y)² + (z - ref.z)²)`` (spread, 3-D).
* ``tolerance_radius`` = ``initial_position_sigma + tolerance_growth · turned``, where
  ``turned`` is the absolute heading change accumulated so far along the theoretical path
  (``Σ |delta_heading_k| · (1 - theoretical_slip) · progress_k``): constant while the path goes
  straight, growing while it turns (paper, Fig. 4).
* ``heading_error`` = ``yaw - ref.yaw`` wrapped to [-π, π).
* ``drift`` = ``|d_run - d_ref|`` (planar), where ``d = Rot(-yaw[0]) · (p - p[0])`` is a run's
  displacement from its own start, in its own start frame, and ``d_ref`` the reference run's in
  the reference's start frame: what the drive itself adds, whatever pose the run started from
  (0 at the first sample, 0 for a run that is the reference run moved rigidly). Without ``yaw``
  the start yaw is taken as 0; without a reference run it is an error, as for
  ``global_error``.
* ``speed`` = ``hypot(dx/dt, dy/dt)`` with ``numpy.gradient`` along ``t`` (central differences
  inside, one-sided at the ends); 0 when a run has a single sample.
* ``acceleration`` = ``d speed / dt``, the same way.

>>> import numpy as np
>>> from idefix_rules.commands import Command
>>> t = np.arange(4.0)
>>> signals = {"t": np.tile(t, (1, 1)), "x": np.array([[0.0, 1.0, 2.0, 3.0]]),
...            "y": np.zeros((1, 4)), "command": np.array([[0, 0, 0, -1]])}
>>> source = DerivedSignals(signals, RunContext(chain=(Command(1.0, 0.3, 0.0),)))
>>> source.get("speed").tolist()
[[1.0, 1.0, 1.0, 1.0]]
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from idefix_rules.chain_end import ended, nothing_to_execute
from idefix_rules.commands import Command, RoverGeometry, command_kinematics, ideal_poses
from idefix_rules.errors import UserInputError, error
from idefix_rules.signals import AXIS_LABELS, DERIVED_SIGNALS, REF_PREFIX, area_signal, lookup


@dataclass(frozen=True)
class RunContext:
    """What derived signals need besides a run's own signals.

    ``chain``: the command chain the runs executed (theoretical path, tolerance growth);
    ``rover``: geometry for the kinematics; ``initial_position_sigma``: σ of the initial position
    uncertainty in m (the starting tolerance radius); ``reference``: the reference run's fmu
    signals by contract name, *without* the run axis, on the runs' time grid (needed by
    ``ref.*``, ``global_error``, ``drift``, ``heading_error`` and the theoretical path's start
    pose).
    """

    chain: tuple[Command, ...] = ()
    rover: RoverGeometry = field(default_factory=RoverGeometry)
    initial_position_sigma: float = 0.0
    reference: Mapping[str, np.ndarray] | None = None


@dataclass(frozen=True)
class DerivedSettings:
    """Rulebook settings that shape derived signals (SI)."""

    theoretical_slip: float = 0.0
    tolerance_growth: float = 0.0


# The derived signals each rulebook setting shapes (what a change of it moves).
SETTING_SIGNALS: dict[str, tuple[str, ...]] = {
    "theoretical_slip": ("theory.x", "theory.y", "theory.yaw", "local_error",
                         "tolerance_radius"),
    "tolerance_growth": ("tolerance_radius",),
}

# Contract names each derived signal reads (for ``required_signals``); ``ref.*`` read the
# reference run's signals of the same name.
DERIVED_INPUTS: dict[str, frozenset[str]] = {
    # 'command' is used when the FMU gives it, else the ideal schedule (see _ideal_command);
    # 'z' likewise adds to the global error only when given (a planar model has none).
    "theory.x": frozenset({"t"}),
    "theory.y": frozenset({"t"}),
    "theory.yaw": frozenset({"t"}),
    "local_error": frozenset({"t", "x", "y"}),
    "global_error": frozenset({"x", "y"}),
    "drift": frozenset({"x", "y"}),
    "tolerance_radius": frozenset({"t"}),
    "heading_error": frozenset({"yaw"}),
    "chain_done": frozenset({"t"}),
    "speed": frozenset({"t", "x", "y"}),
    "acceleration": frozenset({"t", "x", "y"}),
}


# Contract names a derived signal reads when the runs hold them, and does without otherwise
# (a foreign FMU may lack them): readers of stored runs fetch these too, so that a run is
# scored the same however its signals were read.
OPTIONAL_INPUTS: dict[str, frozenset[str]] = {
    "drift": frozenset({"yaw"}),  # the start frame's yaw; 0 without it
    "chain_done": frozenset({"command", "done"}),  # else the ideal schedule
}


def inputs_of(name: str) -> frozenset[str]:
    """Contract names of provided signals (fmu, collision) that reading ``name`` needs (a
    named area's signals: the pose they are computed from)."""
    if name.startswith(REF_PREFIX):
        return frozenset({name[len(REF_PREFIX):]})
    if area_signal(name) is not None:
        return frozenset({"x", "y", "yaw"})
    return DERIVED_INPUTS.get(name, frozenset({name}))


def optional_inputs_of(name: str) -> frozenset[str]:
    """Contract names ``name`` reads when the runs hold them (:data:`OPTIONAL_INPUTS`)."""
    return OPTIONAL_INPUTS.get(name, frozenset())


def wrap_angle(angle: np.ndarray) -> np.ndarray:
    """Wrap to [-π, π)."""
    turns = np.floor((angle + math.pi) * (1.0 / (2.0 * math.pi)))
    return angle - (2.0 * math.pi) * turns


def _from_start(x: np.ndarray, y: np.ndarray, yaw: np.ndarray | None
                ) -> tuple[np.ndarray, np.ndarray]:
    """Displacement from the first sample, in the frame of the first pose:
    ``Rot(-yaw[0]) · (p - p[0])`` per run (``yaw`` None: the start yaw is 0)."""
    dx, dy = x - x[:, :1], y - y[:, :1]
    if yaw is None:
        return dx, dy
    cos, sin = np.cos(yaw[:, :1]), np.sin(yaw[:, :1])
    return cos * dx + sin * dy, cos * dy - sin * dx


class DerivedSignals:
    """The signals of one evaluation call: given ones, ``ref.*`` and derived, each computed once.

    ``get(name)`` returns an array shaped (runs or 1, samples, …) following the signal's axes;
    ``ref.*`` arrays have a run axis of length 1 (they broadcast).
    """

    def __init__(self, signals: Mapping[str, np.ndarray], context: RunContext,
                 settings: DerivedSettings | None = None) -> None:
        self._signals = signals
        self.context = context
        self.settings = settings or DerivedSettings()
        self._cache: dict[str, np.ndarray] = {}
        self._command_cache: tuple[np.ndarray, np.ndarray] | None = None
        self._own_samples: tuple[np.ndarray | None] | None = None
        self._run_lengths: tuple[np.ndarray | None] | None = None
        if "t" not in signals:
            raise UserInputError(error("E701", "the run signals lack the time signal 't'"))
        t_all = np.asarray(signals["t"], dtype=float)
        self.t: np.ndarray = t_all[0] if t_all.ndim == 2 else t_all
        self.runs = int(t_all.shape[0]) if t_all.ndim == 2 else 1
        self.samples = int(self.t.shape[0])

    def provides(self, name: str) -> bool:
        """Whether the run signals hold ``name`` (optional ones: 'command', 'done', 'energy')."""
        return name in self._signals

    def get(self, name: str) -> np.ndarray:
        cached = self._cache.get(name)
        if cached is None:
            cached = self._compute(name)
            self._cache[name] = cached
        return cached

    def last(self, name: str) -> np.ndarray:
        """``get(name)`` at the last sample, (runs, …): the theoretical path and the errors
        against it and the reference run are computed at that sample only (a run's final
        errors), every other signal is taken from :meth:`get`."""
        if name in ("theory.x", "theory.y", "theory.yaw"):
            x, y, yaw = self._theory(last=True)
            return {"theory.x": x, "theory.y": y, "theory.yaw": yaw}[name][:, -1]
        if name == "local_error":
            x, y, _ = self._theory(last=True)
            return np.asarray(np.hypot(self.get("x")[:, -1] - x[:, -1],
                                       self.get("y")[:, -1] - y[:, -1]))
        if name == "heading_error":
            return wrap_angle(self.get("yaw")[:, -1] - self.get("ref.yaw")[:, -1])
        return np.asarray(self.get(name))[:, -1]

    # ------------------------------------------------------------------ sources
    def _given(self, name: str) -> np.ndarray:
        if name not in self._signals:
            raise UserInputError(error("E701", f"the run signals lack {name!r}",
                                       hint="the rulebook reads it; map it in the campaign"))
        array = np.asarray(self._signals[name])
        spec = lookup(name)
        if spec is not None:
            sizes = tuple(self.samples if axis == "time" else len(AXIS_LABELS[axis])
                          for axis in spec.axes)
            if array.shape != (self.runs, *sizes):
                raise UserInputError(error(
                    "E705", f"signal {name!r} has shape {array.shape}, expected "
                            f"{(self.runs, *sizes)} (runs, {', '.join(spec.axes)})"))
        return array if array.dtype == bool else array.astype(float, copy=False)

    def _reference(self, name: str) -> np.ndarray:
        reference = self.context.reference
        if reference is None or name not in reference:
            raise UserInputError(error(
                "E702", f"the reference run's signal {name!r} is needed but not given",
                hint="pass RunContext(reference=...) with the reference run's signals"))
        array = np.asarray(reference[name], dtype=float)
        if array.shape[:1] != (self.samples,):
            raise UserInputError(error(
                "E703", f"reference signal {name!r} has {array.shape[0] if array.ndim else 0} "
                        f"samples, the runs have {self.samples}"))
        return array[np.newaxis]

    def _compute(self, name: str) -> np.ndarray:
        if name.startswith(REF_PREFIX):
            return self._reference(name[len(REF_PREFIX):])
        if name not in DERIVED_SIGNALS:
            if lookup(name) is None:
                raise UserInputError(error("E704", f"unknown signal {name!r}"))
            return self._given(name)
        if name in ("theory.x", "theory.y", "theory.yaw"):
            x, y, yaw = self._theory()
            self._cache["theory.x"], self._cache["theory.y"], self._cache["theory.yaw"] = x, y, yaw
            return self._cache[name]
        if name == "local_error":
            return np.asarray(np.hypot(self.get("x") - self.get("theory.x"),
                                       self.get("y") - self.get("theory.y")))
        if name == "global_error":
            total = np.square(self.get("x") - self.get("ref.x"))
            for axis in ("y", "z") if self.provides("z") else ("y",):
                difference = self.get(axis) - self.get(f"ref.{axis}")
                total += np.square(difference, out=difference)
            return np.asarray(np.sqrt(total, out=total))
        if name == "tolerance_radius":
            turned = self._progress()[1]
            return self.context.initial_position_sigma + self.settings.tolerance_growth * turned
        if name == "heading_error":
            return wrap_angle(self.get("yaw") - self.get("ref.yaw"))
        if name == "drift":
            run_x, run_y = _from_start(self.get("x"), self.get("y"),
                                       self.get("yaw") if self.provides("yaw") else None)
            reference = self.context.reference
            ref_yaw = self.get("ref.yaw") if reference is not None and "yaw" in reference \
                else None
            ref_x, ref_y = _from_start(self.get("ref.x"), self.get("ref.y"), ref_yaw)
            return np.asarray(np.hypot(run_x - ref_x, run_y - ref_y))
        if name == "chain_done":
            return self._chain_done()
        if name == "speed":
            return np.asarray(np.hypot(self._rate(self.get("x")), self._rate(self.get("y"))))
        if name == "acceleration":
            return self._rate(self.get("speed"))
        raise AssertionError(f"derived signal {name!r} has no formula")  # pragma: no cover

    def _chain_done(self) -> np.ndarray:
        """1.0 from the first sample where the chain is complete, as a run's time reads it
        (:mod:`idefix_rules.chain_end`): 'command' back at -1 after the chain started (or
        past its last command), else a mapped 'done' set after a sample without it, else the
        ideal schedule (the commands at their ideal durations from t = 0); a chain with
        nothing to execute is complete wherever the output says so (throughout without
        one)."""
        chain = self.context.chain
        shape = (self.runs, self.samples)
        if self.provides("command") or self.provides("done"):
            command = np.broadcast_to(self._given("command"), shape) \
                if self.provides("command") else None
            done = ended(command, None if command is not None else
                         np.broadcast_to(self._given("done"), shape),
                         started=nothing_to_execute(chain), commands=len(chain))
        elif nothing_to_execute(chain):
            done = np.ones(shape, dtype=bool)
        else:
            active, _ = self._command_progress()
            done = active == len(chain)
        return np.maximum.accumulate(done, axis=1).astype(np.float64)

    def run_lengths(self) -> np.ndarray | None:
        """How many leading samples of each run are its own, (runs,) int (semantics: "A run's
        own samples"): through the first sample after its chain's end from which its pose no
        longer changes (without a pose: the sample after the end); all of them for a run that
        never finished. None when the runs give neither 'command' nor 'done'."""
        if self._run_lengths is None:
            self._run_lengths = (self._lengths(),)
        return self._run_lengths[0]

    def _lengths(self) -> np.ndarray | None:
        if not (self.provides("command") or self.provides("done")):
            return None
        done = self.get("chain_done") > 0
        finished = done[:, -1]
        end = np.where(finished, np.argmax(done, axis=1), self.samples - 1)
        still_from = np.zeros(self.runs, dtype=np.int64)
        pose = [name for name in ("x", "y", "yaw") if self.provides(name)]
        if pose:
            changing = np.zeros((self.runs, self.samples), dtype=bool)
            for name in pose:
                column = np.broadcast_to(self._given(name), (self.runs, self.samples))
                changing |= column != column[:, -1:]  # NaN never equals: all samples count
            last_change = self.samples - 1 - np.argmax(changing[:, ::-1], axis=1)
            still_from = np.where(changing.any(axis=1), last_change + 1, 0)
        last = np.minimum(np.maximum(end + 1, still_from), self.samples - 1)
        return np.where(finished, last + 1, self.samples).astype(np.int64)

    def own_samples(self) -> np.ndarray | None:
        """(runs, samples) bool: the samples that are each run's own (:meth:`run_lengths`);
        None when every sample is (no 'command' nor 'done', or no run holds samples)."""
        if self._own_samples is None:
            lengths = self.run_lengths()
            own = None if lengths is None or bool(np.all(lengths >= self.samples)) else \
                np.arange(self.samples)[np.newaxis] < lengths[:, np.newaxis]
            self._own_samples = (own,)
        return self._own_samples[0]

    def _rate(self, values: np.ndarray) -> np.ndarray:
        if self.samples < 2:
            return np.zeros(np.broadcast_shapes(values.shape, (self.runs, self.samples)))
        step = np.diff(self.t)
        if np.allclose(step, step[0], rtol=1e-9, atol=0.0):  # uniform grid: cheaper formula
            return np.asarray(np.gradient(values, float(step[0]), axis=1))
        return np.asarray(np.gradient(values, self.t, axis=1))

    # ------------------------------------------------------------------ theoretical path
    def _command_progress(self) -> tuple[np.ndarray, np.ndarray]:
        """Per sample: the active command (-1 before the first, len(chain) after the last) and
        the time since that command started."""
        if self._command_cache is not None:
            return self._command_cache
        if self.provides("command"):
            command = np.rint(self._given("command")).astype(int)
        else:
            command = self._ideal_command()
        command = np.broadcast_to(command, (self.runs, self.samples))
        n = len(self.context.chain)
        started = np.maximum.accumulate(command >= 0, axis=1)
        active = np.where(command >= 0, np.minimum(command, n), np.where(started, n, -1))
        # Start time of every command (and of the end) per run: first sample reaching it.
        starts = np.empty((self.runs, n + 2))
        starts[:, 0] = self.t[0]  # the "before" phase
        for k in range(n + 1):
            reached = active >= k
            first = np.argmax(reached, axis=1)
            starts[:, k + 1] = np.where(reached.any(axis=1), self.t[first], np.inf)
        since = self.t[np.newaxis] - np.take_along_axis(starts, active + 1, axis=1)
        self._command_cache = (active, since)
        return active, since

    def _ideal_command(self) -> np.ndarray:
        """The active command per sample when the FMU reports none ('command' is optional):
        the commands follow each other at their ideal durations from t = 0, -1 after."""
        chain, rover = self.context.chain, self.context.rover
        durations = np.array([command_kinematics(c, rover).duration for c in chain])
        starts = np.concatenate([[0.0], np.cumsum(durations)])
        active = np.searchsorted(starts, self.t - self.t[0], side="right") - 1
        running = active < len(chain)
        if len(chain):
            running &= durations[np.minimum(active, len(chain) - 1)] > 0
        return np.where(running, active, -1)[np.newaxis]

    def _progress(self) -> tuple[np.ndarray, np.ndarray]:
        """Active command and absolute heading turned so far along the theoretical path."""
        active, since = self._command_progress()
        scale = 1.0 - self.settings.theoretical_slip
        chain = self.context.chain
        durations = np.array([command_kinematics(c, self.context.rover).duration
                              for c in chain] + [0.0])
        turns = np.array([abs(c.delta_heading) * scale
                          if command_kinematics(c, self.context.rover).duration > 0 else 0.0
                          for c in chain] + [0.0])
        turned_before = np.concatenate([[0.0], np.cumsum(turns)])  # before command k
        index = np.maximum(active, 0)
        duration = durations[index]
        with np.errstate(over="ignore"):  # a subnormal duration: ±inf, clipped
            fraction = np.clip(np.divide(since, duration, out=np.ones_like(since),
                                         where=duration > 0), 0.0, 1.0)
        turned = np.where(active >= 0, turned_before[index] + turns[index] * fraction, 0.0)
        return active, turned

    def _start_pose(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        # Without 'yaw' (a planar model may report position only) the path starts along +x,
        # the start frame of the signal contract.
        if self.context.reference is not None:
            x, y = self.get("ref.x")[:, :1], self.get("ref.y")[:, :1]
            has_yaw = "yaw" in self.context.reference
            return x, y, self.get("ref.yaw")[:, :1] if has_yaw else np.zeros_like(x)
        x, y = self.get("x")[:, :1], self.get("y")[:, :1]
        return x, y, self.get("yaw")[:, :1] if self.provides("yaw") else np.zeros_like(x)

    def _theory(self, last: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The theoretical pose at every sample, (runs, samples); ``last``: at the last
        sample only, (runs, 1) (each sample's pose depends on its own progress alone)."""
        active, since = self._command_progress()
        if last:
            active, since = active[:, -1:], since[:, -1:]
        chain, rover = self.context.chain, self.context.rover
        scale = 1.0 - self.settings.theoretical_slip
        # Start pose of every command in the path's own frame (start at the origin).
        ideal_starts = np.cumsum([0.0] + [command_kinematics(c, rover).duration for c in chain])
        command_starts = ideal_poses(chain, rover, ideal_starts, scale=scale)
        local = np.empty((3, *active.shape))
        local[:, active < 0] = 0.0
        for k, command in enumerate(chain):
            mask = active == k
            if mask.any():
                start = (float(command_starts[k, 0]), float(command_starts[k, 1]),
                         float(command_starts[k, 2]))
                poses = ideal_poses((command,), rover, since[mask], scale=scale, start=start)
                local[:, mask] = poses.T
        done = active >= len(chain)
        local[:, done] = command_starts[len(chain)][:, np.newaxis]
        x0, y0, yaw0 = self._start_pose()
        cos, sin = np.cos(yaw0), np.sin(yaw0)
        return (x0 + cos * local[0] - sin * local[1], y0 + sin * local[0] + cos * local[1],
                yaw0 + local[2])
