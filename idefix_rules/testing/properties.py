"""Ready-made properties of a rulebook, for hypothesis tests of rule engineers and ours.

Each ``check_*`` function evaluates a rulebook on given runs and raises ``AssertionError`` with a
readable message when the property does not hold; pair them with the strategies of
:mod:`idefix_rules.rulebook.strategies`:

>>> from hypothesis import given  # doctest: +SKIP
>>> from idefix_rules.rulebook.strategies import realistic_runs  # doctest: +SKIP
>>> @given(realistic_runs())  # doctest: +SKIP
... def test_risk_is_bounded(compiled_rulebook, batch):
...     check_bounded_risk(compiled_rulebook, *batch)
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from idefix_rules.rulebook.check import CheckedRulebook, check
from idefix_rules.rulebook.compile import CompiledRulebook, compile_rulebook
from idefix_rules.rulebook.derived import RunContext
from idefix_rules.rulebook.model import Binary, Expr, Index, Number, Rulebook
from idefix_rules.rulebook.results import RunEvaluation
from idefix_rules.testing.runner import first_run

Signals = Mapping[str, np.ndarray]


def _compiled(rulebook: Rulebook | CheckedRulebook | CompiledRulebook) -> CompiledRulebook:
    if isinstance(rulebook, CompiledRulebook):
        return rulebook
    return compile_rulebook(rulebook)


def check_bounded_risk(rulebook: Rulebook | CheckedRulebook | CompiledRulebook,
                       signals: Signals, context: RunContext) -> RunEvaluation:
    """Every index and I_max lie in [0, 1], I_max is the largest weighted index, and the path
    risk lies in [0, 1]."""
    compiled = _compiled(rulebook)
    evaluation = compiled.evaluate(signals, context)
    for name in evaluation.index_names:
        values = evaluation.values[name]
        assert np.all((values >= 0) & (values <= 1)), f"index {name} left [0, 1]: {values}"
    stacked = np.stack([evaluation.weighted[n] for n in evaluation.index_names])
    assert np.array_equal(evaluation.i_max, stacked.max(axis=0)), "I_max is not the largest " \
        "weighted index"
    assert np.all((evaluation.i_max >= 0) & (evaluation.i_max <= 1)), \
        f"I_max left [0, 1]: {evaluation.i_max}"
    risk = compiled.path_statistics(evaluation).risk.value
    assert 0 <= risk <= 1, f"path risk {risk} left [0, 1]"
    return evaluation


def _with_index(rulebook: Rulebook, name: str, **fields: object) -> CheckedRulebook:
    indices = tuple(replace(i, **fields) if i.name == name else i  # type: ignore[arg-type]
                    for i in rulebook.indices)
    result = check(replace(rulebook, indices=indices))
    assert result.checked is not None, [d.message for d in result.errors]
    return result.checked


def _index(rulebook: Rulebook, name: str) -> Index:
    return next(i for i in rulebook.indices if i.name == name)


def check_monotone_in_limit(rulebook: Rulebook, index: str, factor: float,
                            signals: Signals, context: RunContext) -> None:
    """Scaling ``index``'s limit by ``factor`` ≥ 1 never raises that index or I_max of any run
    (and ``factor`` ≤ 1 never lowers them). A nominal shrinks with a limit scaled below 1, so
    it stays below the limit (the index only grows with that too)."""
    declared = _index(rulebook, index)
    changes: dict[str, Expr] = {"limit": Binary("*", declared.limit, Number(factor))}
    if declared.nominal is not None and factor < 1:
        changes["nominal"] = Binary("*", declared.nominal, Number(factor))
    changed = _with_index(rulebook, index, **changes)
    before = compile_rulebook(rulebook).evaluate(signals, context)
    after = compile_rulebook(changed).evaluate(signals, context)
    sign = 1 if factor >= 1 else -1
    for label, old, new in (("index " + index, before.values[index], after.values[index]),
                            ("I_max", before.i_max, after.i_max)):
        moved = sign * (new - old)
        assert np.all(moved <= 1e-12), f"{label} moved the wrong way when the limit of " \
            f"{index} was scaled by {factor:g}: {old} → {new}"


def check_monotone_in_weight(rulebook: Rulebook, index: str, weight: float,
                             signals: Signals, context: RunContext) -> None:
    """Setting ``index``'s weight to ``weight`` moves I_max of every run the same way as the
    weight moved (or not at all)."""
    checked = _compiled(rulebook).checked
    old_weight = checked.weights[index]
    changed = _with_index(rulebook, index, weight=Number(weight))
    before = compile_rulebook(checked).evaluate(signals, context).i_max
    after = compile_rulebook(changed).evaluate(signals, context).i_max
    sign = 1 if weight >= old_weight else -1
    assert np.all(sign * (after - before) >= -1e-12), f"I_max moved against the weight of " \
        f"{index} ({old_weight:g} → {weight:g}): {before} → {after}"


def rigid_transform(signals: Signals, context: RunContext, dx: float, dy: float,
                    dyaw: float) -> tuple[dict[str, np.ndarray], RunContext]:
    """The same runs (and reference run) moved by ``(dx, dy)`` and turned by ``dyaw`` about
    the origin of the start frame."""
    cos, sin = math.cos(dyaw), math.sin(dyaw)

    def move(data: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        out = {k: np.array(v, copy=True) for k, v in data.items()}
        if "x" in data and "y" in data:
            x, y = np.asarray(data["x"]), np.asarray(data["y"])
            out["x"] = dx + cos * x - sin * y
            out["y"] = dy + sin * x + cos * y
        if "yaw" in data:
            out["yaw"] = np.asarray(data["yaw"]) + dyaw
        return out

    reference = move(context.reference) if context.reference is not None else None
    return move(signals), replace(context, reference=reference)


def check_rigid_transform_invariance(rulebook: Rulebook | CheckedRulebook | CompiledRulebook,
                                     signals: Signals, context: RunContext, dx: float,
                                     dy: float, dyaw: float, tolerance: float = 1e-9) -> None:
    """Moving and turning the whole scene (runs and reference run together) changes no index,
    no I_max and no chance: rules speak of relative motion, never of where the map's origin
    is. (A rulebook reading absolute ``x``/``y``/``yaw`` fails this on purpose.)"""
    compiled = _compiled(rulebook)
    before = compiled.evaluate(signals, context)
    moved, moved_context = rigid_transform(signals, context, dx, dy, dyaw)
    after = compiled.evaluate(moved, moved_context)
    for name in before.index_names:
        assert np.allclose(before.values[name], after.values[name], atol=tolerance), \
            f"index {name} changed under a rigid transform: {before.values[name]} → " \
            f"{after.values[name]}"
    for name in before.chance_names:
        assert np.array_equal(before.chances[name], after.chances[name]), \
            f"chance {name} changed under a rigid transform"


def path_passes(compiled: CompiledRulebook, signals: Signals, context: RunContext,
                failed_runs: int = 0) -> bool:
    """Whether a path with these runs passes: its chain meets every command rule, the first
    run (standing in for the reference run) every prescreen, the statistics every verdict."""
    if compiled.check_chain(context.chain, context.rover):
        return False
    evaluation = compiled.evaluate(signals, context, per_sample=False)
    first = first_run(evaluation)
    if compiled.prescreen(first):
        return False
    return compiled.verdict(compiled.path_statistics(evaluation, failed_runs)).passed


def check_direction(old: CompiledRulebook, new: CompiledRulebook, direction: str,
                    signals: Signals, context: RunContext,
                    new_signals: Signals | None = None) -> tuple[bool, bool]:
    """A change labelled ``stricter`` never turns a failing path into a passing one, a
    ``looser`` one never the reverse, a ``neutral`` one changes neither. Returns whether the
    path passed before and after. ``new_signals``: the runs as the new rulebook sees them,
    when the change moves what the collision check gives (a named area added, removed or
    moved to another level); by default the same runs."""
    before = path_passes(old, signals, context)
    after = path_passes(new, signals if new_signals is None else new_signals, context)
    if direction == "stricter":
        assert before or not after, "a stricter change turned a fail into a pass"
    elif direction == "looser":
        assert after or not before, "a looser change turned a pass into a fail"
    elif direction == "neutral":
        assert before == after, "a neutral change turned " + \
            ("a pass into a fail" if before else "a fail into a pass")
    return before, after
