"""What a changed named area moves among the signals rules read: its own, and, as an obstacle of
its level, the collision signals.

An area is an obstacle of its level (docs/rulebook-language.md, "Named areas"): the collision
check counts it in ``collision.hits``, ``collision.buffer`` and ``collision.contact`` at that
level (with the level's buffer; the area's own buffer shapes ``area.NAME.buffer`` only), and
``collision.clearance`` is the distance to the nearest obstacle, the area included. So:

* an added area adds obstacles: more hits, buffer entries and contact at its level, less
  clearance (each obstacle is counted on its own: the others count as before); a removed one
  the reverse;
* another level moves what it counts from the old level to the new one;
* a wider buffer flags more samples in ``area.NAME.buffer``;
* a lower steep threshold makes the area larger: ``area.NAME.*`` and the contact at its level
  grow, the clearance shrinks, but its hits and buffer entries may fall as well as rise (a
  connected patch is one obstacle: two patches that grow into one are hit once);
* another kind is other geometry altogether: unknown.

Signals per level are named with their level, ``collision.hits[L1]``, so adding an L1 area
moves the rules that read the hits of L1 (``collision.hits[L1] > 0``, or of every level:
``sum over levels (collision.hits * f_obs)``), not one reading ``collision.hits[L3]``.

>>> from idefix_rules.rulebook.environment import AreaSpec
>>> [(sorted(seed.items()), moved) for seed, moved in area_moves(
...     None, AreaSpec("blocker", "keep_out", "L1", 0.01))]  # doctest: +NORMALIZE_WHITESPACE
[([('signal:collision.buffer[L1]', 1), ('signal:collision.clearance', -1),
   ('signal:collision.contact[L1]', 1), ('signal:collision.hits[L1]', 1)], 1)]
"""

from __future__ import annotations

from collections.abc import Iterable

from idefix_rules.diff.quantities import sign
from idefix_rules.rulebook.environment import AreaSpec
from idefix_rules.rulebook.model import Expr, Name, Select
from idefix_rules.rulebook.walk import children
from idefix_rules.signals import AXIS_LABELS, SIGNALS

LEVELS: tuple[str, ...] = AXIS_LABELS["level"]
# The collision signals with a level axis (hits, buffer, contact); the clearance has none.
PER_LEVEL: tuple[str, ...] = tuple(name for name, spec in SIGNALS.items()
                                   if spec.kind == "collision" and "level" in spec.axes)
CLEARANCE = "collision.clearance"

# Signals that move together, as a seed of :class:`~idefix_rules.diff.polarity.Polarities`
# (``signal:NAME`` → +1 when it grows with the quantity that moved, -1 when it shrinks), and
# the sign of that quantity's move (None: the signals do not move monotonically).
SignalMove = tuple[dict[str, int], int | None]


def at_level(signal: str, level: str) -> str:
    """The name of a per-level signal at one level: ``collision.hits[L1]``."""
    return f"{signal}[{level}]"


def selected_levels(labels: Iterable[str], levels: tuple[str, ...] = LEVELS
                    ) -> tuple[str, ...]:
    """The levels a selection keeps (``[L1]``, ``[wheel, L2]``); all of ``levels`` when it
    names none."""
    chosen = {label for label in labels if label in LEVELS}
    return tuple(level for level in levels if level in chosen) if chosen else levels


def level_reads(expr: Expr) -> set[str]:
    """The per-level signals an expression reads, level by level.

    >>> from idefix_rules.rulebook.model import Binary, Number
    >>> sorted(level_reads(Binary(">", Select(Name("collision.hits"), ("L1",)), Number(0))))
    ['collision.hits[L1]']
    >>> len(level_reads(Name("collision.contact")))
    3
    """
    found: set[str] = set()
    _collect(expr, LEVELS, found)
    return found


def _collect(expr: Expr, levels: tuple[str, ...], found: set[str]) -> None:
    if isinstance(expr, Select):
        levels = selected_levels(expr.labels, levels)
    elif isinstance(expr, Name) and expr.name in PER_LEVEL:
        found.update(at_level(expr.name, level) for level in levels)
    for child in children(expr):
        _collect(child, levels, found)


def _obstacle_seed(level: str) -> dict[str, int]:
    """One obstacle more at ``level``: hits, buffer entries and contact there grow, the
    clearance shrinks."""
    seed = {f"signal:{at_level(signal, level)}": 1 for signal in PER_LEVEL}
    seed[f"signal:{CLEARANCE}"] = -1
    return seed


def area_moves(before: AreaSpec | None, after: AreaSpec | None) -> list[SignalMove]:
    """What an area added (``before`` None), removed (``after`` None) or changed moves (see
    the module docstring); a level and a steep threshold changed together are two moves, the
    level first."""
    if before is None:
        return [] if after is None else [(_obstacle_seed(after.level), 1)]
    if after is None:
        return [(_obstacle_seed(before.level), -1)]
    inside, near = (f"signal:{name}" for name in after.signal_names())
    if before.kind != after.kind:
        return [({inside: 1, near: 1, **_obstacle_seed(before.level),
                  **_obstacle_seed(after.level)}, None)]
    moves: list[SignalMove] = []
    if before.level != after.level:  # counted at the new level instead of the old one
        moves.append(({**{f"signal:{at_level(s, before.level)}": -1 for s in PER_LEVEL},
                       **{f"signal:{at_level(s, after.level)}": 1 for s in PER_LEVEL}}, 1))
    moves.append(({near: 1}, sign(before.buffer, after.buffer)))
    if before.above is not None and after.above is not None:
        grows = sign(after.above, before.above)  # a lower threshold: more steep ground
        contact = at_level("collision.contact", after.level)
        moves.append(({inside: 1, near: 1, f"signal:{contact}": 1,
                       f"signal:{CLEARANCE}": -1}, grows))
        if grows:  # patches grow into each other, a buffer entry becomes a hit
            moves.append(({f"signal:{at_level(s, after.level)}": 1 for s in PER_LEVEL
                           if s != "collision.contact"}, None))
    return moves


def moved_signals(moves: Iterable[SignalMove]) -> tuple[str, ...]:
    """The names of the signals that moved (``collision.hits[L1]``, ``area.crater.buffer``)."""
    return tuple(dict.fromkeys(key.removeprefix("signal:") for seed, moved in moves
                               if moved != 0 for key in seed))
