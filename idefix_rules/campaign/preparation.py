"""What a campaign needs before its first run, checked and built: the compiled rulebook,
the FMU (the campaign's, or the built-in one), the terrain (written where the FMU reads it, or
the one stored in the results file when resuming) and the obstacle checker, every mistake of
the campaign said at once (:func:`prepare_simulation`, for a campaign and a worst-case search
alike)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from idefix_rules.campaign.input import waivers
from idefix_rules.campaign.input.campaign_values import rover_geometry
from idefix_rules.campaign.input.environment import build_terrain, write_terrain
from idefix_rules.campaign.input.expectation_problems import expectation_problems
from idefix_rules.campaign.input.fmu_checks import check_fmu, describe_warnings
from idefix_rules.campaign.input.load import Campaign
from idefix_rules.campaign.input.terrain_checks import (
    check_drawn_starts_on_terrain,
    check_paths_on_terrain,
    check_polygons_on_terrain,
    check_rocks_on_terrain,
    check_start_on_terrain,
)
from idefix_rules.campaign.input.validate import (
    check_geometry,
    check_simulation_size,
    check_tolerance_start,
)
from idefix_rules.campaign.input.yamlsource import format_loc
from idefix_rules.campaign.simulation.simulate import RESULTS_FILE, TERRAIN_PARAMETER
from idefix_rules.campaign.storage import diskspace
from idefix_rules.campaign.storage.journal import roll_back
from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.errors import Diagnostic, UserInputError, error
from idefix_rules.fmu.terrain import Terrain
from idefix_rules.results.collisions import CollisionFunction, collision_function
from idefix_rules.results.terrain import TerrainSource, terrain_for_resume

_T = TypeVar("_T")


def compile_rulebook_file(path: Path) -> Any:
    """Load, check and compile a rulebook (UserInputError on any mistake)."""
    from idefix_rules.rulebook import compile_rulebook, load_rulebook

    return compile_rulebook(load_rulebook(path))


def _fmu_cached() -> bool:
    """Whether the built-in rover FMU is already built for these sources."""
    try:
        from idefix_rules.fmu.build import MODEL_IDENTIFIER, cache_dir, source_hash

        return (cache_dir() / f"{MODEL_IDENTIFIER}-{source_hash()[:16]}.fmu").exists()
    except Exception:  # cannot tell: say nothing rather than something wrong
        return True


def resolve_fmu(campaign: Campaign) -> Path:
    if campaign.fmu is not None:
        return campaign.fmu
    from idefix_rules.fmu import default_fmu_path

    return Path(default_fmu_path())


@dataclass
class PreparedSimulation:
    """What simulating a campaign needs once its inputs are checked: the compiled rulebook,
    the FMU, the run-independent FMU parameters (the terrain file), the obstacle checker
    (None when the rulebook reads no collision) and the warnings to say with the outcome."""

    evaluator: Any
    fmu_path: Path
    fixed: dict[str, float | str]
    collisions: CollisionFunction | None
    warnings: list[str]
    terrain: Terrain  # what the runs are simulated on, stored in the results file
    source: TerrainSource  # where it came from


def prepare_simulation(campaign: Campaign, say: Callable[[str], None],
                       again: str, resume: bool = False,
                       planned_runs: bool = True) -> PreparedSimulation:
    """Compile the rulebook, check the waivers and the FMU's mapping, build the terrain (and
    write it where the FMU reads it) and the obstacle checker; every mistake is a
    :class:`UserInputError` before anything is simulated. ``again`` is the command that goes
    on after a full disk was freed; ``resume``: the terrain stored in the results file so far
    is the one the missing runs are simulated on. ``planned_runs``: the campaign simulates its
    planned Monte Carlo runs, whose draws are checked (False for a worst-case search, which
    draws worlds of its own)."""
    say(f"compiling the rulebook {campaign.rulebook.name}")
    evaluator = compile_rulebook_file(campaign.rulebook)
    # the campaign's mistakes, every one found before any is said (a check that needs what a
    # failed one would give is skipped: the terrain's checks without a terrain)
    problems: list[Diagnostic] = list(waivers.waiver_problems(campaign, evaluator.rulebook))
    if planned_runs:  # a worst-case search judges no expectations
        problems += expectation_problems(campaign, evaluator)
    # the texts each failure quotes from (a DEM's own text is never quoted: it is given empty)
    sources: dict[str, str] = {str(campaign.source): campaign.text}

    def gather(check: Callable[[], _T]) -> _T | None:
        try:
            return check()
        except UserInputError as failure:
            problems.extend(failure.diagnostics)
            sources.update(failure.sources)
            return None

    # the checks below compute with the rover's geometry (durations, bodies): only a sound one
    geometry = gather(lambda: check_geometry(campaign))
    gather(lambda: check_tolerance_start(campaign, evaluator))
    if campaign.fmu is None and not _fmu_cached():
        say("building the rover FMU from its C sources (once; cached afterwards)")
    fmu_path = resolve_fmu(campaign)
    mapping = gather(lambda: check_fmu(campaign, fmu_path, evaluator))
    if geometry:
        gather(lambda: check_simulation_size(campaign))
    say("preparing the terrain")
    terrain = gather(lambda: build_terrain(campaign.model.environment, campaign.dem))
    if terrain is not None and campaign.dem is None:
        generated = terrain
        terrain = gather(lambda: _plausible_synthetic(campaign, generated))
    elif terrain is not None:
        loaded = terrain
        terrain = gather(lambda: _plausible_dem(campaign, loaded))
    if terrain is not None:
        extent = terrain.extent
        gather(lambda: _check_on_terrain(campaign, extent, planned_runs, bool(geometry)))
    if problems:
        raise UserInputError(problems, sources=sources)
    assert mapping is not None and terrain is not None
    # said once, with the outcome
    warnings = describe_warnings(mapping.warnings, {str(campaign.source): campaign.text})
    fixed: dict[str, float | str] = {}
    source = TerrainSource.of(campaign.dem)
    if resume:  # the runs still missing are simulated on the terrain stored so far
        terrain, notes = _resumed_terrain(campaign.output / RESULTS_FILE, terrain, source)
        warnings += notes
    if mapping.terrain_input:
        doing, then = "write the terrain file", f"free space, then run `{again}`"
        diskspace.require(campaign.output, terrain.heights.size * 8, doing, then)
        with diskspace.guard(campaign.output, doing, then):
            fixed[TERRAIN_PARAMETER] = str(write_terrain(terrain, campaign.output))
    collisions = collision_function(campaign.model.environment, evaluator, terrain,
                                    rover_geometry(campaign))
    return PreparedSimulation(evaluator, fmu_path, fixed, collisions, warnings, terrain,
                              source)


def _plausible_synthetic(campaign: Campaign, terrain: Terrain) -> Terrain:
    """A synthetic terrain whose slope over its size, or roughness, lifts the ground beyond
    the heights a terrain file may hold (±100 km) is the campaign's mistake, said at its
    ``synthetic`` section (not at the terrain file written from it)."""
    from idefix_rules.fmu.terrain import beyond_heights

    beyond = beyond_heights(terrain.heights)
    if not beyond:
        return terrain
    loc = ("environment", "terrain", "synthetic")
    raise UserInputError(error(
        "C100", f"{format_loc(loc)}: the terrain it describes is not plausible: {beyond}",
        campaign.span(loc), hint="the slope over the whole size, or the roughness, lifts the "
        "ground that far: give a smaller size, slope or roughness"),
        sources={str(campaign.source): campaign.text})


def _plausible_dem(campaign: Campaign, terrain: Terrain) -> Terrain:
    """A DEM of bare heights whose cell (the campaign's) makes it wider than the rover model
    takes, or a terrain file whose rocks and the campaign's are more than it holds: said at the
    campaign's value (the DEM's own mistakes are said at its lines)."""
    from idefix_rules.fmu.terrain import HEIGHT_GRID_SUFFIXES
    from idefix_rules.limits import MAX_TERRAIN_EXTENT, MAX_TERRAIN_ROCKS

    problems = []
    ny, nx = terrain.heights.shape
    widest = (max(nx, ny) - 1) * terrain.cell
    bare = campaign.dem is not None and campaign.dem.suffix.lower() in HEIGHT_GRID_SUFFIXES
    if bare and widest > MAX_TERRAIN_EXTENT:  # a terrain file's own cell is said at its line
        loc: tuple[str, ...] = ("environment", "terrain", "cell")
        problems.append(error(
            "C100", f"{format_loc(loc)}: a cell of {terrain.cell:.12g} m makes the DEM's {nx} "
                    f"x {ny} heights {widest:.12g} m wide; at most "
                    f"{MAX_TERRAIN_EXTENT / 1000:g} km", campaign.span(loc),
            hint="the rover model starts within 1000 km of the terrain's origin; is the cell "
                 "the DEM's spacing in metres?"))
    given = len(campaign.model.environment.rocks)
    if len(terrain.rocks) > MAX_TERRAIN_ROCKS:
        loc = ("environment", "rocks")
        problems.append(error(
            "F202", f"{format_loc(loc)}: {given} rocks and the {len(terrain.rocks) - given} of "
                    f"the terrain file make {len(terrain.rocks)}; at most {MAX_TERRAIN_ROCKS} "
                    f"(the rover model holds {MAX_TERRAIN_ROCKS})", campaign.span(loc),
            hint="keep the rocks near the paths"))
    if problems:
        raise UserInputError(problems, sources={str(campaign.source): campaign.text})
    return terrain


def _resumed_terrain(results: Path, terrain: Terrain, source: TerrainSource
                     ) -> tuple[Terrain, list[str]]:
    """The terrain a ``--resume`` of ``results`` simulates on (the stored one) and what to say
    about it (:func:`~idefix_rules.results.terrain.terrain_for_resume`)."""
    if not results.is_file():
        return terrain, []
    roll_back(results)  # a change of its structure a kill cut off (journal.py)
    try:
        store = ResultStore.open(results)
    except UserInputError:  # not a results file: resuming it says so, with what to do
        return terrain, []
    try:
        return terrain_for_resume(store.file, terrain, source, results)
    finally:
        store.close()


def _check_on_terrain(campaign: Campaign, extent: tuple[float, float, float, float],
                      planned_runs: bool = True, geometry: bool = True) -> None:
    """Rocks, the rover's start and its chains on the terrain, every mistake said at once (a
    chain is checked only from a start on the terrain: from one off it, every chain is off;
    and only with a sound ``geometry``, which its driven outline is computed from)."""
    problems: list[Diagnostic] = []

    def gather(check: Callable[[Campaign, tuple[float, float, float, float]], None]) -> bool:
        try:
            check(campaign, extent)
        except UserInputError as failure:
            problems.extend(failure.diagnostics)
            return False
        return True

    gather(check_rocks_on_terrain)
    gather(check_polygons_on_terrain)
    terrain_given = campaign.model.environment.terrain.dem is not None \
        or campaign.model.environment.terrain.synthetic is not None
    # the built-in rover starts at initial.x, initial.y on the terrain it is given (a foreign
    # FMU may start from parameters of its own; without a terrain the ground is flat
    # everywhere)
    if campaign.fmu is None and terrain_given and gather(check_start_on_terrain) and geometry:
        gather(check_paths_on_terrain)
        if planned_runs:
            gather(check_drawn_starts_on_terrain)
    if problems:
        raise UserInputError(problems, sources={str(campaign.source): campaign.text})
