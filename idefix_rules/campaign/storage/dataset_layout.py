"""How results.h5 lays out a path's runs: blocks of rows, chunks, and the bytes each takes."""

from __future__ import annotations

import json
import zlib
from collections.abc import Mapping
from typing import Any

import h5py
import numpy as np

from idefix_rules.campaign.storage.encoded_chunks import encode_chunk
from idefix_rules.results.format import COMPRESSION_LEVEL, storage_dtype
from idefix_rules.signals import lookup

REASON_BYTES = 240
REASON_DTYPE = f"S{REASON_BYTES}"

# Rows of a path's runs allocated at first, and the largest step a block allocation adds. Every
# block boundary is a multiple of ROW_CHUNK, the chunk of the per-row datasets (status, failure,
# parameters), so each of their chunks is written whole, once, when its block is allocated.
FIRST_ROWS = 64
MAX_STEP_ROWS = 4096
ROW_CHUNK = 64
# Chunk index entry and node share per stored chunk (v1 B-tree: key, address, node slack).
INDEX_BYTES_PER_CHUNK = 96
# Object header, attributes and chunk index root node of a group or dataset.
HEADER_BYTES = 4 * 1024
# The undo journal of a structural change: the old pages it overwrites (the chunk index nodes
# and header a block allocation rewrites in place, per dataset).
JOURNAL_BYTES_PER_DATASET = 32 * 1024


def allocated_rows(needed: int, runs: int) -> int:
    """How many rows of a path's runs are allocated once row ``needed - 1`` is: 64, then
    doubling, then 4,096 more at a time, never more than the ``runs`` planned. The sequence
    does not depend on the order rows are written, so a resumed campaign allocates the same.

    >>> [allocated_rows(n, 1_000_000) for n in (1, 64, 65, 5_000, 9_000)]
    [64, 64, 128, 8192, 12288]
    >>> allocated_rows(1, 6)
    6
    """
    rows = FIRST_ROWS
    while rows < needed:
        rows += min(rows, MAX_STEP_ROWS)
    return min(rows, runs)


def early_dcpl() -> h5py.h5p.PropDCID:
    """Creation properties of a run signal dataset: its chunks allocated and filled at once."""
    dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
    dcpl.set_alloc_time(h5py.h5d.ALLOC_TIME_EARLY)
    # Write the fill value when the space is allocated, also without a user-defined one: space
    # freed by an allocation cut off by a kill is reused, and must not show its old bytes.
    dcpl.set_fill_time(h5py.h5d.FILL_TIME_ALLOC)
    return dcpl


def row_dataset(group: h5py.Group, name: str, runs: int, dtype: Any,
                fillvalue: Any) -> h5py.Dataset:
    """A per-row dataset (``status``, ``failure``, a parameter): a row for every planned run,
    chunks of :data:`ROW_CHUNK` rows allocated when first written (a block allocation writes
    them whole); rows never allocated read as the fill value."""
    dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
    dcpl.set_alloc_time(h5py.h5d.ALLOC_TIME_INCR)
    dcpl.set_fill_time(h5py.h5d.FILL_TIME_ALLOC)
    return group.create_dataset(name, shape=(runs,), dtype=dtype, fillvalue=fillvalue,
                                chunks=(max(1, min(runs, ROW_CHUNK)),), dcpl=dcpl)


def fill_chunk_bytes(name: str, shape: tuple[int, ...]) -> int:
    """Bytes one allocated but unwritten run of signal ``name`` takes (its compressed NaN
    chunk and its chunk index entry)."""
    fill = np.full(shape, np.nan, dtype=storage_dtype(name))
    # HDF5 writes the fill chunks itself, with zlib at COMPRESSION_LEVEL (not the workers'
    # zlib-ng, whose level 4 packs a NaN chunk 2.5 to 4.4 times tighter: 3000 and 30000 x 4
    # samples)
    shuffled = fill.view(np.uint8).reshape(-1, fill.itemsize).T.tobytes()
    return len(zlib.compress(shuffled, COMPRESSION_LEVEL)) + INDEX_BYTES_PER_CHUNK


def row_bytes(shapes: Mapping[str, tuple[int, ...]], parameters: int) -> int:
    """Bytes one allocated row takes before its run is stored."""
    return (sum(fill_chunk_bytes(key, shape) for key, shape in shapes.items())
            + REASON_BYTES + 1 + 8 * parameters + INDEX_BYTES_PER_CHUNK)


def write_rows(group: h5py.Group, start: int, stop: int,
               parameters: Mapping[str, np.ndarray]) -> None:
    """Write rows ``start:stop`` of the per-row datasets (status and failure as they read,
    fill values where never written; the sampled parameters), which allocates their
    chunks whole."""
    if stop <= start:
        return
    for key in ("status", "failure"):
        group[key][start:stop] = group[key][start:stop]
    for key, dataset in group["parameters"].items():
        values = parameters.get(key)
        if values is None:
            raise ValueError(f"the sampled values of parameter {key!r} are needed to "
                             f"allocate more runs: give them to allocate_runs first")
        dataset[start:stop] = np.asarray(values[start:stop], dtype=np.float64)


def run_bytes(signals: Mapping[str, np.ndarray]) -> int:
    """Bytes a run like ``signals`` takes once stored (compressed chunks, index entries, its
    status, failure and parameter rows): the estimate free-space checks use per run."""
    return sum(len(encode_chunk(name, values).data) + INDEX_BYTES_PER_CHUNK
               for name, values in signals.items()) + REASON_BYTES + 64


def encode_reason(reason: str) -> bytes:
    data = reason.encode("utf-8")[:REASON_BYTES]
    return data.decode("utf-8", errors="ignore").encode("utf-8")


def signal_attrs(name: str) -> dict[str, Any]:
    spec = lookup(name)
    if spec is None:
        return {"unit": "", "axes": json.dumps(["time"])}
    return {"unit": spec.unit, "axes": json.dumps(list(spec.axes))}
