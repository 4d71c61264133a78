"""Hypothesis strategies for valid rule models: indices, chances, rules and whole rulebooks."""

from __future__ import annotations

from typing import Any

from hypothesis import strategies as st

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
from idefix_rules.signals import AXIS_LABELS

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
