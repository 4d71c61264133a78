"""The campaign schema's shared field types: quantities with units, seeds, flags, strictness."""

from __future__ import annotations

import math
from typing import Annotated, Any

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    StrictBool,
    StrictInt,
    ValidationInfo,
)
from pydantic_core import PydanticCustomError

from idefix_rules import units
from idefix_rules.campaign.input.yamlsource import flag_value
from idefix_rules.limits import MAX_SEED
from idefix_rules.units import Dimension, UnitError, describe, parse_quantity


def _seed_range(value: int) -> int:
    if not 0 <= value <= MAX_SEED:
        raise PydanticCustomError("seed", "a seed is a whole number from 0 to 2^64 - 1 "
                                  "({maximum}), got {got}",
                                  {"maximum": str(MAX_SEED), "got": str(value)})
    return value


# StrictInt: YAML's `true` is not a seed
Seed = Annotated[StrictInt, AfterValidator(_seed_range)]

# The campaign's YAML reads only true and false as booleans (YAML 1.2: a keep-out area named
# `off` stays a name); a flag still takes yes/no/on/off as written, anything else StrictBool
# refuses.
Flag = Annotated[StrictBool, BeforeValidator(flag_value)]


def _quantity(dimension: Dimension | None) -> BeforeValidator:
    """A validator turning ``"5 cm"`` into SI; ``dimension=None`` accepts any dimension."""

    def parse(value: Any) -> float:
        wanted = describe(dimension) if dimension is not None else "a number or a quantity"
        if isinstance(value, bool) or not isinstance(value, str | int | float):
            raise PydanticCustomError("quantity", "expected {wanted}, got {got}",
                                      {"wanted": wanted, "got": show(value)})
        try:
            if isinstance(value, int | float) or not _has_unit(value):
                if dimension is None or dimension.is_dimensionless:
                    number = float(parse_quantity(value).value)
                    if not math.isfinite(number):  # YAML's .inf: said here, not downstream
                        raise PydanticCustomError("quantity", "expected a finite value, got "
                                                  "{got}", {"got": show(value)})
                    return number
                raise PydanticCustomError("quantity", "expected {wanted}, got {got}",
                                          {"wanted": wanted, "got": show(value)})
            quantity = parse_quantity(value)
        except UnitError as failure:
            # position: the character to blame, for the diagnostic's column
            raise PydanticCustomError("quantity", "{reason}",
                                      {"reason": str(failure),
                                       "position": failure.position}) from None
        if dimension is not None and quantity.dimension != dimension:
            raise PydanticCustomError(
                "quantity", "expected {wanted}, got {got} ({got_kind})",
                {"wanted": wanted, "got": show(value), "got_kind": describe(quantity.dimension)})
        if not math.isfinite(quantity.value):
            raise PydanticCustomError("quantity", "expected a finite value, got {got}",
                                      {"got": show(value)})
        return float(quantity.value)

    return BeforeValidator(parse)


def _has_unit(text: str) -> bool:
    try:
        number = float(text)
    except ValueError:
        return True
    return not math.isfinite(number)


def show(value: Any) -> str:
    """A value as a message quotes it: text in double quotes, a boolean and nothing (an empty
    value, YAML's null) in YAML's words, anything else as its repr.

    >>> show("90"), show(None), show(True), show(0.05)
    ('"90"', 'nothing', 'true', '0.05')
    """
    if value is None:
        return "nothing"
    if isinstance(value, bool):
        return str(value).lower()
    return f'"{value}"' if isinstance(value, str) else repr(value)


Length = Annotated[float, _quantity(units.LENGTH)]
PositiveLength = Annotated[float, _quantity(units.LENGTH), Field(gt=0)]
Angle = Annotated[float, _quantity(units.ANGLE)]
AngularRate = Annotated[float, _quantity(units.ANGULAR_RATE)]
Duration = Annotated[float, _quantity(units.TIME)]
Ratio = Annotated[float, _quantity(units.DIMENSIONLESS)]
Charge = Annotated[float, _quantity(units.CHARGE)]
AnyQuantity = Annotated[float, _quantity(None)]


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


# Validation context of a campaign read back from a results file: it was valid when it ran,
# so the checks added since (marked with new_run) do not refuse it (its results stand).
STORED_CAMPAIGN = {"stored": True}


def new_run(info: ValidationInfo) -> bool:
    """Whether a check added to the schema later applies: to a campaign about to run, not to
    one stored with results (:data:`STORED_CAMPAIGN`)."""
    return not (isinstance(info.context, dict) and info.context.get("stored"))
