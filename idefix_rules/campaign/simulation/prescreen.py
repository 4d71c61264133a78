"""A reference run under the rulebook: its run context and the pre-screen findings that keep a
chain from the Monte Carlo part (the simulation stage, and each side of a results diff)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from idefix_rules.commands import Command, RoverGeometry
from idefix_rules.results.collisions import CollisionFunction


def run_context(chain: Sequence[Command], rover: RoverGeometry, sigma: float,
                reference: Mapping[str, np.ndarray] | None) -> Any:
    from idefix_rules.rulebook import RunContext

    return RunContext(chain=tuple(chain), rover=rover, initial_position_sigma=sigma,
                      reference=reference)


def prescreen_reference(evaluator: Any, chain: Sequence[Command], rover: RoverGeometry,
                        sigma: float, reference: Mapping[str, np.ndarray],
                        collisions: CollisionFunction | None = None) -> list[Any]:
    """The rulebook's pre-screen findings on a reference run (empty: go on to Monte Carlo)."""
    signals = {key: np.asarray(value)[None, ...] for key, value in reference.items()}
    if collisions is not None:
        extra, _ = collisions(signals)
        signals.update(extra)
    evaluation = evaluator.evaluate(signals, run_context(chain, rover, sigma, reference))
    return list(evaluator.prescreen(evaluation))


def finding_text(item: Any) -> str:
    """One line for a rule finding (command violation or pre-screen finding)."""
    for method in ("describe", "message"):
        value = getattr(item, method, None)
        if callable(value):
            return str(value())
        if isinstance(value, str):
            return value
    rule = getattr(item, "rule", None)
    reason = getattr(item, "reason", None)
    if rule is not None:
        return f"{rule}: {reason}" if reason else str(rule)
    return str(item)
