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
condition (the rest of the condition unchanged), a comparison that gained or lost its boundary
(``<`` → ``<=`` holds on the boundary too, like its right side moved up by an infinitesimal), a
level's buffer (more buffer entries, ``collision.buffer``), ``tolerance_growth`` (a wider
``tolerance_radius``), a named area (:mod:`idefix_rules.diff.collisions`: an obstacle of its
level, so an added one raises the hits, buffer entries and contact of that level and lowers the
clearance; another level moves them to the new level; a wider buffer or a lower steep threshold
widens its own signals). An added command rule, prescreen or verdict is stricter, a removed one
looser; an added index raises the risk (stricter when verdicts bound the risk from above).
Header, ranking, titles, rationales, maps ``confidence`` (which only decides whether a verdict
is *decided*), ``indifference`` (which only decides whether two paths' ranks are tied) and a
verdict's margin (``indifference`` after its condition, ``verdict_indifference``: whether an
open verdict is within the margin of its limit; a path passes or fails as before) are neutral;
a changed expression shape, a level size threshold read by the rules, ``theoretical_slip``,
an area's kind, or the hits of an area whose steep threshold moved (patches that grow into one
are hit once) are unknown.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping

from idefix_rules.diff.affected import affected_condition, affected_index
from idefix_rules.diff.collisions import SignalMove, area_moves
from idefix_rules.diff.polarity import Direction, Polarities, direction_of, merge
from idefix_rules.diff.quantities import (
    effective_nominal,
    index_of,
    leaf_moves,
    sign,
)
from idefix_rules.rulebook.check import CheckedRulebook
from idefix_rules.rulebook.derived import SETTING_SIGNALS
from idefix_rules.rulebook.model import Expr, Rulebook
from idefix_rules.rulebook.semantics import names_in


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
                     sign(old.constants[name], new.constants[name]))]
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
    labels: list[Direction] = []
    if "value" in fields:
        inside = _leaf_label(new, index_of(old, name).value, index_of(new, name).value)
        if inside == "unknown":  # a new shape, or moves that disagree: nothing else can decide
            return "unknown"
        labels.append(inside)
    if "limit" in fields or old.limits.get(name) != new.limits.get(name):
        labels.append(_label(new, {f"limit:{name}": 1},
                             sign(old.limits[name], new.limits[name])))
    if (name in old.nominals or name in new.nominals) and \
            effective_nominal(old, name) != effective_nominal(new, name):
        labels.append(_label(new, {f"nominal:{name}": 1},
                             sign(effective_nominal(old, name), effective_nominal(new, name))))
    if "weight" in fields or old.weights.get(name) != new.weights.get(name):
        labels.append(_label(new, {f"weight:{name}": 1},
                             sign(old.weights[name], new.weights[name])))
    if "value" not in fields:  # the value reads constants that moved (a factor table …)
        value = index_of(new, name).value
        through = Polarities(new.rulebook, new.constants, {f"index:{name}": 1}).passes()
        for constant in sorted(names_in(value)):
            if constant in old.constants and constant in new.constants:
                moved = sign(old.constants[constant], new.constants[constant])
                own = Polarities(new.rulebook, new.constants, {f"const:{constant}": 1}).of(value)
                labels.append("unknown" if moved is None or own is None
                              else direction_of(through, moved * own) if own else "neutral")
    return merge(labels)


def _leaf_label(new: CheckedRulebook, old_expr: Expr, new_expr: Expr) -> Direction:
    """Numbers that moved inside an expression whose shape stayed: each moved number is a
    quantity of its own; they must all push the same way."""
    moves = leaf_moves(old_expr, new_expr)
    if moves is None:
        return "unknown"
    labels = [_label(new, {key: 1}, moved) for key, moved in moves]
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
    moved = 1 if added else -1
    if section in ("command", "prescreen", "verdict"):
        return "stricter" if added else "looser"
    if section == "index":
        # Adding an index raises the risk as far as that index: like its weight going up from 0.
        return _label(checked, {f"weight:{name}": 1}, moved)
    if section == "area":  # obstacles of its level: more hits, buffer entries, contact
        spec = next(area for area in checked.areas if area.name == name)
        return _signals_label(checked, area_moves(None, spec) if added
                              else area_moves(spec, None))
    return "neutral"


def setting_direction(old: CheckedRulebook, new: CheckedRulebook, name: str) -> Direction:
    moved = sign(old.settings.get(name, 0.0), new.settings.get(name, 0.0))
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
    labels = [_label(new, {"signal:collision.buffer": 1}, sign(before.buffer, after.buffer))]
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
        return merge([own, affected_index(old, new, name, upstream)])
    if section == "verdict" and set(fields) == {"indifference"}:
        return "neutral"  # a margin only turns an open verdict into one within the margin
    if section in ("command", "chance", "prescreen", "verdict"):
        if kind == "affected":
            return affected_condition(old, new, section, name, upstream)
        return condition_direction(old, new, section, name)
    if section == "setting":
        return setting_direction(old, new, name)
    if section == "obstacle level":
        return level_direction(old, new, name)
    if section == "area":
        return area_direction(old, new, name)
    return "neutral"  # header, combine (confidence, indifference, …), ranking


def area_direction(old: CheckedRulebook, new: CheckedRulebook, name: str) -> Direction:
    """What the area's signals and, as an obstacle of its level, the collision signals do
    (:func:`~idefix_rules.diff.collisions.area_moves`): a wider buffer flags more samples in
    ``area.NAME.buffer``; a lower steep threshold makes the area larger; another level counts
    it there instead; another kind: unknown."""
    before = {s.name: s for s in old.areas}.get(name)
    after = {s.name: s for s in new.areas}.get(name)
    if before is None or after is None:
        return "unknown"
    return _signals_label(new, area_moves(before, after))


def _signals_label(checked: CheckedRulebook, moves: Iterable[SignalMove]) -> Direction:
    """Signals that moved together, each with its own polarity to what moved (the clearance
    shrinks as the hits grow); a move of no known sign is unknown when the rules read any of
    its signals, neutral when they read none."""
    labels: list[Direction] = []
    for seed, moved in moves:
        polarity = Polarities(checked.rulebook, checked.constants, seed).passes()
        labels.append(("neutral" if polarity == 0 else "unknown") if moved is None
                      else direction_of(polarity, moved))
    return merge(labels)
