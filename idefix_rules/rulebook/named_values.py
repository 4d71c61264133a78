"""Named values a compiled rulebook reads besides signals: constants, a command's quantities."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from idefix_rules.commands import Command, RoverGeometry, rule_quantities
from idefix_rules.rulebook.expressions import Closure, Frame, layout
from idefix_rules.signals import AXIS_LABELS


def command_quantities(command: Command, number: int, rover: RoverGeometry) -> dict[str, float]:
    """The names a command rule reads, SI, from :func:`rule_quantities` (worked out exactly
    from the command's numbers as written)."""
    return {
        "max_wheel_rate": command.max_wheel_rate,
        "delta_position": command.delta_position,
        "delta_heading": command.delta_heading,
        **rule_quantities(command, rover),
        "command_number": float(number),
    }


def layout_constants(constants: Mapping[str, Any]) -> dict[str, Any]:
    """Checked constants (floats, ``{label: value}`` tables) in the compiled layout."""
    out: dict[str, Any] = {}
    for name, value in constants.items():
        if isinstance(value, dict):
            axis = next(a for a, labels in AXIS_LABELS.items() if next(iter(value)) in labels)
            row = np.array([[value[label] for label in AXIS_LABELS[axis]]])
            out[name] = layout(row, (axis,))
        else:
            out[name] = float(value)
    return out


def scope_closure(name: str) -> Closure:
    def run(frame: Frame) -> Any:
        value = frame.scope[name]
        return value if np.ndim(value) == 0 else layout(np.asarray(value), ())
    return run
