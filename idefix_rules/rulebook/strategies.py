"""Hypothesis strategies for rulebooks and run signals, reusable by rule engineers' tests.

* :func:`rulebooks` — *valid* rule models (they pass :func:`~idefix_rules.rulebook.check`), built
  type-correct by construction: every index reduces a per-sample quantity of a known dimension
  to one value per run, limits have the value's dimension, a nominal (when drawn) is the limit
  times a fraction in [1/8, 7/8], weights lie in [0, 1]. Numbers are non-negative floats with
  units as written, so ``parse(format(model)) == model`` holds.
* :func:`chains` — short command chains; :func:`run_batches` — ``(signals, context)`` pairs:
  signals of the contract vectorised over runs on one time grid whose ``command`` signal
  follows the chain, and a :class:`~idefix_rules.rulebook.derived.RunContext` with a reference
  run. Values are small dyadic rationals, so sums are exact in every evaluation order.

This module is their import path; they are defined by domain in
:mod:`~idefix_rules.rulebook.model_strategies` (rule models),
:mod:`~idefix_rules.rulebook.run_strategies` (chains and runs, realistic ones included) and
:mod:`~idefix_rules.rulebook.variation_strategies` (a rulebook with one number changed).

>>> from hypothesis import given
>>> @given(rulebooks())
... def test_every_index_has_a_weight(rulebook):
...     assert all(index.weight is not None for index in rulebook.indices)
"""

from __future__ import annotations

from idefix_rules.rulebook.model_strategies import (
    NOMINAL_SHARES,
    index_values,
    indices,
    numbers,
    numbers_value,
    rulebooks,
)
from idefix_rules.rulebook.run_strategies import (
    RunRanges,
    chains,
    chains_within,
    perturbed_runs,
    realistic_chains,
    realistic_runs,
    run_batches,
)
from idefix_rules.rulebook.variation_strategies import rulebook_variations

__all__ = [
    "NOMINAL_SHARES",
    "RunRanges",
    "chains",
    "chains_within",
    "index_values",
    "indices",
    "numbers",
    "numbers_value",
    "perturbed_runs",
    "realistic_chains",
    "realistic_runs",
    "rulebook_variations",
    "rulebooks",
    "run_batches",
]
