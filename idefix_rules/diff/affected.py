"""Direction of a declaration affected indirectly: its text unchanged, a quantity it reads moved."""

from __future__ import annotations

from collections.abc import Iterable

from idefix_rules.diff.collisions import area_moves
from idefix_rules.diff.polarity import Direction, Polarities, combine, direction_of, merge
from idefix_rules.diff.quantities import effective_nominal, index_of, leaf_moves, sign
from idefix_rules.rulebook.check import CheckedRulebook
from idefix_rules.rulebook.model import Expr
from idefix_rules.rulebook.semantics import names_in

Move = tuple[CheckedRulebook, dict[str, int], int | None]


def _moves(old: CheckedRulebook, new: CheckedRulebook, name: str) -> list[Move]:
    """What one changed constant, index or chance moves: (the side whose model reads it, the
    quantity as a seed of :class:`Polarities`, the sign of its move; None = unknown)."""
    if name in old.constants and name in new.constants:
        return [(new, {f"const:{name}": 1}, sign(old.constants[name], new.constants[name]))]
    indices = {i.name for i in new.rulebook.indices}, {i.name for i in old.rulebook.indices}
    if name in indices[0] and name not in indices[1]:  # added: its weight up from 0
        return [(new, {f"weight:{name}": 1}, 1)]
    if name in indices[1] and name not in indices[0]:
        return [(old, {f"weight:{name}": 1}, -1)]
    if name in indices[0]:
        before, after = index_of(old, name), index_of(new, name)
        moves: list[Move] = [
            (new, {f"limit:{name}": 1}, sign(old.limits[name], new.limits[name])),
            (new, {f"nominal:{name}": 1},
             sign(effective_nominal(old, name), effective_nominal(new, name))),
            (new, {f"weight:{name}": 1}, sign(old.weights[name], new.weights[name]))]
        return moves + _number_moves(new, before.value, after.value)
    areas = {a.name: a for a in old.areas}, {a.name: a for a in new.areas}
    if name in areas[0] or name in areas[1]:  # its own signals, and those of its level
        return [(new, seed, moved)
                for seed, moved in area_moves(areas[0].get(name), areas[1].get(name))]
    chances = ({c.name: c for c in old.rulebook.chances}, {c.name: c for c in new.rulebook.chances})
    if name in chances[0] and name in chances[1]:
        return _number_moves(new, chances[0][name].condition, chances[1][name].condition)
    if name == "tolerance_growth":  # a wider tolerance radius
        return [(new, {"signal:tolerance_radius": 1},
                 sign(old.settings.get(name, 0.0), new.settings.get(name, 0.0)))]
    levels = ({v.level: v for v in old.obstacle_levels}, {v.level: v for v in new.obstacle_levels})
    if name in levels[0] and name in levels[1]:
        before_level, after_level = levels[0][name], levels[1][name]
        level_moves: list[Move] = [(new, {"signal:collision.buffer": 1},
                                    sign(before_level.buffer, after_level.buffer))]
        if before_level.below != after_level.below:  # rocks move between levels
            level_moves.append((new, {}, None))
        return level_moves
    return [(new, {}, None)]


def _number_moves(new: CheckedRulebook, before: Expr, after: Expr) -> list[Move]:
    """Each number that moved in an expression whose shape stayed (a new shape: unknown)."""
    moves = leaf_moves(before, after)
    if moves is None:
        return [(new, {}, None)]
    return [(new, {key: 1}, moved) for key, moved in moves]


def affected_index(old: CheckedRulebook, new: CheckedRulebook, name: str,
                    upstream: Iterable[str]) -> Direction:
    """Same text, but a setting or an obstacle level it reads through a signal moved (the
    tolerance radius, the collision buffers): the index's own polarity to the signal, then
    the rules' polarity to the index. Constants are
    :func:`~idefix_rules.diff.direction.index_direction`'s."""
    labels: list[Direction] = []
    value = index_of(new, name).value
    through = Polarities(new.rulebook, new.constants, {f"index:{name}": 1}).passes()
    for changed in sorted(set(upstream) - set(new.constants)):
        for checked, seed, moved in _moves(old, new, changed):
            if not any(key.startswith("signal:") for key in seed):
                labels.append("unknown" if moved is None else "neutral")
                continue
            own = Polarities(checked.rulebook, checked.constants, seed).of(value)
            if moved is None:  # signals that move either way: unknown if it reads them
                labels.append("neutral" if own == 0 else "unknown")
                continue
            labels.append("unknown" if own is None else
                          direction_of(through, moved * own) if own and moved else "neutral")
    return merge(labels)


def affected_condition(old: CheckedRulebook, new: CheckedRulebook, section: str,
                        name: str, upstream: Iterable[str]) -> Direction:
    """Same text, but constants, indices or chances it reads (however indirectly) moved: the
    rule's own polarity to each quantity that moved, on the side that has it."""
    attribute = {"command": "command_rules", "chance": "chances", "prescreen": "prescreens",
                 "verdict": "verdicts"}[section]
    labels: list[Direction] = []
    for changed in sorted(upstream):
        for checked, seed, moved in _moves(old, new, changed):
            if moved is None and not seed:
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
            if moved is None:  # signals that move either way: unknown if it reads them
                labels.append("neutral" if own == 0 else "unknown")
                continue
            labels.append(direction_of(own, moved))
    return merge(labels)
