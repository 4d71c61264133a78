"""The results file (``results.h5``): layout in ``docs/results-format.md``.

Only the parent process writes. A path's datasets are created in full and flushed before its
first run is written: run signals chunked one run per chunk, shuffled and gzip-compressed (HDF5
built-in filters), with every chunk allocated at creation; ``status`` and ``failure``
contiguous. Writing a run replaces its own chunks only: the dataset's chunk index already holds
an entry for every run, so a write updates entries in place and never adds index nodes or
objects. Each run is written as its data, then its ``status`` entry (1 complete, 2 failed), then
a flush: a kill at any moment leaves every run either complete-and-valid or not marked complete,
which ``--resume`` re-runs (``tests/campaign/test_campaign_store_kill.py`` kills a writer at
random moments to check it).

Signals are stored with the precision they need (:func:`storage_dtype`): the pose, time and
energy signals, which the evaluator differentiates, as float64; the per-wheel signals and the
integer-valued ``command`` / ``stuck`` as float32 (docs/results-format.md gives the error).
"""

from __future__ import annotations

import json
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from idefix_rules.commands import Command
from idefix_rules.errors import Span, UserInputError, error
from idefix_rules.signals import lookup

FORMAT = "idefix-results"
FORMAT_VERSION = 2

STATUS_MISSING = 0
STATUS_COMPLETE = 1
STATUS_FAILED = 2
STATUS_NOT_NEEDED = 3  # an adaptive campaign stopped its path before this run

# Read through max / percentile / comparisons or as small angles, never differentiated as
# large values: float32 keeps them to 6e-8 of their value (a tilt of 0.1 rad to 6e-9 rad), far
# inside any rulebook tolerance (docs/results-format.md).
FLOAT32_SIGNALS = frozenset({"wheel.rate", "wheel.slip", "wheel.slip_angle", "wheel.sinkage",
                             "wheel.current", "command", "stuck", "roll", "pitch"})
COMPRESSION = "gzip"
COMPRESSION_LEVEL = 1

REASON_BYTES = 240
_REASON_DTYPE = f"S{REASON_BYTES}"

CHAIN_COLUMNS = ("max_wheel_rate", "delta_position", "delta_heading")
CHAIN_UNITS = ("rad/s", "m", "rad")


def _early_dcpl() -> h5py.h5p.PropDCID:
    dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
    dcpl.set_alloc_time(h5py.h5d.ALLOC_TIME_EARLY)
    # Write the fill value when the space is allocated, also without a user-defined one: space
    # freed by an allocation cut off by a kill is reused, and must not show its old bytes.
    dcpl.set_fill_time(h5py.h5d.FILL_TIME_ALLOC)
    return dcpl


def storage_dtype(name: str) -> np.dtype[Any]:
    """The dtype a run signal is stored with (float32 where that is enough, else float64)."""
    return np.dtype(np.float32 if name in FLOAT32_SIGNALS else np.float64)


@dataclass(frozen=True)
class EncodedChunk:
    """One run of one signal as the bytes of its stored chunk (shuffled, deflated): what the
    HDF5 filters would write, made where the run was simulated so the writer only copies."""

    shape: tuple[int, ...]
    dtype: str
    data: bytes


def encode_chunk(name: str, values: np.ndarray) -> EncodedChunk:
    """The chunk of one run of signal ``name`` (HDF5 shuffle, then deflate at
    :data:`COMPRESSION_LEVEL`), readable by any HDF5 tool like a chunk HDF5 wrote itself."""
    array = np.ascontiguousarray(values, dtype=storage_dtype(name))
    shuffled = array.view(np.uint8).reshape(-1, array.itemsize).T.tobytes()
    return EncodedChunk(array.shape, array.dtype.str, zlib.compress(shuffled, COMPRESSION_LEVEL))


def encode_run(signals: Mapping[str, np.ndarray]) -> dict[str, EncodedChunk]:
    """Every signal of one run encoded as its stored chunk."""
    return {name: encode_chunk(name, values) for name, values in signals.items()}


def encode_reason(reason: str) -> bytes:
    data = reason.encode("utf-8")[:REASON_BYTES]
    return data.decode("utf-8", errors="ignore").encode("utf-8")


def decode_reason(value: bytes) -> str:
    return bytes(value).rstrip(b"\0").decode("utf-8", errors="replace")


def signal_attrs(name: str) -> dict[str, Any]:
    spec = lookup(name)
    if spec is None:
        return {"unit": "", "axes": json.dumps(["time"])}
    return {"unit": spec.unit, "axes": json.dumps(list(spec.axes))}


def previous_results_path(path: Path) -> Path:
    """Where :meth:`ResultStore.create` keeps the results file it replaces."""
    return path.with_name(f"{path.stem}.previous{path.suffix}")


class ResultStore:
    """Writer and reader of one ``results.h5``."""

    def __init__(self, file: h5py.File) -> None:
        self.file = file
        # Open dataset handles per path: looking them up by name costs more than the write.
        self._handles: dict[str, tuple[dict[str, h5py.Dataset], h5py.Dataset, h5py.Dataset]] = {}

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
        if path.is_file():
            path.replace(previous_results_path(path))
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
        return cls(file)

    @classmethod
    def open(cls, path: Path, writable: bool = False) -> ResultStore:
        """Open an existing results file; :class:`UserInputError` if it is not one."""
        try:
            file = h5py.File(path, "r+" if writable else "r")
        except FileNotFoundError:
            raise UserInputError(error("H001", f"results file {path} not found",
                                       Span(str(path)))) from None
        except IsADirectoryError:
            raise UserInputError(error("H002", f"cannot open results file {path}: a folder",
                                       Span(str(path)), hint="give its results.h5")) from None
        except OSError as failure:
            if not h5py.is_hdf5(path):
                raise UserInputError(error(
                    "H002", f"cannot open results file {path}: not an HDF5 file", Span(str(path)),
                    hint="give the results.h5 a campaign run wrote")) from None
            raise UserInputError(error(
                "H002", f"cannot open results file {path}: {failure}", Span(str(path)),
                hint="a file damaged while its structure was being written cannot be resumed: "
                     "run the campaign again without --resume" if writable else None)) from None
        if file.attrs.get("format") != FORMAT:
            file.close()
            raise UserInputError(error("H003", f"{path} is not an idefix results file",
                                       Span(str(path))))
        missing = [name for name in ("provenance", "paths") if name not in file]
        if missing:
            file.close()
            raise UserInputError(error("H003", f"{path} is an incomplete idefix results file "
                                               f"(no {' or '.join(missing)} group)",
                                       Span(str(path)), hint="run the campaign again"))
        return cls(file)

    def close(self) -> None:
        self._handles.clear()
        if self.file.id.valid:
            self.file.flush()
            self.file.close()

    @property
    def attrs(self) -> h5py.AttributeManager:
        return self.file.attrs

    def text(self, key: str) -> str:
        value = self.file["provenance"][key][()]
        return value.decode("utf-8") if isinstance(value, bytes) else str(value)

    # --- paths ------------------------------------------------------------------------------

    @property
    def path_names(self) -> list[str]:
        group = self.file["paths"]
        return sorted(group, key=lambda name: int(group[name].attrs["index"]))

    def path_group(self, name: str) -> h5py.Group:
        return self.file["paths"][name]

    def has_path(self, name: str) -> bool:
        return name in self.file["paths"]

    def create_path(self, name: str, index: int, chain: Sequence[Command],
                    attrs: Mapping[str, Any]) -> h5py.Group:
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
        group = self.path_group(name)
        group.attrs["status"] = status
        group.attrs["reason"] = reason
        self.file.flush()

    def write_reference(self, name: str, signals: Mapping[str, np.ndarray] | None,
                        parameters: Mapping[str, float], reason: str = "") -> None:
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

    def reference(self, name: str) -> dict[str, np.ndarray] | None:
        group = self.path_group(name).get("reference")
        if group is None or group.attrs.get("status") != STATUS_COMPLETE:
            return None
        return {key: dataset[()] for key, dataset in group["signals"].items()}

    def allocate_runs(self, name: str, runs: int, shapes: Mapping[str, tuple[int, ...]],
                      parameters: Mapping[str, np.ndarray],
                      parameter_info: Mapping[str, Mapping[str, Any]]) -> None:
        """Create every dataset of a path's runs at full size, then flush."""
        path_group = self.path_group(name)
        if "runs" in path_group:  # allocation cut off by a kill: no run was written yet
            del path_group["runs"]
        group = path_group.create_group("runs")
        group.attrs["count"] = runs
        signals = group.create_group("signals", track_order=True)
        for key, shape in shapes.items():
            # One run per chunk, every chunk allocated now: a run's write touches its own chunk
            # and index entry only (see the module docstring).
            dataset = signals.create_dataset(key, shape=(runs, *shape), dtype=storage_dtype(key),
                                             fillvalue=np.nan, chunks=(1, *shape),
                                             compression=COMPRESSION,
                                             compression_opts=COMPRESSION_LEVEL, shuffle=True,
                                             dcpl=_early_dcpl())
            for attr, value in signal_attrs(key).items():
                dataset.attrs[attr] = value
        params = group.create_group("parameters", track_order=True)
        for key, values in parameters.items():
            dataset = params.create_dataset(key, data=np.asarray(values, dtype=np.float64))
            for attr, value in parameter_info.get(key, {}).items():
                dataset.attrs[attr] = value
        group.create_dataset("failure", shape=(runs,), dtype=_REASON_DTYPE, fillvalue=b"",
                             dcpl=_early_dcpl())
        # The status is created last: its presence means the run datasets all exist.
        group.create_dataset("status", shape=(runs,), dtype=np.int8, fillvalue=STATUS_MISSING,
                             dcpl=_early_dcpl())
        self.file.flush()

    def has_runs(self, name: str) -> bool:
        group = self.path_group(name).get("runs")
        return group is not None and "status" in group

    def write_run(self, name: str, run: int,
                  signals: Mapping[str, np.ndarray | EncodedChunk]) -> None:
        """Store one complete run: its data (arrays, or chunks :func:`encode_run` made), a
        flush, its status, a flush."""
        datasets, status, _ = self._run_handles(name)
        for key, dataset in datasets.items():
            value = signals[key]
            if isinstance(value, EncodedChunk):
                if value.shape != dataset.shape[1:] or np.dtype(value.dtype) != dataset.dtype:
                    raise ValueError(f"signal {key!r} of run {run} has shape {value.shape} "
                                     f"{value.dtype}, the dataset stores {dataset.shape[1:]} "
                                     f"{dataset.dtype}")
                dataset.id.write_direct_chunk((run,) + (0,) * len(value.shape), value.data)
            else:
                dataset[run] = np.asarray(value, dtype=dataset.dtype)
        self.file.flush()
        status[run] = STATUS_COMPLETE
        self.file.flush()

    def write_failure(self, name: str, run: int, reason: str) -> None:
        _, status, failure = self._run_handles(name)
        failure[run] = encode_reason(reason)
        self.file.flush()
        status[run] = STATUS_FAILED
        self.file.flush()

    def run_status(self, name: str) -> np.ndarray:
        return np.asarray(self.path_group(name)["runs"]["status"][()])

    def failures(self, name: str) -> dict[int, str]:
        group = self.path_group(name)["runs"]
        status = group["status"][()]
        reasons = group["failure"][()]
        return {int(j): decode_reason(reasons[j]) for j in np.flatnonzero(status == STATUS_FAILED)}

    def read_runs(self, name: str, selection: slice | np.ndarray,
                  keys: Sequence[str] | None = None) -> dict[str, np.ndarray]:
        """Signals of the selected runs, ``(runs, samples[, …])`` by contract name, as float64
        whatever their stored precision."""
        datasets = self.path_group(name)["runs"]["signals"]
        wanted = list(datasets) if keys is None else [k for k in keys if k in datasets]
        chosen = np.sort(selection) if isinstance(selection, np.ndarray) else selection
        return {key: np.asarray(datasets[key][chosen], dtype=np.float64) for key in wanted}

    def mark_not_needed(self, name: str, first: int) -> None:
        """Rows from ``first`` on that are still missing will never be simulated: an adaptive
        campaign stopped the path (raw data written in place, like a run's status)."""
        _, status, _ = self._run_handles(name)
        current = status[first:]
        if current.size:
            status[first:] = np.where(current == STATUS_MISSING, STATUS_NOT_NEEDED, current)
        self.file.flush()

    def signal_names(self, name: str) -> list[str]:
        return list(self.path_group(name)["runs"]["signals"])
