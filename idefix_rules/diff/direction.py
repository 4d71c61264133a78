"""Which way a rule change goes: ``stricter``, ``looser``, ``neutral`` or ``unknown``.

A change is **stricter** when no path that fails under the old rulebook can pass under the new
one (on the same runs), **looser** in the opposite case, **neutral** when it cannot change any
pass or fail at all, and **unknown** when monotonicity does not decide it. The label is derived
from the rule model, never from data:

1. The *polarity* of an expression with respect to a quantity ``v`` is ``+1`` when the
   expression can only grow (or stay) as ``v`` grows, ``-1`` when it can only shrink, ``0``
   when it does not read ``v``, and unknown otherwise. It is computed node by node:
   ``a + b``, ``min``, ``max``, ``clamp``, ``sqrt`` and every reducer except ``rms`` and
   ``time_above`` (over time, wheels, parts, levels or runs) keep the polarities of their
   operands; ``abs`` and ``hypot`` keep them for non-negative arguments; ``-`` and ``not``
   flip them; ``a * b`` and ``a / b`` keep them when the other factor is known to be ≥ 0
   (signals such as hits, sinkage or speed, ``abs(…)``, non-negative constants); ``a <= b`` is
   true more often as ``b`` grows and ``a`` shrinks; ``and``/``or`` combine; ``percentile P``
   grows with ``P``, ``time_above T`` shrinks with ``T``. Two opposite polarities make it unknown.
2. An index ``clamp(value / limit, 0, 1)`` grows with its value and shrinks with its limit;
   with a nominal (piecewise linear through (nominal, 0.5) and (limit, 1)) it shrinks with the
   nominal too, at every value below the limit. An index without a nominal is the same shape
   with the nominal at half its limit, so adding, removing or changing a nominal moves the
   nominal from (or to) that half. The run risk (eq. 1) and the path risk (eq. 2) grow with
   every index and weight.
3. A path passes when every command rule, prescreen and verdict holds, so the *pass polarity*
   with respect to ``v`` combines the polarities of all those conditions, reading ``risk``,
   ``mean(I)``, ``max(I)``, index names and ``chance(X)`` through steps 1 and 2.
4. A change that moves ``v`` up is **looser** when the pass polarity is ``+1`` (more passes),
   **stricter** when it is ``-1``, **neutral** when it is 0 or ``v`` did not move in SI.

What moves: a constant (each of its uses), an index's limit, nominal or weight, a number in a
condition (the rest of the condition unchanged), a level's buffer (more buffer entries,
``collision.buffer``), ``tolerance_growth`` (a wider ``tolerance_radius``). An added command
rule, prescreen or verdict is stricter, a removed one looser; an added index raises the risk
(stricter when verdicts bound the risk from above). Header, ranking, titles, rationales, maps
``confidence`` (which only decides whether a verdict is *decided*), ``indifference`` (which
only decides whether two paths' ranks are tied) and a verdict's margin (``indifference`` after
its condition, ``verdict_indifference``: whether an open verdict is within the margin of its
limit; a path passes or fails as before) are neutral; a changed
expression shape, a level size threshold read by the rules, or ``theoretical_slip`` are
unknown.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator, Mapping
from typing import Any, Literal

from idefix_rules.rulebook.check import CheckedRulebook
from idefix_rules.rulebook.derived import SETTING_SIGNALS
from idefix_rules.rulebook.fold import number_si
from idefix_rules.rulebook.lints import NON_NEGATIVE
from idefix_rules.rulebook.model import (
    Binary,
    Call,
    Expr,
    Index,
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


Atom = Callable[[Expr], "Polarity | NotAtom"]


class NotAtom:
    """Marker: the expression is not an atom of the quantity in question."""


NOT_ATOM = NotAtom()


class Polarities:
    """Polarity of expressions of one rulebook with respect to one moving quantity ``seed``.

    ``seed`` maps atoms to their polarity: ``const:NAME``, ``signal:NAME``, ``limit:INDEX``,
    ``nominal:INDEX``, ``weight:INDEX``, or ``id:N`` for one particular number node
    (``id(node)``).
    """

    def __init__(self, model: Rulebook, constants: Mapping[str, Any],
                 seed: Mapping[str, int]) -> None:
        self.model = model
        self.constants = constants
        self.seed = dict(seed)
        self._index_cache: dict[str, Polarity] = {}
        self._chance_cache: dict[str, Polarity] = {}

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
        """Polarity of ``expr`` (see the module docstring)."""
        if isinstance(expr, Number):
            return self.seed.get(f"id:{id(expr)}", 0)
        if isinstance(expr, Name):
            return self._name(expr.name)
        if isinstance(expr, Select):
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
            return self._binary(expr)
        return None

    def _name(self, name: str) -> Polarity:
        if f"const:{name}" in self.seed:
            return self.seed[f"const:{name}"]
        if f"signal:{name}" in self.seed:
            return self.seed[f"signal:{name}"]
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
            nominal = self.of(index.nominal) if index.nominal is not None else 0
            self._index_cache[name] = combine(
                self.of(index.value), negate(self.of(index.limit)), negate(nominal),
                negate(self.seed.get(f"limit:{name}", 0)),
                negate(self.seed.get(f"nominal:{name}", 0)), self.seed.get(f"index:{name}", 0))
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


def _sign(old: Any, new: Any) -> int | None:
    """Sign of the move from ``old`` to ``new`` (tables: every entry the same way)."""
    if isinstance(old, dict) or isinstance(new, dict):
        if not (isinstance(old, dict) and isinstance(new, dict)) or old.keys() != new.keys():
            return None
        signs = {_sign(old[k], new[k]) for k in old} - {0}
        if not signs:
            return 0
        return signs.pop() if len(signs) == 1 else None
    a, b = float(old), float(new)
    if math.isclose(a, b, rel_tol=1e-12, abs_tol=0.0):
        return 0
    return 1 if b > a else -1


def _label(checked: CheckedRulebook, seed: Mapping[str, int], moved: int | None) -> Direction:
    if moved is None:
        return "unknown"
    if moved == 0:
        return "neutral"
    unit_seed = {key: 1 for key in seed}
    polarity = Polarities(checked.rulebook, checked.constants, unit_seed).passes()
    return direction_of(polarity, moved)


# ----------------------------------------------------------------------------- per change

def constant_direction(old: CheckedRulebook, new: CheckedRulebook, name: str) -> Direction:
    """Every use of the constant: the rules (pass polarity) and the settings and obstacle
    levels that read it."""
    if name not in old.constants or name not in new.constants:
        return "neutral"
    labels = [_label(new, {f"const:{name}": 1},
                     _sign(old.constants[name], new.constants[name]))]
    labels += [setting_direction(old, new, s.name) for s in new.rulebook.settings
               if name in names_in(s.value)]
    labels += [level_direction(old, new, lv.level) for lv in new.rulebook.obstacle_levels
               if name in set().union(*(names_in(e) for e in (lv.below, lv.buffer)
                                        if e is not None))]
    labels += [area_direction(old, new, area.name) for area in new.rulebook.areas
               if name in set().union(*(names_in(e) for e in (area.buffer, area.above)
                                        if e is not None))]
    return merge(labels)


def index_direction(old: CheckedRulebook, new: CheckedRulebook, name: str,
                    fields: Iterable[str]) -> Direction:
    """A changed index: its limit, nominal and weight (in SI) may move; a new value shape is
    unknown. A nominal added or removed moves from or to half the limit (the shape of an index
    without one)."""
    fields = set(fields) - {"title", "map"}
    if "value" in fields:
        value_change = _number_change(_index(old, name).value, _index(new, name).value)
        if value_change is None:
            return "unknown"
    labels: list[Direction] = []
    if "value" in fields:
        labels.append(_leaf_label(new, _index(old, name).value, _index(new, name).value))
    if "limit" in fields or old.limits.get(name) != new.limits.get(name):
        labels.append(_label(new, {f"limit:{name}": 1},
                             _sign(old.limits[name], new.limits[name])))
    if (name in old.nominals or name in new.nominals) and \
            effective_nominal(old, name) != effective_nominal(new, name):
        labels.append(_label(new, {f"nominal:{name}": 1},
                             _sign(effective_nominal(old, name), effective_nominal(new, name))))
    if "weight" in fields or old.weights.get(name) != new.weights.get(name):
        labels.append(_label(new, {f"weight:{name}": 1},
                             _sign(old.weights[name], new.weights[name])))
    if "value" not in fields:  # the value reads constants that moved (a factor table …)
        value = _index(new, name).value
        through = Polarities(new.rulebook, new.constants, {f"index:{name}": 1}).passes()
        for constant in sorted(names_in(value)):
            if constant in old.constants and constant in new.constants:
                moved = _sign(old.constants[constant], new.constants[constant])
                own = Polarities(new.rulebook, new.constants, {f"const:{constant}": 1}).of(value)
                labels.append("unknown" if moved is None or own is None
                              else direction_of(through, moved * own) if own else "neutral")
    return merge(labels)


def effective_nominal(checked: CheckedRulebook, name: str) -> float:
    """The index's nominal in SI; half its limit when it gives none (``value / limit`` is 0.5
    there)."""
    return checked.nominals.get(name, 0.5 * checked.limits[name])


def _index(checked: CheckedRulebook, name: str) -> Index:
    return next(i for i in checked.rulebook.indices if i.name == name)


def merge(labels: Iterable[Direction]) -> Direction:
    """Several moves at once: all the same way (or neutral) keep that way, else unknown."""
    found = set(labels) - {"neutral"}
    if not found:
        return "neutral"
    return found.pop() if len(found) == 1 else "unknown"


def _number_change(old: Expr, new: Expr) -> list[tuple[Number, Number]] | None:
    """Pairs of numbers that differ between two expressions of the same shape (None: the
    shape differs)."""
    if type(old) is not type(new):
        return None
    if isinstance(old, Number) and isinstance(new, Number):
        return [] if old == new else [(old, new)]
    pairs: list[tuple[Number, Number]] = []
    if isinstance(old, Name) and isinstance(new, Name):
        return [] if old.name == new.name else None
    if isinstance(old, Binary) and isinstance(new, Binary):
        if old.op != new.op:
            return None
        children = [(old.left, new.left), (old.right, new.right)]
    elif isinstance(old, Unary) and isinstance(new, Unary):
        if old.op != new.op:
            return None
        children = [(old.operand, new.operand)]
    elif isinstance(old, Select) and isinstance(new, Select):
        if old.labels != new.labels:
            return None
        children = [(old.operand, new.operand)]
    elif isinstance(old, Call) and isinstance(new, Call):
        if old.function != new.function or len(old.args) != len(new.args):
            return None
        children = list(zip(old.args, new.args, strict=True))
    elif isinstance(old, Reduce) and isinstance(new, Reduce):
        if (old.reducer, old.domain) != (new.reducer, new.domain) or \
                (old.parameter is None) != (new.parameter is None) or \
                (old.window is None) != (new.window is None):
            return None
        children = [(old.operand, new.operand)]
        if old.parameter is not None and new.parameter is not None:
            children.append((old.parameter, new.parameter))
        if old.window is not None and new.window is not None:
            if old.window.kind != new.window.kind:
                return None
            children.append((old.window.value, new.window.value))
    elif isinstance(old, Table) and isinstance(new, Table):
        if [k for k, _ in old.entries] != [k for k, _ in new.entries]:
            return None
        children = [(a, b) for (_, a), (_, b) in zip(old.entries, new.entries, strict=True)]
    else:
        return None
    for a, b in children:
        found = _number_change(a, b)
        if found is None:
            return None
        pairs += found
    return pairs


def _leaf_label(new: CheckedRulebook, old_expr: Expr, new_expr: Expr) -> Direction:
    """Numbers that moved inside an expression whose shape stayed: each moved number is a
    quantity of its own; they must all push the same way."""
    pairs = _number_change(old_expr, new_expr)
    if pairs is None:
        return "unknown"
    labels = []
    for old_number, new_number in pairs:
        try:
            moved = _sign(number_si(old_number), number_si(new_number))
        except (ValueError, KeyError):
            return "unknown"
        labels.append(_label(new, {f"id:{id(new_number)}": 1}, moved))
    return merge(labels)


def condition_direction(old: CheckedRulebook, new: CheckedRulebook, section: str,
                        name: str) -> Direction:
    """A changed command rule, chance, prescreen or verdict condition."""
    attribute = {"command": "command_rules", "chance": "chances", "prescreen": "prescreens",
                 "verdict": "verdicts"}[section]
    before = next(r for r in getattr(old.rulebook, attribute) if r.name == name)
    after = next(r for r in getattr(new.rulebook, attribute) if r.name == name)
    return _leaf_label(new, before.condition, after.condition)


def added_direction(checked: CheckedRulebook, section: str, name: str, added: bool
                    ) -> Direction:
    """A declaration on one side only (``checked`` is the side that has it)."""
    sign = 1 if added else -1
    if section in ("command", "prescreen", "verdict"):
        return "stricter" if added else "looser"
    if section == "index":
        # Adding an index raises the risk as far as that index: like its weight going up from 0.
        return _label(checked, {f"weight:{name}": 1}, sign)
    return "neutral"


def setting_direction(old: CheckedRulebook, new: CheckedRulebook, name: str) -> Direction:
    moved = _sign(old.settings.get(name, 0.0), new.settings.get(name, 0.0))
    if name == "tolerance_growth":
        return _label(new, {"signal:tolerance_radius": 1}, moved)
    reads = set().union(*(names_in(e) for e in _expressions(new.rulebook)))
    if moved == 0 or not reads & set(SETTING_SIGNALS["theoretical_slip"]):
        return "neutral"
    return "unknown"


def level_direction(old: CheckedRulebook, new: CheckedRulebook, level: str) -> Direction:
    """Buffer wider → more buffer entries; a size threshold moves rocks between levels."""
    before = {s.level: s for s in old.obstacle_levels}.get(level)
    after = {s.level: s for s in new.obstacle_levels}.get(level)
    if before is None or after is None:
        return "unknown"
    labels = [_label(new, {"signal:collision.buffer": 1}, _sign(before.buffer, after.buffer))]
    if before.below != after.below:
        reads = set().union(*(names_in(e) for e in _expressions(new.rulebook)))
        labels.append("unknown" if any(n.startswith("collision.") for n in reads)
                      else "neutral")
    return merge(labels)


def _expressions(model: Rulebook) -> Iterator[Expr]:
    for index in model.indices:
        yield index.value
    for group in (model.command_rules, model.chances, model.prescreens, model.verdicts):
        for rule in group:
            yield rule.condition


def change_direction(old: CheckedRulebook, new: CheckedRulebook, section: str, name: str,
                     kind: str, fields: Iterable[str], upstream: Iterable[str] = ()
                     ) -> Direction:
    """Direction of one change of the rule diff (``kind``: added, removed, changed,
    affected; ``fields``: the items that differ; ``upstream``: for an affected declaration,
    the changed constants, indices and chances it depends on)."""
    if kind in ("added", "removed"):
        return added_direction(new if kind == "added" else old, section, name,
                               kind == "added")
    if section == "constant":
        return constant_direction(old, new, name)
    if section == "index":
        own = index_direction(old, new, name, fields)
        if kind != "affected":
            return own
        return merge([own, _affected_index(old, new, name, upstream)])
    if section == "verdict" and set(fields) == {"indifference"}:
        return "neutral"  # a margin only turns an open verdict into one within the margin
    if section in ("command", "chance", "prescreen", "verdict"):
        if kind == "affected":
            return _affected_condition(old, new, section, name, upstream)
        return condition_direction(old, new, section, name)
    if section == "setting":
        return setting_direction(old, new, name)
    if section == "obstacle level":
        return level_direction(old, new, name)
    if section == "area":
        return area_direction(old, new, name)
    return "neutral"  # header, combine (confidence, indifference, …), ranking


def area_direction(old: CheckedRulebook, new: CheckedRulebook, name: str) -> Direction:
    """A wider buffer flags more samples in ``area.NAME.buffer``; a lower steep threshold
    makes the area larger (both signals); another kind or level: unknown."""
    before = {s.name: s for s in old.areas}.get(name)
    after = {s.name: s for s in new.areas}.get(name)
    if before is None or after is None or before.kind != after.kind or \
            before.level != after.level:
        return "unknown"
    inside, near = f"signal:area.{name}.inside", f"signal:area.{name}.buffer"
    labels = [_label(new, {near: 1}, _sign(before.buffer, after.buffer))]
    if before.above is not None and after.above is not None:
        grows = _sign(after.above, before.above)  # lower threshold: more steep ground
        labels.append(_label(new, {inside: 1, near: 1}, grows))
    return merge(labels)


Move = tuple[CheckedRulebook, dict[str, int], int | None]


def _moves(old: CheckedRulebook, new: CheckedRulebook, name: str) -> list[Move]:
    """What one changed constant, index or chance moves: (the side whose model reads it, the
    quantity as a seed of :class:`Polarities`, the sign of its move; None = unknown)."""
    if name in old.constants and name in new.constants:
        return [(new, {f"const:{name}": 1}, _sign(old.constants[name], new.constants[name]))]
    indices = {i.name for i in new.rulebook.indices}, {i.name for i in old.rulebook.indices}
    if name in indices[0] and name not in indices[1]:  # added: its weight up from 0
        return [(new, {f"weight:{name}": 1}, 1)]
    if name in indices[1] and name not in indices[0]:
        return [(old, {f"weight:{name}": 1}, -1)]
    if name in indices[0]:
        before, after = _index(old, name), _index(new, name)
        moves: list[Move] = [
            (new, {f"limit:{name}": 1}, _sign(old.limits[name], new.limits[name])),
            (new, {f"nominal:{name}": 1},
             _sign(effective_nominal(old, name), effective_nominal(new, name))),
            (new, {f"weight:{name}": 1}, _sign(old.weights[name], new.weights[name]))]
        return moves + _number_moves(new, before.value, after.value)
    areas = {a.name: a for a in old.areas}, {a.name: a for a in new.areas}
    if name in areas[0] and name in areas[1]:
        before_area, after_area = areas[0][name], areas[1][name]
        if before_area.kind != after_area.kind or before_area.level != after_area.level:
            return [(new, {}, None)]
        area_moves: list[Move] = [(new, {f"signal:area.{name}.buffer": 1},
                                   _sign(before_area.buffer, after_area.buffer))]
        if before_area.above is not None and after_area.above is not None:
            area_moves.append((new, {f"signal:area.{name}.inside": 1,
                                     f"signal:area.{name}.buffer": 1},
                               _sign(after_area.above, before_area.above)))
        return area_moves
    chances = ({c.name: c for c in old.rulebook.chances}, {c.name: c for c in new.rulebook.chances})
    if name in chances[0] and name in chances[1]:
        return _number_moves(new, chances[0][name].condition, chances[1][name].condition)
    if name == "tolerance_growth":  # a wider tolerance radius
        return [(new, {"signal:tolerance_radius": 1},
                 _sign(old.settings.get(name, 0.0), new.settings.get(name, 0.0)))]
    levels = ({v.level: v for v in old.obstacle_levels}, {v.level: v for v in new.obstacle_levels})
    if name in levels[0] and name in levels[1]:
        before_level, after_level = levels[0][name], levels[1][name]
        level_moves: list[Move] = [(new, {"signal:collision.buffer": 1},
                                    _sign(before_level.buffer, after_level.buffer))]
        if before_level.below != after_level.below:  # rocks move between levels
            level_moves.append((new, {}, None))
        return level_moves
    return [(new, {}, None)]


def _number_moves(new: CheckedRulebook, before: Expr, after: Expr) -> list[Move]:
    """Each number that moved in an expression whose shape stayed (a new shape: unknown)."""
    pairs = _number_change(before, after)
    if pairs is None:
        return [(new, {}, None)]
    moves: list[Move] = []
    for old_number, new_number in pairs:
        try:
            moved = _sign(number_si(old_number), number_si(new_number))
        except (ValueError, KeyError):
            moved = None
        moves.append((new, {f"id:{id(new_number)}": 1}, moved))
    return moves


def _affected_index(old: CheckedRulebook, new: CheckedRulebook, name: str,
                    upstream: Iterable[str]) -> Direction:
    """Same text, but a setting or an obstacle level it reads through a signal moved (the
    tolerance radius, the collision buffers): the index's own polarity to the signal, then
    the rules' polarity to the index. Constants are :func:`index_direction`'s."""
    labels: list[Direction] = []
    value = _index(new, name).value
    through = Polarities(new.rulebook, new.constants, {f"index:{name}": 1}).passes()
    for changed in sorted(set(upstream) - set(new.constants)):
        for checked, seed, moved in _moves(old, new, changed):
            if not any(key.startswith("signal:") for key in seed):
                labels.append("unknown" if moved is None else "neutral")
                continue
            if moved is None:
                labels.append("unknown")
                continue
            own = Polarities(checked.rulebook, checked.constants, seed).of(value)
            labels.append("unknown" if own is None else
                          direction_of(through, moved * own) if own and moved else "neutral")
    return merge(labels)


def _affected_condition(old: CheckedRulebook, new: CheckedRulebook, section: str,
                        name: str, upstream: Iterable[str]) -> Direction:
    """Same text, but constants, indices or chances it reads (however indirectly) moved: the
    rule's own polarity to each quantity that moved, on the side that has it."""
    attribute = {"command": "command_rules", "chance": "chances", "prescreen": "prescreens",
                 "verdict": "verdicts"}[section]
    labels: list[Direction] = []
    for changed in sorted(upstream):
        for checked, seed, moved in _moves(old, new, changed):
            if moved is None:
                labels.append("unknown")
                continue
            if moved == 0:
                continue
            model = checked.rulebook
            rule = next(r for r in getattr(model, attribute) if r.name == name)
            polarities = Polarities(model, checked.constants, seed)
            own = polarities.of(rule.condition)
            if section == "chance":  # a chance acts through the rules that read it
                own = combine(*(polarities.of(r.condition)
                                for r in (*model.prescreens, *model.verdicts)
                                if name in names_in(r.condition)))
            labels.append(direction_of(own, moved))
    return merge(labels)
