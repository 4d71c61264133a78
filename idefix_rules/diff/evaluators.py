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

import numpy as np

from idefix_rules.campaign.store import ResultStore
from idefix_rules.rulebook import check_text, compile_rulebook
from idefix_rules.rulebook.check import CheckedRulebook
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


def collision_setup(checked: CheckedRulebook) -> tuple[Any, ...]:
    """What a rulebook's collisions are computed with: its obstacle levels (thresholds and
    buffers) and its named areas (obstacles of their levels)."""
    return (*checked.obstacle_levels, *checked.areas)


def ground_key(checked: CheckedRulebook, areas: Any) -> tuple[Any, ...]:
    """What a rulebook puts on the ground for the collision check: its obstacle levels and,
    of its named areas (``areas``: their geometry in a campaign, by name), those that cover
    some ground, with their level and shape. Two rulebooks with the same key give the same
    collision signals (an area's own buffer only shapes its ``area.NAME.buffer`` signal)."""
    covered = []
    for name in sorted(areas):
        area = areas[name]
        if area.empty:
            continue
        shape = hashlib.sha256()
        for polygon in area.polygons:
            shape.update(np.ascontiguousarray(polygon, dtype=float).tobytes())
        if area.mask is not None:
            shape.update(np.ascontiguousarray(area.mask).tobytes())
        covered.append((name, area.level, shape.hexdigest()))
    return (*checked.obstacle_levels, *covered)


def area_reads(evaluator: CompiledRulebook) -> frozenset[str]:
    """The signals of named areas the rulebook reads (computed from the poses, never stored)."""
    return frozenset(evaluator.area_signals_read)


def stored_rulebook(store: ResultStore, candidates: Sequence[CheckedRulebook]
                    ) -> CheckedRulebook | None:
    """The rulebook whose evaluation is stored in ``store`` (its collisions were computed with
    it), or None when that rulebook is not known."""
    group = store.file.get("evaluation")
    if group is None:
        return None
    digest = str(group.attrs.get("rulebook_sha256", ""))
    for checked in candidates:
        if source_sha256(checked) == digest:
            return checked
    try:
        text = store.text("rulebook")
    except KeyError:
        return None
    if hashlib.sha256(text.encode("utf-8")).hexdigest() != digest:
        return None
    result = check_text(text, "<stored rulebook>")
    return result.checked


def can_use_stored(evaluators: Sequence[Any], stored: tuple[Any, ...] | None,
                   keys: Sequence[tuple[Any, ...]]) -> bool:
    """True when every evaluator that reads collisions reads only stored ones and puts on the
    ground (``keys``, :func:`ground_key` per evaluator) what the stored collisions were
    computed with (``stored``). The signals of named areas come from the poses either way."""
    if stored is None:
        return False
    for evaluator, key in zip(evaluators, keys, strict=True):
        reads = collision_reads(evaluator)
        if reads and (not reads <= set(STORED_COLLISIONS) or key != stored):
            return False
    return True
