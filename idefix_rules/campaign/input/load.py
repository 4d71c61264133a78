"""Loading a campaign file: YAML with positions → pydantic → :class:`Campaign` (paths resolved).

Every mistake of a file is reported in one :class:`UserInputError`, each diagnostic at
``campaign.yaml:line:col`` with the dotted location, e.g.
``paths.detour[1].delta_heading: expected an angle, got "90"``.
"""

from __future__ import annotations

import difflib
import hashlib
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from idefix_rules.campaign.input.environment_section import TerrainSection
from idefix_rules.campaign.input.expectations import (
    EXPECTATION_KINDS,
    CollisionExpectation,
    MeanRiskExpectation,
    PathVerdictExpectation,
    RankFirstExpectation,
)
from idefix_rules.campaign.input.schema import AdaptiveRuns, CampaignFile
from idefix_rules.campaign.input.yamlsource import SourceMap, load_yaml
from idefix_rules.commands import Command, RoverGeometry, chain_duration
from idefix_rules.errors import Diagnostic, Span, UserInputError, error, read_user_text
from idefix_rules.fmu.terrain import HEIGHT_GRID_SUFFIXES
from idefix_rules.limits import (
    CAMPAIGN_TOO_LARGE,
    MAX_CAMPAIGN_BYTES,
    MAX_WORKERS,
    check_file_size,
)

BUILTIN_FMU = "builtin"


@dataclass(frozen=True)
class PathSpec:
    """One named command chain of the campaign."""

    name: str
    index: int
    chain: tuple[Command, ...]


@dataclass(frozen=True)
class Campaign:
    """A validated campaign with every file path resolved against the campaign file."""

    source: Path
    text: str
    sha256: str
    model: CampaignFile
    paths: tuple[PathSpec, ...]
    rulebook: Path
    output: Path
    fmu: Path | None  # None: the built-in rover FMU
    dem: Path | None
    runs: int
    seed: int
    workers: int | None  # None: all cores
    locations: SourceMap
    adaptive: AdaptiveRuns | None = None  # `runs: auto`; then ``runs`` is its cap

    @property
    def name(self) -> str:
        return self.model.name or self.source.stem

    def span(self, loc: Sequence[str | int]) -> Span:
        return self.locations.span(loc)

    def with_overrides(self, runs: int | str | None = None, seed: int | None = None,
                       output: Path | None = None, workers: int | None = None,
                       max_runs: int | None = None, min_runs: int | None = None) -> Campaign:
        """The same campaign with command-line overrides applied (``runs="auto"``: adaptive;
        ``max_runs`` / ``min_runs`` apply to an adaptive campaign)."""
        adaptive = self.adaptive
        if runs == "auto" and adaptive is None:
            adaptive = AdaptiveRuns()
        elif isinstance(runs, int):
            adaptive = None
        if adaptive is not None:
            adaptive = replace(adaptive,
                               max_runs=adaptive.max_runs if max_runs is None else max_runs,
                               min_runs=adaptive.min_runs if min_runs is None else min_runs)
            runs = adaptive.max_runs
        return replace(
            self,
            adaptive=adaptive,
            runs=self.runs if not isinstance(runs, int) else runs,
            seed=self.seed if seed is None else seed,
            output=self.output if output is None else output,
            workers=self.workers if workers is None else workers,
        )


def format_loc(loc: Sequence[str | int]) -> str:
    """``("paths", "detour", 1, "delta_heading")`` → ``paths.detour[1].delta_heading``."""
    text = ""
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        else:
            text += ("." if text else "") + str(part)
    return text


def _data_loc(data: Any, loc: Sequence[str | int]) -> tuple[tuple[str | int, ...], bool]:
    """Keep only the parts of a pydantic ``loc`` that exist in the data (drops union tags).

    Returns the cleaned location and whether its last part exists in the data. A union tag
    may also be a key of the data (an expectation's ``verdict`` is its tag and its key), so
    a tag is read both ways: as the key where only that reading finds the location in the
    data, as the tag otherwise (pydantic puts the tag before every location in a member).

    >>> entry = {"path": "p", "verdict": "fail", "rank": 1}
    >>> _data_loc({"expect": [entry]}, ("expect", 0, "verdict", "rank"))
    (('expect', 0, 'rank'), True)
    >>> _data_loc({"expect": [entry]}, ("expect", 0, "verdict", "verdict"))
    (('expect', 0, 'verdict'), True)
    """
    found, _, cleaned = _read_loc(data, tuple(loc))
    return cleaned, found


def _read_loc(node: Any, loc: tuple[str | int, ...]) -> tuple[bool, bool, tuple[str | int, ...]]:
    """For :func:`_data_loc`: whether all of ``loc`` was found in ``node``, whether the
    reading fits the data (it looks for no key inside a plain value), and the parts kept."""
    if not loc:
        return True, True, ()
    part, rest = loc[0], loc[1:]
    if part == "[key]":  # pydantic's marker for a mapping's key: the key before it
        return True, True, ()
    in_dict = isinstance(node, dict) and part in node
    in_list = isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node)
    if in_dict or in_list:
        found, fits, cleaned = _read_loc(node[part], rest)
        as_data = (found, fits, (part, *cleaned))
        if part in _UNION_TAGS and isinstance(node, dict) and rest:
            as_tag = _read_loc(node, rest)
            # the tag reading wins when it reads more of the location, or on a tie where
            # neither reading finds the key (a kind's key missing from its entry)
            if as_tag[:2] > as_data[:2] or (as_tag[:2] == as_data[:2] and not as_tag[0]):
                return as_tag
        return as_data
    if not isinstance(node, dict | list):
        return False, False, ()
    if isinstance(part, str) and part.isidentifier() and part not in _UNION_TAGS:
        return False, True, (part,)  # a missing key: kept for the message
    # a union tag ("normal") or another marker of pydantic's: not in the data
    return _read_loc(node, rest) if rest else (False, True, ())


_UNION_TAGS = frozenset({"fixed", "normal", "truncated_normal", "uniform", "log_normal",
                         "verdict", "rank_first", "max_mean_risk", "max_collision_chance"})


def _inside_value(span: Span, value: str, position: int, text: str) -> Span:
    """The span of character ``position`` of the string ``value`` written at ``span`` (the
    value's own span when it is not written there as such, e.g. with escapes)."""
    lines = text.splitlines()
    if not 0 < span.line <= len(lines):
        return span
    found = lines[span.line - 1].find(value, max(span.column - 1, 0))
    if found < 0 or found > span.column + 1:  # the value, after at most a quote
        return span
    column = found + position + 1
    return Span(span.path, span.line, column, span.line, column + 1)


def _diagnostics_from_validation(failure: ValidationError, data: Any,
                                 locations: SourceMap, text: str) -> list[Diagnostic]:
    diagnostics = []
    seen = set()
    errors = failure.errors(include_url=False)
    for item in errors:
        loc, found = _data_loc(data, item["loc"])
        kind = item["type"]
        hint = None
        if kind == "extra_forbidden":
            message = "unknown key"
            span = locations.span(loc, at_key=True)
            hint = _did_you_mean(loc, data)
        elif kind == "missing" and item["loc"] and isinstance(item["loc"][-1], int) \
                and isinstance(item.get("input"), list):
            # a list too short for its tuple (semi_axes of two values): pydantic reports each
            # item it lacks as a missing key
            wanted = 1 + max(other["loc"][-1] for other in errors
                             if other["type"] == "missing" and other["loc"][:-1] == item["loc"][:-1]
                             and isinstance(other["loc"][-1], int))
            got = len(item["input"])
            message = f"expected {wanted} values, got {got}"
            loc, _ = _data_loc(data, item["loc"][:-1])  # the list itself
            span = locations.span(loc)
        elif kind == "missing":
            message = "missing required key"
            span = locations.span(loc[:-1] if not found else loc)
        elif kind in _BOUND_WORDS:  # pydantic's "Input should be greater than 0"
            bound = next(iter(item.get("ctx", {}).values()), "")
            message = f"must be {_BOUND_WORDS[kind]} {bound}"
            span = locations.span(loc)
        elif kind in ("too_long", "too_short"):  # "Tuple should have at most 2 items …"
            context = item.get("ctx", {})
            limit = context.get("max_length" if kind == "too_long" else "min_length")
            message = (f"expected {'at most' if kind == 'too_long' else 'at least'} {limit} "
                       f"value{'' if limit == 1 else 's'}, got {context.get('actual_length')}")
            span = locations.span(loc)
        elif kind == "literal_error":  # "Input should be 'monte_carlo', … or 'sobol'"
            expected = item.get("ctx", {}).get("expected", "")
            message = f"expected {expected}, got {_shown(item.get('input'))}"
            span = locations.span(loc, at_key=item["loc"][-1:] == ("[key]",))
        elif kind in ("model_type", "model_attributes_type", "dict_type"):
            # pydantic's words name its classes ("instance of TerrainSection"): not the user's
            message = f"expected a mapping (key: value), got {_shown(item.get('input'))}"
            span = locations.span(loc)
        elif kind == "union_tag_invalid":
            context = item.get("ctx", {})
            message = (f"unknown {context.get('discriminator', 'kind').strip(chr(39))} "
                       f"{context.get('tag')!r} (expected one of: "
                       f"{context.get('expected_tags', '')})")
            span = locations.span((*loc, "distribution"))
        elif kind == "expectation" and isinstance(item.get("input"), dict):
            # an entry of no kind: its keys the schema does not know are likely the kind
            # misspelt (`rank: 1` for `rank_first`)
            message = str(item["msg"])
            span = locations.span(loc)
            extra = [(*loc, key) for key in item["input"] if key not in _ALL_EXPECTATION_KEYS]
            for key_loc in extra:
                diagnostics.append(error("C100", f"{format_loc(key_loc)}: unknown key",
                                         locations.span(key_loc, at_key=True),
                                         _did_you_mean(key_loc, data)))
        else:
            # a validator's own words, without pydantic's "Value error, " before them
            message = str(item["msg"]).removeprefix("Value error, ")
            # "[key]": pydantic's marker for a mistake in a mapping key, not its value
            span = locations.span(loc, at_key=item["loc"][-1:] == ("[key]",))
            position = item.get("ctx", {}).get("position")
            if isinstance(position, int) and isinstance(item.get("input"), str):
                span = _inside_value(span, item["input"], position, text)
        where = format_loc(loc)
        text = f"{where}: {message}" if where else message
        if (text, str(span)) in seen:
            continue
        seen.add((text, str(span)))
        diagnostics.append(error("C100", text, span, hint))
    diagnostics.sort(key=lambda d: (d.span.line, d.span.column) if d.span else (0, 0))
    return diagnostics


def _shown(value: Any) -> str:
    """A value as the campaign file wrote it (a string in quotes, a number as it is)."""
    return f"'{value}'" if isinstance(value, str) else str(value)


# pydantic's bound checks in the words of the other messages
_BOUND_WORDS = {"greater_than": "above", "greater_than_equal": "at least",
                "less_than": "below", "less_than_equal": "at most"}


def _did_you_mean(loc: Sequence[str | int], data: Any) -> str | None:
    """The hint for the unknown key ending ``loc``: the known key closest to it, if any is
    close (a misspelling, or the start of a longer key: ``rank`` for ``rank_first``)."""
    if not loc:
        return None
    written, known = str(loc[-1]), _known_keys(loc, data)
    close = difflib.get_close_matches(written, known, n=1) or [
        key for key in known if len(written) >= 3 and key.startswith(written)][:1]
    return f"did you mean '{close[0]}'?" if close else None


def _known_keys(loc: Sequence[str | int], data: Any) -> list[str]:
    """The keys the campaign schema knows where ``loc``'s last key stands (a section that is
    a model of its own, or an expectation: those of its kind, all kinds' for an entry of no
    kind; none where the schema says less)."""
    if len(loc) == 3 and loc[0] == "expect" and isinstance(loc[1], int):
        expect = data.get("expect") if isinstance(data, dict) else None
        entry = expect[loc[1]] if isinstance(expect, list) and 0 <= loc[1] < len(expect) \
            else None
        kinds = [model for kind, model in EXPECTATION_KINDS.items()
                 if isinstance(entry, dict) and kind in entry]
        return _field_names(*kinds) if kinds else list(_ALL_EXPECTATION_KEYS)
    model: Any = CampaignFile
    for part in loc[:-1]:
        field = model.model_fields.get(part) if isinstance(part, str) else None
        annotation = getattr(field, "annotation", None)
        if not (isinstance(annotation, type) and issubclass(annotation, BaseModel)):
            return []
        model = annotation
    return _field_names(model)


def _field_names(*models: type[BaseModel]) -> list[str]:
    return list(dict.fromkeys(field.alias or name for model in models
                              for name, field in model.model_fields.items()))


_ALL_EXPECTATION_KEYS = _field_names(*EXPECTATION_KINDS.values())


def _looks_like_a_rulebook(text: str) -> bool:
    """Whether the first line that is neither blank nor a comment opens a rulebook.

    >>> _looks_like_a_rulebook('# ops\\nrulebook "ops" version "1.0.0"\\n')
    True
    >>> _looks_like_a_rulebook("name: c\\nrulebook: ops.rules\\n")
    False
    """
    for line in text.splitlines():
        stripped = line.strip()
        if stripped and not stripped.startswith("#"):
            return re.match(r'rulebook\s+"', stripped) is not None
    return False


def load_campaign(path: str | Path) -> Campaign:
    """Read, validate and resolve a campaign file; :class:`UserInputError` on any mistake."""
    source = Path(path)
    shown = str(path)
    check_file_size(source, MAX_CAMPAIGN_BYTES, CAMPAIGN_TOO_LARGE, "campaign file")
    text = read_user_text(source, "C010", "campaign file")
    if _looks_like_a_rulebook(text):
        raise UserInputError(error(
            "C101", f"{shown} is a rulebook (it starts with 'rulebook \"…\"'), not a campaign",
            Span(shown, 1, 1), hint=f"check it with `idefix-verify check {shown}`; a campaign "
                                    "(YAML) names its rulebook with 'rulebook: PATH'"),
            sources={shown: ""})
    document = load_yaml(text, shown)
    if not isinstance(document.data, dict):  # maybe no campaign at all: quote none of it
        raise UserInputError(error("C101", "a campaign file is a mapping (key: value lines)",
                                   Span(shown, 1, 1)), sources={shown: ""})
    try:
        model = CampaignFile.model_validate(document.data)
    except ValidationError as failure:
        raise UserInputError(_diagnostics_from_validation(failure, document.data,
                                                          document.locations, text)
                             + _raw_expectation_paths(document.data, document.locations),
                             sources={shown: text}) from None
    base = source.resolve().parent
    diagnostics = _cross_checks(model, document.locations, base)
    if diagnostics:
        raise UserInputError(diagnostics, sources={shown: text})
    paths = tuple(
        PathSpec(name, index, tuple(Command(c.max_wheel_rate, c.delta_position, c.delta_heading)
                                    for c in chain))
        for index, (name, chain) in enumerate(model.paths.items()))
    return Campaign(
        source=source.resolve(),
        text=text,
        sha256=hashlib.sha256(text.encode("utf-8")).hexdigest(),
        model=model,
        paths=paths,
        rulebook=(base / model.rulebook).resolve(),
        output=(base / model.output).resolve(),
        fmu=None if model.fmu.path == BUILTIN_FMU else (base / model.fmu.path).resolve(),
        dem=(base / model.environment.terrain.dem).resolve()
        if model.environment.terrain.dem else None,
        runs=model.run_count,
        seed=model.uncertainty.seed,
        workers=None if model.workers == "auto" else model.workers,
        locations=document.locations,
        adaptive=model.adaptive,
    )


def _raw_expectation_paths(data: Mapping[str, Any], locations: SourceMap
                           ) -> list[Diagnostic]:
    """C202 on the data as written, when the schema refused something else in the file:
    every mistake of a file is said at once (a path an expectation names that ``paths:``
    does not have was said only once the rest was right)."""
    paths, expect = data.get("paths"), data.get("expect")
    if not isinstance(paths, Mapping) or not isinstance(expect, list):
        return []
    found = []
    for index, item in enumerate(expect):
        if not isinstance(item, Mapping):
            continue
        for key in ("path", "rank_first"):
            name = item.get(key)
            if isinstance(name, str) and name not in paths:
                found.append(error("C202", f"expect[{index}].{key}: unknown path {name!r} "
                                           f"(paths: {', '.join(map(str, paths))})",
                                   locations.span(("expect", index, key))))
    return found


def _cross_checks(model: CampaignFile, locations: SourceMap, base: Path) -> list[Diagnostic]:
    """Checks that need more than one field: files exist, expectations name known paths."""
    found: list[Diagnostic] = []

    def need_file(relative: str, loc: tuple[str | int, ...], what: str) -> None:
        if (base / relative).is_dir():
            found.append(error("C200", f"{format_loc(loc)}: {what} {relative!r} is a folder, "
                                       "not a file", locations.span(loc)))
        elif not (base / relative).is_file():
            found.append(error("C200", f"{format_loc(loc)}: {what} {relative!r} not found "
                                       f"(relative paths start at the campaign file's folder)",
                               locations.span(loc)))

    need_file(model.rulebook, ("rulebook",), "rulebook")
    if model.fmu.path != BUILTIN_FMU:
        need_file(model.fmu.path, ("fmu", "path"), "FMU")
    if model.environment.terrain.dem:
        need_file(model.environment.terrain.dem, ("environment", "terrain", "dem"), "DEM file")
        found.extend(_dem_grid_checks(model.environment.terrain, locations))
    else:  # a synthetic terrain (or the default one) has its own grid settings
        terrain = model.environment.terrain
        found.extend(error(
            "C204", f"environment.terrain.{key}: only a .npy or .csv DEM takes a {key}; a "
                    "synthetic terrain's grid is set by its own settings (synthetic: {size, "
                    "cell})", locations.span(("environment", "terrain", key)))
            for key in ("cell", "origin") if getattr(terrain, key) is not None)
    if model.workers != "auto" and not 1 <= model.workers <= MAX_WORKERS:
        found.append(error("C201", f"workers: expected 'auto' or a number from 1 to "
                                   f"{MAX_WORKERS}, got {model.workers}",
                           locations.span(("workers",))))
    found.extend(_adaptive_checks(model, locations))
    for index, expectation in enumerate(model.expect):
        if isinstance(expectation, RankFirstExpectation):
            name, key = expectation.rank_first, "rank_first"
        elif isinstance(expectation, PathVerdictExpectation | MeanRiskExpectation
                        | CollisionExpectation):
            name, key = expectation.path, "path"
        else:  # pragma: no cover - the schema admits no other kind
            continue
        if name not in model.paths:
            known = ", ".join(model.paths)
            found.append(error("C202", f"expect[{index}].{key}: unknown path {name!r} "
                                       f"(paths: {known})",
                               locations.span(("expect", index, key))))
    return found


def _adaptive_checks(model: CampaignFile, locations: SourceMap) -> list[Diagnostic]:
    """``max_runs``, ``min_runs`` and ``batch_runs`` belong to ``runs: auto``, and the minimum
    cannot exceed the cap."""
    if model.runs != "auto":
        return [error("C700", f"{key}: only used with 'runs: auto' (runs is {model.runs})",
                      locations.span((key,), at_key=True),
                      hint="write 'runs: auto' for an adaptive campaign, or remove the key")
                for key in ("max_runs", "min_runs", "batch_runs")
                if getattr(model, key) is not None]
    adaptive = model.adaptive
    assert adaptive is not None
    if adaptive.min_runs > adaptive.max_runs:
        key = "min_runs" if model.min_runs is not None else "max_runs"
        return [error("C701", f"{key}: min_runs {adaptive.min_runs} exceeds max_runs "
                              f"{adaptive.max_runs}", locations.span((key,)))]
    return []


def _dem_grid_checks(terrain: TerrainSection, locations: SourceMap) -> list[Diagnostic]:
    """A ``.npy``/``.csv`` DEM is bare heights and needs ``cell``; a terrain file carries its
    own cell and origin, so giving them as well would be silently ignored."""
    dem = str(terrain.dem)
    suffix = Path(dem).suffix.lower()
    loc: tuple[str | int, ...] = ("environment", "terrain")
    if suffix in HEIGHT_GRID_SUFFIXES:
        if terrain.cell is None:
            return [error("C203", f"{format_loc((*loc, 'dem'))}: {dem!r} holds heights only; "
                                  "give the grid spacing as environment.terrain.cell",
                          locations.span((*loc, "dem")), hint='e.g. cell: "2 cm" (origin '
                          "defaults to centring the grid on (0, 0))")]
        return []
    given = [key for key in ("cell", "origin") if getattr(terrain, key) is not None]
    return [error("C204", f"{format_loc((*loc, key))}: {dem!r} is a terrain file, which gives "
                          f"its own {key}; remove it (only .npy and .csv DEMs take one)",
                  locations.span((*loc, key))) for key in given]


# --- what the campaign says of the rover, for the evaluation ---------------------------------

# Campaign regolith keys are the FMU's soil parameters without their prefix.
REGOLITH_PREFIX = "soil."
GEOMETRY_PARAMETERS = {"rover.wheel_radius": "wheel_radius", "rover.half_track": "half_track",
                       "rover.half_wheelbase": "half_wheelbase",
                       "controller.wheel_acceleration": "wheel_acceleration"}
INITIAL_POSITION = ("initial.x", "initial.y")


def stop_limit(campaign: Campaign, chain: Sequence[Command], rover: RoverGeometry
               ) -> tuple[float, int, float]:
    """When a run of ``chain`` is stopped: (stop time, output samples, ideal duration). The stop
    time is the chain's ideal duration × ``duration_margin`` + ``extra_time``, rounded up to a
    whole output interval (``docs/campaign-format.md``, "simulation")."""
    settings = campaign.model.simulation
    ideal = chain_duration(tuple(chain), rover)
    raw_stop = ideal * settings.duration_margin + settings.extra_time
    if not math.isfinite(raw_stop / settings.output_interval):  # longer than a double holds
        return math.inf, UNBOUNDED_SAMPLES, ideal
    steps = max(1, math.ceil(raw_stop / settings.output_interval - 1e-9))
    return steps * settings.output_interval, steps + 1, ideal


# The sample count of a run whose stop time is beyond a double (a command 1e308 m long): more
# than any limit, so it is refused before anything is simulated.
UNBOUNDED_SAMPLES = 2 ** 63


def rover_geometry(campaign: Campaign) -> RoverGeometry:
    """Kinematic geometry: defaults, or fixed/nominal values the campaign gives."""
    values = nominal_parameters(campaign)
    overrides = {field_name: float(values[name]) for name, field_name in
                 GEOMETRY_PARAMETERS.items() if name in values}
    return RoverGeometry(**overrides)


def regolith_parameter(key: str) -> str:
    """The FMU parameter a regolith key sets: ``cohesion`` → ``soil.cohesion``; a name with a
    dot as given."""
    return key if "." in key else REGOLITH_PREFIX + key


def where_set(campaign: Campaign, names: Iterable[str]) -> list[tuple[str | int, ...]]:
    """Where the campaign sets any of the FMU parameters ``names``: an uncertain parameter
    (which overrides a fixed value per run) before a regolith value."""
    wanted = set(names)
    model = campaign.model
    places: list[tuple[str | int, ...]] = [
        ("uncertainty", "parameters", name) for name in model.uncertainty.parameters
        if name in wanted]
    places += [("environment", "regolith", key) for key in model.environment.regolith
               if regolith_parameter(key) in wanted]
    return places


def nominal_parameters(campaign: Campaign) -> dict[str, float]:
    """Parameter values of the reference run: regolith values, then uncertainty nominals."""
    from idefix_rules.campaign.input.sampling import nominal_values  # scipy: only when needed

    values = {regolith_parameter(key): value
              for key, value in campaign.model.environment.regolith.items()}
    values.update(nominal_values(campaign.model.uncertainty.parameters))
    return values


def initial_position_sigma(campaign: Campaign) -> float:
    """σ of the initial position (the larger of x and y): the starting tolerance radius."""
    from idefix_rules.campaign.input.sampling import standard_deviation

    parameters = campaign.model.uncertainty.parameters
    sigmas = [standard_deviation(parameters[name]) for name in INITIAL_POSITION
              if name in parameters]
    return max(sigmas, default=0.0)
