"""Reading stored runs without copying them: run datasets mapped into memory.

The results file stores every run dataset contiguous, uncompressed and allocated when its path
starts (``docs/results-format.md``), so its bytes sit at a fixed offset of the file and numpy
can map them (:class:`numpy.memmap`, copy-on-write: the file is never written). A chunk of runs
is then a view; the evaluator touches only the samples it reads, straight from the page cache,
instead of HDF5 copying every value into a new array first. Datasets that are chunked,
compressed, not native float64 or in a file driver other than the default fall back to h5py.

:class:`MappedRuns` stands in for :class:`~idefix_rules.campaign.store.ResultStore` where
:func:`~idefix_rules.campaign.evaluation.complete_chunks` reads runs.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from idefix_rules.campaign.store import ResultStore


def mapped(dataset: h5py.Dataset, filename: Path) -> np.ndarray | None:
    """The dataset as a copy-on-write memory map, or None when it cannot be mapped."""
    if dataset.chunks is not None or dataset.compression is not None or dataset.external:
        return None
    if dataset.dtype != np.dtype("<f8") or dataset.file.driver != "sec2":
        return None
    offset = dataset.id.get_offset()
    if offset is None or dataset.size == 0:
        return None
    return np.memmap(filename, dtype=dataset.dtype, mode="c", offset=offset,
                     shape=dataset.shape)


class MappedRuns:
    """The run reading of a :class:`ResultStore`, through memory maps where possible."""

    def __init__(self, store: ResultStore) -> None:
        self.store = store
        self.filename = Path(store.file.filename)
        self._maps: dict[tuple[str, str], np.ndarray | None] = {}

    def run_status(self, name: str) -> np.ndarray:
        return self.store.run_status(name)

    def _map(self, name: str, key: str, dataset: h5py.Dataset) -> np.ndarray | None:
        if (name, key) not in self._maps:
            self._maps[(name, key)] = mapped(dataset, self.filename)
        return self._maps[(name, key)]

    def read_runs(self, name: str, selection: slice | np.ndarray,
                  keys: Sequence[str] | None = None) -> dict[str, np.ndarray]:
        """Like :meth:`ResultStore.read_runs`; mapped datasets come back as views."""
        datasets = self.store.path_group(name)["runs"]["signals"]
        wanted = list(datasets) if keys is None else [k for k in keys if k in datasets]
        if isinstance(selection, np.ndarray):
            selection = np.sort(selection)
        out: dict[str, Any] = {}
        for key in wanted:
            view = self._map(name, key, datasets[key])
            out[key] = view[selection] if view is not None else datasets[key][selection]
        return out

    def close(self) -> None:
        self._maps.clear()
