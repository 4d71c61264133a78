"""Data the figures need that the results file does not hold directly: risk maps, final errors.

The results file keeps per-run index values, not per-sample ones. For the result map the
stored runs of each path are evaluated again, chunk by chunk, with the rulebook stored in
``/provenance/rulebook`` (the one the evaluation used), the same run context and the same
collision checker as the campaign's evaluation, and the per-sample run risk (max over indices
of weight × per-sample value) is binned on the map grid (:mod:`idefix_rules.report.riskmap`).
The same pass computes each run's final local error and final heading error (box plots, paper
Fig. 9) with the rulebook's derived signals.

If the stored rulebook cannot be compiled by this version of the tool, the map falls back to
each run's stored I_max along its whole track and the report says so.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from idefix_rules.campaign.store import STATUS_COMPLETE, ResultStore
from idefix_rules.campaign.stored_terrain import StoredTerrain, terrain_for_rescoring
from idefix_rules.commands import Command, RoverGeometry, chain_duration, ideal_poses
from idefix_rules.obstacles.bodies import RoverBodies
from idefix_rules.report.data import PathReport, ReportData
from idefix_rules.report.environment import MapEnvironment, map_environment
from idefix_rules.report.riskmap import (
    RiskAccumulator,
    RiskGrid,
    cell_size_for,
    grid_covering,
    per_sample_risk,
)
from idefix_rules.report.runs import (
    EMBEDDED_RUNS,
    CellRuns,
    contact_points,
    run_series,
    wheel_bands,
    wheel_tracks,
)

CHUNK_RUNS = 64
# Wheel width the footprints are drawn with: the obstacle checker's wheel (docs/obstacles.md).
WHEEL_WIDTH = RoverBodies().wheel_width
POSE_SIGNALS = ("t", "x", "y", "z", "roll", "pitch", "yaw")
ERROR_SIGNALS = ("t", "x", "y", "yaw", "command")


@dataclass
class Setup:
    """How the stored runs are evaluated again (mirrors the campaign's evaluation)."""

    checked: Any | None = None  # CheckedRulebook of the stored rulebook
    evaluator: Any | None = None  # compiled rulebook, None when it cannot be compiled
    rover: RoverGeometry = field(default_factory=RoverGeometry)
    sigma: float = 0.0
    collisions: Any | None = None
    environment: MapEnvironment = field(default_factory=MapEnvironment)
    notes: list[str] = field(default_factory=list)
    campaign_text: str = ""


@dataclass
class MapSet:
    """Per-path accumulators on one grid, and the combined one."""

    grid: RiskGrid
    cell_reason: str
    per_path: dict[str, RiskAccumulator]
    combined: RiskAccumulator
    per_sample: bool  # False: the fallback (stored I_max along the whole track)
    reference_tracks: dict[str, tuple[np.ndarray, np.ndarray]]
    # The interactive page's data (:mod:`.runs`): per path.
    cells: dict[str, CellRuns] = field(default_factory=dict)
    series: dict[str, dict[int, dict[str, Any]]] = field(default_factory=dict)
    contacts: dict[str, list[dict[str, Any]]] = field(default_factory=dict)
    ideal_tracks: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    wheel_tracks: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]] = field(
        default_factory=dict)
    wheel_bands: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)


def _campaign_model(text: str, path: str) -> Any:
    from idefix_rules.campaign.schema import CampaignFile
    from idefix_rules.campaign.yamlsource import load_yaml

    return CampaignFile.model_validate(load_yaml(text, path).data)


def setup_from_store(store: ResultStore) -> Setup:
    """Compile the stored rulebook and rebuild the campaign's run context and collisions."""
    setup = Setup()
    try:
        rulebook_text = store.text("rulebook")
        stored = store.file["provenance"]["rulebook"].attrs
        rulebook_path = str(stored.get("path", "rulebook.rules"))
    except KeyError:
        setup.notes.append("the results file holds no rulebook text: no per-sample risk")
        rulebook_text, rulebook_path = "", ""
    if rulebook_text:
        try:
            from idefix_rules.rulebook import check_text

            result = check_text(rulebook_text, rulebook_path)
            setup.checked = result.checked
            if setup.checked is None:
                setup.notes.append("the stored rulebook does not pass this version's checks")
        except Exception as failure:
            setup.notes.append(f"the stored rulebook could not be read: {failure}")
    if setup.checked is not None:
        try:
            from idefix_rules.rulebook import compile_rulebook

            setup.evaluator = compile_rulebook(setup.checked)
        except Exception as failure:
            setup.notes.append(f"the stored rulebook could not be compiled "
                               f"({type(failure).__name__}: {failure})")
    campaign_text = store.text("campaign") if "campaign" in store.file["provenance"] else ""
    setup.campaign_text = campaign_text
    ground = _stored_terrain(store)
    setup.environment, notes = map_environment(campaign_text, setup.checked, ground.terrain)
    setup.notes += notes
    if campaign_text:
        _campaign_context(store, campaign_text, setup, ground.terrain)
    if setup.collisions is not None:  # the maps' collision and area risks stand on it
        setup.notes += ground.warnings
    return setup


def _stored_terrain(store: ResultStore) -> StoredTerrain:
    """The terrain the campaign was simulated on (rock heights, the ground, steep areas), as
    the evaluation takes it (:func:`terrain_for_rescoring`)."""
    try:
        return terrain_for_rescoring(store.file, store.path)
    except Exception as failure:  # a stored terrain this version cannot read
        return StoredTerrain(None, (f"the stored terrain could not be read "
                                    f"({type(failure).__name__}: {failure}): the rocks are "
                                    "placed on the flat datum",))


def _campaign_context(store: ResultStore, text: str, setup: Setup, terrain: Any) -> None:
    """Rover geometry, initial-position σ and the collision checker, as the campaign had them."""
    campaign_path = str(store.attrs.get("campaign_path", "campaign.yaml"))
    try:
        model = _campaign_model(text, campaign_path)
        from idefix_rules.campaign.load import Campaign, PathSpec
        from idefix_rules.campaign.simulate import initial_position_sigma, rover_geometry
        from idefix_rules.campaign.yamlsource import SourceMap

        base = Path(campaign_path).parent
        paths = tuple(PathSpec(name, index, ()) for index, name in enumerate(model.paths))
        campaign = Campaign(source=Path(campaign_path), text=text,
                            sha256=hashlib.sha256(text.encode("utf-8")).hexdigest(),
                            model=model, paths=paths, rulebook=base / model.rulebook,
                            output=base / model.output, fmu=None, dem=None, runs=model.run_count,
                            seed=model.uncertainty.seed, workers=None,
                            locations=SourceMap(campaign_path))
        setup.rover = rover_geometry(campaign)
        setup.sigma = initial_position_sigma(campaign)
    except Exception as failure:
        setup.notes.append(f"campaign geometry not rebuilt ({type(failure).__name__}): "
                           "default rover geometry used")
        return
    if setup.evaluator is not None and getattr(setup.evaluator, "needs_collisions", False):
        try:
            from idefix_rules.campaign.evaluation import collision_function

            setup.collisions = collision_function(model.environment, setup.evaluator, terrain)
        except Exception as failure:
            setup.notes.append(f"collision signals not rebuilt ({type(failure).__name__}: "
                               f"{failure}): the maps show each run's I_max instead")
            setup.evaluator = None


def _complete_rows(store: ResultStore, name: str) -> np.ndarray:
    if not store.has_runs(name):
        return np.zeros(0, dtype=np.int64)
    return np.flatnonzero(store.run_status(name) == STATUS_COMPLETE)


def _chunks(store: ResultStore, name: str, keys: list[str] | None,
            chunk_runs: int = CHUNK_RUNS) -> Iterator[tuple[np.ndarray, dict[str, np.ndarray]]]:
    rows = _complete_rows(store, name)
    for begin in range(0, rows.size, chunk_runs):
        chunk = rows[begin:begin + chunk_runs]
        data = store.read_runs(name, slice(int(chunk[0]), int(chunk[-1]) + 1), keys)
        offset = chunk - chunk[0]
        yield chunk, {key: values[offset] for key, values in data.items()}


def choose_grid(store: ResultStore, data: ReportData, setup: Setup) -> tuple[RiskGrid, str]:
    """A grid covering every complete run's track (and nearby obstacles), cell from the rover."""
    bounds = [np.inf, -np.inf, np.inf, -np.inf]

    def include(x: np.ndarray, y: np.ndarray) -> None:
        nonlocal bounds
        if np.isfinite(x).any() and np.isfinite(y).any():
            bounds = [min(bounds[0], np.nanmin(x)), max(bounds[1], np.nanmax(x)),
                      min(bounds[2], np.nanmin(y)), max(bounds[3], np.nanmax(y))]

    for path in data.paths:
        reference = store.reference(path.name)
        if reference is not None and "x" in reference and "y" in reference:
            include(np.asarray(reference["x"]), np.asarray(reference["y"]))
        for _, chunk in _chunks(store, path.name, ["x", "y"], 256):
            if "x" in chunk and "y" in chunk:  # a foreign FMU need not give a position
                include(chunk["x"], chunk["y"])
    obstacle_bounds = setup.environment.bounds()
    if obstacle_bounds is not None and not np.isfinite(bounds).all():
        bounds = list(obstacle_bounds)
    elif obstacle_bounds is not None:
        # Obstacles near the tracks widen the map; far-away areas are clipped.
        reach = 1.0
        bounds = [max(min(bounds[0], obstacle_bounds[0]), bounds[0] - reach),
                  min(max(bounds[1], obstacle_bounds[1]), bounds[1] + reach),
                  max(min(bounds[2], obstacle_bounds[2]), bounds[2] - reach),
                  min(max(bounds[3], obstacle_bounds[3]), bounds[3] + reach)]
    if not np.isfinite(bounds).all():  # no position and no obstacle: an empty map
        bounds = [-1.0, 1.0, -1.0, 1.0]
    cell = cell_size_for(setup.rover)
    track = 2.0 * setup.rover.half_track
    xmin, xmax, ymin, ymax = (float(b) for b in bounds)
    # The margin holds the wheels (corners of the rover) around the body-centre tracks.
    reach = float(np.hypot(setup.rover.half_track, setup.rover.half_wheelbase)) + 0.05
    grid = grid_covering(xmin, xmax, ymin, ymax, cell=cell, margin=reach)
    reason = (f"{grid.cell * 100:.1f} cm cells: 1/20 of the rover's track width "
              f"({track:.2f} m), rounded to 5 mm")
    if grid.cell != cell:
        reason += f", doubled until the map has at most {max(grid.nx, grid.ny)} cells a side"
    return grid, reason


def _risk_of_chunk(setup: Setup, path: PathReport, rows: np.ndarray,
                   signals: dict[str, np.ndarray], context: Any,
                   across: Any = None) -> np.ndarray:
    if setup.evaluator is None or setup.checked is None:
        return np.broadcast_to(path.i_max[rows][:, None], signals["x"].shape)
    if setup.collisions is not None:
        extra, _ = setup.collisions(signals)
        signals.update(extra)
    evaluation = setup.evaluator.evaluate(signals, context, across=across)
    shape = signals["x"].shape
    per_sample = {name: np.broadcast_to(np.asarray(values, dtype=float), shape)
                  for name, values in evaluation.per_sample.items()}
    return per_sample_risk(per_sample, setup.checked.weights)


def _first_pass(store: ResultStore, name: str, setup: Setup, context: Any) -> Any:
    """Path-level values (reductions over runs) of the path, so that each chunk's map shows
    the path's value rather than the chunk's (None when the rulebook has none)."""
    if setup.evaluator is None or context is None \
            or not getattr(setup.evaluator, "runs_reductions", ()):
        return None
    from idefix_rules.rulebook.across import first_pass

    return first_pass([setup.evaluator], lambda names: (
        signals for _, signals in _chunks(store, name, sorted(names))), context)[0]


def _final_errors(setup: Setup, signals: dict[str, np.ndarray],
                  context: Any) -> tuple[np.ndarray, np.ndarray] | None:
    try:
        from idefix_rules.rulebook.derived import DerivedSettings, DerivedSignals
    except ImportError:
        return None
    settings = getattr(setup.checked, "settings", {}) or {}
    derived = DerivedSignals(signals, context, DerivedSettings(
        theoretical_slip=float(settings.get("theoretical_slip", 0.0)),
        tolerance_growth=float(settings.get("tolerance_growth", 0.0))))
    local = np.asarray(derived.get("local_error"))[:, -1]
    if "yaw" not in signals or context.reference is None or "yaw" not in context.reference:
        return local, np.full(local.shape, np.nan)  # a foreign FMU need not give yaw
    return local, np.asarray(derived.get("heading_error"))[:, -1]


# What the report draws from each optional signal, to name what a foreign FMU's runs lack.
OPTIONAL_SIGNALS = {"x": "the result maps show no runs and no box plots are drawn",
                    "y": "the result maps show no runs and no box plots are drawn",
                    "yaw": "the final heading error box plot is not drawn",
                    "energy": "Table 1 shows no energy",
                    "command": "a run's time is its stop time"}


def missing_signal_notes(store: ResultStore, data: ReportData) -> list[str]:
    """One note per optional signal the stored runs lack, saying what is not drawn."""
    stored: set[str] = set()
    for path in data.paths:
        reference = store.reference(path.name)
        stored |= set(reference or ())
    if not stored:
        return []
    return [f"the runs hold no '{name}' (the FMU's signal map does not provide it): {what}"
            for name, what in OPTIONAL_SIGNALS.items()
            if name not in stored and not (name == "command" and "done" in stored)]


def _context(store: ResultStore, name: str, setup: Setup) -> Any:
    from idefix_rules.rulebook.derived import RunContext

    chain = tuple(Command(*map(float, row)) for row in store.path_group(name)["chain"][()])
    return RunContext(chain=chain, rover=setup.rover, initial_position_sigma=setup.sigma,
                      reference=store.reference(name))


def _ideal_track(store: ResultStore, name: str, setup: Setup) -> tuple[np.ndarray, np.ndarray]:
    """The commanded chain executed ideally (no slip) from the start pose: the ideal path."""
    chain = tuple(Command(*map(float, row)) for row in store.path_group(name)["chain"][()])
    duration = chain_duration(chain, setup.rover)
    times = np.linspace(0.0, duration, 400) if duration > 0 else np.zeros(1)
    poses = ideal_poses(chain, setup.rover, times)
    return poses[:, 0], poses[:, 1]


def _details(store: ResultStore, name: str) -> Any:
    evaluation = store.path_group(name).get("evaluation")
    if evaluation is None or "collisions" not in evaluation:
        return None
    collisions = evaluation["collisions"]
    return collisions["details"][()] if "details" in collisions else None


def prepare(store: ResultStore, data: ReportData, setup: Setup,
            advance: Callable[[float, str], None] | None = None,
            embed: Mapping[str, int] | None = None) -> MapSet:
    """Fill the risk maps, each path's final errors and the interactive page's per-run data
    (cells, thinned runs, contacts) in one chunked pass over the runs; ``advance(share,
    path)`` hears as each path starts (share: of the runs done before it). ``embed`` names a
    run per path the page holds besides its worst ones (a worst-case search's worst run)."""
    setup.notes += missing_signal_notes(store, data)
    grid, reason = choose_grid(store, data, setup)
    per_path: dict[str, RiskAccumulator] = {}
    references: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    maps = MapSet(grid, reason, per_path, RiskAccumulator(grid), setup.evaluator is not None,
                  references)
    required = sorted(set(getattr(setup.evaluator, "required_signals", ()) or ())
                      | set(POSE_SIGNALS) | set(ERROR_SIGNALS) | {"energy"}
                      | {"wheel.slip", "wheel.slip_angle", "wheel.sinkage"})
    limits = dict(getattr(setup.checked, "limits", {}) or {})
    weights = dict(getattr(setup.checked, "weights", {}) or {})
    runs = [int(path.complete.sum()) if path.evaluated else 0 for path in data.paths]
    for position, path in enumerate(data.paths):
        if advance is not None:
            advance(sum(runs[:position]) / max(sum(runs), 1), path.name)
        reference = store.reference(path.name)
        if store.has_path(path.name) and "chain" in store.path_group(path.name):
            maps.ideal_tracks[path.name] = _ideal_track(store, path.name, setup)
        if reference is not None and "x" in reference:
            references[path.name] = (np.asarray(reference["x"]), np.asarray(reference["y"]))
            if "yaw" in reference:
                maps.wheel_tracks[path.name] = wheel_tracks(
                    np.asarray(reference["x"]), np.asarray(reference["y"]),
                    np.asarray(reference["yaw"]), setup.rover)
                maps.wheel_bands[path.name] = wheel_bands(
                    np.asarray(reference["x"]), np.asarray(reference["y"]),
                    np.asarray(reference["yaw"]), setup.rover, WHEEL_WIDTH)
        if not path.evaluated or not path.complete.any() or reference is None \
                or not {"x", "y"} <= set(reference):
            continue
        accumulator = RiskAccumulator(grid)
        cells = CellRuns(grid, len(path.index_names))
        embedded = {int(run) for run in path.worst_order(limits, weights)[:EMBEDDED_RUNS]}
        if embed is not None and path.name in embed:
            embedded.add(int(embed[path.name]))
        series: dict[int, dict[str, Any]] = {}
        contacts: list[dict[str, Any]] = []
        details = _details(store, path.name)
        context = _context(store, path.name, setup) if reference is not None else None
        local, heading = [], []
        across = _first_pass(store, path.name, setup, context)
        stored = store.path_group(path.name)["runs"]["signals"]
        keys = [key for key in required if key in stored]
        for rows, signals in _chunks(store, path.name, keys):
            risk = _risk_of_chunk(setup, path, rows, signals, context, across)
            accumulator.add(signals["x"], signals["y"], risk)
            cells.add(rows, signals["x"], signals["y"], risk, path.dominant, embedded)
            for position, run in enumerate(rows):
                if int(run) in embedded:
                    series[int(run)] = run_series(signals, position, risk, reference)
            if details is not None:
                contacts += contact_points(details, rows, signals, setup.rover)
            errors = _final_errors(setup, signals, context) if context is not None else None
            if errors is not None:
                local.append(errors[0])
                heading.append(errors[1])
        per_path[path.name] = accumulator
        maps.cells[path.name] = cells
        maps.series[path.name] = series
        maps.contacts[path.name] = contacts
        if local:
            path.final_local_error = np.concatenate(local)
            headings = np.concatenate(heading)
            path.final_heading_error = None if np.isnan(headings).all() else headings
    for accumulator in per_path.values():
        maps.combined.merge(accumulator)
    return maps
