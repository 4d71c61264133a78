"""The campaign file schema (pydantic): what a campaign may say, in SI after validation.

Dimensioned values are strings with units (``"5 mm/s"``, ``"90 deg"``), parsed with
:func:`idefix_rules.units.parse_quantity`; a bare number where a dimension is expected is an
error. The format is documented in ``docs/campaign-format.md``.
"""

from __future__ import annotations

import contextlib
import math
import unicodedata
from dataclasses import dataclass
from datetime import date
from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Discriminator,
    Field,
    PrivateAttr,
    StrictBool,
    StrictInt,
    Tag,
    ValidationInfo,
    model_validator,
)
from pydantic_core import PydanticCustomError

from idefix_rules import units
from idefix_rules.campaign.input.yamlsource import flag_value
from idefix_rules.limits import MAX_ROCK_SEMI_AXIS, MAX_RUNS, MAX_SEED, MAX_WORKERS
from idefix_rules.units import Dimension, UnitError, describe, parse_quantity

LEVELS = ("L1", "L2", "L3")



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
                                      {"wanted": wanted, "got": _show(value)})
        try:
            if isinstance(value, int | float) or not _has_unit(value):
                if dimension is None or dimension.is_dimensionless:
                    number = float(parse_quantity(value).value)
                    if not math.isfinite(number):  # YAML's .inf: said here, not downstream
                        raise PydanticCustomError("quantity", "expected a finite value, got "
                                                  "{got}", {"got": _show(value)})
                    return number
                raise PydanticCustomError("quantity", "expected {wanted}, got {got}",
                                          {"wanted": wanted, "got": _show(value)})
            quantity = parse_quantity(value)
        except UnitError as failure:
            # position: the character to blame, for the diagnostic's column
            raise PydanticCustomError("quantity", "{reason}",
                                      {"reason": str(failure),
                                       "position": failure.position}) from None
        if dimension is not None and quantity.dimension != dimension:
            raise PydanticCustomError(
                "quantity", "expected {wanted}, got {got} ({got_kind})",
                {"wanted": wanted, "got": _show(value), "got_kind": describe(quantity.dimension)})
        if not math.isfinite(quantity.value):
            raise PydanticCustomError("quantity", "expected a finite value, got {got}",
                                      {"got": _show(value)})
        return float(quantity.value)

    return BeforeValidator(parse)


def _has_unit(text: str) -> bool:
    try:
        number = float(text)
    except ValueError:
        return True
    return not math.isfinite(number)


def _show(value: Any) -> str:
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


# --- fmu -------------------------------------------------------------------------------------

class ChainSection(Strict):
    """How a chain reaches the FMU (docs/bring-your-own-fmu.md): ``parameters`` (the chain
    arrays, as the built-in rover takes them), ``inputs`` (set-points along the ideal
    kinematics fed each communication step: FMU input → set-point name) or ``none``."""

    delivery: Literal["parameters", "inputs", "none"] = "parameters"
    inputs: dict[str, str] = {}


def _finite(value: Any) -> Any:
    if isinstance(value, int | float) and not isinstance(value, bool) \
            and not math.isfinite(value):
        raise PydanticCustomError("finite", "expected a finite number, got {got}",
                                  {"got": _show(value)})
    return value


class FmuSection(Strict):
    path: str = "builtin"
    signals: dict[str, str] | None = None
    parameters: dict[str, str] | None = None
    chain: ChainSection = ChainSection()
    # An output mapped to the signal 'done' reports the chain complete from this value on.
    done_at: Annotated[float, BeforeValidator(_finite)] = 1.0


# --- environment -----------------------------------------------------------------------------

# Terrain grids hold at most this many nodes (docs/terrain-format.md: nx·ny ≤ 16 million).
MAX_TERRAIN_NODES = 16_000_000


# Validation context of a campaign read back from a results file: it was valid when it ran,
# so the checks added since (marked with _new_run) do not refuse it (its results stand).
STORED_CAMPAIGN = {"stored": True}


def _new_run(info: ValidationInfo) -> bool:
    """Whether a check added to the schema later applies: to a campaign about to run, not to
    one stored with results (:data:`STORED_CAMPAIGN`)."""
    return not (isinstance(info.context, dict) and info.context.get("stored"))


def _inclination(value: float, info: ValidationInfo) -> float:
    """A plane's inclination: from 0 to under 90 deg (``slope_direction`` says which way it
    falls; at 90 deg the plane is a wall, its heights infinite)."""
    if _new_run(info) and not 0.0 <= value < math.pi / 2:
        raise PydanticCustomError("slope", "expected an inclination from 0 deg to under 90 "
                                  "deg (slope_direction gives the way it falls), got {got} deg",
                                  {"got": f"{math.degrees(value):g}"})
    return value


def _not_negative_length(value: float, info: ValidationInfo) -> float:
    if _new_run(info) and not value >= 0.0:
        raise PydanticCustomError("not_negative", "expected a length of 0 m or more, got "
                                  "{got} m", {"got": f"{value:g}"})
    return value


class SyntheticTerrain(Strict):
    size: Length = Field(default=4.0, gt=0)
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
    cell: Length | None = Field(default=None, gt=0)
    origin: tuple[Length, Length] | None = None
    synthetic: SyntheticTerrain | None = None

    @model_validator(mode="after")
    def _one_source(self) -> TerrainSection:
        if self.dem is not None and self.synthetic is not None:
            raise PydanticCustomError("terrain", "give either 'dem' or 'synthetic', not both")
        return self


def _rock_size(value: float, info: ValidationInfo) -> float:
    """A rock's radius or semi-axis: at most :data:`MAX_ROCK_SEMI_AXIS` (a larger one is
    terrain, and its squares would overflow the obstacle checker's geometry)."""
    if _new_run(info) and value > MAX_ROCK_SEMI_AXIS:
        raise PydanticCustomError(
            "rock", "expected a rock radius or semi-axis of at most {most} m, got {got} m (a "
            "larger rock is a hill or a crater: give it in the terrain's dem)",
            {"most": f"{MAX_ROCK_SEMI_AXIS:g}", "got": f"{value:.12g}"})
    return value


RockAxis = Annotated[PositiveLength, AfterValidator(_rock_size)]


class RockSpec(Strict):
    x: Length
    y: Length
    radius: RockAxis | None = None
    semi_axes: tuple[RockAxis, RockAxis, RockAxis] | None = None
    embed: Length = 0.0
    level: Literal["L1", "L2", "L3"] | None = None

    @model_validator(mode="after")
    def _one_size(self, info: ValidationInfo) -> RockSpec:
        if (self.radius is None) == (self.semi_axes is None):
            raise PydanticCustomError("rock", "give exactly one of 'radius' or 'semi_axes'")
        height = 2.0 * self.axes[2]
        if _new_run(info) and not 0.0 <= self.embed < height:
            raise PydanticCustomError(
                "rock", "embed {embed} m: a rock sits from 0 m (on the ground) to under its "
                "height {height} m deep (fully buried); a negative depth would float it",
                {"embed": f"{self.embed:g}", "height": f"{height:g}"})
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


class EnvironmentSection(Strict):
    terrain: TerrainSection = TerrainSection()
    rocks: list[RockSpec] = []
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


# --- uncertainty -----------------------------------------------------------------------------

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


# --- paths -----------------------------------------------------------------------------------

class CommandSpec(Strict):
    max_wheel_rate: AngularRate = Field(gt=0)
    delta_position: Length
    delta_heading: Angle


# --- expectations ----------------------------------------------------------------------------

class PathVerdictExpectation(Strict):
    path: str
    verdict: Literal["pass", "fail", "marginal"]


class RankFirstExpectation(Strict):
    rank_first: str


def _fraction(value: float, info: ValidationInfo) -> float:
    """A risk or a chance: from 0 to 100 % (a bare number is the fraction itself: 0.3 is
    30 %, 30 is 3000 %, which no path could exceed)."""
    if _new_run(info) and not 0.0 <= value <= 1.0:
        raise PydanticCustomError(
            "fraction", "expected a risk or chance from 0 to 100 %, got {got} (a bare number "
            "is a fraction: write \"30 %\" or 0.3)", {"got": f"{value * 100:g} %"})
    return value


Fraction = Annotated[Ratio, AfterValidator(_fraction)]


class MeanRiskExpectation(Strict):
    path: str
    max_mean_risk: Fraction


class CollisionExpectation(Strict):
    path: str
    max_collision_chance: dict[Literal["L1", "L2", "L3", "any"], Fraction]


# An expectation's kind is the key that names it (and tags it in pydantic's union).
EXPECTATION_KINDS: dict[str, type[Strict]] = {
    "verdict": PathVerdictExpectation,
    "rank_first": RankFirstExpectation,
    "max_mean_risk": MeanRiskExpectation,
    "max_collision_chance": CollisionExpectation,
}
_EXPECTATION_KEYS = tuple(EXPECTATION_KINDS)


def _expectation_kind(value: Any) -> str | None:
    if isinstance(value, BaseModel):
        for key in _EXPECTATION_KEYS:
            if hasattr(value, key):
                return key
        return None
    if isinstance(value, dict):
        for key in _EXPECTATION_KEYS:
            if key in value:
                return key
    return None


Expectation = Annotated[
    Annotated[PathVerdictExpectation, Tag("verdict")]
    | Annotated[RankFirstExpectation, Tag("rank_first")]
    | Annotated[MeanRiskExpectation, Tag("max_mean_risk")]
    | Annotated[CollisionExpectation, Tag("max_collision_chance")],
    Discriminator(_expectation_kind, custom_error_type="expectation",
                  custom_error_message="an expectation needs one of: verdict, rank_first, "
                                       "max_mean_risk, max_collision_chance"),
]


def _one_kind(value: Any) -> Any:
    """An expectation of two kinds at once is two expectations: said as such, not as an
    unknown key of whichever kind was read first."""
    if isinstance(value, dict):
        kinds = [key for key in _EXPECTATION_KEYS if key in value]
        if len(kinds) > 1:
            raise ValueError(f"an expectation has one kind; this one gives {' and '.join(kinds)}: "
                             "write each as its own entry of expect")
    return value


ExpectationEntry = Annotated[Expectation, BeforeValidator(_one_kind)]


# --- waivers --------------------------------------------------------------------------------

def _plain_text(value: Any) -> Any:
    if isinstance(value, str) and not value.strip():
        raise PydanticCustomError("text", "expected a non-empty text")
    return value


Text = Annotated[str, BeforeValidator(_plain_text)]


def _written_date(value: Any, info: ValidationInfo) -> Any:
    """A date as YAML writes one (2027-03-31) or as text; a bare number is no date (pydantic
    would read 20990101 as seconds since 1970)."""
    quoted_number = isinstance(value, str) and value.strip().lstrip("+-").replace(
        ".", "", 1).isdigit()  # "4102444800": seconds since 1970 to pydantic, too
    if _new_run(info) and (quoted_number or (isinstance(value, int | float)
                           and not isinstance(value, bool))):
        raise PydanticCustomError("date", "expected a date written YYYY-MM-DD (e.g. "
                                  "2027-03-31), got the number {got}", {"got": repr(value)})
    return value


class Waiver(Strict):
    """A known, accepted failure of one rule on one path (or ``all``) of this plan, signed and
    dated (docs/campaign-format.md, "waivers"). ``command_rules: true`` lets it waive a
    command rule, which it never does otherwise."""

    rule: str
    path: str = "all"
    reason: Text
    approved_by: Text
    until: Annotated[date, BeforeValidator(_written_date)]
    command_rules: Flag = False

    def covers(self, path: str) -> bool:
        return self.path in ("all", path)


# --- simulation and the whole file -----------------------------------------------------------

# The stop limit's default margin over the chain's ideal duration: the built-in rover's
# controller ends a command at the latest after 2 × (ideal duration + ramp time) and may add a
# timed trim after an arc, so a run still driving at 3 × ideal + 5 s has had commands time out
# (docs/campaign-format.md, "simulation"). Runs end with their chain: a generous limit is cheap.
DEFAULT_DURATION_MARGIN = 3.0


class SimulationSection(Strict):
    output_interval: Duration = Field(default=0.1, gt=0)
    duration_margin: Ratio = Field(default=DEFAULT_DURATION_MARGIN, ge=1.0)
    extra_time: Duration = Field(default=5.0, ge=0)


MAX_PATH_NAME = 100  # characters: a name for people, and a part of figure file names


def _path_name(value: Any, info: ValidationInfo) -> Any:
    # Path names become HDF5 group names, file names of figures and JUnit test names.
    if isinstance(value, str) and (
            not value.strip() or "/" in value or value in (".", "..")
            or (_new_run(info) and (len(value) > MAX_PATH_NAME or any(
                unicodedata.category(c) in ("Cc", "Cs") for c in value)))):
        shown = repr(value if len(value) <= 40 else value[:37] + "...")
        if value in (".", ".."):  # which satisfy the rule below, so it would not say why
            raise PydanticCustomError(
                "path_name", "path name {name} is not usable: '.' and '..' mean this folder "
                "and the one above in a file path, and a path name becomes the file name of "
                "its figures; give it a letter or digit", {"name": shown})
        raise PydanticCustomError("path_name", "path name {name} is not usable: give a "
                                  "non-empty name of at most {most} characters, without '/' "
                                  "or control characters", {"name": shown,
                                                            "most": MAX_PATH_NAME})
    return value


PathName = Annotated[str, BeforeValidator(_path_name)]


def _output_folder(value: Any) -> Any:
    """An empty ``output:`` (a template's unfilled field) would write into the campaign file's
    folder, beside whatever is there: refused, as ``--out ''`` is; ``.`` says it on purpose."""
    if isinstance(value, str) and not value.strip():
        raise PydanticCustomError(
            "output_folder", "an empty folder name: give the folder the results go to "
            "(results/NAME), or '.' for the campaign file's own folder", {})
    return value


OutputFolder = Annotated[str, BeforeValidator(_output_folder)]

RunCount = Annotated[StrictInt, Field(ge=1, le=MAX_RUNS)]

def _runs(value: Any) -> Any:
    """A whole run count in range, or ``auto`` (any case, as ``--runs`` takes it); one
    message for either mistake."""
    if isinstance(value, str) and value.strip().lower() == "auto":
        return "auto"
    if (isinstance(value, int) and not isinstance(value, bool)
                           and 1 <= value <= MAX_RUNS):
        return value
    got = str(value).lower() if isinstance(value, bool) else _show(value)  # as YAML wrote it
    raise PydanticCustomError("runs", "expected a whole number of runs from 1 to {limit} or "
                              "'auto', got {got}", {"limit": MAX_RUNS, "got": got})


Runs = Annotated[StrictInt | Literal["auto"], BeforeValidator(_runs)]


def _workers(value: Any) -> Any:
    """``auto`` (any case, as ``--workers`` takes it) or a whole number, in one message for
    anything else (the range is C201's, :mod:`~idefix_rules.campaign.input.load`)."""
    if isinstance(value, str) and value.strip().lower() == "auto":
        return "auto"
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    got = str(value).lower() if isinstance(value, bool) else _show(value)
    raise PydanticCustomError("workers", "expected 'auto' or a whole number of worker processes "
                              "from 1 to {limit}, got {got}", {"limit": MAX_WORKERS, "got": got})


Workers = Annotated[StrictInt | Literal["auto"], BeforeValidator(_workers)]

# `runs: auto` (docs/campaign-format.md): the cap, the first look and the batch between looks.
DEFAULT_MAX_RUNS = 1000
DEFAULT_MIN_RUNS = 32
DEFAULT_BATCH_RUNS = 32


@dataclass(frozen=True)
class AdaptiveRuns:
    """``runs: auto``: paths are looked at after ``min_runs`` runs, then every ``batch_runs``,
    and stop when decided or at ``max_runs``.

    >>> AdaptiveRuns(min_runs=32, max_runs=100, batch_runs=32).looks()
    [32, 64, 96, 100]
    """

    min_runs: int = DEFAULT_MIN_RUNS
    max_runs: int = DEFAULT_MAX_RUNS
    batch_runs: int = DEFAULT_BATCH_RUNS

    def looks(self) -> list[int]:
        """The run counts at which a path's statistics are looked at, the cap last."""
        first = min(self.min_runs, self.max_runs)
        return [*range(first, self.max_runs, self.batch_runs), self.max_runs]


class CampaignFile(Strict):
    name: str | None = None
    description: str = ""
    fmu: FmuSection = FmuSection()
    environment: EnvironmentSection = EnvironmentSection()
    uncertainty: UncertaintySection = UncertaintySection()
    paths: dict[PathName, Annotated[list[CommandSpec], Field(min_length=1)]] = Field(
        min_length=1)
    # StrictInt: YAML's `true` is not a run count or a seed
    runs: Runs = 100
    max_runs: RunCount | None = None  # only with `runs: auto`
    min_runs: RunCount | None = None
    batch_runs: RunCount | None = None
    rulebook: str
    output: OutputFolder = "results"
    workers: Workers = "auto"
    simulation: SimulationSection = SimulationSection()
    expect: list[ExpectationEntry] = []
    waivers: list[Waiver] = []

    @property
    def adaptive(self) -> AdaptiveRuns | None:
        """The adaptive settings with their defaults, or None for a fixed run count."""
        if self.runs != "auto":
            return None
        return AdaptiveRuns(min_runs=self.min_runs or DEFAULT_MIN_RUNS,
                            max_runs=self.max_runs or DEFAULT_MAX_RUNS,
                            batch_runs=self.batch_runs or DEFAULT_BATCH_RUNS)

    @property
    def run_count(self) -> int:
        """Runs allocated per path: the fixed count, or the cap of ``runs: auto``."""
        adaptive = self.adaptive
        if adaptive is not None:
            return adaptive.max_runs
        assert self.runs != "auto"
        return self.runs
