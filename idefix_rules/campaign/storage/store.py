"""The results file (``results.h5``): layout in ``docs/results-format.md``.

Only the parent process writes. A path's run datasets are allocated a block of rows at a time
(:func:`~idefix_rules.campaign.storage.dataset_layout.allocated_rows`: 64, then doubling up to
4,096 more at a time), so planning a million runs costs almost no disk before the first one is
stored: run signals chunked one run per chunk, shuffled and gzip-compressed (HDF5 built-in
filters), grown along the run axis with every chunk of a block allocated (filled with NaN) when
the block is; ``status``, ``failure`` and ``parameters`` have a row for every planned run and a
chunk per 64 rows, uncompressed, written (with their fill values, or the sampled values) when the
block holding those rows is allocated.
Writing a run replaces its own chunks only: the chunk indexes already hold an entry for every
allocated run, so a write updates entries in place and never adds index nodes or objects; only
a block allocation changes the file's structure, after a flush and after checking the free
space (:mod:`idefix_rules.campaign.storage.diskspace`). Each run is written as its data, then its
``status`` entry (1 complete, 2 failed), then a flush: a kill at any moment leaves every run
either complete-and-valid or not marked complete, which ``--resume`` re-runs
(``tests/campaign/test_campaign_store_kill.py`` kills a writer at random moments to check it).

Signals are stored with the precision they need (:func:`storage_dtype`): the planar position,
heading and time, which the evaluator differentiates, as float64; the per-wheel signals, the
tilt angles, the height, the charge and the integer-valued ``command`` / ``stuck`` as float32
(docs/results-format.md gives the error).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from idefix_rules.campaign.storage import diskspace
from idefix_rules.campaign.storage.dataset_layout import (
    HEADER_BYTES,
    INDEX_BYTES_PER_CHUNK,
    JOURNAL_BYTES_PER_DATASET,
    REASON_DTYPE,
    ROW_CHUNK,
    allocated_rows,
    early_dcpl,
    encode_reason,
    row_bytes,
    row_dataset,
    signal_attrs,
    write_rows,
)
from idefix_rules.campaign.storage.encoded_chunks import EncodedChunk, decode_chunk
from idefix_rules.campaign.storage.journal import JournaledFile, repair_end, roll_back, undo_path
from idefix_rules.commands import Command
from idefix_rules.results.format import (
    CHAIN_COLUMNS,
    CHAIN_UNITS,
    COMPRESSION,
    COMPRESSION_LEVEL,
    FLOAT32_SIGNALS,
    FORMAT,
    FORMAT_VERSION,
    RESUMABLE_FORMAT_VERSIONS,
    STATUS_COMPLETE,
    STATUS_FAILED,
    STATUS_MISSING,
    STATUS_NOT_NEEDED,
    decode_reason,
    storage_dtype,
)
from idefix_rules.results.reader import StoredResults

# The format's names, for the writer's callers (defined in idefix_rules.results.format).
__all__ = ["CHAIN_COLUMNS", "CHAIN_UNITS", "COMPRESSION", "COMPRESSION_LEVEL",
           "FLOAT32_SIGNALS", "FORMAT", "FORMAT_VERSION", "RESUMABLE_FORMAT_VERSIONS",
           "STATUS_COMPLETE", "STATUS_FAILED", "STATUS_MISSING", "STATUS_NOT_NEEDED",
           "ResultStore", "decode_reason", "previous_results_path", "storage_dtype"]


def previous_results_path(path: Path) -> Path:
    """Where :meth:`ResultStore.create` keeps the results file it replaces."""
    return path.with_name(f"{path.stem}.previous{path.suffix}")


class ResultStore(StoredResults):
    """Writer of one ``results.h5`` (and its reader: :class:`StoredResults`)."""

    def __init__(self, file: h5py.File, path: Path | None = None) -> None:
        super().__init__(file, path)
        # Open dataset handles per path: looking them up by name costs more than the write.
        self._handles: dict[str, tuple[dict[str, h5py.Dataset], h5py.Dataset, h5py.Dataset]] = {}
        # The sampled parameters of each path's planned runs, written a block at a time, and
        # the rows allocated so far.
        self._plans: dict[str, dict[str, np.ndarray]] = {}
        self._allocated: dict[str, int] = {}

    def _require(self, needed: int, doing: str) -> None:
        diskspace.require(self.folder, needed, doing)

    @contextlib.contextmanager
    def _structural(self, needed: int, doing: str, datasets: int) -> Iterator[None]:
        """A change of the file's structure (``needed`` bytes), all or nothing: checked
        against the free space, made after a flush of what is stored so far with the file
        reopened through an undo journal (:mod:`idefix_rules.campaign.storage.journal`), flushed and
        closed before the journal is dropped. Cut off by an error it is rolled back at once
        (and the store closed); cut off by a kill, the next writer rolls it back. ``datasets``
        is the number of datasets it changes (the journal's size)."""
        needed += JOURNAL_BYTES_PER_DATASET * (datasets + 1)
        self._require(needed, doing)
        self._handles.clear()
        self.file.close()
        journal = JournaledFile(self.path)
        try:
            journal.begin()
            self.file = h5py.File(journal, "r+")
            yield
            self.file.close()
        except BaseException:
            journal.discard()
            with contextlib.suppress(Exception):
                self.file.close()
            journal.close()
            roll_back(self.path)
            raise
        failure = journal.failure
        journal.close()
        if failure is not None:
            roll_back(self.path)
            if diskspace.is_disk_full(failure):
                raise diskspace.DiskFull(self.folder, diskspace.free_bytes(self.folder),
                                         needed + diskspace.MARGIN, doing) from None
            raise failure
        undo_path(self.path).unlink(missing_ok=True)  # the change is complete on disk
        # No HDF5 file lock: worker processes forked while the file was open share the one
        # taken then (the output folder's lock keeps other campaigns out).
        self.file = h5py.File(self.path, "r+", locking=False)

    def structural_change(self, needed: int, doing: str, datasets: int
                          ) -> contextlib.AbstractContextManager[None]:
        """A change of the file's structure other than the runs' (``needed`` bytes, changing
        ``datasets`` existing datasets), made all or nothing through the undo journal as a
        block allocation is; ``self.file`` is open to write inside the ``with`` block."""
        return self._structural(needed, doing, datasets)

    def _run_handles(self, name: str) -> tuple[dict[str, h5py.Dataset], h5py.Dataset,
                                               h5py.Dataset]:
        handles = self._handles.get(name)
        if handles is None:
            group = self.path_group(name)["runs"]
            datasets = {key: group["signals"][key] for key in group["signals"]}
            handles = (datasets, group["status"], group["failure"])
            self._handles[name] = handles
        return handles

    # --- opening ----------------------------------------------------------------------------

    @classmethod
    def create(cls, path: Path, attrs: Mapping[str, Any],
               texts: Mapping[str, str]) -> ResultStore:
        """A new results file. An existing one is kept as ``<stem>.previous.h5`` (replacing an
        older copy), so a re-run that fails early never loses the last campaign's results."""
        path.parent.mkdir(parents=True, exist_ok=True)
        previous = previous_results_path(path)
        # a change cut off by a kill is undone in the file it was made in, wherever it now is
        roll_back(path if path.is_file() else previous, undo_path(path))
        if path.is_file():
            path.replace(previous)
        text_bytes = sum(len(text.encode("utf-8")) for text in texts.values())
        diskspace.require(path.parent, 8 * HEADER_BYTES + text_bytes, f"create {path.name}")
        file = h5py.File(path, "w", track_order=True)
        file.attrs["format"] = FORMAT
        file.attrs["format_version"] = FORMAT_VERSION
        for key, value in attrs.items():
            file.attrs[key] = value
        provenance = file.create_group("provenance")
        for key, text in texts.items():
            provenance.create_dataset(key, data=text, dtype=h5py.string_dtype("utf-8"))
        file.create_group("paths", track_order=True)
        file.flush()
        return cls(file, path)

    @classmethod
    def open(cls, path: Path, writable: bool = False) -> ResultStore:
        """Open an existing results file; :class:`UserInputError` if it is not one. Opened to
        write, a structural change a kill cut off is rolled back first
        (:func:`~idefix_rules.campaign.storage.journal.roll_back`)."""
        if writable:
            roll_back(path)
            repair_end(path)
        store = cls.opened(Path(path), "r+" if writable else "r", damaged_hint=(
            "a file damaged while its structure was being written cannot be resumed: run the "
            "campaign again without --resume") if writable else None)
        assert isinstance(store, ResultStore)
        return store

    def close(self) -> None:
        """Flush and close (closed also when the flush fails, e.g. on a full disk)."""
        self._handles.clear()
        self._allocated.clear()
        if self.file.id.valid:
            try:
                self.file.flush()
            finally:
                self.file.close()

    # --- paths ------------------------------------------------------------------------------

    def create_path(self, name: str, index: int, chain: Sequence[Command],
                    attrs: Mapping[str, Any]) -> h5py.Group:
        self._require(2 * HEADER_BYTES, f"store path {name!r}")
        group = self.file["paths"].create_group(name)
        group.attrs["index"] = index
        for key, value in attrs.items():
            group.attrs[key] = value
        table = np.array([[c.max_wheel_rate, c.delta_position, c.delta_heading] for c in chain],
                         dtype=np.float64).reshape(-1, 3)
        dataset = group.create_dataset("chain", data=table)
        dataset.attrs["columns"] = list(CHAIN_COLUMNS)
        dataset.attrs["units"] = list(CHAIN_UNITS)
        self.file.flush()
        return group

    def set_path_status(self, name: str, status: str, reason: str = "") -> None:
        self._require(len(reason.encode("utf-8")), f"store the status of path {name!r}")
        group = self.path_group(name)
        group.attrs["status"] = status
        group.attrs["reason"] = reason
        self.file.flush()

    def write_reference(self, name: str, signals: Mapping[str, np.ndarray] | None,
                        parameters: Mapping[str, float], reason: str = "") -> None:
        size = sum(np.asarray(values).size * 8 for values in (signals or {}).values())
        self._require(HEADER_BYTES * (3 + len(signals or {})) + size,
                      f"store the reference run of path {name!r}")
        group = self.path_group(name).create_group("reference")
        params = group.create_group("parameters")
        for key, value in parameters.items():
            params.attrs[key] = value
        if signals is not None:
            data = group.create_group("signals", track_order=True)
            for key, values in signals.items():
                dataset = data.create_dataset(key, data=np.asarray(values, dtype=np.float64),
                                              compression=COMPRESSION, shuffle=True,
                                              compression_opts=COMPRESSION_LEVEL)
                for attr, attr_value in signal_attrs(key).items():
                    dataset.attrs[attr] = attr_value
        group.attrs["status"] = STATUS_COMPLETE if signals is not None else STATUS_FAILED
        group.attrs["failure"] = reason
        self.file.flush()

    def allocate_runs(self, name: str, runs: int, shapes: Mapping[str, tuple[int, ...]],
                      parameters: Mapping[str, np.ndarray],
                      parameter_info: Mapping[str, Mapping[str, Any]]) -> None:
        """Create a path's run datasets for ``runs`` planned runs with the first block of rows
        allocated (:func:`allocated_rows`), then flush; later blocks are allocated as runs
        need them. ``parameters`` are the sampled values of every planned run; each block
        stores its rows' values. When an earlier process (``--resume``) created them already,
        only ``parameters`` are taken up for the blocks still to come."""
        if self.has_runs(name):
            self._plans[name] = {key: np.asarray(values) for key, values in parameters.items()}
            return
        self._handles.pop(name, None)
        self._allocated.pop(name, None)
        rows = allocated_rows(1, runs)
        with self._structural(HEADER_BYTES * (5 + len(shapes) + len(parameters))
                              + rows * row_bytes(shapes, len(parameters)),
                              f"allocate the runs of path {name!r}", 0):
            self._create_runs(name, runs, rows, shapes, parameters, parameter_info)

    def _create_runs(self, name: str, runs: int, rows: int,
                     shapes: Mapping[str, tuple[int, ...]],
                     parameters: Mapping[str, np.ndarray],
                     parameter_info: Mapping[str, Mapping[str, Any]]) -> None:
        path_group = self.path_group(name)
        if "runs" in path_group:  # allocation cut off by a kill: no run was written yet
            del path_group["runs"]
        group = path_group.create_group("runs")
        group.attrs["count"] = runs
        signals = group.create_group("signals", track_order=True)
        for key, shape in shapes.items():
            # One run per chunk, every chunk of a block allocated with it: a run's write
            # touches its own chunk and index entry only (see the module docstring).
            dataset = signals.create_dataset(key, shape=(rows, *shape),
                                             maxshape=(runs, *shape), dtype=storage_dtype(key),
                                             fillvalue=np.nan, chunks=(1, *shape),
                                             compression=COMPRESSION,
                                             compression_opts=COMPRESSION_LEVEL, shuffle=True,
                                             dcpl=early_dcpl())
            for attr, value in signal_attrs(key).items():
                dataset.attrs[attr] = value
        params = group.create_group("parameters", track_order=True)
        self._plans[name] = {key: np.asarray(values) for key, values in parameters.items()}
        for key in parameters:
            dataset = row_dataset(params, key, runs, np.float64, np.nan)
            dataset[:rows] = np.asarray(self._plans[name][key][:rows], dtype=np.float64)
            for attr, value in parameter_info.get(key, {}).items():
                dataset.attrs[attr] = value
        row_dataset(group, "failure", runs, REASON_DTYPE, b"")
        # The status is created last: its presence means the run datasets all exist (and the
        # first block's parameters are stored).
        row_dataset(group, "status", runs, np.int8, STATUS_MISSING)
        write_rows(group, 0, rows, self._plans[name])

    def _ensure_rows(self, name: str, needed: int) -> None:
        """Allocate the blocks of rows up to row ``needed - 1`` of a path's runs: the
        per-row datasets' rows first (so a block cut off by a kill is written again), then
        the signals grow; a flush before and after."""
        if needed <= self._allocated.get(name, 0):
            return
        datasets, _, _ = self._run_handles(name)
        group = self.path_group(name)["runs"]
        allocated = next(iter(datasets.values())).shape[0] if datasets \
            else int(group["status"].shape[0])
        self._allocated[name] = allocated
        if needed <= allocated:
            return
        runs = int(group.attrs.get("count", group["status"].shape[0]))
        rows = allocated_rows(needed, runs)
        shapes = {key: tuple(dataset.shape[1:]) for key, dataset in datasets.items()}
        with self._structural((rows - allocated)
                              * row_bytes(shapes, len(group["parameters"])),
                              f"allocate runs {allocated + 1}-{rows} of path {name!r}",
                              len(shapes) + len(group["parameters"]) + 2):
            group = self.path_group(name)["runs"]  # (the file was opened anew)
            write_rows(group, allocated, rows, self._plans.get(name, {}))
            for dataset in group["signals"].values():
                dataset.resize(rows, axis=0)
        self._allocated[name] = rows

    def set_parameters(self, name: str, start: int, values: Mapping[str, np.ndarray]) -> None:
        """The parameter values of rows ``start …`` of a path's runs when they are chosen as
        the path runs (a worst-case search), not planned up front: kept for the blocks of rows
        still to allocate, and written in place into rows already allocated (their chunks
        exist: raw data, like a run's status). Every key must be a parameter given to
        :meth:`allocate_runs`."""
        plans = self._plans[name]
        count = 0
        for key, array in values.items():
            row_values = np.asarray(array, dtype=np.float64)
            count = row_values.size
            plans[key] = np.array(plans[key], dtype=np.float64)  # a copy this store may write
            plans[key][start:start + count] = row_values
        datasets, _, _ = self._run_handles(name)
        group = self.path_group(name)["runs"]
        allocated = next(iter(datasets.values())).shape[0] if datasets \
            else int(group["status"].shape[0])
        stop = min(start + count, allocated)
        if stop > start:
            for key in values:
                group["parameters"][key][start:stop] = plans[key][start:stop]
            self.file.flush()

    def write_run(self, name: str, run: int,
                  signals: Mapping[str, np.ndarray | EncodedChunk]) -> None:
        """Store one complete run: its data (arrays, or chunks :func:`encode_run` made), a
        flush, its status, a flush."""
        self._ensure_rows(name, run + 1)
        datasets, status, _ = self._run_handles(name)
        for key, dataset in datasets.items():
            value = signals[key]
            if isinstance(value, EncodedChunk):
                if value.shape != dataset.shape[1:]:
                    raise ValueError(f"signal {key!r} of run {run} has shape {value.shape} "
                                     f"{value.dtype}, the dataset stores {dataset.shape[1:]} "
                                     f"{dataset.dtype}")
                if np.dtype(value.dtype) != dataset.dtype:
                    # a dataset an earlier format made (z and energy were float64 before
                    # format 5), continued by --resume: the values in its precision
                    dataset[run] = decode_chunk(value).astype(dataset.dtype)
                else:
                    dataset.id.write_direct_chunk((run,) + (0,) * len(value.shape), value.data)
            else:
                dataset[run] = np.asarray(value, dtype=dataset.dtype)
        self.file.flush()
        status[run] = STATUS_COMPLETE
        self.file.flush()

    def write_failure(self, name: str, run: int, reason: str) -> None:
        self._ensure_rows(name, run + 1)
        _, status, failure = self._run_handles(name)
        failure[run] = encode_reason(reason)
        self.file.flush()
        status[run] = STATUS_FAILED
        self.file.flush()

    def unmark_not_needed(self, name: str) -> None:
        """Rows marked not needed are missing again (an adaptive campaign replays its looks,
        which mark them again where the path stops)."""
        _, status, _ = self._run_handles(name)
        current = status[()]
        if np.any(current == STATUS_NOT_NEEDED):
            status[...] = np.where(current == STATUS_NOT_NEEDED, STATUS_MISSING, current)
            self.file.flush()

    def mark_not_needed(self, name: str, first: int) -> None:
        """Rows from ``first`` on that are still missing will never be simulated: an adaptive
        campaign stopped the path (raw data written in place, like a run's status)."""
        _, status, _ = self._run_handles(name)
        current = status[first:]
        if not current.size:
            return
        # rows never allocated get their chunks now: one byte and an index share each
        with self._structural(current.size * (1 + INDEX_BYTES_PER_CHUNK // ROW_CHUNK + 1),
                              f"mark the rows of path {name!r} an adaptive campaign did not "
                              "need", 1):
            self.path_group(name)["runs"]["status"][first:] = np.where(
                current == STATUS_MISSING, STATUS_NOT_NEEDED, current)
