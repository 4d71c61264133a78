"""The collision checks of an adaptive campaign's looks, kept for its evaluation stage.

Each look of an adaptive campaign (``runs: auto``) scores its new runs, and the obstacle
checker (the costly part of scoring) runs on their poses. The evaluation stage after the last
look scores every run again, because a rule over the runs of a path (``mean over runs``)
changes as runs are added; a run's collisions do not: they are a pure function of its poses
and the obstacles. :class:`RememberedCollisions` keeps, per path and run, what the evaluation
stores of them (hits, buffer, the contacts as intervals, the clearance profile, the details)
and gives the looks and the evaluation stage those rows instead of checking the runs (again),
the way
``idefix-verify diff --results`` reuses the stored ones
(:class:`~idefix_rules.results.collisions.StoredChunks`). It stands in for the checker
wherever one is expected and checks, with it, what it does not hold. On the local pool the
workers check each run they simulate after handing it back (:func:`run_collisions`, on the
poses at their stored precision) and the campaign records their answer when it comes, so no
look checks a run either. After a check that failed in a worker (``worker_failure``) no
worker checks again in that campaign, and the looks check the runs.

Only rulebooks whose collision reads are among the stored signals (``collision.hits``,
``collision.buffer``, ``collision.contact``) are given remembered rows; any other read
(``collision.clearance`` per sample, say) is checked again. Kept per run: about 1.7 kB of data on
the pebble field (the details 0.56 kB, the clearance profile 0.96 kB), 2.3 kB with Python's
share; at most
:data:`BUDGET_BYTES` over all paths, the paths past it checked again.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from idefix_rules.results.collisions import (
    CONTACT_COLUMNS,
    POSE_SIGNALS,
    STORED_COLLISIONS,
    ObstacleCheck,
    StoredChunks,
    area_reads,
    clearance_profile,
    collision_reads,
    contact_intervals,
)
from idefix_rules.results.format import storage_dtype

# What the kept rows of all paths may take (about 150,000 runs of the pebble field); a path
# whose rows would pass it is given up (its kept rows freed) and checked again by the
# evaluation stage.
BUDGET_BYTES = 256 * 1024 * 1024
# Python's share of a kept row besides its data (three small arrays, a bytes object, four dict
# entries), counted against the budget: 590 B measured with tracemalloc over 1,000 rows.
ROW_OVERHEAD_BYTES = 600
# Python's share of each contact table kept, its array object (128 B, sys.getsizeof) and list
# slot (8 B): a worker's check is recorded run by run, so a run with a contact keeps a table
# of its own.
TABLE_OVERHEAD_BYTES = 136


class _PathRows:
    """What the evaluation stores of one path's collisions, for the runs seen so far."""

    def __init__(self) -> None:
        self.bytes = 0
        self.hits: dict[int, np.ndarray] = {}
        self.buffer: dict[int, np.ndarray] = {}
        self.profile: dict[int, np.ndarray] = {}
        self.details: dict[int, bytes] = {}
        self.contact: list[np.ndarray] = []


class RememberedCollisions:
    """The campaign's obstacle checker, with what its checks found kept per path and run."""

    def __init__(self, checker: ObstacleCheck, budget: int = BUDGET_BYTES) -> None:
        self.checker = checker
        self.budget = budget
        self.paths: dict[str, _PathRows] = {}
        self.given_up: set[str] = set()  # paths over the budget: checked again
        # the first check that failed in a worker (timeout, error, crash): no worker checks
        # after it, the looks check the runs
        self.worker_failure: str | None = None

    def __call__(self, poses: Mapping[str, np.ndarray], runs: np.ndarray | None = None
                 ) -> tuple[dict[str, np.ndarray], list[dict[str, Any]]]:
        return self.checker(poses, runs)

    def usable_for(self, evaluator: Any) -> bool:
        """Whether the rulebook reads only collision signals the remembered rows hold."""
        return collision_reads(evaluator) <= set(STORED_COLLISIONS)

    def record(self, name: str, rows: np.ndarray, stored: Mapping[str, Any]) -> None:
        """Keep what :func:`~idefix_rules.campaign.evaluation.evaluate.evaluate_path` gives
        to store for the complete runs ``rows`` of path ``name`` (``hits``, ``buffer``,
        ``contact``, ``clearance_profile``, ``details``); rows already kept are left alone.
        A look that lacks a piece (a rulebook reading no buffer) records nothing; a path
        whose rows pass the budget is given up."""
        if name in self.given_up or stored.get("hits") is None or stored.get("details") is None:
            return
        kept = self.paths.setdefault(name, _PathRows())
        rows = np.asarray(rows)
        texts = {int(row): text for chunk_rows, chunk_texts in stored["details"]
                 for row, text in zip(np.asarray(chunk_rows).tolist(), chunk_texts,
                                      strict=True)}
        new = [index for index, row in enumerate(rows.tolist()) if row not in kept.details]
        if not new or set(rows[new].tolist()) - set(texts):
            return
        pieces = {"hits": kept.hits, "buffer": kept.buffer, "clearance_profile": kept.profile}
        for index in new:
            row = int(rows[index])
            for key, into in pieces.items():
                if stored.get(key) is not None:
                    # a copy: a view would keep the look's whole array alive
                    into[row] = np.array(stored[key][index])
                    kept.bytes += into[row].nbytes
            kept.details[row] = texts[row]
            kept.bytes += len(texts[row]) + ROW_OVERHEAD_BYTES
        contact = stored.get("contact")
        if contact is not None and len(contact):
            table = np.asarray(contact).reshape(-1, len(CONTACT_COLUMNS))
            fresh = table[np.isin(table[:, 0], rows[new])]
            kept.contact.append(fresh)
            kept.bytes += fresh.nbytes + TABLE_OVERHEAD_BYTES
        if sum(path.bytes for path in self.paths.values()) > self.budget:
            del self.paths[name]  # its rows freed: the evaluation stage checks them again
            self.given_up.add(name)

    def covers(self, name: str, rows: np.ndarray) -> bool:
        """Whether every one of the complete runs ``rows`` of path ``name`` is kept."""
        kept = self.paths.get(name)
        return kept is not None and all(row in kept.details for row in np.asarray(rows).tolist())

    def source(self, name: str, rows: np.ndarray, evaluator: Any) -> StoredChunks:
        """The kept collision rows of path ``name`` as a chunk source (rows outside
        ``rows`` are not read), with the named areas' signals computed from each chunk's
        poses when ``evaluator`` reads them (the chunk holds the poses only then)."""
        kept = self.paths[name]
        size = int(np.max(rows)) + 1 if len(rows) else 0
        stored: dict[str, np.ndarray] = {
            "collision.hits": _rows_array(kept.hits, size),
            "collision.contact": _table(kept.contact)}
        if len(kept.buffer) == len(kept.details):
            stored["collision.buffer"] = _rows_array(kept.buffer, size)
        areas = self.checker.area_signals if area_reads(evaluator) else _no_areas
        return StoredChunks(stored, areas)

    def stored_pieces(self, name: str, rows: np.ndarray) -> dict[str, Any]:
        """What the evaluation stores of the collisions of runs ``rows`` of path ``name``
        (the pieces :func:`evaluate_path` would have computed), in the order of ``rows``."""
        kept = self.paths[name]
        order = np.asarray(rows).tolist()
        table = _table(kept.contact)
        pieces: dict[str, Any] = {
            "hits": np.stack([kept.hits[row] for row in order]) if order else None,
            "buffer": np.stack([kept.buffer[row] for row in order])
            if order and len(kept.buffer) == len(kept.details) else None,
            "details": [(np.asarray(rows), np.array([kept.details[row] for row in order],
                                                     dtype=bytes))],
            "contact": table[np.isin(table[:, 0], rows)],
            "clearance_profile": np.stack([kept.profile[row] for row in order])
            if order and len(kept.profile) == len(kept.details) else None}
        return pieces


def detail_texts(records: Sequence[Mapping[str, Any]]) -> np.ndarray:
    """A chunk's per-run collision details as the JSON text the evaluation stores (UTF-8
    bytes, one row per run): kept this way, not as nested dicts, until the path is written.

    >>> detail_texts([{"run": 3, "hits": {"wheel": []}}])
    array([b'{"run": 3, "hits": {"wheel": []}}'], dtype='|S33')
    """
    return np.array([json.dumps(record).encode("utf-8") for record in records], dtype=bytes)


def collision_pieces(rows: np.ndarray, extra: Mapping[str, np.ndarray],
                     details: Sequence[Mapping[str, Any]], t: np.ndarray | None
                     ) -> dict[str, Any]:
    """What the evaluation stores of a chunk's collision check (``extra``, ``details``: the
    checker's answer for the runs ``rows``; ``t`` their time grid): kept small, the contacts
    as intervals and the clearance as a profile. :meth:`RememberedCollisions.record` takes
    it."""
    contact = extra.get("collision.contact")
    clearance = extra.get("collision.clearance")
    return {
        "hits": extra.get("collision.hits"),
        "buffer": extra.get("collision.buffer"),
        "details": [(rows, detail_texts(details))],
        "contact": None if contact is None else contact_intervals(contact, rows),
        "clearance_profile": None if clearance is None or t is None
        else clearance_profile(clearance, t)}


def run_collisions(checker: ObstacleCheck, signals: Mapping[str, np.ndarray], run: int
                   ) -> dict[str, Any]:
    """:func:`collision_pieces` of one run, checked where it was simulated: on its poses as
    the results file stores them (each at its stored precision), so the answer is the one a
    check of the stored run gives (a run's check depends on its own poses only)."""
    poses = {key: np.asarray(signals[key], dtype=storage_dtype(key)).astype(np.float64)[None]
             for key in POSE_SIGNALS}
    rows = np.array([run], dtype=np.int64)
    extra, details = checker(poses, rows)
    return collision_pieces(rows, extra, details, poses["t"])


def _no_areas(signals: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    return {}


def _rows_array(values: Mapping[int, np.ndarray], size: int) -> np.ndarray:
    """A (size, …) array holding ``values`` at their rows (zero elsewhere, never read: a
    chunk reads only complete runs, all of them kept)."""
    first = next(iter(values.values()))
    out = np.zeros((size, *first.shape), dtype=first.dtype)
    for row, value in values.items():
        if row < size:
            out[row] = value
    return out


def _table(parts: list[np.ndarray]) -> np.ndarray:
    """The contact intervals kept, in one table sorted by run (then as recorded)."""
    if not parts:
        return np.zeros((0, len(CONTACT_COLUMNS)), dtype=np.int32)
    table = np.concatenate(parts)
    return table[np.argsort(table[:, 0], kind="stable")]
