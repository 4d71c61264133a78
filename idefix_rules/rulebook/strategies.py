"""Hypothesis strategies for rulebooks and run signals, reusable by rule engineers' tests.

* :func:`rulebooks` — *valid* rule models (they pass :func:`~idefix_rules.rulebook.check`), built
  type-correct by construction: every index reduces a per-sample quantity of a known dimension
  to one value per run, limits have the value's dimension, a nominal (when drawn) is the limit
  times a fraction in [1/8, 7/8], weights lie in [0, 1]. Numbers are non-negative floats with
  units as written, so ``parse(format(model)) == model`` holds.
* :func:`chains` — short command chains; :func:`run_batches` — ``(signals, context)`` pairs:
  signals of the contract vectorised over runs on one time grid whose ``command`` signal
  follows the chain, and a :class:`~idefix_rules.rulebook.derived.RunContext` with a reference
  run. Values are small dyadic rationals, so sums are exact in every evaluation order.

>>> from hypothesis import given
>>> @given(rulebooks())
... def test_every_index_has_a_weight(rulebook):
...     assert all(index.weight is not None for index in rulebook.indices)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from hypothesis import assume
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from idefix_rules.commands import Command, RoverGeometry
from idefix_rules.rulebook.derived import RunContext
from idefix_rules.rulebook.model import (
    Binary,
    Call,
    Chance,
    Combine,
    CommandRule,
    Constant,
    Expr,
    Header,
    Index,
    Name,
    Number,
    ObstacleLevel,
    Prescreen,
    Ranking,
    RankKey,
    Reduce,
    Rulebook,
    Select,
    Setting,
    Table,
    Unary,
    VerdictRule,
    Window,
)
from idefix_rules.signals import AXIS_LABELS, FMU_SIGNALS

# Per-sample signals by dimension name: (name, has a wheel axis).
_SIGNALS: dict[str, list[tuple[str, bool]]] = {
    "ratio": [("wheel.slip", True)],
    "angle": [("pitch", False), ("roll", False), ("heading_error", False),
              ("wheel.slip_angle", True)],
    "length": [("global_error", False), ("local_error", False), ("drift", False),
               ("tolerance_radius", False), ("wheel.sinkage", True), ("z", False)],
    "speed": [("speed", False)],
}
_REFERENCED = {"pitch": "ref.pitch", "roll": "ref.roll", "z": "ref.z"}
_UNITS: dict[str, list[str | None]] = {
    "ratio": [None, "%"], "angle": ["deg", "rad"], "length": ["cm", "m", "mm"],
    "speed": ["cm/s", "mm/s"], "time": ["s"],
}
_WORDS = st.text(alphabet="abcdefghijklmnopqrstuvwxyz", min_size=1, max_size=6)
_TEXT = st.text(alphabet="abcdefghijklmnopqrstuvwxyz ABCDEFGHIJ0123456789.,:%()-", min_size=1,
                max_size=30).map(str.strip).filter(bool)


def numbers(unit: str | None = None, low: int = 0, high: int = 100) -> st.SearchStrategy[Number]:
    """A literal: an integer or half in [low, high], as float, in ``unit``."""
    return st.integers(2 * low, 2 * high).map(lambda k: Number(k / 2, unit))


def _quantity(dimension: str, low: int = 1, high: int = 100) -> st.SearchStrategy[Number]:
    return st.sampled_from(_UNITS[dimension]).flatmap(lambda u: numbers(u, low, high))


@st.composite
def _per_sample(draw: Any, dimension: str, depth: int = 2) -> Expr:
    """A per-sample quantity (axis time, no wheel axis left) of ``dimension``."""
    name, has_wheels = draw(st.sampled_from(_SIGNALS[dimension]))
    leaf: Expr = Name(name)
    if name in _REFERENCED and draw(st.booleans()):
        leaf = Binary("-", leaf, Name(_REFERENCED[name]))
    if has_wheels:
        if draw(st.booleans()):
            leaf = Select(leaf, (draw(st.sampled_from(AXIS_LABELS["wheel"])),))
        else:
            reducer = draw(st.sampled_from(["max", "min", "mean", "sum", "rms"]))
            operand = Call("abs", (leaf,)) if draw(st.booleans()) else leaf
            leaf = Reduce(reducer, "wheels", operand)
    if depth <= 0:
        return leaf
    choice = draw(st.integers(0, 5))
    if choice == 0:
        return Call("abs", (leaf,))
    if choice == 1:
        return Binary("+", leaf, draw(_per_sample(dimension, depth - 1)))
    if choice == 2:
        return Call(draw(st.sampled_from(["max", "min"])),
                    (leaf, draw(_per_sample(dimension, depth - 1))))
    if choice == 3:
        return Binary("*", leaf, draw(numbers(None, 0, 4)))
    if choice == 4:  # a time reduction nested inside the per-sample quantity
        return Binary("-", leaf, Reduce(draw(st.sampled_from(["mean", "min", "final"])), "time",
                                        leaf))
    return leaf


@st.composite
def _window(draw: Any) -> Window | None:
    kind = draw(st.sampled_from([None, None, "command", "after", "before"]))
    if kind is None:
        return None
    if kind == "command":
        return Window("command", Number(float(draw(st.integers(1, 3)))))
    return Window(kind, draw(numbers("s", 0, 20)))


@st.composite
def index_values(draw: Any) -> tuple[Expr, str]:
    """An index value (one number per run) and its dimension name."""
    dimension = draw(st.sampled_from(sorted(_SIGNALS)))
    operand = draw(_per_sample(dimension))
    if dimension == "length" and draw(st.integers(0, 3)) == 0:
        operand = Binary("/", Name("global_error"), Name("tolerance_radius"))
        dimension = "ratio"
    reducer = draw(st.sampled_from(["final", "initial", "max", "min", "mean", "rms",
                                    "percentile", "time_above", "max", "integral", "count",
                                    "fraction"]))
    parameter = None
    result = dimension
    if reducer in ("count", "fraction"):
        operand = Binary(">", operand, draw(_quantity(dimension, 0, 50)))
        result = "ratio"
    elif reducer == "percentile":
        parameter = Number(float(draw(st.integers(0, 100))))
    elif reducer == "time_above":
        parameter = draw(_quantity(dimension, 0, 50))
        result = "time"
    elif reducer == "integral":
        result = dimension + "*time"
    across = draw(st.integers(0, 7))  # path-level values: reductions over runs
    if across == 0:  # inside the time reduction: e.g. the mean trajectory, sample by sample
        operand = Reduce(draw(st.sampled_from(["any", "all"] if reducer in ("count", "fraction")
                                              else ["mean", "max", "min", "rms", "sum"])),
                         "runs", operand)
    value: Expr = Reduce(reducer, "time", operand, parameter, draw(_window()))
    if across == 1:  # around it: one number for the path
        runs_reducer = draw(st.sampled_from(["mean", "max", "min", "rms", "percentile"]))
        value = Reduce(runs_reducer, "runs", value,
                       Number(float(draw(st.integers(0, 100))))
                       if runs_reducer == "percentile" else None)
    elif across == 2:  # a run against the path's mean
        value = Binary("-", value, Reduce("mean", "runs", value))
    if draw(st.integers(0, 4)) == 0:
        value = Call("abs", (value,))
    return value, result


def _limit(dimension: str) -> st.SearchStrategy[Expr]:
    if dimension.endswith("*time"):
        base = dimension.removesuffix("*time")
        return st.tuples(_quantity(base), numbers("s", 1, 50)).map(lambda p: Binary("*", *p))
    return _quantity(dimension)


_OBSTACLE_VALUE = Reduce("sum", "parts", Reduce("sum", "levels",
                                                Binary("*", Name("collision.hits"),
                                                       Name("f_obs"))))
_OBSTACLE_MAP = Reduce("max", "parts", Reduce("max", "levels",
                                              Binary("*", Name("collision.contact"),
                                                     Name("f_obs"))))


@st.composite
def indices(draw: Any, name: str, with_obstacles: bool = False) -> Index:
    """One valid index named ``name``."""
    weight = Number(draw(st.integers(0, 10)) / 10)
    title = draw(st.none() | _TEXT)
    rationale = draw(st.none() | _TEXT)
    if with_obstacles:
        return Index(name, _OBSTACLE_VALUE, Number(1.0), weight, title,
                     _OBSTACLE_MAP if draw(st.booleans()) else None, rationale)
    value, dimension = draw(index_values())
    limit = draw(_limit(dimension))
    return Index(name, value, limit, weight, title, None, rationale, draw(_nominal(limit)))


# Nominals as a share of the limit: inside (0, 1), away from the nearly-a-step ends (W614).
NOMINAL_SHARES = (0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 0.875)


def _nominal(limit: Expr) -> st.SearchStrategy[Expr | None]:
    """None (``value / limit``) or the limit times a share in [1/8, 7/8]."""
    shares = st.sampled_from(NOMINAL_SHARES).map(lambda share: Binary("*", limit,
                                                                      Number(share)))
    return st.none() | shares


@st.composite
def _chance_condition(draw: Any) -> Expr:
    kind = draw(st.integers(0, 2))
    if kind == 0:
        level = draw(st.sampled_from(AXIS_LABELS["level"]))
        return Reduce("any", "parts", Binary(">", Select(Name("collision.hits"), (level,)),
                                             Number(0.0)))
    if kind == 1:
        return Binary(">", Reduce("max", "time", Call("abs", (Name("pitch"),))),
                      draw(_quantity("angle", 0, 45)))
    return Reduce("any", "wheels", Binary(">", Reduce("max", "time", Name("wheel.sinkage")),
                                          draw(_quantity("length", 0, 10))))


_COMMAND_CONDITIONS = (
    Binary("<=", Call("abs", (Name("delta_heading"),)), Number(90.0, "deg")),
    Binary("or", Binary(">=", Name("delta_position"), Number(5.0, "cm")),
           Binary(">=", Call("abs", (Name("delta_heading"),)), Number(10.0, "deg"))),
    Binary("<=", Call("abs", (Name("speed"),)), Number(1.0, "cm/s")),
    Binary("<=", Name("wheel_speed"), Number(2.0, "cm/s")),
    Binary("<=", Name("duration"), Number(600.0, "s")),
)


@st.composite
def rulebooks(draw: Any, max_indices: int = 4, obstacles: bool | None = None) -> Rulebook:
    """A valid rule model. ``obstacles``: None = maybe, True/False = with/without I_obs."""
    count = draw(st.integers(1, max_indices))
    with_obstacles = draw(st.booleans()) if obstacles is None else obstacles
    names = [f"I_{i}{draw(_WORDS)}" for i in range(count)]
    index_list = [draw(indices(n)) for n in names]
    constants = []
    if with_obstacles:
        index_list.append(draw(indices("I_obs", with_obstacles=True)))
        names.append("I_obs")
        factors = [draw(numbers(None, 0, 2)) for _ in AXIS_LABELS["level"]]
        constants.append(Constant("f_obs", Table(tuple(zip(AXIS_LABELS["level"], factors,
                                                           strict=True))),
                                  draw(st.none() | _TEXT)))
    if draw(st.booleans()):  # a named limit
        first = index_list[0]
        constants.append(Constant("c_limit", first.limit, draw(st.none() | _TEXT)))
        index_list[0] = Index(first.name, first.value, Name("c_limit"), first.weight,
                              first.title, first.map, first.rationale, first.nominal)
    chance_names = [f"p_{i}{draw(_WORDS)}" for i in range(draw(st.integers(0, 2)))]
    chances = [Chance(n, draw(_chance_condition()), draw(st.none() | _TEXT))
               for n in chance_names]
    settings = []
    if draw(st.booleans()):
        settings.append(Setting("theoretical_slip", draw(numbers("%", 0, 50))))
    if draw(st.booleans()):
        settings.append(Setting("tolerance_growth", draw(numbers("cm/rad", 0, 20))))
    levels = []
    if draw(st.booleans()):
        below = sorted(draw(st.lists(st.integers(1, 60), min_size=2, max_size=2, unique=True)))
        levels = [ObstacleLevel("L1", Number(float(below[0]), "cm"), draw(numbers("cm", 0, 10))),
                  ObstacleLevel("L2", Number(float(below[1]), "cm"), draw(numbers("cm", 0, 10))),
                  ObstacleLevel("L3", None, draw(numbers("cm", 0, 20)))]
    command_rules = [CommandRule(f"r_{i}", c, draw(st.none() | _TEXT)) for i, c in
                     enumerate(draw(st.lists(st.sampled_from(_COMMAND_CONDITIONS),
                                             max_size=3, unique=True)))]
    prescreens = []
    if draw(st.booleans()):
        prescreens.append(Prescreen("ps_index", Binary("<", Name(names[-1]), Number(1.0))))
    if chance_names and draw(st.booleans()):
        prescreens.append(Prescreen("ps_chance", Unary("not", Name(chance_names[0]))))
    verdicts = [VerdictRule("v_risk", Binary("<=", Name("risk"), numbers_value(draw, "%")),
                            draw(st.none() | _TEXT),
                            indifference=draw(st.sampled_from([None, Number(1.0, "%")])))]
    for n in chance_names[:1]:
        verdicts.append(VerdictRule("v_chance", Binary("<=", Call("chance", (Name(n),)),
                                                       numbers_value(draw, "%"))))
    if draw(st.booleans()):
        verdicts.append(VerdictRule("v_mean", Binary(
            "and", Binary("<", Call("mean", (Name(names[0]),)), Number(1.0)),
            Binary("<=", Name("time"), Number(1000.0, "s")))))
    keys = draw(st.lists(st.sampled_from(["risk", "time", "energy"]), min_size=1, max_size=3,
                         unique=True))
    ranking = Ranking(tuple(RankKey(Name(k), draw(st.booleans())) for k in keys))
    confidence = draw(st.sampled_from([None, Number(90.0, "%"), Number(95.0, "%"),
                                       Number(99.0, "%")]))
    indifference = draw(st.sampled_from([None, Number(0.0, "%"), Number(2.0, "%"),
                                         Number(0.05)]))
    verdict_indifference = draw(st.sampled_from([None, Number(0.5, "%")]))
    return Rulebook(
        header=Header(draw(_WORDS), f"{draw(st.integers(0, 3))}.{draw(st.integers(0, 9))}.0",
                      draw(_TEXT)),
        constants=tuple(constants),
        settings=tuple(settings),
        obstacle_levels=tuple(levels),
        command_rules=tuple(command_rules),
        indices=tuple(index_list),
        chances=tuple(chances),
        combine=Combine(confidence=confidence, indifference=indifference,
                        verdict_indifference=verdict_indifference),
        prescreens=tuple(prescreens),
        verdicts=tuple(verdicts),
        ranking=ranking,
    )


def numbers_value(draw: Any, unit: str | None) -> Number:
    number: Number = draw(numbers(unit, 0, 100))
    return number


# ----------------------------------------------------------------------------- signals

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


@st.composite
def rulebook_variations(draw: Any, rulebook: Rulebook) -> tuple[str, Rulebook]:
    """``(description, rulebook)``: ``rulebook`` with one number changed — a scalar
    constant, an index limit, nominal or weight, or the number a command rule, verdict or
    prescreen compares with — by a factor drawn in [0.25, 4] (weights are drawn in [0, 1]).
    A change that would make the rulebook invalid (a nominal at or above its limit) is not
    drawn."""
    from idefix_rules.rulebook.check import check

    description, variant = draw(_variations(rulebook))
    assume(check(variant).ok)
    return str(description), variant


@st.composite
def _variations(draw: Any, rulebook: Rulebook) -> tuple[str, Rulebook]:
    from dataclasses import replace as replaced

    factor = draw(st.sampled_from([0.25, 0.5, 0.8, 0.9, 1.1, 1.25, 2.0, 4.0]))
    scalar = [c for c in rulebook.constants if isinstance(c.value, Number)]
    thresholds = [(attribute, rule) for attribute in ("command_rules", "verdicts", "prescreens")
                  for rule in getattr(rulebook, attribute)
                  if isinstance(rule.condition, Binary) and isinstance(rule.condition.right,
                                                                       Number)
                  and rule.condition.right.value != 0]
    with_nominal = [i for i in rulebook.indices if i.nominal is not None]
    choices = ["limit", "weight"] + (["constant", "constant"] if scalar else []) + \
        (["threshold"] if thresholds else []) + (["nominal"] if with_nominal else [])
    choice = draw(st.sampled_from(choices))
    if choice == "constant":
        constant = draw(st.sampled_from(scalar))
        number = constant.value
        assert isinstance(number, Number)
        new = replaced(constant, value=Number(number.value * factor, number.unit))
        constants = tuple(new if c.name == constant.name else c for c in rulebook.constants)
        return (f"constant {constant.name} × {factor:g}",
                replaced(rulebook, constants=constants))
    if choice == "threshold":
        attribute, rule = draw(st.sampled_from(thresholds))
        condition = rule.condition
        right = condition.right
        moved = replaced(condition, right=Number(right.value * factor, right.unit))
        rules = tuple(replaced(r, condition=moved) if r.name == rule.name else r
                      for r in getattr(rulebook, attribute))
        fields: dict[str, Any] = {attribute: rules}
        return f"threshold of {rule.name} × {factor:g}", replaced(rulebook, **fields)
    index = draw(st.sampled_from(with_nominal if choice == "nominal" else rulebook.indices))
    if choice == "nominal":
        assert index.nominal is not None
        changed = replaced(index, nominal=Binary("*", index.nominal, Number(factor)))
    elif choice == "limit":
        changed = replaced(index, limit=Binary("*", index.limit, Number(factor)))
    else:
        weight = Number(draw(st.sampled_from([0.0, 0.25, 0.5, 0.75, 1.0])))
        changed = replaced(index, weight=weight)
    indices_ = tuple(changed if i.name == index.name else i for i in rulebook.indices)
    return f"index {index.name} {choice} changed", replaced(rulebook, indices=indices_)
