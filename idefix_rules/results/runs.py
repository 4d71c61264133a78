"""Reading a path's stored runs chunk by chunk, fast.

A results file stores each run of each signal as one chunk, shuffled and deflated (HDF5's
built-in filters, ``docs/results-format.md``). Through h5py a read decompresses every chunk
in turn on the calling thread, under h5py's lock. :class:`ParallelRuns` reads the same
chunks' bytes straight from the file (their places are listed once per dataset) and inflates
and unshuffles them on worker threads: zlib-ng (the same deflate format as zlib, inflated
about twice as fast: 1.33 against 0.69 GB/s out on a campaign's chunks, python-isal 1.10) and
numpy's copies release the GIL, so the cores share the work, and reading goes on while the
evaluation computes. What it gives back equals h5py's reading bit for bit (float64 whatever
the stored precision); a dataset stored any other way is read through h5py, or mapped when it
is contiguous float64 (format 1, :mod:`idefix_rules.results.mapped`).

:func:`complete_chunks` yields a path's complete runs a chunk at a time from either reader,
so memory is bounded by the chunk size, not the run count.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, Protocol

import h5py
import numpy as np
from zlib_ng import zlib_ng

from idefix_rules.results.format import STATUS_COMPLETE
from idefix_rules.results.mapped import MappedRuns
from idefix_rules.results.reader import StoredResults, damaged, reading

DEFAULT_CHUNK_RUNS = 64


class RunReader(Protocol):
    """What reading runs needs of a results file (:class:`StoredResults` or a stand-in)."""

    def run_status(self, name: str) -> np.ndarray: ...

    def read_runs(self, name: str, selection: slice | np.ndarray,
                  keys: Sequence[str] | None = None) -> dict[str, np.ndarray]: ...


def complete_rows(status: np.ndarray, within: slice | None = None) -> np.ndarray:
    """Row numbers of complete runs, in order (only those in ``within`` when given)."""
    rows = np.flatnonzero(status == STATUS_COMPLETE)
    if within is None:
        return rows
    start, stop, _ = within.indices(status.size)
    return rows[(rows >= start) & (rows < stop)]


def read_rows(store: RunReader, name: str, rows: np.ndarray,
              keys: Sequence[str] | None) -> dict[str, np.ndarray]:
    """The signals ``keys`` (None: all) of the runs ``rows`` (sorted), axis 0 in their order."""
    start, stop = int(rows[0]), int(rows[-1]) + 1
    chunk = store.read_runs(name, slice(start, stop), keys)
    if stop - start == len(rows):  # no gaps: the chunk as read
        return chunk
    offset = rows - start
    return {key: values[offset] for key, values in chunk.items()}


def complete_chunks(store: RunReader, name: str, keys: Sequence[str] | set[str] | None,
                    chunk_runs: int = DEFAULT_CHUNK_RUNS, within: slice | None = None
                    ) -> Iterator[tuple[np.ndarray, dict[str, np.ndarray]]]:
    """``(rows, signals)`` of a path's complete runs (those among the rows ``within``, when
    given), ``chunk_runs`` at a time; ``keys`` None reads every stored signal."""
    complete = complete_rows(store.run_status(name), within)
    wanted = None if keys is None else sorted(keys)
    for begin in range(0, len(complete), chunk_runs):
        rows = complete[begin:begin + chunk_runs]
        yield rows, read_rows(store, name, rows, wanted)


# --- reading stored chunks on threads ----------------------------------------------------------

_SHUFFLE = h5py.h5z.FILTER_SHUFFLE
_DEFLATE = h5py.h5z.FILTER_DEFLATE


@dataclass(frozen=True)
class ChunkLayout:
    """Where each run's chunk of one signal lies in the file and how it is encoded."""

    dtype: np.dtype[Any]
    shape: tuple[int, ...]  # one run
    shuffled: bool
    deflated: bool
    offsets: np.ndarray  # per row, -1 where no chunk is stored
    sizes: np.ndarray
    masks: np.ndarray  # HDF5's filter mask per chunk (0: every filter applied)


def chunk_layout(dataset: h5py.Dataset) -> ChunkLayout | None:
    """The layout of a run dataset whose chunks can be read and decoded here: one run per
    chunk, little-endian float32/float64, filters shuffle and/or deflate only, in a plain
    file. None otherwise (h5py reads it)."""
    if dataset.chunks is None or dataset.chunks != (1, *dataset.shape[1:]):
        return None
    if dataset.dtype.str not in ("<f4", "<f8") or dataset.file.driver != "sec2":
        return None
    plist = dataset.id.get_create_plist()
    filters = [plist.get_filter(i)[0] for i in range(plist.get_nfilters())]
    if filters not in ([], [_DEFLATE], [_SHUFFLE], [_SHUFFLE, _DEFLATE]):
        return None
    rows = dataset.shape[0]
    offsets = np.full(rows, -1, dtype=np.int64)
    sizes = np.zeros(rows, dtype=np.int64)
    masks = np.zeros(rows, dtype=np.int64)

    def take(info: Any) -> None:
        row = int(info.chunk_offset[0])
        if info.byte_offset is not None and row < rows:
            offsets[row], sizes[row], masks[row] = info.byte_offset, info.size, \
                info.filter_mask

    try:
        dataset.id.chunk_iter(take)
    except (AttributeError, RuntimeError, ValueError):  # an HDF5 without chunk iteration
        return None
    return ChunkLayout(dataset.dtype, tuple(dataset.shape[1:]), _SHUFFLE in filters,
                       _DEFLATE in filters, offsets, sizes, masks)


def decode_rows(chunks: Sequence[bytes], layout: ChunkLayout, into: np.ndarray,
                finite: bool = False, complete: np.ndarray | None = None) -> None:
    """Inflate and unshuffle stored chunks, one run each, into ``into`` (runs, …) float64.

    Run by run: a chunk is inflated, its byte planes joined into a buffer of one run (float64
    ones straight into the run's row) and converted into its row. A run's buffer stays in
    the processor's cache; joining and converting a block of runs at once streamed every
    byte through memory twice more.

    A chunk whose stored bytes equal the one before it (the shared time grid, a flag no run
    raised) is the same run again: its row is copied, not inflated. Comparing two chunks of
    different lengths costs nothing, so runs that differ pay nothing for it.

    ``finite``: a row holding a value that is not finite, unless it is all NaN, raises
    :class:`NotFinite` (a stored run's outputs are finite; a row all NaN is the fill of a run
    not stored). ``complete`` (one flag per chunk): the rows of runs stored complete, which
    raise when all NaN too."""
    size = layout.dtype.itemsize
    count = int(np.prod(layout.shape, dtype=np.int64))
    joined = np.empty((count, size), dtype=np.uint8)
    previous: bytes | None = None
    for position, data in enumerate(chunks):
        if previous is not None and data == previous:
            into[position] = into[position - 1]
            continue
        previous = data
        plain = zlib_ng.decompress(data) if layout.deflated else data
        if len(plain) != size * count:
            raise ValueError(f"a stored chunk holds {len(plain)} bytes, {size * count} "
                             "expected")
        stored = np.frombuffer(plain, dtype=np.uint8)
        row = into[position]
        if not layout.shuffled:
            row[...] = stored.view(layout.dtype).reshape(layout.shape)
            continue
        # byte planes: every value's first bytes, then its second bytes …
        direct = row.dtype == layout.dtype and row.flags.c_contiguous
        target = row.reshape(count).view(np.uint8).reshape(count, size) if direct else joined
        planes = stored.reshape(size, count)
        for byte in range(size):
            target[:, byte] = planes[byte]
        if not direct:
            row[...] = joined.view(layout.dtype).reshape(layout.shape)
        # a run is stored only when every output of it is finite (worker.check_outputs): one
        # that is not was changed after it was written (checked while the row is in cache); a
        # row all NaN is the fill of a run not stored (failed, or not simulated yet)
        if finite and not np.isfinite(row).all() and (
                not np.isnan(row).all() or (complete is not None and complete[position])):
            raise NotFinite(position)


class NotFinite(ValueError):
    """A decoded run holds values that are not finite: ``position`` in the chunks given."""

    def __init__(self, position: int) -> None:
        super().__init__(f"run at position {position} holds values that are not finite")
        self.position = position


class ParallelRuns:
    """The run reading of a results file, its chunks decoded on ``threads`` threads (see the
    module docstring). Stands in for :class:`StoredResults` wherever runs are read."""

    def __init__(self, store: StoredResults, threads: int = 2, finite: bool = True) -> None:
        self.store = store
        self.threads = max(1, threads)
        # a run holding a value that is not finite is damage (H004), see decode_rows
        self.finite = finite
        self._layouts: dict[tuple[str, str], ChunkLayout | None] = {}
        self._mapped = MappedRuns(store)  # contiguous datasets (format 1): mapped
        self._file: int | None = None
        self._pool: ThreadPoolExecutor | None = None
        self._lock = threading.Lock()

    def run_status(self, name: str) -> np.ndarray:
        return self.store.run_status(name)

    def _layout(self, name: str, key: str, dataset: h5py.Dataset) -> ChunkLayout | None:
        if (name, key) not in self._layouts:
            self._layouts[(name, key)] = chunk_layout(dataset)
        return self._layouts[(name, key)]

    def _descriptor(self) -> int:
        with self._lock:  # paths may be read from several threads (the diff)
            if self._file is None:
                self._file = os.open(self.store.path, os.O_RDONLY)
            return self._file

    def read_runs(self, name: str, selection: slice | np.ndarray,
                  keys: Sequence[str] | None = None) -> dict[str, np.ndarray]:
        """Like :meth:`StoredResults.read_runs` (float64, axis 0 the selected rows)."""
        with reading(self.store.path, f"/paths/{name}/runs/signals"):
            return self._read_runs(name, selection, keys)

    def _read_runs(self, name: str, selection: slice | np.ndarray,
                   keys: Sequence[str] | None) -> dict[str, np.ndarray]:
        datasets = self.store.path_group(name)["runs"]["signals"]
        wanted = list(datasets) if keys is None else [k for k in keys if k in datasets]
        out: dict[str, np.ndarray] = {}
        jobs: list[tuple[str, ChunkLayout, np.ndarray, np.ndarray]] = []
        # the runs stored complete: their rows are finite, even where all of one is NaN
        status = self.store.run_status(name) if self.finite else None
        for key in wanted:
            dataset = datasets[key]
            if isinstance(selection, slice):
                rows = np.arange(*selection.indices(dataset.shape[0]))
            else:
                rows = np.sort(np.asarray(selection, dtype=np.int64))
            layout = self._layout(name, key, dataset)
            usable = layout is not None and rows.size > 0 \
                and bool(np.all(layout.offsets[rows] >= 0)) and not layout.masks[rows].any()
            if not usable or layout is None:
                out[key] = self._mapped.read_runs(name, selection, [key])[key]
                if status is not None:  # mapped (format 1) or read by HDF5: checked here
                    self._check_finite(name, key, out[key], rows, status)
                continue
            out[key] = np.empty((rows.size, *layout.shape), dtype=np.float64)
            jobs.append((key, layout, rows, out[key]))
        self._decode(name, jobs, status)
        return out

    def _check_finite(self, name: str, key: str, values: np.ndarray, rows: np.ndarray,
                      status: np.ndarray) -> None:
        """H004 when a row of a run stored complete holds a value that is not finite (as
        :func:`decode_rows` checks the rows it decodes)."""
        complete = status[rows] == STATUS_COMPLETE if rows.size else np.zeros(0, dtype=bool)
        if not complete.any():
            return
        flat = np.asarray(values).reshape(len(rows), -1)
        bad = np.flatnonzero(complete & ~np.isfinite(flat).all(axis=1))
        if bad.size:
            raise damaged(self.store.path, f"/paths/{name}/runs/signals/{key}",
                          f"run {int(rows[bad[0]])} holds values that are not finite, which "
                          "no stored run does")

    def _decode(self, name: str,
                jobs: list[tuple[str, ChunkLayout, np.ndarray, np.ndarray]],
                status: np.ndarray | None = None) -> None:
        """Read and decode every (layout, rows, output) job, split over the threads
        (``status``: the path's run states, to check the complete runs' rows)."""
        descriptor = self._descriptor()
        parts = [(key, layout, rows[i::self.threads], target[i::self.threads])
                 for key, layout, rows, target in jobs for i in range(self.threads)
                 if rows[i::self.threads].size]

        def run(part: tuple[str, ChunkLayout, np.ndarray, np.ndarray]) -> None:
            key, layout, rows, target = part
            try:
                decode_rows([os.pread(descriptor, int(layout.sizes[row]),
                                      int(layout.offsets[row])) for row in rows], layout, target,
                            self.finite, None if status is None
                            else status[rows] == STATUS_COMPLETE)
            except NotFinite as bad:
                raise damaged(self.store.path, f"/paths/{name}/runs/signals/{key}",
                              f"run {int(rows[bad.position])} holds values that are not "
                              "finite, which no stored run does") from None

        if self.threads == 1 or len(parts) <= 1:
            for part in parts:
                run(part)
            return
        with self._lock:
            if self._pool is None:
                self._pool = ThreadPoolExecutor(self.threads, thread_name_prefix="results")
            pool = self._pool
        for future in [pool.submit(run, part) for part in parts]:
            future.result()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
        if self._file is not None:
            os.close(self._file)
            self._file = None
        self._layouts.clear()
        self._mapped.close()

    def __enter__(self) -> ParallelRuns:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
