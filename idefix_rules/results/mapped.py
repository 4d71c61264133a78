"""Reading stored runs without copying them: run datasets mapped into memory.

Results files of format 1 store every run dataset contiguous, uncompressed and allocated when
its path starts, so its bytes sit at a fixed offset of the file and numpy can map them
(:class:`numpy.memmap`, copy-on-write: the file is never written). A chunk of runs is then a
map of its rows; the evaluator touches only the samples it reads, straight from the page cache,
instead of HDF5 copying every value into a new array first. Datasets that are chunked,
compressed (format 2 and later: ``docs/results-format.md``), not native float64 or in a file
driver other than the default are read through h5py, a chunk of rows at a time, as float64
(:class:`~idefix_rules.results.runs.ParallelRuns` maps through this module what it can).

:class:`MappedRuns` stands in for :class:`~idefix_rules.results.reader.StoredResults` where
:func:`~idefix_rules.results.runs.complete_chunks` reads runs.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from idefix_rules.results.reader import StoredResults


def mappable(dataset: h5py.Dataset) -> int | None:
    """File offset of a dataset's bytes when it can be mapped, else None."""
    if dataset.chunks is not None or dataset.compression is not None or dataset.external:
        return None
    if dataset.dtype != np.dtype("<f8") or dataset.file.driver != "sec2":
        return None
    if dataset.size == 0:
        return None
    offset: int | None = dataset.id.get_offset()
    return offset


class MappedRuns:
    """The run reading of a :class:`StoredResults`, through memory maps where possible.

    Each read maps only the rows it covers, so what stays mapped is bounded by the chunks in
    use (a view keeps its map alive; the map goes when the chunk's arrays do).
    """

    def __init__(self, store: StoredResults) -> None:
        self.store = store
        self.filename = Path(store.file.filename)
        self._offsets: dict[tuple[str, str], int | None] = {}

    def run_status(self, name: str) -> np.ndarray:
        return self.store.run_status(name)

    def _rows(self, name: str, key: str, dataset: h5py.Dataset, start: int,
              stop: int) -> np.ndarray:
        if (name, key) not in self._offsets:
            self._offsets[(name, key)] = mappable(dataset)
        offset = self._offsets[(name, key)]
        if offset is None:  # chunked and compressed (format 2): decompressed rows, float64
            return np.asarray(dataset[start:stop], dtype=np.float64)
        row_bytes = dataset.dtype.itemsize * int(np.prod(dataset.shape[1:], dtype=np.int64))
        return np.memmap(self.filename, dtype=dataset.dtype, mode="c",
                         offset=offset + start * row_bytes,
                         shape=(stop - start, *dataset.shape[1:]))

    def read_runs(self, name: str, selection: slice | np.ndarray,
                  keys: Sequence[str] | None = None) -> dict[str, np.ndarray]:
        """Like :meth:`StoredResults.read_runs`; mapped datasets come back as maps of the rows."""
        datasets = self.store.path_group(name)["runs"]["signals"]
        wanted = list(datasets) if keys is None else [k for k in keys if k in datasets]
        out: dict[str, Any] = {}
        for key in wanted:
            dataset = datasets[key]
            if isinstance(selection, slice):
                start, stop, step = selection.indices(dataset.shape[0])
                rows = self._rows(name, key, dataset, start, max(start, stop))
                out[key] = rows if step == 1 else rows[::step]
            else:
                chosen = np.sort(selection)
                if chosen.size == 0:
                    out[key] = np.asarray(dataset[chosen], dtype=np.float64)
                    continue
                first, last = int(chosen[0]), int(chosen[-1]) + 1
                out[key] = np.asarray(self._rows(name, key, dataset, first, last)[chosen - first])
        return out

    def close(self) -> None:
        self._offsets.clear()
