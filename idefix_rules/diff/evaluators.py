"""The two evaluators of a results diff: each rulebook compiled for per-run values only.

A diff compares per-run values, I_max, dominant indices, chances and verdicts; it never shows
result maps. So each rulebook is compiled with its per-sample maps replaced by a constant
(:func:`values_only`): values, raw values, I_max, dominant indices and chances are exactly
those of the full rulebook, the evaluator skips the per-sample work, and it no longer reads
``collision.contact`` when only a map did. That is what lets the stored ``collisions/hits``
stand in for the obstacle checker (:mod:`idefix_rules.results.collisions`).
"""

from __future__ import annotations

import dataclasses

from idefix_rules.rulebook import compile_rulebook
from idefix_rules.rulebook.check import CheckedRulebook
from idefix_rules.rulebook.compile import CompiledRulebook
from idefix_rules.rulebook.model import Number


def values_only(checked: CheckedRulebook) -> CompiledRulebook:
    """The rulebook compiled without result maps (see the module docstring)."""
    model = checked.rulebook
    indices = tuple(dataclasses.replace(index, map=Number(0.0)) for index in model.indices)
    plain = dataclasses.replace(model, indices=indices)
    return compile_rulebook(dataclasses.replace(checked, rulebook=plain))
