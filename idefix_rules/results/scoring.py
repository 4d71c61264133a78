"""Scoring a stored path chunk by chunk: the one way stored runs are evaluated.

:func:`score_chunks` reads a path's complete runs a chunk at a time (only the signals the
rulebooks read), gives each chunk its collision signals (from the obstacle checker or from
what the evaluation stored, :mod:`idefix_rules.results.collisions`) and evaluates it under
one or several compiled rulebooks. A rulebook that reduces over the runs of a path
(``mean over runs (…)``) first gets its path-level values from a pass over every complete
run; the chunks that pass reads are kept for the evaluation, not read again, as far as they
fit :data:`FIRST_PASS_BYTES` (the later ones are read again). Rulebooks with the same derived
settings and the same collision signals share one derived-signal source per chunk (and every
index value or chance they write alike).

The campaign's evaluation, ``idefix-verify diff --results`` and the report all score through
it; each keeps from the chunks what it needs (per-run values, per-sample maps).

:func:`stored_evaluation` gives back, instead, the per-run values the evaluation stored,
when they are those a rulebook would compute again.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import signal
import threading
import time
from collections import deque
from collections.abc import Callable, Hashable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, ThreadPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from idefix_rules.results.collisions import (
    POSE_SIGNALS,
    ChunkCollisions,
    CollisionFunction,
    StoredChunks,
)
from idefix_rules.results.format import STATUS_COMPLETE
from idefix_rules.results.reader import reading
from idefix_rules.results.runs import (
    DEFAULT_CHUNK_RUNS,
    RunReader,
    complete_rows,
    read_rows,
)

# Signals read whenever stored: a run's time and energy, whether its chain finished.
RUN_SIGNALS = frozenset({"command", "done", "energy", "t"})
# Of those, what derived signals use when stored (a run's progress along its chain), read
# for the per-sample values too.
PROGRESS_SIGNALS = frozenset({"command", "done", "t"})
# The chunks of signals a path's first pass (reductions over runs) reads are kept for the
# evaluation pass up to this many bytes; the chunks past it are read again. The budget is
# what a path's first 200 runs of the example's longest chain take (x, y, t, command of 9,600
# samples): kept, they do not raise the evaluation's peak, as the chunks are kept while
# nothing else is held and handed back as the evaluation takes them (docs/operations.md,
# "Memory"); 512 MB raised it by 236 MB at 1,000 runs, with no time saved that showed
# beyond the noise of a shared machine.
FIRST_PASS_BYTES = 64 * 1024 * 1024


@dataclass
class ScoredChunk:
    """One chunk of a path's complete runs, scored."""

    rows: np.ndarray  # the path's run numbers, axis 0 of everything below
    signals: dict[str, np.ndarray]  # the stored signals read
    evaluations: list[Any | None]  # per rulebook (None: not scored, or per-sample only)
    # per rulebook: its collision signals and per-run collision details (None: it reads none)
    collisions: list[tuple[dict[str, np.ndarray], list[dict[str, Any]]] | None] = field(
        default_factory=list)
    # per rulebook, scored with ``per_run=False``: each index's normalised per-sample value
    samples: list[dict[str, np.ndarray] | None] = field(default_factory=list)
    # per rulebook, the derived signals it was scored on (DerivedSignals, each signal it
    # computed kept; None: not scored): a caller derives more from them without computing
    # those again
    sources: list[Any | None] = field(default_factory=list)


def signals_to_read(evaluators: Iterable[Any | None], extra: Iterable[str] = (),
                    poses: bool = False, per_run: bool = True) -> set[str]:
    """What a chunk must hold for ``evaluators``: the signals they read (required and
    optional), a run's time, energy and end, the height a global error adds to a position,
    ``extra``, and the poses when the obstacle checker runs on them. ``per_run=False``:
    only what their per-sample values read (no energy, no signal of a chance alone, the
    height only when they read a global error)."""
    keys = set(RUN_SIGNALS if per_run else PROGRESS_SIGNALS) | set(extra)
    for evaluator in evaluators:
        if evaluator is None:
            continue
        if per_run:
            keys |= set(evaluator.required_signals) | set(evaluator.optional_signals)
        else:
            keys |= set(evaluator.sample_signals) | set(evaluator.sample_optional_signals)
    if per_run and "x" in keys:
        keys.add("z")
    if poses:
        keys |= set(POSE_SIGNALS)
    return keys


def _chunk_size(signals: Mapping[str, np.ndarray]) -> int:
    return sum(values.nbytes for values in signals.values())


class FirstPassCache:
    """The path-level accumulators of the whole chunks of each path's complete runs so far.

    An adaptive campaign's look computes the path-level values over every run stored so far;
    with this, it folds only the chunks past the last look's whole chunks onto their kept
    accumulators. The fold is the same sequence of sums as reading every chunk again, so the
    values are the same to the bit; an entry is used only while its rows are the first rows of
    the path's complete runs."""

    def __init__(self) -> None:
        self._entries: dict[Hashable, tuple[np.ndarray, list[Any]]] = {}

    def get(self, key: Hashable, rows: np.ndarray) -> tuple[int, list[Any] | None]:
        """How many of ``rows`` the kept accumulators cover, and those (0, None: none)."""
        entry = self._entries.get(key)
        if entry is None:
            return 0, None
        covered, accumulators = entry
        if covered.size > rows.size or not np.array_equal(rows[:covered.size], covered):
            return 0, None
        return int(covered.size), accumulators

    def put(self, key: Hashable, rows: np.ndarray, accumulators: list[Any]) -> None:
        self._entries[key] = (np.array(rows, copy=True), accumulators)


class _FirstPass:
    """The path-level values of each rulebook, and the chunks read for them when kept."""

    def __init__(self, evaluators: Sequence[Any | None]) -> None:
        self.evaluators = evaluators
        self.across: list[Any] = [None] * len(evaluators)
        self.kept: dict[int, dict[str, np.ndarray]] | None = None  # by first row

    def run(self, reader: RunReader, name: str, context: Any, rows: np.ndarray,
            chunk_runs: int, keep: bool, cache: FirstPassCache | None = None) -> None:
        from idefix_rules.rulebook.across import first_pass

        kept: dict[int, dict[str, np.ndarray]] = {}
        size = 0

        def chunks_of(some: np.ndarray) -> Callable[[set[str]], Iterator[dict[str, np.ndarray]]]:
            def chunks(names: set[str]) -> Iterator[dict[str, np.ndarray]]:
                nonlocal size
                wanted = sorted(names)
                for begin in range(0, len(some), chunk_runs):
                    part = some[begin:begin + chunk_runs]
                    signals = read_rows(reader, name, part, wanted)
                    if keep and size + _chunk_size(signals) <= FIRST_PASS_BYTES:
                        size += _chunk_size(signals)
                        kept[int(part[0])] = signals  # the chunks past the budget: read again
                    yield signals
            return chunks

        if cache is None:
            self.across = first_pass(self.evaluators, chunks_of(rows), context)
        else:
            key = (name, chunk_runs, tuple(id(e) for e in self.evaluators))
            covered, start = cache.get(key, rows)
            whole = rows.size - rows.size % chunk_runs  # chunk boundaries as without a cache
            if whole > covered:
                start = first_pass(self.evaluators, chunks_of(rows[covered:whole]), context,
                                   start)
                cache.put(key, rows[:whole], start)
            self.across = first_pass(self.evaluators, chunks_of(rows[whole:]), context, start)
        self.kept = kept if keep and kept else None

    def take(self, first_row: int) -> dict[str, np.ndarray]:
        """The kept signals of the chunk starting at ``first_row`` (empty when none)."""
        if self.kept is None:
            return {}
        return self.kept.pop(first_row, {})


def _read_chunks(reader: RunReader, name: str, rows: np.ndarray, keys: set[str],
                 chunk_runs: int, first: _FirstPass, timings: dict[str, float]
                 ) -> Iterator[tuple[np.ndarray, dict[str, np.ndarray]]]:
    """The chunks of ``rows``, the next one read on a thread while the caller works."""
    starts = list(range(0, len(rows), chunk_runs))
    if not starts:
        return

    def read(begin: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        part = rows[begin:begin + chunk_runs]
        kept = first.take(int(part[0]))
        missing = sorted(keys - set(kept))
        signals = read_rows(reader, name, part, missing) if missing else {}
        signals.update({key: values for key, values in kept.items() if key in keys})
        return part, signals

    with ThreadPoolExecutor(1, thread_name_prefix="results-read") as pool:
        mark = time.perf_counter()
        pending = pool.submit(read, starts[0])
        for index in range(len(starts)):
            chunk = pending.result()
            if index + 1 < len(starts):
                pending = pool.submit(read, starts[index + 1])
            timings["read"] = timings.get("read", 0.0) + time.perf_counter() - mark
            yield chunk
            mark = time.perf_counter()


# --- collision checks on worker processes ----------------------------------------------------

# The collision checker of the pool's workers: set before the pool forks, so the workers
# inherit it (its python-fcl objects cannot be pickled).
_WORKER_COLLISIONS: CollisionFunction | None = None
_FORK_LOCK = threading.Lock()


def _check_in_worker(poses: dict[str, np.ndarray], rows: np.ndarray
                     ) -> tuple[dict[str, np.ndarray], list[dict[str, Any]]]:
    assert _WORKER_COLLISIONS is not None
    return _WORKER_COLLISIONS(poses, rows)


def ignore_ctrl_c() -> None:
    """In a collision-check worker: Ctrl-C is the parent's to handle (it stops the evaluation
    and says so); a worker that took it printed its own traceback."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def with_collisions(chunks: Iterable[tuple[np.ndarray, dict[str, np.ndarray]]],
                    collisions: CollisionFunction, workers: int
                    ) -> Iterator[tuple[np.ndarray, dict[str, np.ndarray], Any]]:
    """``(rows, signals, (collision signals, details))`` per chunk, in chunk order.

    With several workers the collision checks (the costly part of an evaluation) run in forked
    processes, at most two chunks per worker in flight; each chunk's result is a pure function
    of its poses, so the outcome does not depend on the number of workers.
    """
    if workers <= 1 or "fork" not in multiprocessing.get_all_start_methods():
        for rows, signals in chunks:
            yield rows, signals, collisions(signals, rows)
        return
    global _WORKER_COLLISIONS
    pending: deque[tuple[np.ndarray, dict[str, np.ndarray], Future[Any]]] = deque()
    # the checks are bound by the CPU: no more processes than cores, whatever `workers`
    # (1024 would fork as many at once for a single chunk); the outcome is the same
    workers = min(workers, os.cpu_count() or 1)
    # A worker killed from outside (the out-of-memory killer, an operator) breaks the pool:
    # the chunks it held, and every chunk after them, are checked in this process instead,
    # with the same outcome (a chunk's checks depend on its poses alone).
    broken = False

    def outcome(rows: np.ndarray, signals: dict[str, np.ndarray], future: Future[Any]) -> Any:
        """A chunk's checks: its worker's (those finished before the break too), else here."""
        nonlocal broken
        try:
            return future.result()
        except BrokenProcessPool:
            broken = True
            return collisions(signals, rows)

    with _FORK_LOCK:
        _WORKER_COLLISIONS = collisions
        try:
            with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork"),
                                     initializer=ignore_ctrl_c) as pool:
                for rows, signals in chunks:
                    if broken:  # the chunks before it are yielded already (below)
                        yield rows, signals, collisions(signals, rows)
                        continue
                    poses = {key: signals[key] for key in POSE_SIGNALS}
                    try:
                        future = pool.submit(_check_in_worker, poses, rows)
                    except BrokenProcessPool as failure:
                        broken = True
                        future = Future()  # checked here, as a chunk the break took
                        future.set_exception(failure)
                    pending.append((rows, signals, future))
                    while len(pending) >= 2 * workers or (broken and pending):
                        done_rows, done_signals, future = pending.popleft()
                        yield done_rows, done_signals, outcome(done_rows, done_signals, future)
                while pending:
                    done_rows, done_signals, future = pending.popleft()
                    yield done_rows, done_signals, outcome(done_rows, done_signals, future)
        finally:
            _WORKER_COLLISIONS = None


# --- scoring ----------------------------------------------------------------------------------

def _evaluate(evaluators: Sequence[Any | None], signals: dict[str, np.ndarray],
              collided: list[tuple[dict[str, np.ndarray], list[dict[str, Any]]] | None],
              context: Any, across: Sequence[Any], per_sample: bool, per_run: bool = True
              ) -> tuple[list[Any | None], list[Any | None]]:
    """One chunk under every rulebook: each one's evaluation and derived-signal source.
    Rulebooks with equal derived settings and the same collision signals share one signal
    source: derived signals are computed once, and so is every index value or chance the
    rulebooks write the same. ``per_run=False``: each rulebook's per-sample values only
    (:meth:`CompiledRulebook.per_sample_values`)."""
    sources: dict[tuple[Any, int], tuple[Any, dict[Any, Any]]] = {}
    out: list[Any | None] = []
    used: list[Any | None] = []
    for position, evaluator in enumerate(evaluators):
        if evaluator is None:
            out.append(None)
            used.append(None)
            continue
        extra = collided[position]
        chunk = {**signals, **extra[0]} if extra is not None else signals
        key = (evaluator.derived_settings, id(extra[0]) if extra is not None else 0)
        if key not in sources:
            sources[key] = (evaluator.derived_signals(chunk, context), {})
        source, shared = sources[key]
        used.append(source)
        if not per_run:
            out.append(evaluator.per_sample_values(chunk, context, source=source,
                                                   across=across[position]))
            continue
        out.append(evaluator.evaluate(chunk, context, per_sample=per_sample, source=source,
                                      shared=shared, across=across[position]))
    return out, used


def score_chunks(reader: RunReader, name: str, evaluators: Sequence[Any | None],
                 context: Any, collisions: Sequence[ChunkCollisions | None] = (), *,
                 keys: Iterable[str] = (), per_sample: bool = False, per_run: bool = True,
                 chunk_runs: int = DEFAULT_CHUNK_RUNS, within: slice | None = None,
                 workers: int = 1, threads: int = 1, across_chunk_runs: int | None = None,
                 timings: dict[str, float] | None = None,
                 across_cache: FirstPassCache | None = None) -> Iterator[ScoredChunk]:
    """Score the complete runs of path ``name`` (those among the rows ``within``, when
    given) chunk by chunk under each of ``evaluators`` (None: skipped), in run order.

    ``collisions``: per rulebook, what gives a chunk its collision signals (a checker or the
    stored ones; None or missing: it reads none); one checker shared by several rulebooks
    checks each chunk once. ``keys``: signals to read besides those the rulebooks read.
    ``per_sample``: keep the per-sample values (the report's maps). ``per_run=False``:
    compute nothing else (``evaluations`` hold None, ``samples`` each rulebook's per-sample
    values): no per-run value, chance, time or energy, only the signals the per-sample values
    read, and no first pass unless they reduce over runs. ``workers`` > 1: the
    collision checks run in that many forked processes (one checker only); ``threads`` > 1:
    that many chunks are evaluated at the same time. ``timings`` adds the seconds spent
    reading, checking collisions and evaluating (waiting for it, when on threads).

    Path-level values (reductions over runs) are computed over every complete run of the
    path, ``within`` or not (an adaptive campaign's look scores its new runs with the
    values of all runs so far). ``across_chunk_runs``: the chunk size of that first pass
    (default ``chunk_runs``); its sums over chunks depend on it in the last bit, so a caller
    whose ``chunk_runs`` varies (an adaptive campaign's looks, with the number of processes)
    fixes it. ``across_cache``: keeps the first pass's whole chunks for the next call on
    more runs of the same path (:class:`FirstPassCache`)."""
    timings = timings if timings is not None else {}
    for key in ("read", "collisions", "evaluate"):
        timings.setdefault(key, 0.0)
    status = reader.run_status(name)
    rows = complete_rows(status, within)
    if not rows.size:
        return
    sources = list(collisions) + [None] * (len(evaluators) - len(collisions))
    checkers = {id(source): source for source in sources if source is not None}
    first = _FirstPass(evaluators)
    reductions = "runs_reductions" if per_run else "sample_runs_reductions"
    if any(getattr(e, reductions, ()) for e in evaluators if e is not None):
        mark = time.perf_counter()
        every = complete_rows(status)
        across = across_chunk_runs or chunk_runs
        first.run(reader, name, context, every, across,
                  keep=across == chunk_runs and (within is None or np.array_equal(every, rows)),
                  cache=across_cache)
        timings["read"] += time.perf_counter() - mark
    needs_poses = any(not _is_stored(source) for source in checkers.values())
    wanted = signals_to_read(evaluators, keys, needs_poses, per_run)
    chunks = _read_chunks(reader, name, rows, wanted, chunk_runs, first, timings)
    checked = _with_sources(chunks, sources, checkers, workers, timings)
    pool = ThreadPoolExecutor(threads, thread_name_prefix="results-score") if threads > 1 \
        else None
    pending: deque[tuple[np.ndarray, dict[str, np.ndarray], list[Any], Future[Any]]] = deque()

    def submit(signals: dict[str, np.ndarray], collided: list[Any]
               ) -> Future[tuple[list[Any | None], list[Any | None]]]:
        arguments = (evaluators, signals, collided, context, first.across, per_sample,
                     per_run)
        if pool is not None:
            return pool.submit(_evaluate, *arguments)
        future: Future[tuple[list[Any | None], list[Any | None]]] = Future()
        future.set_result(_evaluate(*arguments))
        return future

    def done() -> ScoredChunk:
        done_rows, done_signals, collided, future = pending.popleft()
        mark = time.perf_counter()
        evaluations, used = future.result()
        timings["evaluate"] += time.perf_counter() - mark
        if not per_run:
            return ScoredChunk(done_rows, done_signals, [None] * len(evaluations), collided,
                               evaluations, used)
        return ScoredChunk(done_rows, done_signals, evaluations, collided, sources=used)

    try:
        for part, signals, collided in checked:
            mark = time.perf_counter()
            pending.append((part, signals, collided, submit(signals, collided)))
            timings["evaluate"] += time.perf_counter() - mark
            while len(pending) >= max(1, threads):
                yield done()
        while pending:
            yield done()
    finally:
        if pool is not None:
            pool.shutdown(cancel_futures=True)


def _is_stored(source: Any) -> bool:
    return isinstance(source, StoredChunks)


def _with_sources(chunks: Iterator[tuple[np.ndarray, dict[str, np.ndarray]]],
                  sources: Sequence[ChunkCollisions | None],
                  checkers: Mapping[int, ChunkCollisions], workers: int,
                  timings: dict[str, float]
                  ) -> Iterator[tuple[np.ndarray, dict[str, np.ndarray], list[Any]]]:
    """Each chunk with every rulebook's collision signals (each source once per chunk; a
    single obstacle checker on ``workers`` processes)."""
    computed = [source for source in checkers.values() if not _is_stored(source)]
    if len(computed) == 1 and workers > 1:
        checker: Any = computed[0]
        forked = with_collisions(chunks, checker, workers)
        while True:
            mark = time.perf_counter()
            try:
                rows, signals, result = next(forked)
            except StopIteration:
                return
            timings["collisions"] += time.perf_counter() - mark
            found = {id(checker): result}
            for key, source in checkers.items():
                if key not in found:
                    found[key] = source(signals, rows)
            yield rows, signals, [found[id(s)] if s is not None else None for s in sources]
        return
    for rows, signals in chunks:
        mark = time.perf_counter()
        found = {key: source(signals, rows) for key, source in checkers.items()}
        timings["collisions"] += time.perf_counter() - mark
        yield rows, signals, [found[id(s)] if s is not None else None for s in sources]


# --- the evaluation as stored ---------------------------------------------------------------

def stored_evaluation(store: Any, name: str, evaluator: Any, rulebook_sha256: str,
                      package_version: str) -> tuple[np.ndarray, Any] | None:
    """The per-run values the evaluation stored for path ``name`` — ``(rows, RunEvaluation)``
    over its complete runs — when they are those ``evaluator`` computes again: the stored
    evaluation was made by this version of the tool (``package_version``) with the same
    rulebook text (``rulebook_sha256``), over every run now complete. None otherwise.

    Per-sample values are not stored: the evaluation has none (``dominant_sample`` 0)."""
    from idefix_rules.rulebook.results import RunEvaluation

    root = store.file.get("evaluation")
    group = store.path_group(name).get("evaluation")
    if root is None or group is None or "i_max" not in group:
        return None
    if str(root.attrs.get("rulebook_sha256", "")) != rulebook_sha256:
        return None
    if _evaluated_by(root) != package_version:
        return None
    names = tuple(json.loads(str(group.attrs.get("index_names", "[]"))))
    if names != tuple(evaluator.index_names):
        return None
    status = store.run_status(name)
    rows = np.flatnonzero(status == STATUS_COMPLETE)
    with reading(Path(store.path), f"/paths/{name}/evaluation/i_max"):
        i_max = np.asarray(group["i_max"][()], dtype=np.float64)
    if i_max.shape[0] != status.shape[0] or not np.all(np.isfinite(i_max[rows])):
        return None
    needed = [f"indices/{n}" for n in names] + [f"raw/{n}" for n in names] + [
        f"chances/{n}" for n in evaluator.chance_names] + ["dominant", "time", "energy"]
    if any(path not in group for path in needed):
        return None

    def column(path: str, dtype: Any = np.float64) -> np.ndarray:
        return np.asarray(group[path][()], dtype=dtype)[rows]

    values = {n: column(f"indices/{n}") for n in names}
    weights = dict(getattr(evaluator.checked, "weights", {}) or {})
    evaluation = RunEvaluation(
        index_names=names, values=values, raw={n: column(f"raw/{n}") for n in names},
        per_sample={n: np.empty((rows.size, 0)) for n in names},
        weighted={n: float(weights.get(n, 1.0)) * values[n] for n in names},
        i_max=i_max[rows], dominant=column("dominant", np.int64),
        dominant_sample=np.zeros(rows.size, dtype=np.int64),
        chance_names=tuple(evaluator.chance_names),
        chances={n: column(f"chances/{n}", np.int8) != 0 for n in evaluator.chance_names},
        time=column("time"), energy=column("energy"))
    return rows, evaluation


def _evaluated_by(root: Any) -> str:
    """The tool version that wrote the stored evaluation (from its summary; "" if unknown)."""
    try:
        summary = json.loads(str(root.attrs.get("summary", "")) or "{}")
    except ValueError:
        return ""
    return str(summary.get("package_version", "")) if isinstance(summary, dict) else ""
