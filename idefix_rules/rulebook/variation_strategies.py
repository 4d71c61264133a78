"""Hypothesis strategies for variations of a rulebook: one number changed."""

from __future__ import annotations

from typing import Any

from hypothesis import assume
from hypothesis import strategies as st

from idefix_rules.rulebook.model import Binary, Number, Rulebook


@st.composite
def rulebook_variations(draw: Any, rulebook: Rulebook) -> tuple[str, Rulebook]:
    """``(description, rulebook)``: ``rulebook`` with one number changed — a scalar
    constant, an index limit, nominal or weight, or the number a command rule, verdict or
    prescreen compares with — by a factor drawn in [0.25, 4] (weights are drawn in [0, 1]).
    A change that would make the rulebook invalid (a nominal at or above its limit) is not
    drawn."""
    from idefix_rules.rulebook.check import check

    description, variant = draw(_variations(rulebook))
    assume(check(variant).ok)
    return str(description), variant


@st.composite
def _variations(draw: Any, rulebook: Rulebook) -> tuple[str, Rulebook]:
    from dataclasses import replace as replaced

    factor = draw(st.sampled_from([0.25, 0.5, 0.8, 0.9, 1.1, 1.25, 2.0, 4.0]))
    scalar = [c for c in rulebook.constants if isinstance(c.value, Number)]
    thresholds = [(attribute, rule) for attribute in ("command_rules", "verdicts", "prescreens")
                  for rule in getattr(rulebook, attribute)
                  if isinstance(rule.condition, Binary) and isinstance(rule.condition.right,
                                                                       Number)
                  and rule.condition.right.value != 0]
    with_nominal = [i for i in rulebook.indices if i.nominal is not None]
    choices = ["limit", "weight"] + (["constant", "constant"] if scalar else []) + \
        (["threshold"] if thresholds else []) + (["nominal"] if with_nominal else [])
    choice = draw(st.sampled_from(choices))
    if choice == "constant":
        constant = draw(st.sampled_from(scalar))
        number = constant.value
        assert isinstance(number, Number)
        new = replaced(constant, value=Number(number.value * factor, number.unit))
        constants = tuple(new if c.name == constant.name else c for c in rulebook.constants)
        return (f"constant {constant.name} × {factor:g}",
                replaced(rulebook, constants=constants))
    if choice == "threshold":
        attribute, rule = draw(st.sampled_from(thresholds))
        condition = rule.condition
        right = condition.right
        moved = replaced(condition, right=Number(right.value * factor, right.unit))
        rules = tuple(replaced(r, condition=moved) if r.name == rule.name else r
                      for r in getattr(rulebook, attribute))
        fields: dict[str, Any] = {attribute: rules}
        return f"threshold of {rule.name} × {factor:g}", replaced(rulebook, **fields)
    index = draw(st.sampled_from(with_nominal if choice == "nominal" else rulebook.indices))
    if choice == "nominal":
        assert index.nominal is not None
        changed = replaced(index, nominal=Binary("*", index.nominal, Number(factor)))
    elif choice == "limit":
        changed = replaced(index, limit=Binary("*", index.limit, Number(factor)))
    else:
        weight = Number(draw(st.sampled_from([0.0, 0.25, 0.5, 0.75, 1.0])))
        changed = replaced(index, weight=weight)
    indices_ = tuple(changed if i.name == index.name else i for i in rulebook.indices)
    return f"index {index.name} {choice} changed", replaced(rulebook, indices=indices_)
