"""Chunks compressed in the workers are stored as they are and read by HDF5's own filters."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from idefix_rules.campaign.storage.encoded_chunks import encode_chunk, encode_run
from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.commands import Command


def test_encoded_runs_are_stored_as_encoded_and_hdf5_reads_them(tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    run = {"x": np.cumsum(rng.normal(size=50)), "wheel.slip": rng.random((50, 4)),
           "command": np.repeat([0.0, 1.0], 25)}
    store = ResultStore.create(tmp_path / "r.h5", {"runs": 2}, {"campaign": "name: e\n"})
    try:
        store.create_path("p", 0, [Command(0.1, 0.2, 0.0)], {"status": "simulated"})
        store.allocate_runs("p", 2, {key: value.shape for key, value in run.items()}, {}, {})
        store.write_run("p", 0, encode_run(run))  # compressed by "the worker"
        store.write_run("p", 1, run)  # compressed by HDF5
        signals = store.path_group("p")["runs"]["signals"]
        for key, values in run.items():
            dataset = signals[key]
            zero = (0,) * (dataset.ndim - 1)
            # the worker's bytes, as they are (a deflate stream of zlib-ng's, not zlib's)
            assert dataset.id.read_direct_chunk((0, *zero))[1] == \
                encode_chunk(key, values).data, key
            read = store.read_runs("p", slice(0, 2), [key])[key]
            expected = values.astype(dataset.dtype).astype(np.float64)
            assert np.array_equal(read[0], expected) and np.array_equal(read[1], expected)
            # HDF5's filter pipeline inflates the worker's chunk as its own
            assert np.array_equal(dataset[0].astype(np.float64), expected), key
        np.testing.assert_array_equal(store.run_status("p"), [1, 1])
    finally:
        store.close()


def test_an_encoded_run_of_the_wrong_shape_is_refused(tmp_path: Path) -> None:
    store = ResultStore.create(tmp_path / "r.h5", {"runs": 1}, {"campaign": "name: e\n"})
    try:
        store.create_path("p", 0, [Command(0.1, 0.2, 0.0)], {"status": "simulated"})
        store.allocate_runs("p", 1, {"x": (50,)}, {}, {})
        with pytest.raises(ValueError, match="signal 'x' of run 0 has shape"):
            store.write_run("p", 0, encode_run({"x": np.zeros(49)}))
        assert store.run_status("p")[0] == 0  # nothing marked complete
    finally:
        store.close()


def test_a_resumed_older_file_keeps_the_precision_its_datasets_were_made_with(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from idefix_rules.results import format as results_format

    rng = np.random.default_rng(5)
    run = {"z": 0.3 + rng.normal(0.0, 1e-3, 50), "energy": np.cumsum(rng.random(50))}
    store = ResultStore.create(tmp_path / "r.h5", {"runs": 1}, {"campaign": "name: e\n"})
    try:
        store.create_path("p", 0, [Command(0.1, 0.2, 0.0)], {"status": "simulated"})
        # before format 5, z and energy were stored as float64
        with monkeypatch.context() as patch:
            patch.setattr(results_format, "FLOAT32_SIGNALS",
                          results_format.FLOAT32_SIGNALS - {"z", "energy"})
            store.allocate_runs("p", 1, {key: value.shape for key, value in run.items()},
                                {}, {})
        store.write_run("p", 0, encode_run(run))  # a format-5 worker: float32 chunks
        signals = store.path_group("p")["runs"]["signals"]
        for key, values in run.items():
            assert signals[key].dtype == np.float64
            read = store.read_runs("p", slice(0, 1), [key])[key][0]
            np.testing.assert_array_equal(read, values.astype(np.float32).astype(np.float64))
    finally:
        store.close()


def test_the_free_space_estimate_of_an_unwritten_row_covers_what_hdf5_writes(
        tmp_path: Path) -> None:
    """Rows are allocated with HDF5's own NaN fill chunks (zlib at the format's level, not
    the workers' zlib-ng): the estimate the free-space check uses must not fall short."""
    from idefix_rules.campaign.storage.dataset_layout import (
        INDEX_BYTES_PER_CHUNK,
        fill_chunk_bytes,
    )

    shapes = {"x": (3000,), "wheel.slip": (30000, 4)}
    store = ResultStore.create(tmp_path / "r.h5", {"runs": 2}, {"campaign": "name: e\n"})
    try:
        store.create_path("p", 0, [Command(0.1, 0.2, 0.0)], {"status": "simulated"})
        store.allocate_runs("p", 2, shapes, {}, {})
        signals = store.path_group("p")["runs"]["signals"]
        for key, shape in shapes.items():
            written = signals[key].id.get_chunk_info(0).size
            estimate = fill_chunk_bytes(key, shape) - INDEX_BYTES_PER_CHUNK
            assert written <= estimate <= 1.2 * written, (key, written, estimate)
    finally:
        store.close()
