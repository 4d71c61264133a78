"""The two evaluators of a results diff, and where their collision signals come from.

A diff compares per-run values, I_max, dominant indices, chances and verdicts; it never shows
result maps. So each rulebook is compiled with its per-sample maps replaced by a constant
(:func:`values_only`): values, raw values, I_max, dominant indices and chances are exactly
those of the full rulebook, the evaluator skips the per-sample work, and it no longer reads
``collision.contact`` when only a map did. That is what lets the stored ``collisions/hits``
stand in for the obstacle checker.
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Sequence
from typing import Any

from idefix_rules.campaign.store import ResultStore
from idefix_rules.rulebook import check_text, compile_rulebook
from idefix_rules.rulebook.check import CheckedRulebook, ObstacleLevelSpec
from idefix_rules.rulebook.compile import CompiledRulebook
from idefix_rules.rulebook.model import Number

# Collision signals the results file stores per run (evaluation/collisions/<name>).
STORED_COLLISIONS = {"collision.hits": "hits", "collision.buffer": "buffer"}


def values_only(checked: CheckedRulebook) -> CompiledRulebook:
    """The rulebook compiled without result maps (see the module docstring)."""
    model = checked.rulebook
    indices = tuple(dataclasses.replace(index, map=Number(0.0)) for index in model.indices)
    plain = dataclasses.replace(model, indices=indices)
    return compile_rulebook(dataclasses.replace(checked, rulebook=plain))


def source_sha256(checked: CheckedRulebook) -> str:
    return hashlib.sha256(checked.rulebook.source.encode("utf-8")).hexdigest()


def collision_reads(evaluator: CompiledRulebook) -> frozenset[str]:
    return frozenset(n for n in evaluator.required_signals if n.startswith("collision."))


def stored_levels(store: ResultStore, candidates: Sequence[CheckedRulebook]
                  ) -> tuple[ObstacleLevelSpec, ...] | None:
    """Obstacle levels of the rulebook whose evaluation is stored in ``store`` (its collisions
    were computed with them), or None when that rulebook is not known."""
    group = store.file.get("evaluation")
    if group is None:
        return None
    digest = str(group.attrs.get("rulebook_sha256", ""))
    for checked in candidates:
        if source_sha256(checked) == digest:
            return checked.obstacle_levels
    try:
        text = store.text("rulebook")
    except KeyError:
        return None
    if hashlib.sha256(text.encode("utf-8")).hexdigest() != digest:
        return None
    result = check_text(text, "<stored rulebook>")
    return result.checked.obstacle_levels if result.checked is not None else None


def can_use_stored(evaluators: Sequence[Any], levels: tuple[ObstacleLevelSpec, ...] | None
                   ) -> bool:
    """True when every evaluator that reads collisions reads only stored ones and has the
    obstacle levels (thresholds and buffers) the stored collisions were computed with."""
    if levels is None:
        return False
    for evaluator in evaluators:
        reads = collision_reads(evaluator)
        if reads and (not reads <= set(STORED_COLLISIONS)
                      or tuple(evaluator.obstacle_levels) != tuple(levels)):
            return False
    return True
