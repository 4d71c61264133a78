"""Hypothesis strategies for command chains and run signals, realistic runs included."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from idefix_rules.commands import Command, RoverGeometry
from idefix_rules.rulebook.derived import RunContext
from idefix_rules.signals import FMU_SIGNALS


def chains(max_commands: int = 3) -> st.SearchStrategy[tuple[Command, ...]]:
    """Short chains of straight drives, arcs and point turns (SI)."""
    command = st.builds(Command,
                        st.sampled_from([0.05, 0.1, 0.2]),
                        st.sampled_from([0.0, 0.1, 0.25, 0.5]),
                        st.sampled_from([0.0, 0.25, -0.5, 1.0]))
    return st.lists(command, min_size=1, max_size=max_commands).map(tuple)


def _dyadic(draw: Any, shape: tuple[int, ...], low: int = -64, high: int = 64,
            denominator: int = 16) -> np.ndarray:
    values = draw(arrays(np.int16, shape, elements=st.integers(low, high)))
    return np.asarray(values, dtype=float) / denominator


@st.composite
def run_batches(draw: Any, max_runs: int = 3, max_samples: int = 24,
                chain: tuple[Command, ...] | None = None,
                non_finite: bool = False) -> tuple[dict[str, np.ndarray], RunContext]:
    """``(signals, context)``: every fmu and collision signal of the contract for a few runs.

    The ``command`` signal steps through the chain's commands (each for at least one sample,
    the same for every run) and ends with ``-1``; ``non_finite`` allows NaN/inf in ``pitch``.
    """
    chain = chain if chain is not None else draw(chains())
    runs = draw(st.integers(1, max_runs))
    samples = draw(st.integers(len(chain) + 1, max(max_samples, len(chain) + 1)))
    dt = draw(st.sampled_from([0.25, 0.5, 1.0, 2.0]))
    t = np.arange(samples) * dt
    cuts = sorted(draw(st.lists(st.integers(1, samples - 1), min_size=len(chain),
                                max_size=len(chain), unique=True)))
    command = np.full(samples, -1.0)
    starts = [0, *cuts[:-1]]
    for k, (start, stop) in enumerate(zip(starts, cuts, strict=True)):
        command[start:stop] = k
    signals: dict[str, np.ndarray] = {"t": np.tile(t, (runs, 1)),
                                      "command": np.tile(command, (runs, 1))}

    def fmu(count: int) -> dict[str, np.ndarray]:
        out = {}
        for name, spec in FMU_SIGNALS.items():
            if name in ("t", "command"):
                continue
            shape = (count, samples) + ((4,) if "wheel" in spec.axes else ())
            low = 0 if name in ("energy", "wheel.sinkage", "stuck") else -64
            out[name] = _dyadic(draw, shape, low)
        out["energy"] = np.cumsum(np.abs(out["energy"]), axis=1)
        return out

    signals.update(fmu(runs))
    hits = _dyadic(draw, (runs, 3, 3), 0, 2, 1)
    signals["collision.hits"] = hits
    signals["collision.buffer"] = _dyadic(draw, (runs, 3, 3), 0, 2, 1)
    signals["collision.contact"] = _dyadic(draw, (runs, samples, 3, 3), 0, 1, 1)
    signals["collision.clearance"] = _dyadic(draw, (runs, samples, 3), 0, 64)
    if non_finite and draw(st.booleans()):
        run, sample = draw(st.integers(0, runs - 1)), draw(st.integers(0, samples - 1))
        signals["pitch"] = signals["pitch"].copy()
        signals["pitch"][run, sample] = draw(st.sampled_from([np.nan, np.inf, -np.inf]))
    reference = {k: v[0] for k, v in fmu(1).items()}
    reference["t"], reference["command"] = t, command
    sigma = draw(st.integers(1, 8)) / 16
    return signals, RunContext(chain, RoverGeometry(), sigma, reference)


# ----------------------------------------------------------------------------- realistic runs

@dataclass(frozen=True)
class RunRanges:
    """Ranges of physically shaped runs; a test narrows what it needs (SI units).

    Slip stays within ``slip`` (ratio), slip angle within ±``slip_angle`` (rad), sinkage within
    [0, ``sinkage``] (m), roll and pitch within ±``tilt`` (rad) of the reference run, the pose
    within ``drift`` (m) and ``heading_drift`` (rad) of the commanded path; ``hits`` bounds the
    obstacle hits per part and level; ``stuck`` lets a run get stuck; chains drive their wheels
    at up to ``max_wheel_rate`` (rad/s); ``step`` lists the sampling steps to draw from (s).
    """

    slip: tuple[float, float] = (-0.1, 0.6)
    slip_angle: float = 0.5
    sinkage: float = 0.04
    tilt: float = 0.2
    drift: float = 0.03
    heading_drift: float = 0.2
    hits: int = 1
    stuck: bool = True
    max_wheel_rate: float = 0.1
    runs: tuple[int, int] = (1, 4)
    samples: tuple[int, int] = (16, 48)
    step: tuple[float, ...] = (0.5, 1.0, 2.0)


def _smooth(draw: Any, runs: int, t: np.ndarray, low: float, high: float,
            lanes: int = 0) -> np.ndarray:
    """Smooth curves within [low, high]: a level plus a few slow sines, clipped."""
    shape = (runs, len(t)) + ((lanes,) if lanes else ())
    span = max(t[-1] - t[0], 1e-9)
    level = draw(st.floats(low, high, allow_nan=False))
    amplitude = draw(st.floats(0.0, (high - low) / 2, allow_nan=False))
    periods = draw(st.integers(1, 3))
    phases = np.asarray(draw(arrays(np.float64, (runs,) + ((lanes,) if lanes else ()),
                                    elements=st.floats(0.0, 6.28))))
    if lanes:
        curve = level + amplitude * np.sin(2 * np.pi * periods * t[np.newaxis, :, np.newaxis]
                                           / span + phases[:, np.newaxis, :])
    else:
        curve = level + amplitude * np.sin(2 * np.pi * periods * t[np.newaxis] / span
                                           + phases[:, np.newaxis])
    return np.asarray(np.clip(np.broadcast_to(curve, shape), low, high), dtype=float)


def realistic_chains(max_commands: int = 3, max_wheel_rate: float = 0.1
                     ) -> st.SearchStrategy[tuple[Command, ...]]:
    """Chains of straight drives, arcs and point turns at a rate up to ``max_wheel_rate``."""
    command = st.builds(
        Command,
        st.floats(0.02, max_wheel_rate, allow_nan=False),
        st.sampled_from([0.0, 0.1, 0.2, 0.3, 0.5]),
        st.sampled_from([0.0, 0.2, -0.35, 0.5, 1.0]))
    return st.lists(command, min_size=1, max_size=max_commands).filter(
        lambda chain: any(c.delta_position or c.delta_heading for c in chain)).map(tuple)


@st.composite
def chains_within(draw: Any, compiled: Any, max_commands: int = 3
                  ) -> tuple[Command, ...]:
    """Chains that every command rule of ``compiled`` (a CompiledRulebook) accepts."""
    from hypothesis import assume

    chain: tuple[Command, ...] = draw(realistic_chains(max_commands))
    assume(not compiled.check_chain(chain))
    return chain


@st.composite
def realistic_runs(draw: Any, ranges: RunRanges | None = None,
                   chain: tuple[Command, ...] | None = None
                   ) -> tuple[dict[str, np.ndarray], RunContext]:
    """``(signals, context)`` of physically shaped runs: monotone time on one grid, poses
    that follow the commanded path with a smooth drift, bounded slip, slip angle, sinkage and
    tilt (``ranges``), cumulative energy, a few obstacle hits; the reference run is the
    commanded path itself."""
    from idefix_rules.commands import chain_duration, command_kinematics, ideal_poses

    ranges = ranges or RunRanges()
    chain = chain if chain is not None else draw(realistic_chains(
        max_wheel_rate=ranges.max_wheel_rate))
    rover = RoverGeometry()
    runs = draw(st.integers(*ranges.runs))
    samples = draw(st.integers(*ranges.samples))
    duration = chain_duration(chain, rover) * 1.1 + 1.0
    step = max(draw(st.sampled_from(ranges.step)), duration / (samples - 1))
    t = np.arange(samples) * step
    command = np.full(samples, -1.0)
    start = 0.0
    for k, item in enumerate(chain):
        end = start + command_kinematics(item, rover).duration
        command[(t >= start) & (t < end)] = k
        start = end
    ideal = ideal_poses(chain, rover, t)
    signals: dict[str, np.ndarray] = {"t": np.tile(t, (runs, 1)),
                                      "command": np.tile(command, (runs, 1))}
    growth = np.clip(t / max(t[-1], 1e-9), 0, 1)[np.newaxis]
    signals["x"] = ideal[:, 0] + growth * _smooth(draw, runs, t, -ranges.drift, ranges.drift)
    signals["y"] = ideal[:, 1] + growth * _smooth(draw, runs, t, -ranges.drift, ranges.drift)
    signals["yaw"] = ideal[:, 2] + growth * _smooth(draw, runs, t, -ranges.heading_drift,
                                                    ranges.heading_drift)
    signals["z"] = _smooth(draw, runs, t, -0.01, 0.01)
    signals["roll"] = _smooth(draw, runs, t, -ranges.tilt, ranges.tilt)
    signals["pitch"] = _smooth(draw, runs, t, -ranges.tilt, ranges.tilt)
    signals["wheel.slip"] = _smooth(draw, runs, t, *ranges.slip, lanes=4)
    signals["wheel.slip_angle"] = _smooth(draw, runs, t, -ranges.slip_angle, ranges.slip_angle,
                                          lanes=4)
    signals["wheel.sinkage"] = _smooth(draw, runs, t, 0.0, ranges.sinkage, lanes=4)
    rates = np.zeros((samples, 4))
    for k, item in enumerate(chain):
        rates[command == k] = command_kinematics(item, rover).wheel_rates
    signals["wheel.rate"] = np.tile(rates, (runs, 1, 1))
    signals["wheel.current"] = np.abs(signals["wheel.rate"]) * 2.0
    signals["energy"] = np.cumsum(signals["wheel.current"].sum(axis=2), axis=1) * step
    stuck = ranges.stuck and draw(st.booleans()) and draw(st.booleans())
    signals["stuck"] = np.zeros((runs, samples))
    if stuck:
        signals["stuck"][0, samples // 2:] = 1.0
    hits = np.asarray(draw(arrays(np.int8, (runs, 3, 3), elements=st.integers(0, ranges.hits))),
                      dtype=float)
    signals["collision.hits"] = hits
    signals["collision.buffer"] = hits.copy()
    contact = np.zeros((runs, samples, 3, 3))
    contact[:, samples // 3] = hits > 0
    signals["collision.contact"] = contact
    signals["collision.clearance"] = np.where(contact.max(axis=3) > 0, 0.0, 0.5)
    reference: dict[str, np.ndarray] = {name: np.zeros((samples, 4) if "wheel" in spec.axes
                                                       else samples)
                                        for name, spec in FMU_SIGNALS.items()}
    reference.update({"t": t, "command": command, "x": ideal[:, 0], "y": ideal[:, 1],
                      "yaw": ideal[:, 2], "wheel.rate": rates})
    sigma = draw(st.floats(0.005, 0.03))
    return signals, RunContext(chain, rover, sigma, reference)


@st.composite
def perturbed_runs(draw: Any, signal: str | None = None, ranges: RunRanges | None = None
                   ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], RunContext, str]:
    """``(nominal, perturbed, context, signal)``: a realistic run and the same run with one
    signal (``signal``, or one drawn) raised by a positive smooth bump."""
    nominal, context = draw(realistic_runs(ranges))
    name = signal or draw(st.sampled_from(["wheel.slip", "wheel.slip_angle", "wheel.sinkage",
                                           "roll", "pitch"]))
    perturbed = {k: v.copy() for k, v in nominal.items()}
    t = nominal["t"][0]
    runs = nominal["t"].shape[0]
    lanes = 4 if nominal[name].ndim == 3 else 0
    bump = _smooth(draw, runs, t, 0.0, draw(st.floats(0.01, 0.5)), lanes=lanes)
    perturbed[name] = nominal[name] + bump
    return nominal, perturbed, context, name
