"""Data the figures need that the results file does not hold directly: risk maps, final errors.

The results file keeps per-run index values, not per-sample ones. For the result map the
stored runs of each path are scored again chunk by chunk
(:func:`idefix_rules.results.scoring.score_chunks`) with the rulebook the stored evaluation
used (``/evaluation/rulebook_text``, else ``/provenance/rulebook``), the run context of the
stored campaign (:class:`idefix_rules.results.campaign.StoredCampaign`) and its collision
signals (stored by the
evaluation when they are those the rulebook reads, else from the obstacle checker on the
stored terrain), and the per-sample run risk (max over indices of weight × per-sample value)
is binned on the map grid (:mod:`idefix_rules.report.riskmap`).
The same pass computes each run's final local error and final heading error (box plots, paper
Fig. 9) with the rulebook's derived signals.

If the stored rulebook cannot be compiled by this version of the tool, the map falls back to
each run's stored I_max along its whole track and the report says so.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from idefix_rules.campaign.evaluation.evaluation_datasets import EVALUATION_RULEBOOK
from idefix_rules.commands import RoverGeometry, chain_duration, ideal_poses
from idefix_rules.obstacles.bodies import RoverBodies
from idefix_rules.report.data import PathReport, ReportData
from idefix_rules.report.environment import MapEnvironment, map_environment
from idefix_rules.report.riskmap import (
    RiskAccumulator,
    RiskGrid,
    cell_size_for,
    grid_covering,
    per_sample_risk,
    run_cell_maxima,
)
from idefix_rules.report.runs import (
    EMBEDDED_RUNS,
    SERIES,
    CellRuns,
    contact_points,
    run_series,
    wheel_bands,
    wheel_tracks,
)
from idefix_rules.results.campaign import StoredCampaign
from idefix_rules.results.collisions import CollisionSources, stored_clearance_profile
from idefix_rules.results.reader import StoredResults
from idefix_rules.results.runs import ParallelRuns, complete_chunks
from idefix_rules.results.scoring import score_chunks

CHUNK_RUNS = 64
# Wheel width the footprints are drawn with: the obstacle checker's wheel (docs/obstacles.md).
WHEEL_WIDTH = RoverBodies().wheel_width
# What the report reads of every run besides what the rulebook's per-sample values read:
# the track and heading (maps, contacts, thinned runs), what the final errors need, and the
# run panel's series (runs.SERIES).
POSE_SIGNALS = ("t", "x", "y", "roll", "pitch", "yaw")
ERROR_SIGNALS = ("t", "x", "y", "yaw", "command")
SERIES_SIGNALS = tuple(spec.signal for spec in SERIES if not spec.signal.startswith("collision."))


@dataclass
class Setup:
    """How the stored runs are evaluated again (mirrors the campaign's evaluation)."""

    checked: Any | None = None  # CheckedRulebook of the stored rulebook
    evaluator: Any | None = None  # compiled rulebook, None when it cannot be compiled
    rover: RoverGeometry = field(default_factory=RoverGeometry)
    sigma: float = 0.0
    collisions: CollisionSources | None = None  # None: the rulebook reads no collision
    environment: MapEnvironment = field(default_factory=MapEnvironment)
    notes: list[str] = field(default_factory=list)
    campaign_text: str = ""
    stored: StoredCampaign | None = None


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


def setup_from_store(store: StoredResults) -> Setup:
    """Compile the stored rulebook and take the stored campaign's run context and collisions
    (:class:`~idefix_rules.results.campaign.StoredCampaign`)."""
    stored = StoredCampaign(store)
    setup = Setup(stored=stored)
    try:
        evaluation = store.file.get("evaluation")
        if evaluation is not None and EVALUATION_RULEBOOK in evaluation:
            # the rulebook the stored evaluation used (`evaluate --rulebook` judged with
            # another than the campaign's): its limits and per-sample risks, not the campaign's
            value = evaluation[EVALUATION_RULEBOOK][()]
            rulebook_text = value.decode("utf-8") if isinstance(value, bytes) else str(value)
            rulebook_path = str(evaluation.attrs.get("rulebook_path", "rulebook.rules"))
        else:
            rulebook_text = store.text("rulebook")
            attributes = store.file["provenance"]["rulebook"].attrs
            rulebook_path = str(attributes.get("path", "rulebook.rules"))
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
    # the terrain the campaign was simulated on (rock heights, the ground, steep areas), as
    # the evaluation takes it
    ground = stored.ground(tolerant=True)
    setup.environment, notes = map_environment(campaign_text, setup.checked, ground.terrain)
    setup.notes += notes
    if campaign_text:
        _campaign_context(stored, setup)
    if setup.collisions is not None:  # the maps' collision and area risks stand on it
        setup.notes += ground.warnings
    setup.notes += unseen_ground_notes(store, stored, setup.evaluator)
    return setup


def unseen_ground_notes(store: StoredResults, stored: StoredCampaign, evaluator: Any
                        ) -> list[str]:
    """The campaign's terrain and rocks an FMU without a terrain input did not see (C510, as
    the campaign said it before simulating), for the rulebook the report scores with; none for
    a results file that does not say (written before ``terrain_seen``)."""
    from pathlib import PurePath

    from idefix_rules.campaign.input.fmu_checks import given_ground, unseen_ground_text
    from idefix_rules.results.format import attribute_text

    seen = store.attrs.get("terrain_seen")
    if seen is None or bool(seen) or stored.campaign is None:
        return []
    fmu_name = PurePath(attribute_text(store.attrs.get("fmu_path", "the FMU"))).name
    reads_collisions = bool(getattr(evaluator, "needs_collisions", False))
    return [f"environment.{what}: {unseen_ground_text(what, fmu_name, reads_collisions)} "
            "(C510)" for what in given_ground(stored.campaign.model.environment)]


def _campaign_context(stored: StoredCampaign, setup: Setup) -> None:
    """Rover geometry, initial-position σ and the collision signals, as the campaign had
    them."""
    if stored.campaign is None:
        setup.notes.append(f"campaign geometry not rebuilt ({type(stored.problem).__name__}): "
                           "default rover geometry used")
        return
    setup.rover, setup.sigma = stored.rover, stored.sigma
    if setup.evaluator is not None and getattr(setup.evaluator, "needs_collisions", False):
        try:
            sources = CollisionSources(stored, [setup.evaluator], [setup.checked])
            if sources.mode == "recomputed":
                sources.function(0)  # the checker now, so a failure is said here
            setup.collisions = sources
        except Exception as failure:
            setup.notes.append(f"collision signals not rebuilt ({type(failure).__name__}: "
                               f"{failure}): the maps show each run's I_max instead")
            setup.evaluator = None


def choose_grid(store: StoredResults, data: ReportData, setup: Setup,
                runs: Any = None,
                references: Mapping[str, Mapping[str, np.ndarray] | None] | None = None
                ) -> tuple[RiskGrid, str]:
    """A grid covering every complete run's track (and nearby obstacles), cell from the rover.
    ``references``: each path's reference run, when read already."""
    bounds = [np.inf, -np.inf, np.inf, -np.inf]

    def include(x: np.ndarray, y: np.ndarray) -> None:
        nonlocal bounds
        if np.isfinite(x).any() and np.isfinite(y).any():
            bounds = [min(bounds[0], np.nanmin(x)), max(bounds[1], np.nanmax(x)),
                      min(bounds[2], np.nanmin(y)), max(bounds[3], np.nanmax(y))]

    for path in data.paths:
        reference = references[path.name] if references is not None \
            else store.reference(path.name)
        if reference is not None and "x" in reference and "y" in reference:
            include(np.asarray(reference["x"]), np.asarray(reference["y"]))
        if not store.has_path(path.name) or not store.has_runs(path.name):
            continue
        for _, chunk in complete_chunks(runs or store, path.name, ["x", "y"], 256):
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


def _scored(runs: ParallelRuns, path: PathReport, setup: Setup, context: Any,
            keys: set[str]
            ) -> Iterator[tuple[np.ndarray, dict[str, np.ndarray], np.ndarray, Any | None]]:
    """``(rows, signals, per-sample risk, derived signals)`` of the path's complete runs,
    chunk by chunk: the stored rulebook's per-sample risk and the derived signals it was
    computed from, or each run's stored I_max along its whole track (and no derived signals)
    when the rulebook cannot be evaluated. ``signals`` holds the collision signals too."""
    if setup.evaluator is None or setup.checked is None or context is None:
        for rows, signals in complete_chunks(runs, path.name, keys, CHUNK_RUNS):
            yield rows, signals, np.broadcast_to(path.i_max[rows][:, None],
                                                 signals["x"].shape), None
        return
    sources = setup.collisions.for_path(path.name) if setup.collisions is not None else [None]
    weights = setup.checked.weights
    # the per-sample values only: the per-run ones are stored (Table 1 reads them)
    for chunk in score_chunks(runs, path.name, [setup.evaluator], context, sources,
                              keys=keys, per_sample=True, per_run=False,
                              chunk_runs=CHUNK_RUNS):
        signals = chunk.signals
        collided = chunk.collisions[0] if chunk.collisions else None
        if collided is not None:
            signals = {**signals, **collided[0]}
        shape = signals["x"].shape
        samples = chunk.samples[0]
        assert samples is not None
        per_sample = {name: np.broadcast_to(np.asarray(values, dtype=float), shape)
                      for name, values in samples.items()}
        yield chunk.rows, signals, per_sample_risk(per_sample, weights), chunk.sources[0]


def _final_errors(setup: Setup, signals: dict[str, np.ndarray], context: Any,
                  scored: Any | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """Each run's local and heading error at its last sample, with the rulebook's derived
    signals (``scored``: those the per-sample risk was computed from, when their settings
    are the rulebook's: what they hold already is not computed again)."""
    try:
        from idefix_rules.rulebook.derived import DerivedSettings, DerivedSignals
    except ImportError:
        return None
    settings = getattr(setup.checked, "settings", {}) or {}
    wanted = DerivedSettings(theoretical_slip=float(settings.get("theoretical_slip", 0.0)),
                             tolerance_growth=float(settings.get("tolerance_growth", 0.0)))
    derived = scored if isinstance(scored, DerivedSignals) and scored.settings == wanted \
        and scored.context is context else DerivedSignals(signals, context, wanted)
    local = np.asarray(derived.last("local_error"))
    if "yaw" not in signals or context.reference is None or "yaw" not in context.reference:
        return local, np.full(local.shape, np.nan)  # a foreign FMU need not give yaw
    return local, np.asarray(derived.last("heading_error"))


# What the report draws from each optional signal, to name what a foreign FMU's runs lack.
OPTIONAL_SIGNALS = {"x": "the result maps show no runs and no box plots are drawn",
                    "y": "the result maps show no runs and no box plots are drawn",
                    "yaw": "the final heading error box plot is not drawn",
                    "energy": "Table 1 shows no energy",
                    "command": "a run's time is its stop time"}


def missing_signal_notes(store: StoredResults, data: ReportData,
                         references: Mapping[str, Mapping[str, np.ndarray] | None] | None = None
                         ) -> list[str]:
    """One note per optional signal the stored runs lack, saying what is not drawn
    (``references``: each path's reference run, when read already)."""
    stored: set[str] = set()
    for path in data.paths:
        reference = references[path.name] if references is not None \
            else store.reference(path.name)
        stored |= set(reference or ())
    if not stored:
        return []
    return [f"the runs hold no '{name}' (the FMU's signal map does not provide it): {what}"
            for name, what in OPTIONAL_SIGNALS.items()
            if name not in stored and not (name == "command" and "done" in stored)]


def _ideal_track(store: StoredResults, name: str, setup: Setup
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The commanded chain executed ideally (no slip) from the start pose: the ideal path."""
    chain = store.chain(name)
    duration = chain_duration(chain, setup.rover)
    times = np.linspace(0.0, duration, 400) if duration > 0 else np.zeros(1)
    poses = ideal_poses(chain, setup.rover, times)
    return poses[:, 0], poses[:, 1]


def _details(store: StoredResults, name: str) -> Any:
    evaluation = store.path_group(name).get("evaluation")
    if evaluation is None or "collisions" not in evaluation:
        return None
    collisions = evaluation["collisions"]
    return collisions["details"][()] if "details" in collisions else None


def prepare(store: StoredResults, data: ReportData, setup: Setup,
            advance: Callable[[float, str], None] | None = None,
            embed: Mapping[str, int] | None = None,
            mapped: Callable[[MapSet, str], None] | None = None) -> MapSet:
    """Fill the risk maps, each path's final errors and the interactive page's per-run data
    (cells, thinned runs, contacts) in one chunked pass over the runs; ``advance(share,
    path)`` hears as each path starts (share: of the runs done before it). ``embed`` names a
    run per path the page holds besides its worst ones (a worst-case search's worst run).
    ``mapped(maps, path)`` hears as soon as a path's map and what is drawn over it are
    complete (the report draws that map meanwhile); every path's reference run, ideal path
    and wheel tracks are there before the first."""
    references = {path.name: store.reference(path.name) for path in data.paths}
    setup.notes += missing_signal_notes(store, data, references)
    runs_reader = ParallelRuns(store)
    try:
        return _prepare(store, runs_reader, data, setup, references, advance, embed, mapped)
    finally:
        runs_reader.close()


def _prepare(store: StoredResults, runs_reader: ParallelRuns, data: ReportData, setup: Setup,
             stored_references: Mapping[str, Mapping[str, np.ndarray] | None],
             advance: Callable[[float, str], None] | None,
             embed: Mapping[str, int] | None = None,
             mapped: Callable[[MapSet, str], None] | None = None) -> MapSet:
    grid, reason = choose_grid(store, data, setup, runs_reader, stored_references)
    per_path: dict[str, RiskAccumulator] = {}
    references: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    maps = MapSet(grid, reason, per_path, RiskAccumulator(grid), setup.evaluator is not None,
                  references)
    for path in data.paths:  # what every path's map draws of the others
        reference = stored_references[path.name]
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
    required = set(POSE_SIGNALS) | set(ERROR_SIGNALS) | set(SERIES_SIGNALS)
    limits = dict(getattr(setup.checked, "limits", {}) or {})
    weights = dict(getattr(setup.checked, "weights", {}) or {})
    runs = [int(path.complete.sum()) if path.evaluated else 0 for path in data.paths]
    for position, path in enumerate(data.paths):
        if advance is not None:
            advance(sum(runs[:position]) / max(sum(runs), 1), path.name)
        reference = stored_references[path.name]
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
        context = setup.stored.context(path.name, reference) if setup.stored is not None \
            else None
        local, heading = [], []
        # the evaluation's clearance profiles, for runs whose collisions come from the store
        profiles = stored_clearance_profile(store, path.name) \
            if setup.collisions is not None else None
        for rows, signals, risk, derived in _scored(runs_reader, path, setup, context,
                                                    required):
            maxima = run_cell_maxima(grid, signals["x"], signals["y"], risk)
            accumulator.add_maxima(maxima, len(rows))
            cells.add_maxima(rows, maxima, path.dominant, embedded)
            for position, run in enumerate(rows):
                if int(run) in embedded:
                    stored = {"collision.clearance": profiles[int(run)]} \
                        if profiles is not None else None
                    series[int(run)] = run_series(signals, position, risk, reference, stored)
            if details is not None:
                contacts += contact_points(details, rows, signals, setup.rover)
            errors = _final_errors(setup, signals, context, derived) \
                if context is not None else None
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
        if mapped is not None:
            mapped(maps, path.name)
    for accumulator in per_path.values():
        maps.combined.merge(accumulator)
    return maps
