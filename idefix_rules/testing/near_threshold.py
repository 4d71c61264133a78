"""Runs drawn *near the threshold* under test, so properties about limits are not vacuous.

Runs drawn at random mostly sit far from every limit: a property such as "a stricter limit
never lets a failing path pass" then holds on every draw because no draw is anywhere near where
the change matters. :func:`near_threshold_runs` draws a realistic run
(:func:`~idefix_rules.rulebook.strategies.realistic_runs`) and scales its deviations from the
reference run (pose, roll, pitch, wheel slip, slip angle, sinkage) until one index lands just
inside or just outside a level: its limit by default (``level=1``), or any value of the index
such as the verdict's risk limit (``level=0.7``). Each draw calls :func:`hypothesis.event`
(``I_s: just inside 1``, ``I_s: just outside 1``), so ``pytest --hypothesis-show-statistics``
shows how often each side was hit.

>>> from hypothesis import given  # doctest: +SKIP
>>> @given(near_threshold_runs(compiled, "I_s", level=0.7))  # doctest: +SKIP
... def test_stricter_slip(batch): ...
"""

from __future__ import annotations

from typing import Any

import numpy as np
from hypothesis import assume, event
from hypothesis import strategies as st

from idefix_rules.rulebook.compile import CompiledRulebook
from idefix_rules.rulebook.derived import RunContext
from idefix_rules.rulebook.run_strategies import RunRanges, realistic_runs

SIDES = ("just inside", "just outside")
# Signals whose deviation from the reference run is scaled (the others keep time, commands,
# wheel rates, energy and collisions as drawn).
SCALED = ("x", "y", "yaw", "z", "roll", "pitch", "wheel.slip", "wheel.slip_angle",
          "wheel.sinkage")
_STEPS = 40


def scaled_runs(signals: dict[str, np.ndarray], context: RunContext, factor: float
                ) -> dict[str, np.ndarray]:
    """The runs with every deviation from the reference run multiplied by ``factor``."""
    reference = context.reference or {}
    out = dict(signals)
    for name in SCALED:
        if name in signals:
            base = np.asarray(reference.get(name, 0.0), dtype=float)
            out[name] = base + factor * (np.asarray(signals[name]) - base)
    return out


def _measure(compiled: CompiledRulebook, index: str, level: float,
             signals: dict[str, np.ndarray], context: RunContext) -> float:
    """Where the worst run sits: raw / limit for ``level`` 1 (past the limit the index stays
    1), the normalised index otherwise."""
    evaluation = compiled.evaluate(signals, context, per_sample=False)
    if level >= 1:
        value = evaluation.raw[index] / compiled.checked.limits[index]
    else:
        value = evaluation.values[index]
    return float(np.nanmax(value))


def land(compiled: CompiledRulebook, index: str, target: float, level: float,
         signals: dict[str, np.ndarray], context: RunContext) -> dict[str, np.ndarray] | None:
    """The runs scaled so that ``index`` measures ``target`` (bisection on the factor), or
    None when scaling cannot get there (the index does not read the scaled signals)."""
    def at(factor: float) -> float:
        return _measure(compiled, index, level, scaled_runs(signals, context, factor), context)

    low, high = 0.0, 1.0
    while at(high) < target:
        high *= 2
        if high > 2 ** 12:
            return None
    if at(low) > target:
        return None
    for _ in range(_STEPS):
        middle = (low + high) / 2
        low, high = (middle, high) if at(middle) < target else (low, middle)
    return scaled_runs(signals, context, (low + high) / 2)


@st.composite
def near_threshold_runs(draw: Any, compiled: CompiledRulebook, index: str | None = None,
                        level: float = 1.0, margin: float = 0.1,
                        ranges: RunRanges | None = None
                        ) -> tuple[dict[str, np.ndarray], RunContext]:
    """``(signals, context)`` whose ``index`` (or one drawn) sits *just inside* or *just
    outside* ``level`` in its worst run: ``level × (1 − d)`` or ``level × (1 + d)`` with ``d``
    drawn in (0, ``margin``]. ``level`` 1 is the index's limit; below 1 it is a value of the
    normalised index (the verdict's risk limit, say). Draws that cannot land there are
    rejected; every kept draw records an :func:`hypothesis.event`."""
    name = index or draw(st.sampled_from(list(compiled.checked.limits)))
    side = draw(st.sampled_from(SIDES))
    distance = draw(st.floats(margin / 100, margin, allow_nan=False))
    target = level * (1 - distance if side == "just inside" else 1 + distance)
    signals, context = draw(realistic_runs(ranges))
    landed = land(compiled, name, target, level, signals, context)
    if landed is None:
        event(f"{name}: cannot be moved to {level:g}")
    assume(landed is not None)
    assert landed is not None
    measured = _measure(compiled, name, level, landed, context)
    inside = measured < level
    assume(inside == (side == "just inside"))
    event(f"{name}: {side} {level:g}")
    return landed, context
