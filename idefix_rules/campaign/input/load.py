"""Loading a campaign file: YAML with positions → pydantic → :class:`Campaign` (paths resolved).

Every mistake of a file is reported in one :class:`UserInputError`, each diagnostic at
``campaign.yaml:line:col`` with the dotted location, e.g.
``paths.detour[1].delta_heading: expected an angle, got "90"``. pydantic's errors are put in
those words by :mod:`~idefix_rules.campaign.input.validation_errors`; what a loaded campaign says
of the rover and its runs is read by :mod:`~idefix_rules.campaign.input.campaign_values`.
"""

from __future__ import annotations

import hashlib
import re
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from idefix_rules.campaign.input.environment_section import TerrainSection
from idefix_rules.campaign.input.expectations import (
    CollisionExpectation,
    MeanRiskExpectation,
    PathVerdictExpectation,
    RankFirstExpectation,
)
from idefix_rules.campaign.input.schema import AdaptiveRuns, CampaignFile
from idefix_rules.campaign.input.validation_errors import diagnostics_from_validation
from idefix_rules.campaign.input.yamlsource import SourceMap, format_loc, load_yaml
from idefix_rules.commands import Command
from idefix_rules.errors import Diagnostic, Span, UserInputError, error, read_user_text
from idefix_rules.fmu.terrain import HEIGHT_GRID_SUFFIXES
from idefix_rules.limits import (
    CAMPAIGN_TOO_LARGE,
    MAX_CAMPAIGN_BYTES,
    MAX_WORKERS,
    check_file_size,
)
from idefix_rules.shell import command_line

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


def _zip_archive(source: Path) -> str | None:
    """What a campaign path that is a zip archive is (``an FMU`` when it holds a
    ``modelDescription.xml``); None for any other file, or one that cannot be read (said by
    the checks that read it). A pipe (``<(…)``) is not looked into: what this read would be
    gone for the campaign's own read."""
    try:
        if not source.is_file():
            return None
        with source.open("rb") as file:
            if file.read(4) not in (b"PK\x03\x04", b"PK\x05\x06"):
                return None
        with zipfile.ZipFile(source) as archive:
            fmu = "modelDescription.xml" in archive.namelist()
    except (OSError, zipfile.BadZipFile, EOFError, ValueError):
        return None
    return "an FMU (a zip archive holding a modelDescription.xml)" if fmu else "a zip archive"


def load_campaign(path: str | Path) -> Campaign:
    """Read, validate and resolve a campaign file; :class:`UserInputError` on any mistake."""
    source = Path(path)
    shown = str(path)
    archive = _zip_archive(source)
    if archive is not None:  # before its size, which says nothing of what it is
        fmu = archive.startswith("an FMU")
        raise UserInputError(error(
            "C101", f"{shown} is {archive}, not a campaign file (YAML)" + (
                ": a campaign names its FMU under fmu.path" if fmu else ""),
            Span(shown), hint=None if not fmu else (
                "give the campaign file that names it, e.g. `fmu: {path: " + source.name
                + "}` (docs/bring-your-own-fmu.md)")), sources={shown: ""})
    check_file_size(source, MAX_CAMPAIGN_BYTES, CAMPAIGN_TOO_LARGE, "campaign file")
    text = read_user_text(source, "C010", "campaign file")
    if _looks_like_a_rulebook(text):
        raise UserInputError(error(
            "C101", f"{shown} is a rulebook (it starts with 'rulebook \"…\"'), not a campaign",
            Span(shown, 1, 1),
            hint=f"check it with `{command_line('idefix-verify', 'check', shown)}`; a campaign "
                 "(YAML) names its rulebook with 'rulebook: PATH'"),
            sources={shown: ""})
    document = load_yaml(text, shown)
    if not isinstance(document.data, dict):  # maybe no campaign at all: quote none of it
        raise UserInputError(error("C101", "a campaign file is a mapping (key: value lines)",
                                   Span(shown, 1, 1)), sources={shown: ""})
    try:
        model = CampaignFile.model_validate(document.data)
    except ValidationError as failure:
        raise UserInputError(diagnostics_from_validation(failure, document.data,
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


def declared_output(path: str | Path) -> Path | None:
    """The output folder a campaign file names (its ``output``, or the default), read without
    validating the rest: for a campaign :func:`load_campaign` refused, the folder whose
    outputs it would have replaced. None when the file is no regular file holding a YAML
    mapping (a pipe is never read twice), or its ``output`` is no folder name.

    >>> import tempfile
    >>> folder = Path(tempfile.mkdtemp())
    >>> _ = (folder / "c.yaml").write_text("runs: eight\\noutput: out\\n")
    >>> declared_output(folder / "c.yaml") == (folder / "out").resolve()
    True
    """
    source = Path(path)
    try:
        if not source.is_file() or _zip_archive(source) is not None:
            return None
        check_file_size(source, MAX_CAMPAIGN_BYTES, CAMPAIGN_TOO_LARGE, "campaign file")
        text = read_user_text(source, "C010", "campaign file")
        if _looks_like_a_rulebook(text):
            return None
        data = load_yaml(text, str(path)).data
    except Exception:  # no campaign to read a folder from: none is named
        return None
    if not isinstance(data, dict):
        return None
    value = data.get("output", CampaignFile.model_fields["output"].default)
    if not isinstance(value, str) or not value.strip():
        return None
    try:
        return (source.resolve().parent / value).resolve()
    except (ValueError, OSError):  # no usable folder name (a NUL in it): none is named
        return None


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
