"""The campaign file schema (pydantic): what a campaign may say, in SI after validation.

Dimensioned values are strings with units (``"5 mm/s"``, ``"90 deg"``), parsed with
:func:`idefix_rules.units.parse_quantity`; a bare number where a dimension is expected is an
error. The format is documented in ``docs/campaign-format.md``. The field types live in
:mod:`~idefix_rules.campaign.input.field_types`, the larger sections in their own modules
(:mod:`~idefix_rules.campaign.input.environment_section`,
:mod:`~idefix_rules.campaign.input.distributions`,
:mod:`~idefix_rules.campaign.input.expectations`).
"""

from __future__ import annotations

import math
import unicodedata
from dataclasses import dataclass
from datetime import date
from typing import Annotated, Any, Literal

from pydantic import BeforeValidator, Field, StrictInt, ValidationInfo
from pydantic_core import PydanticCustomError

from idefix_rules.campaign.input.distributions import UncertaintySection
from idefix_rules.campaign.input.environment_section import EnvironmentSection
from idefix_rules.campaign.input.expectations import ExpectationEntry
from idefix_rules.campaign.input.field_types import (
    Angle,
    AngularRate,
    Duration,
    Flag,
    Length,
    Ratio,
    Strict,
    new_run,
    show,
)
from idefix_rules.limits import MAX_RUNS, MAX_WORKERS

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
                                  {"got": show(value)})
    return value


class FmuSection(Strict):
    path: Storable = "builtin"
    signals: dict[str, str] | None = None
    parameters: dict[str, str] | None = None
    chain: ChainSection = ChainSection()
    # An output mapped to the signal 'done' reports the chain complete from this value on.
    done_at: Annotated[float, BeforeValidator(_finite)] = 1.0


# --- paths -----------------------------------------------------------------------------------

class CommandSpec(Strict):
    max_wheel_rate: AngularRate = Field(gt=0)
    delta_position: Length
    delta_heading: Angle


# --- waivers --------------------------------------------------------------------------------

def _storable(value: Any) -> Any:
    """A text the results file stores (HDF5 attributes) or a file path: no NUL character
    and no lone surrogate (``"\\ud800"``), which neither can hold."""
    if isinstance(value, str):
        for index, character in enumerate(value):
            if character == "\0" or unicodedata.category(character) == "Cs":
                raise PydanticCustomError(
                    "text", "character {index} is {what}, which no text stored in the results "
                    "file or file name can hold: remove it",
                    {"index": str(index + 1),
                     "what": "a NUL (\\0)" if character == "\0"
                     else f"a lone surrogate (\\u{ord(character):04x})"})
    return value


def _plain_text(value: Any) -> Any:
    if isinstance(value, str) and not value.strip():
        raise PydanticCustomError("text", "expected a non-empty text")
    return _storable(value)


Text = Annotated[str, BeforeValidator(_plain_text)]
Storable = Annotated[str, BeforeValidator(_storable)]


def _written_date(value: Any, info: ValidationInfo) -> Any:
    """A date as YAML writes one (2027-03-31) or as text; a bare number is no date (pydantic
    would read 20990101 as seconds since 1970)."""
    quoted_number = isinstance(value, str) and value.strip().lstrip("+-").replace(
        ".", "", 1).isdigit()  # "4102444800": seconds since 1970 to pydantic, too
    if new_run(info) and (quoted_number or (isinstance(value, int | float)
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
    if isinstance(value, str) and value == "all" and new_run(info):
        raise PydanticCustomError(
            "path_name", "path name 'all' is reserved: a waiver's `path: all` means every "
            "path, so a waiver meant for this one would cover them all; give it another name",
            {})
    if isinstance(value, str) and (
            not value.strip() or "/" in value or value in (".", "..")
            or (new_run(info) and (len(value) > MAX_PATH_NAME or any(
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
    return _storable(value)


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
    got = str(value).lower() if isinstance(value, bool) else show(value)  # as YAML wrote it
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
    got = str(value).lower() if isinstance(value, bool) else show(value)
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
    name: Storable | None = None
    description: Storable = ""
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
    rulebook: Storable
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
