"""Polarity of a rulebook's expressions to one moving quantity, and the direction it gives."""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from contextlib import contextmanager
from typing import Any, Literal

from idefix_rules.diff.collisions import LEVELS, PER_LEVEL, at_level, selected_levels
from idefix_rules.rulebook.fold import number_si
from idefix_rules.rulebook.lints import NON_NEGATIVE
from idefix_rules.rulebook.model import (
    Binary,
    Call,
    Expr,
    Name,
    Number,
    Reduce,
    Rulebook,
    Select,
    Table,
    Unary,
)
from idefix_rules.rulebook.semantics import names_in

Direction = Literal["stricter", "looser", "neutral", "unknown"]
Polarity = int | None  # +1, -1, 0, or None (unknown)

# Names that are never negative (counts, distances, magnitudes; shared with the lints).
NON_NEGATIVE_SIGNALS = NON_NEGATIVE
_MONOTONE_REDUCERS = frozenset({"final", "initial", "max", "min", "mean", "sum", "integral",
                                "percentile", "any", "all", "count", "fraction",
                                "time_above"})


def combine(*polarities: Polarity) -> Polarity:
    """Polarity of something that grows with each part: opposite parts make it unknown."""
    found = 0
    for polarity in polarities:
        if polarity is None:
            return None
        if polarity == 0:
            continue
        if found and polarity != found:
            return None
        found = polarity
    return found


def negate(polarity: Polarity) -> Polarity:
    return None if polarity is None else -polarity


class Polarities:
    """Polarity of expressions of one rulebook with respect to one moving quantity ``seed``.

    ``seed`` maps atoms to their polarity: ``const:NAME``, ``signal:NAME`` (a collision
    signal per level also at one level, ``signal:collision.hits[L1]``: a selection of other
    levels does not read it), ``limit:INDEX``, ``nominal:INDEX``, ``weight:INDEX``, or ``id:N``
    for one particular number node (``id(node)``).
    """

    def __init__(self, model: Rulebook, constants: Mapping[str, Any],
                 seed: Mapping[str, int]) -> None:
        self.model = model
        self.constants = constants
        self.seed = dict(seed)
        self._index_cache: dict[str, Polarity] = {}
        self._chance_cache: dict[str, Polarity] = {}
        self._levels = LEVELS  # the levels the selections around the node keep

    @contextmanager
    def _at_levels(self, levels: tuple[str, ...]) -> Iterator[None]:
        outer, self._levels = self._levels, levels
        try:
            yield
        finally:
            self._levels = outer

    # ------------------------------------------------------------------ helpers
    def non_negative(self, expr: Expr) -> bool:
        if isinstance(expr, Number):
            return number_si(expr) >= 0
        if isinstance(expr, Name):
            if expr.name in self.constants:
                value = self.constants[expr.name]
                values = value.values() if isinstance(value, dict) else [value]
                return all(float(v) >= 0 for v in values)
            return (expr.name in NON_NEGATIVE_SIGNALS or expr.name in self.index_names
                    or expr.name in ("risk", "failed", "runs", "time"))
        if isinstance(expr, Select):
            return self.non_negative(expr.operand)
        if isinstance(expr, Table):
            return all(self.non_negative(v) for _, v in expr.entries)
        if isinstance(expr, Call):
            if expr.function in ("abs", "sqrt", "hypot") or (
                    expr.function in ("chance", "mean") and len(expr.args) == 1):
                return True
            return all(self.non_negative(a) for a in expr.args)
        if isinstance(expr, Reduce):
            if expr.reducer in ("count", "fraction", "time_above", "any", "all"):
                return True
            if expr.reducer == "rate":  # a non-negative quantity still falls
                return False
            return self.non_negative(expr.operand)
        if isinstance(expr, Binary) and expr.op in ("+", "*", "/"):
            return self.non_negative(expr.left) and self.non_negative(expr.right)
        return False

    @property
    def index_names(self) -> set[str]:
        return {i.name for i in self.model.indices}

    # ------------------------------------------------------------------ expressions
    def of(self, expr: Expr) -> Polarity:
        """Polarity of ``expr`` (see :mod:`idefix_rules.diff.direction`)."""
        if isinstance(expr, Number):
            return self.seed.get(f"id:{id(expr)}", 0)
        if isinstance(expr, Name):
            return self._name(expr.name)
        if isinstance(expr, Select):
            with self._at_levels(selected_levels(expr.labels, self._levels)):
                return self.of(expr.operand)
        if isinstance(expr, Table):
            return combine(*(self.of(v) for _, v in expr.entries))
        if isinstance(expr, Unary):
            inner = self.of(expr.operand)
            return negate(inner)
        if isinstance(expr, Call):
            return self._call(expr)
        if isinstance(expr, Reduce):
            return self._reduce(expr)
        if isinstance(expr, Binary):
            # a comparison that gained or lost its equality moves itself (``id:N`` of it)
            own = self.seed.get(f"id:{id(expr)}", 0)
            return combine(own, self._binary(expr)) if own else self._binary(expr)
        return None

    def _name(self, name: str) -> Polarity:
        if f"const:{name}" in self.seed:
            return self.seed[f"const:{name}"]
        if f"signal:{name}" in self.seed:
            return self.seed[f"signal:{name}"]
        if name in PER_LEVEL:
            return combine(*(self.seed.get(f"signal:{at_level(name, level)}", 0)
                             for level in self._levels))
        if name in self.constants:
            return self._constant(name)
        if name in self.index_names:
            return self.index(name)
        if name == "risk":
            return self.risk()
        if name in {c.name for c in self.model.chances}:
            return self.chance(name)
        return 0

    def _constant(self, name: str) -> Polarity:
        """A constant defined from the moving constant moves with it."""
        constant = next((c for c in self.model.constants if c.name == name), None)
        if constant is None or not (names_in(constant.value) & self._moving_constants()):
            return 0
        return self.of(constant.value)

    def _moving_constants(self) -> set[str]:
        return {key[len("const:"):] for key in self.seed if key.startswith("const:")} | {
            c.name for c in self.model.constants if names_in(c.value) & {
                key[len("const:"):] for key in self.seed if key.startswith("const:")}}

    def _call(self, expr: Call) -> Polarity:
        if expr.function in ("chance", "mean", "max") and len(expr.args) == 1 and \
                isinstance(expr.args[0], Name) and (
                    expr.args[0].name in self.index_names or
                    expr.args[0].name in {c.name for c in self.model.chances}):
            return self._name(expr.args[0].name)
        parts = [self.of(a) for a in expr.args]
        if expr.function in ("min", "max", "clamp", "sqrt"):
            return combine(*parts)
        if expr.function in ("abs", "hypot"):  # grows with each |argument|
            if all(p == 0 for p in parts):
                return 0
            return combine(*parts) if all(self.non_negative(a) for a in expr.args) else None
        return None if any(p != 0 for p in parts) else 0

    def _reduce(self, expr: Reduce) -> Polarity:
        operand = self.of(expr.operand)
        window = self.of(expr.window.value) if expr.window is not None else 0
        if window != 0:
            return None
        parameter = self.of(expr.parameter) if expr.parameter is not None else 0
        if expr.reducer == "time_above":
            parameter = negate(parameter)
        if expr.reducer == "rms" and operand != 0 and not self.non_negative(expr.operand):
            return None
        if expr.reducer not in _MONOTONE_REDUCERS and expr.reducer != "rms":
            return None if operand or parameter else 0
        return combine(operand, parameter)

    def _binary(self, expr: Binary) -> Polarity:
        left, right = self.of(expr.left), self.of(expr.right)
        op = expr.op
        if op == "+":
            return combine(left, right)
        if op == "-":
            return combine(left, negate(right))
        if op == "*":
            return combine(self._scaled(left, expr.right), self._scaled(right, expr.left))
        if op == "/":
            return combine(self._scaled(left, expr.right),
                           negate(self._scaled(right, expr.left)))
        if op in ("<", "<="):
            return combine(negate(left), right)
        if op in (">", ">="):
            return combine(left, negate(right))
        if op in ("and", "or"):
            return combine(left, right)
        return None if left or right else 0  # ==, !=, ^

    def _scaled(self, polarity: Polarity, factor: Expr) -> Polarity:
        """Polarity of ``x · factor`` (or ``x / factor``) from x's, when the factor is ≥ 0."""
        if polarity == 0:
            return 0
        return polarity if self.non_negative(factor) else None

    # ------------------------------------------------------------------ run and path level
    def index(self, name: str) -> Polarity:
        """Normalised index ``clamp(value / limit, 0, 1)`` (through (nominal, 0.5) with a
        nominal): grows with the value, shrinks with the limit and with the nominal."""
        if name not in self._index_cache:
            self._index_cache[name] = 0  # guards recursion through prescreens
            index = next(i for i in self.model.indices if i.name == name)
            with self._at_levels(LEVELS):  # its own value, whatever selection reads it
                nominal = self.of(index.nominal) if index.nominal is not None else 0
                self._index_cache[name] = combine(
                    self.of(index.value), negate(self.of(index.limit)), negate(nominal),
                    negate(self.seed.get(f"limit:{name}", 0)),
                    negate(self.seed.get(f"nominal:{name}", 0)),
                    self.seed.get(f"index:{name}", 0))
        return self._index_cache[name]

    def risk(self) -> Polarity:
        """I_max = max of weight × index (eq. 1), and its mean over runs (eq. 2)."""
        parts = []
        for index in self.model.indices:
            weight = combine(self.of(index.weight), self.seed.get(f"weight:{index.name}", 0))
            parts += [self.index(index.name), weight]
        return combine(*parts)

    def chance(self, name: str) -> Polarity:
        if name not in self._chance_cache:
            self._chance_cache[name] = 0
            chance = next(c for c in self.model.chances if c.name == name)
            with self._at_levels(LEVELS):
                self._chance_cache[name] = self.of(chance.condition)
        return self._chance_cache[name]

    def passes(self) -> Polarity:
        """Pass polarity of a path: every command rule, prescreen and verdict holds."""
        return combine(*(self.of(rule.condition) for rule in self._requirements()))

    def _requirements(self) -> Iterator[Any]:
        yield from self.model.command_rules
        yield from self.model.prescreens
        yield from self.model.verdicts


def direction_of(pass_polarity: Polarity, moved: int) -> Direction:
    """Label of a change moving a quantity by sign ``moved`` (+1 up, -1 down, 0 not at all)."""
    if moved == 0 or pass_polarity == 0:
        return "neutral"
    if pass_polarity is None:
        return "unknown"
    return "looser" if pass_polarity * moved > 0 else "stricter"


def merge(labels: Iterable[Direction]) -> Direction:
    """Several moves at once: all the same way (or neutral) keep that way, else unknown."""
    found = set(labels) - {"neutral"}
    if not found:
        return "neutral"
    return found.pop() if len(found) == 1 else "unknown"
