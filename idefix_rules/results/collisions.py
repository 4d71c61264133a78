"""Collision signals of stored runs: from the obstacle checker on their poses, or read back
from what the evaluation stored.

The campaign's evaluation checks every run's poses against the obstacles (python-fcl) and
stores per run the obstacles hit and the buffer zones entered (``evaluation/collisions``).
Scoring the same runs again with a rulebook that puts the same obstacles on the ground
(:func:`ground_key`) and reads only what is stored (:data:`STORED_COLLISIONS`) takes them
from there instead of checking again. The signals of the rulebook's named areas are always
computed from the poses: they are cheap and follow each rulebook's own area declarations.
"""

from __future__ import annotations

import functools
import hashlib
import itertools
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Protocol

import numpy as np

from idefix_rules.commands import RoverGeometry
from idefix_rules.plain import as_plain
from idefix_rules.results.format import CLEARANCE_POINTS, STATUS_COMPLETE
from idefix_rules.results.reader import StoredResults

POSE_SIGNALS = ("t", "x", "y", "z", "roll", "pitch", "yaw")
# Collision signals the results file stores per run (evaluation/collisions/<name>); the
# per-sample contacts as a table of intervals (format 5 on, :func:`contact_intervals`).
STORED_COLLISIONS = {"collision.hits": "hits", "collision.buffer": "buffer",
                     "collision.contact": "contact"}
CONTACT_COLUMNS = ("run", "part", "level", "first_sample", "stop_sample", "value")


class CollisionFunction(Protocol):
    """Collision signals and per-run details of runs of poses (axis 0 = run). ``runs`` are the
    path's run numbers of those rows, written into the details (None: numbered from 0)."""

    def __call__(self, poses: Mapping[str, np.ndarray], runs: np.ndarray | None = None
                 ) -> tuple[dict[str, np.ndarray], list[dict[str, Any]]]: ...


def collision_function(environment: Any, evaluator: Any, terrain: Any = None,
                       rover: RoverGeometry | None = None) -> ObstacleCheck | None:
    """The obstacle checker for a campaign environment, or None if the rulebook needs none;
    it gives the collision signals and the signals of the rulebook's named areas, for a rover of
    ``rover``'s geometry (the campaign's: :func:`~idefix_rules.campaign.input.campaign_values.
    rover_geometry`; the defaults when None)."""
    if not getattr(evaluator, "needs_collisions", False):
        return None
    from idefix_rules.campaign.input.environment import named_areas, obstacle_set

    return ObstacleCheck(obstacle_set(environment, evaluator, terrain),
                         named_areas(environment, evaluator, terrain), rover or RoverGeometry())


class ObstacleCheck:
    """The obstacle checker of a campaign (a :class:`CollisionFunction`): the collision
    signals of runs of poses against its obstacles, with the signals of its named areas."""

    def __init__(self, obstacles: Any, areas: Mapping[str, Any], rover: RoverGeometry) -> None:
        from idefix_rules.obstacles import RoverBodies

        self.obstacles = obstacles
        self.areas = areas
        self.rover = rover
        # the collision bodies' wheels where the campaign's geometry puts them (its half
        # track, half wheelbase and wheel radius), as the rover model drives them
        self.bodies = RoverBodies.from_geometry(rover)

    def __call__(self, poses: Mapping[str, np.ndarray], runs: np.ndarray | None = None
                 ) -> tuple[dict[str, np.ndarray], list[dict[str, Any]]]:
        from idefix_rules.obstacles import collision_signals

        result = collision_signals({k: poses[k] for k in POSE_SIGNALS}, self.obstacles,
                                   self.bodies)
        details = [as_plain(d) for d in result.details]
        if runs is not None:
            # The checker numbers the rows it was given from 0; a chunk of complete runs is
            # not contiguous when runs failed, so each row takes its own run number.
            for record in details:
                record["run"] = int(runs[record["run"]])
        signals = dict(result.signals)
        signals.update(self.area_signals(poses))
        return signals, details

    def area_signals(self, poses: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The signals of the named areas (``area.NAME.inside`` / ``.buffer``) alone."""
        if not self.areas:
            return {}
        from idefix_rules.obstacles.named import all_area_signals

        return all_area_signals(self.areas, poses, self.rover)


# --- what a rulebook puts on the ground --------------------------------------------------------

def source_sha256(checked: Any) -> str:
    """The sha256 of a checked rulebook's text (what ``/evaluation`` records)."""
    return hashlib.sha256(checked.rulebook.source.encode("utf-8")).hexdigest()


def collision_reads(evaluator: Any) -> frozenset[str]:
    """The ``collision.*`` signals a compiled rulebook reads."""
    return frozenset(n for n in evaluator.required_signals if n.startswith("collision."))


def area_reads(evaluator: Any) -> frozenset[str]:
    """The signals of named areas the rulebook reads (computed from the poses, never stored)."""
    return frozenset(getattr(evaluator, "area_signals_read", ()))


def collision_setup(checked: Any) -> tuple[Any, ...]:
    """What a rulebook's collisions are computed with: its obstacle levels (thresholds and
    buffers) and its named areas (obstacles of their levels)."""
    return (*checked.obstacle_levels, *checked.areas)


def ground_key(checked: Any, areas: Mapping[str, Any]) -> tuple[Any, ...]:
    """What a rulebook puts on the ground for the collision check: its obstacle levels and,
    of its named areas (``areas``: their geometry in a campaign, by name), those that cover
    some ground, with their level and shape. Two rulebooks with the same key give the same
    collision signals (an area's own buffer only shapes its ``area.NAME.buffer`` signal)."""
    covered = []
    for name in sorted(areas):
        area = areas[name]
        if area.empty:
            continue
        shape = hashlib.sha256()
        for polygon in area.polygons:
            shape.update(np.ascontiguousarray(polygon, dtype=float).tobytes())
        if area.mask is not None:
            shape.update(np.ascontiguousarray(area.mask).tobytes())
        covered.append((name, area.level, shape.hexdigest()))
    return (*checked.obstacle_levels, *covered)


def stored_rulebook(store: StoredResults, candidates: Sequence[Any]) -> Any | None:
    """The checked rulebook whose evaluation is stored in ``store`` (its collisions were
    computed with it): one of ``candidates`` with the same text, else the stored text
    checked; None when that rulebook is not known."""
    group = store.file.get("evaluation")
    if group is None:
        return None
    digest = str(group.attrs.get("rulebook_sha256", ""))
    for checked in candidates:
        if source_sha256(checked) == digest:
            return checked
    try:
        text = store.text("rulebook")
    except KeyError:
        return None
    if hashlib.sha256(text.encode("utf-8")).hexdigest() != digest:
        return None
    from idefix_rules.rulebook import check_text

    return check_text(text, "<stored rulebook>").checked


def can_use_stored(evaluators: Sequence[Any], stored: tuple[Any, ...] | None,
                   keys: Sequence[tuple[Any, ...]]) -> bool:
    """True when every evaluator that reads collisions reads only stored ones and puts on the
    ground (``keys``, :func:`ground_key` per evaluator) what the stored collisions were
    computed with (``stored``). The signals of named areas come from the poses either way."""
    if stored is None:
        return False
    for evaluator, key in zip(evaluators, keys, strict=True):
        reads = collision_reads(evaluator)
        if reads and (not reads <= set(STORED_COLLISIONS) or key != stored):
            return False
    return True


# --- what the evaluation stores of the per-sample collision signals ---------------------------

def contact_intervals(contact: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``collision.contact`` of runs ``rows`` ((runs, samples, part, level), mostly 0) as a
    table of intervals, one row per stretch of equal nonzero value: run, part, level, first
    sample, stop sample (exclusive), value (:data:`CONTACT_COLUMNS`).

    >>> contact = np.zeros((1, 6, 3, 3), np.int8); contact[0, 2:4, 0, 1] = 1
    >>> contact_intervals(contact, np.array([7])).tolist()
    [[7, 0, 1, 2, 4, 1]]
    """
    values = np.asarray(contact)
    runs, samples = values.shape[:2]
    found = []
    flat = values.reshape(runs, samples, -1)
    for run, column in zip(*np.nonzero(flat.any(axis=1)), strict=True):
        series = flat[run, :, column].astype(np.int64)
        edges = np.flatnonzero(np.diff(np.concatenate(([0], series, [0]))) != 0)
        part, level = divmod(int(column), values.shape[3])
        for first, stop in itertools.pairwise(edges):
            if series[first]:
                found.append((int(rows[run]), part, level, int(first), int(stop),
                              int(series[first])))
    return np.array(found, dtype=np.int32).reshape(-1, len(CONTACT_COLUMNS))


def contact_from_intervals(table: np.ndarray, rows: np.ndarray, samples: int,
                           shape: tuple[int, int] = (3, 3), dtype: Any = np.int8
                           ) -> np.ndarray:
    """``collision.contact`` of runs ``rows`` ((runs, samples, part, level), int8 unless
    ``dtype`` says otherwise) from the stored table of intervals (:func:`contact_intervals`)."""
    out = np.zeros((rows.size, samples, *shape), dtype=dtype)
    if table.size:
        position = {int(run): index for index, run in enumerate(rows)}
        for run, part, level, first, stop, value in np.asarray(table):
            index = position.get(int(run))
            if index is not None:
                out[index, first:stop, part, level] = value
    return out


def profile_edges(valid: int, points: int = CLEARANCE_POINTS) -> np.ndarray:
    """The edges of at most ``points`` equal stretches of ``valid`` samples."""
    count = max(1, min(points, valid))
    return np.linspace(0, valid, count + 1).round().astype(int)


def clearance_profile(clearance: np.ndarray, t: np.ndarray,
                      points: int = CLEARANCE_POINTS) -> np.ndarray:
    """Per run, the smallest clearance of any body part (``collision.clearance``, (runs,
    samples, part)) over each of ``points`` equal stretches of its samples with a time
    (NaN where a stretch has none, or the run fewer samples): (runs, points)."""
    values = np.asarray(clearance, dtype=np.float64)
    nearest = values.min(axis=2) if values.ndim > 2 else values
    out = np.full((values.shape[0], points), np.nan)
    for run in range(values.shape[0]):
        timed = np.isfinite(t[run])
        valid = int(np.flatnonzero(timed)[-1] + 1) if timed.any() else 0
        edges = profile_edges(valid, points)
        for index, (start, stop) in enumerate(itertools.pairwise(edges)):
            stretch = nearest[run, start:max(stop, start + 1)]
            finite = stretch[np.isfinite(stretch)]
            if finite.size:
                out[run, index] = float(finite.min())
    return out


def stored_clearance_profile(store: StoredResults, name: str) -> np.ndarray | None:
    """The path's stored clearance profiles (rows, :data:`CLEARANCE_POINTS`), None when not
    stored (files before format 5, rulebooks reading no collision)."""
    group = store.path_group(name).get("evaluation/collisions")
    if group is None or "clearance_profile" not in group:
        return None
    return np.asarray(group["clearance_profile"][()], dtype=np.float64)


def stored_collisions(store: StoredResults, name: str, wanted: set[str]
                      ) -> dict[str, np.ndarray] | None:
    """A path's stored collision arrays (every row), or None when one that is ``wanted`` is
    missing or not stored for every complete run."""
    group = store.path_group(name).get("evaluation/collisions")
    if group is None:
        return None
    status = store.run_status(name)
    complete = status == STATUS_COMPLETE
    arrays = {}
    for signal, dataset in STORED_COLLISIONS.items():
        if dataset not in group:
            if signal in wanted:
                return None
            continue
        values = np.asarray(group[dataset][()])
        if signal == "collision.contact":  # a table of intervals, not a row per run
            arrays[signal] = values.reshape(-1, len(CONTACT_COLUMNS))
            continue
        if values.shape[0] != status.shape[0] or not np.all(np.isfinite(values[complete])):
            return None
        arrays[signal] = values
    return arrays


# A chunk's collision signals and per-run details, given its signals and run numbers.
ChunkCollisions = Callable[[Mapping[str, np.ndarray], np.ndarray],
                           tuple[dict[str, np.ndarray], list[dict[str, Any]]]]


class CollisionSources:
    """Where each of several rulebooks scoring one stored campaign takes its collision
    signals from: ``stored`` when every one that reads collisions can use the stored ones,
    else ``recomputed`` by the obstacle checker (once per distinct set of obstacle levels),
    ``none`` when no rulebook reads any. ``checked``: the rulebooks' checked forms, in the
    order of ``evaluators`` (to recognise the stored evaluation's rulebook without checking
    its text again)."""

    def __init__(self, campaign: Any, evaluators: Sequence[Any],
                 checked: Sequence[Any] = (), reuse: bool = True) -> None:
        self.campaign = campaign  # a StoredCampaign
        self.evaluators = list(evaluators)
        self.needed = [bool(collision_reads(e) or area_reads(e)) for e in evaluators]
        self._areas: dict[tuple[Any, ...], dict[str, Any]] = {}
        self._functions: dict[tuple[Any, ...], CollisionFunction | None] = {}
        self._ground_used = False  # whether a check stood on the stored terrain
        self.recomputed_paths: list[str] = []
        self.mode = "none"
        if not any(self.needed):
            return
        stored = stored_rulebook(campaign.store, list(checked)) if reuse else None
        if stored is None:
            self.mode = "recomputed"
            return
        keys = [ground_key(e.checked, self._named_areas(e)) for e in self.evaluators]
        stored_key = ground_key(stored, self._named_areas(stored))
        self.mode = "stored" if can_use_stored(self.evaluators, stored_key, keys) \
            else "recomputed"

    @property
    def warnings(self) -> list[str]:
        """What the user should know about the terrain the checks stand on (an older file
        holding none, a DEM changed since the simulation), once a check needed it."""
        return list(self.campaign.ground().warnings) if self._ground_used else []

    def describe(self) -> str:
        """``none``, ``stored``, ``recomputed``, or ``stored (recomputed for: a, b)``."""
        if self.mode == "stored" and self.recomputed_paths:
            return f"stored (recomputed for: {', '.join(self.recomputed_paths)})"
        return self.mode

    def function(self, position: int) -> CollisionFunction | None:
        """The obstacle checker of rulebook ``position`` (None when it reads no collisions);
        one per distinct set of obstacle levels, built on first use."""
        if not self.needed[position]:
            return None
        evaluator = self.evaluators[position]
        key = collision_setup(evaluator.checked)
        if key not in self._functions:
            self._ground_used = True
            self._functions[key] = self.campaign.collision_function(evaluator)
        return self._functions[key]

    def _named_areas(self, evaluator: Any) -> dict[str, Any]:
        """The named areas of a rulebook (compiled or checked) on this campaign's ground."""
        checked = getattr(evaluator, "checked", evaluator)
        key = collision_setup(checked)
        if key not in self._areas:
            self._ground_used = self._ground_used or bool(checked.areas)
            self._areas[key] = self.campaign.named_areas(checked) if checked.areas else {}
        return self._areas[key]

    def _area_signals(self, position: int, signals: Mapping[str, np.ndarray]
                      ) -> dict[str, np.ndarray]:
        evaluator = self.evaluators[position]
        if not area_reads(evaluator):
            return {}
        from idefix_rules.obstacles.named import all_area_signals

        return all_area_signals(self._named_areas(evaluator), signals, RoverGeometry())

    def for_path(self, name: str) -> list[ChunkCollisions | None]:
        """Per rulebook, what gives a chunk of the path's runs its collision signals (None:
        it reads none). Rulebooks with the same obstacle levels share one checker (the
        scoring checks each chunk once per distinct one)."""
        stored = None
        if self.mode == "stored":
            wanted = set().union(*(collision_reads(e) for e in self.evaluators))
            stored = stored_collisions(self.campaign.store, name, wanted)
            if stored is None:
                self.recomputed_paths.append(name)  # not stored for every run: check them
        sources: list[ChunkCollisions | None] = []
        # one source for the rulebooks that read no named area: the scoring then gives them
        # the same signals, and their derived signals are computed once
        plain = StoredChunks(stored, lambda signals: {}) if stored is not None else None
        for position, needed in enumerate(self.needed):
            if not needed:
                sources.append(None)
            elif stored is not None and not area_reads(self.evaluators[position]):
                sources.append(plain)
            elif stored is not None:
                sources.append(StoredChunks(stored, functools.partial(self._area_signals,
                                                                      position)))
            else:
                sources.append(self.function(position))
        return sources


class StoredChunks:
    """A chunk's stored collision rows, with the area signals computed from its poses."""

    def __init__(self, stored: Mapping[str, np.ndarray],
                 areas: Callable[[Mapping[str, np.ndarray]], dict[str, np.ndarray]]) -> None:
        self.stored = stored
        self.areas = areas

    def __call__(self, signals: Mapping[str, np.ndarray], rows: np.ndarray | None = None
                 ) -> tuple[dict[str, np.ndarray], list[dict[str, Any]]]:
        assert rows is not None
        picked = {}
        for key, values in self.stored.items():
            if key == "collision.contact":
                samples = next(iter(signals.values())).shape[1]
                # as float64, the type an evaluation computes with: no int8 copy converted
                # then (the zeros cost nothing until they are read)
                picked[key] = contact_from_intervals(values, rows, samples, dtype=np.float64)
            else:
                picked[key] = values[rows]
        return {**picked, **self.areas(signals)}, []
