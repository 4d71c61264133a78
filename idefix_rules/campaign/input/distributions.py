"""The campaign file's ``uncertainty`` section: the distributions a parameter may take."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field, PrivateAttr, model_validator
from pydantic_core import PydanticCustomError

from idefix_rules import units
from idefix_rules.campaign.input.field_types import AnyQuantity, Flag, Ratio, Seed, Strict
from idefix_rules.units import Dimension, UnitError, describe, parse_quantity


class _DistributionBase(Strict):
    """Values carry units; a bare number means a dimensionless parameter."""

    _dimension: Dimension = PrivateAttr(default=units.DIMENSIONLESS)

    @model_validator(mode="wrap")
    @classmethod
    def _common_dimension(cls, data: Any, handler: Any) -> Any:
        instance = handler(data)
        if isinstance(data, dict):
            dimensions = {}
            for key, value in data.items():
                if key in ("distribution", "sigma") or not isinstance(value, str | int | float):
                    continue
                try:
                    dimensions[key] = parse_quantity(value).dimension
                except UnitError:
                    continue
            kinds = set(dimensions.values())
            if len(kinds) > 1:
                listing = ", ".join(f"{key} is {describe(dim)}" for key, dim in dimensions.items())
                raise PydanticCustomError("dimension", "values disagree in dimension: {listing}",
                                          {"listing": listing})
            if kinds:
                instance._dimension = kinds.pop()
        return instance

    @property
    def dimension(self) -> Dimension:
        return self._dimension


class Fixed(_DistributionBase):
    distribution: Literal["fixed"]
    value: AnyQuantity


class Normal(_DistributionBase):
    distribution: Literal["normal"]
    mean: AnyQuantity
    std: AnyQuantity = Field(gt=0)


class TruncatedNormal(_DistributionBase):
    distribution: Literal["truncated_normal"]
    mean: AnyQuantity
    std: AnyQuantity = Field(gt=0)
    low: AnyQuantity
    high: AnyQuantity

    @model_validator(mode="after")
    def _ordered(self) -> TruncatedNormal:
        if not self.low < self.high:
            raise PydanticCustomError("bounds", "'low' must be below 'high'")
        return self


class Uniform(_DistributionBase):
    distribution: Literal["uniform"]
    low: AnyQuantity
    high: AnyQuantity

    @model_validator(mode="after")
    def _ordered(self) -> Uniform:
        if not self.low < self.high:
            raise PydanticCustomError("bounds", "'low' must be below 'high'")
        return self


class LogNormal(_DistributionBase):
    """Log-normal given by its median (with unit) and the std of the log (dimensionless)."""

    distribution: Literal["log_normal"]
    median: AnyQuantity = Field(gt=0)
    sigma: Ratio = Field(gt=0)


Distribution = Annotated[Fixed | Normal | TruncatedNormal | Uniform | LogNormal,
                         Field(discriminator="distribution")]

SamplingMethod = Literal["monte_carlo", "latin_hypercube", "sobol"]


class UncertaintySection(Strict):
    method: SamplingMethod = "monte_carlo"
    seed: Seed = 0
    # Run j of every path draws the same values (common random numbers); false: each path
    # draws its own.
    paired: Flag = True
    parameters: dict[str, Distribution] = {}
