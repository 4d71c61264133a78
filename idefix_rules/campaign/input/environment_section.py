"""The campaign file's ``environment`` section: terrain, rocks, keep-out and named areas."""

from __future__ import annotations

import contextlib
import math
import re
from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    Field,
    PrivateAttr,
    ValidationInfo,
    ValidatorFunctionWrapHandler,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from idefix_rules.campaign.input.field_types import (
    Angle,
    AnyQuantity,
    Length,
    PositiveLength,
    Seed,
    Strict,
    new_run,
)
from idefix_rules.limits import (
    MAX_ROCK_SEMI_AXIS,
    MAX_TERRAIN_EXTENT,
    MAX_TERRAIN_ROCKS,
    MIN_ROCK_SEMI_AXIS,
)
from idefix_rules.units import Dimension, UnitError, parse_quantity, parse_unit

# Terrain grids hold at most this many nodes (docs/terrain-format.md: nx·ny ≤ 16 million).
MAX_TERRAIN_NODES = 16_000_000


def _inclination(value: float, info: ValidationInfo) -> float:
    """A plane's inclination: from 0 to under 90 deg (``slope_direction`` says which way it
    falls; at 90 deg the plane is a wall, its heights infinite)."""
    if new_run(info) and not 0.0 <= value < math.pi / 2:
        raise PydanticCustomError("slope", "expected an inclination from 0 deg to under 90 "
                                  "deg (slope_direction gives the way it falls), got {got} deg",
                                  {"got": f"{math.degrees(value):g}"})
    return value


def _not_negative_length(value: float, info: ValidationInfo) -> float:
    if new_run(info) and not value >= 0.0:
        raise PydanticCustomError("not_negative", "expected a length of 0 m or more, got "
                                  "{got} m", {"got": f"{value:g}"})
    return value


def _terrain_width(value: float, info: ValidationInfo) -> float:
    """A terrain's size, or a DEM's cell (the grid is at least one cell wide): at most
    :data:`MAX_TERRAIN_EXTENT` (the rover model starts within 1000 km of the terrain's origin;
    far wider grids overflowed its rut grid)."""
    if new_run(info) and value > MAX_TERRAIN_EXTENT:
        raise PydanticCustomError(
            "terrain", "expected at most {most} km, got {got} m: the rover model starts within "
            "1000 km of the terrain's origin, so a terrain is at most {most} km wide",
            {"most": f"{MAX_TERRAIN_EXTENT / 1000:g}", "got": f"{value:.12g}"})
    return value


TerrainWidth = Annotated[Length, AfterValidator(_terrain_width)]


class SyntheticTerrain(Strict):
    size: TerrainWidth = Field(default=4.0, gt=0)
    cell: Length = Field(default=0.02, gt=0)
    slope: Annotated[Angle, AfterValidator(_inclination)] = 0.0
    slope_direction: Angle = 0.0
    # the height's standard deviation
    roughness: Annotated[Length, AfterValidator(_not_negative_length)] = 0.0
    seed: Seed = 0

    @model_validator(mode="after")
    def _grid_size(self) -> SyntheticTerrain:
        if self.cell >= self.size:
            raise PydanticCustomError("terrain", "cell {cell} m must be smaller than size {size} m",
                                      {"cell": f"{self.cell:g}", "size": f"{self.size:g}"})
        side = self.size / self.cell + 1.0  # nodes a side; side ** 2 overflows at 1e160 m
        if side > MAX_TERRAIN_NODES or side * side > MAX_TERRAIN_NODES:
            raise PydanticCustomError(
                "terrain", "size {size} m with cell {cell} m gives {side} × {side} grid nodes, "
                "more than {limit}", {"size": f"{self.size:g}", "cell": f"{self.cell:g}",
                                      "side": f"{side:.3g}", "limit": MAX_TERRAIN_NODES})
        return self


class TerrainSection(Strict):
    """``dem``: a terrain file (docs/terrain-format.md), ``.npy`` or ``.csv`` heights (these
    need ``cell``; ``origin`` defaults to centring the grid); or ``synthetic`` settings."""

    dem: str | None = None
    cell: TerrainWidth | None = Field(default=None, gt=0)
    origin: tuple[Length, Length] | None = None
    synthetic: SyntheticTerrain | None = None

    @model_validator(mode="after")
    def _one_source(self) -> TerrainSection:
        if self.dem is not None and self.synthetic is not None:
            raise PydanticCustomError("terrain", "give either 'dem' or 'synthetic', not both")
        return self


def _rock_size(value: float, info: ValidationInfo) -> float:
    """A rock's radius or semi-axis: from :data:`MIN_ROCK_SEMI_AXIS` (a smaller grain is
    regolith, and how deep a point lies inside it overflowed the obstacle checker) to
    :data:`MAX_ROCK_SEMI_AXIS` (a larger one is terrain, and its squares would overflow the
    obstacle checker's geometry)."""
    if new_run(info) and value < MIN_ROCK_SEMI_AXIS:
        raise PydanticCustomError(
            "rock", "expected a rock radius or semi-axis of at least {least} m, got {got} m (a "
            "smaller grain is part of the regolith, which the soil model represents; the "
            "collision check resolves 0.1 mm)",
            {"least": f"{MIN_ROCK_SEMI_AXIS:g}", "got": f"{value:.12g}"})
    if new_run(info) and value > MAX_ROCK_SEMI_AXIS:
        raise PydanticCustomError(
            "rock", "expected a rock radius or semi-axis of at most {most} m, got {got} m (a "
            "larger rock is a hill or a crater: give it in the terrain's dem)",
            {"most": f"{MAX_ROCK_SEMI_AXIS:g}", "got": f"{value:.12g}"})
    return value


RockAxis = Annotated[PositiveLength, AfterValidator(_rock_size)]

# the unit of a quantity as written: "8 cm" → "cm"
_QUANTITY_UNIT = re.compile(r"^[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?\s*(.*)$")


class RockSpec(Strict):
    x: Length
    y: Length
    radius: RockAxis | None = None
    semi_axes: tuple[RockAxis, RockAxis, RockAxis] | None = None
    embed: Length = 0.0
    level: Literal["L1", "L2", "L3"] | None = None

    @field_validator("embed", mode="wrap")
    @classmethod
    def _embed_in_height(cls, value: Any, handler: ValidatorFunctionWrapHandler,
                         info: ValidationInfo) -> float:
        """How deep a rock sits: from 0 (on the ground) to under its height (buried), said at
        ``embed`` in the unit written there (the size, checked before it, gives the height;
        without one size the model's check says so)."""
        depth = float(handler(value))
        radius, semi_axes = info.data.get("radius"), info.data.get("semi_axes")
        size = semi_axes[2] if semi_axes is not None else radius
        if not new_run(info) or size is None or (radius is not None and semi_axes is not None):
            return depth
        height = 2.0 * float(size)
        if 0.0 <= depth < height:
            return depth
        written = str(value).strip()
        unit = _QUANTITY_UNIT.match(written)
        try:
            shown = parse_unit(unit[1]).from_si(height) if unit and unit[1] else height
            unit_text = unit[1] if unit and unit[1] else "m"
        except UnitError:
            shown, unit_text = height, "m"
        raise PydanticCustomError(
            "rock", "expected a depth from 0 {unit} (on the ground) to under the rock's height "
            "{height} {unit} (fully buried), got {embed}{floats}",
            {"unit": unit_text, "height": f"{shown:.6g}", "embed": written,
             "floats": ": a negative depth would float it" if depth < 0 else ""})

    @model_validator(mode="after")
    def _one_size(self) -> RockSpec:
        if (self.radius is None) == (self.semi_axes is None):
            raise PydanticCustomError("rock", "give exactly one of 'radius' or 'semi_axes'")
        return self

    @property
    def axes(self) -> tuple[float, float, float]:
        if self.semi_axes is not None:
            return self.semi_axes
        assert self.radius is not None
        return (self.radius, self.radius, self.radius)


class RockLevels(Strict):
    l1_max_size: Length
    l2_max_size: Length


class KeepOutArea(Strict):
    name: str
    polygon: list[tuple[Length, Length]] = Field(min_length=3)
    level: Literal["L1", "L2", "L3"] = "L3"


class NamedAreaGeometry(Strict):
    """Where a keep-out or unknown-surface area the rulebook declares lies: polygons (x, y)."""

    polygons: list[list[tuple[Length, Length]]] = []


def _rock_count(value: list[RockSpec], info: ValidationInfo) -> list[RockSpec]:
    """At most :data:`MAX_TERRAIN_ROCKS` rocks, as many as the rover model holds (YAML aliases
    write thousands in a few lines)."""
    if new_run(info) and len(value) > MAX_TERRAIN_ROCKS:
        raise PydanticCustomError(
            "rocks", "{count} rocks; at most {most} (the rover model holds {most})",
            {"count": len(value), "most": MAX_TERRAIN_ROCKS})
    return value


class EnvironmentSection(Strict):
    terrain: TerrainSection = TerrainSection()
    rocks: Annotated[list[RockSpec], AfterValidator(_rock_count)] = []
    rock_levels: RockLevels | None = None
    keep_out: list[KeepOutArea] = []
    areas: dict[str, NamedAreaGeometry] = {}
    regolith: dict[str, AnyQuantity] = {}
    # each regolith value's dimension as written (a bare number: dimensionless), checked
    # against its FMU parameter's unit once the FMU is known
    _regolith_dimensions: dict[str, Dimension] = PrivateAttr(default_factory=dict)

    @model_validator(mode="wrap")
    @classmethod
    def _written_dimensions(cls, data: Any, handler: Any) -> Any:
        instance = handler(data)
        regolith = data.get("regolith") if isinstance(data, dict) else None
        if isinstance(regolith, dict):
            for key, value in regolith.items():
                with contextlib.suppress(UnitError, TypeError, ValueError):
                    instance._regolith_dimensions[key] = parse_quantity(value).dimension
        return instance

    @property
    def regolith_dimensions(self) -> dict[str, Dimension]:
        """The dimension each regolith value was written with."""
        return dict(self._regolith_dimensions)
