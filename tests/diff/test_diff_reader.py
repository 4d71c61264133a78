"""Mapped reading of stored runs gives exactly what h5py reads, and falls back when it must."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.commands import Command
from idefix_rules.results.mapped import MappedRuns, mappable


def small_store(path: Path, contiguous: bool = False) -> ResultStore:
    """Five runs of ``x`` and ``wheel.slip``, run 2 never written; ``contiguous`` rewrites the
    signals the way format 1 stored them (contiguous float64), which is what can be mapped."""
    store = ResultStore.create(path, {"runs": 5}, {"campaign": "name: t\n"})
    store.create_path("p", 0, [Command(0.1, 0.2, 0.0)], {"status": "simulated"})
    store.allocate_runs("p", 5, {"x": (7,), "wheel.slip": (7, 4)}, {}, {})
    rng = np.random.default_rng(3)
    for run in (0, 1, 3, 4):  # run 2 is never written
        store.write_run("p", run, {"x": rng.normal(size=7), "wheel.slip": rng.normal(size=(7, 4))})
    if contiguous:
        signals = store.path_group("p")["runs"]["signals"]
        for key in ("x", "wheel.slip"):
            values = np.asarray(signals[key][()], dtype=np.float64)
            del signals[key]
            signals.create_dataset(key, data=values)
        store._handles.clear()
    return store


def test_format_2_stores_compressed_chunks_read_back_as_float64(tmp_path: Path) -> None:
    store = small_store(tmp_path / "results.h5")
    try:
        signals = store.path_group("p")["runs"]["signals"]
        assert signals["x"].compression == "gzip" and signals["x"].shuffle
        assert signals["x"].chunks == (1, 7) and signals["x"].dtype == np.float64
        assert signals["wheel.slip"].dtype == np.float32  # per-wheel signals: float32
        assert mappable(signals["x"]) is None
        got = MappedRuns(store).read_runs("p", slice(0, 5), ["x", "wheel.slip"])
        expected = store.read_runs("p", slice(0, 5), ["x", "wheel.slip"])
        for key in got:
            assert got[key].dtype == expected[key].dtype == np.float64
            np.testing.assert_array_equal(got[key], expected[key])
        assert np.isnan(got["x"][2]).all()  # never written: the fill value
    finally:
        store.close()


def test_mapped_rows_equal_h5py_rows(tmp_path: Path) -> None:
    store = small_store(tmp_path / "results.h5", contiguous=True)
    try:
        mapped = MappedRuns(store)
        for selection in (slice(0, 5), slice(1, 4), slice(3, 5), np.array([4, 0, 3])):
            expected = store.read_runs("p", selection, ["x", "wheel.slip", "missing"])
            got = mapped.read_runs("p", selection, ["x", "wheel.slip", "missing"])
            assert set(got) == set(expected) == {"x", "wheel.slip"}
            for key in expected:
                np.testing.assert_array_equal(got[key], expected[key])
        rows = mapped.read_runs("p", slice(0, 2), ["x"])["x"]
        assert isinstance(rows, np.memmap)
        rows[0, 0] = 123.0  # copy-on-write: the file keeps its value
        assert store.read_runs("p", slice(0, 1), ["x"])["x"][0, 0] != 123.0
        np.testing.assert_array_equal(mapped.run_status("p"), [1, 1, 0, 1, 1])
    finally:
        store.close()


def test_chunked_datasets_are_read_through_h5py(tmp_path: Path) -> None:
    store = small_store(tmp_path / "results.h5", contiguous=True)
    try:
        signals = store.path_group("p")["runs"]["signals"]
        signals.create_dataset("y", data=np.arange(35.0).reshape(5, 7), chunks=(1, 7),
                               compression="gzip")
        assert mappable(signals["y"]) is None and mappable(signals["x"]) is not None
        got = MappedRuns(store).read_runs("p", slice(1, 3), ["y"])["y"]
        assert not isinstance(got, np.memmap)
        np.testing.assert_array_equal(got, np.arange(35.0).reshape(5, 7)[1:3])
    finally:
        store.close()


def test_a_complete_run_not_finite_in_a_mapped_dataset_is_damage(tmp_path: Path) -> None:
    """Format 1 (mapped) and rows read through HDF5 are checked as decoded chunks are: a run
    stored complete holds only finite values, all NaN included; run 2, never written, is the
    fill and no damage."""
    from idefix_rules.errors import UserInputError
    from idefix_rules.results.runs import ParallelRuns

    store = small_store(tmp_path / "results.h5", contiguous=True)
    try:
        with ParallelRuns(store) as runs:  # untouched: the fill of run 2 is no damage
            assert np.isnan(runs.read_runs("p", slice(0, 5), ["x"])["x"][2]).all()
        signals = store.path_group("p")["runs"]["signals"]
        for values in (np.full(7, np.nan), np.r_[np.zeros(6), np.inf]):
            signals["x"][3] = values
            with ParallelRuns(store) as runs:
                with pytest.raises(UserInputError) as caught:
                    runs.read_runs("p", slice(0, 5), ["x"])
                assert "/paths/p/runs/signals/x" in str(caught.value.diagnostics[0].message)
                assert "run 3 holds values that are not finite" in \
                    caught.value.diagnostics[0].message
                # rows of runs not stored complete are not checked: run 2 alone reads
                np.testing.assert_array_equal(
                    np.isnan(runs.read_runs("p", np.array([2]), ["x"])["x"]), True)
        with ParallelRuns(store, finite=False) as runs:  # asked not to check
            assert np.isnan(runs.read_runs("p", slice(3, 4), ["x"])["x"][0, -1]) or \
                np.isinf(runs.read_runs("p", slice(3, 4), ["x"])["x"][0, -1])
    finally:
        store.close()
