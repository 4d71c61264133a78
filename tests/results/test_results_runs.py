"""Stored chunks read and decoded on threads (``ParallelRuns``: zlib-ng, byte planes joined run
by run) give exactly what h5py reads, bit for bit, whatever the filters and precision; what it
cannot decode is read through h5py."""

from __future__ import annotations

import zlib
from pathlib import Path

import numpy as np
import pytest

from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.commands import Command
from idefix_rules.errors import UserInputError
from idefix_rules.results.runs import ParallelRuns, chunk_layout, decode_rows

RUNS, SAMPLES = 9, 37
# every encoding a run dataset can have that ParallelRuns decodes itself
ENCODINGS = {"plain": {}, "deflate": {"compression": "gzip", "compression_opts": 1},
             "shuffle": {"shuffle": True},
             "shuffle+deflate": {"shuffle": True, "compression": "gzip", "compression_opts": 4}}


def values(rng: np.random.Generator, shape: tuple[int, ...], dtype: str) -> np.ndarray:
    """Smooth signals with awkward values among them: NaN payloads, infinities, -0.0,
    subnormals (the decoding must move bytes, never arithmetic)."""
    data = np.cumsum(rng.normal(size=shape), axis=1).astype(dtype)
    flat = data.reshape(-1)
    special = np.array([np.nan, np.inf, -np.inf, -0.0, np.finfo(dtype).smallest_subnormal,
                        np.finfo(dtype).max], dtype=dtype)
    flat[rng.choice(flat.size, special.size, replace=False)] = special
    bits = flat.view(np.uint32 if dtype == "<f4" else np.uint64)
    bits[rng.integers(flat.size)] |= 0x7FC00001 if dtype == "<f4" else 0x7FF8000000000001
    return data


def store_with_encodings(path: Path) -> ResultStore:
    """A path whose runs 0-8 hold one signal per encoding and precision, one run per chunk,
    run 4 never written (no chunk: h5py's fill value)."""
    store = ResultStore.create(path, {"runs": RUNS}, {"campaign": "name: t\n"})
    store.create_path("p", 0, [Command(0.1, 0.2, 0.0)], {"status": "simulated"})
    store.allocate_runs("p", RUNS, {"x": (SAMPLES,)}, {}, {})
    signals = store.path_group("p")["runs"]["signals"]
    rng = np.random.default_rng(7)
    for label, options in ENCODINGS.items():
        for dtype in ("<f4", "<f8"):
            for key, shape in ((f"{label}.{dtype}", (SAMPLES,)),
                               (f"wheel.{label}.{dtype}", (SAMPLES, 4))):
                data = values(rng, (RUNS, *shape), dtype)
                dataset = signals.create_dataset(key, shape=(RUNS, *shape), dtype=dtype,
                                                 chunks=(1, *shape), fillvalue=np.nan,
                                                 **options)
                for run in range(RUNS):
                    if run != 4:
                        dataset[run] = data[run]
    return store


def same_bits(got: np.ndarray, expected: np.ndarray) -> bool:
    return got.dtype == expected.dtype == np.float64 and got.shape == expected.shape \
        and got.tobytes() == expected.tobytes()


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_decoded_chunks_equal_h5py_bit_for_bit(tmp_path: Path, threads: int) -> None:
    store = store_with_encodings(tmp_path / "results.h5")
    try:
        signals = store.path_group("p")["runs"]["signals"]
        keys = [key for key in signals if key != "x"]
        assert all(chunk_layout(signals[key]) is not None for key in keys)
        # the decoding itself, of values no campaign stores (NaN payloads, infinities)
        with ParallelRuns(store, threads, finite=False) as runs:
            for selection in (slice(0, 4), slice(5, RUNS), slice(0, RUNS, 2),
                              np.array([8, 0, 3, 5])):
                got = runs.read_runs("p", selection, [*keys, "missing"])
                expected = store.read_runs("p", selection, keys)
                assert set(got) == set(expected) == set(keys)
                for key in keys:
                    assert same_bits(got[key], expected[key]), (key, selection)
            # a selection over the run never written falls back to h5py (its fill value)
            got = runs.read_runs("p", slice(3, 6), keys)
            for key in keys:
                assert same_bits(got[key], store.read_runs("p", slice(3, 6), [key])[key])
                assert np.isnan(got[key][1]).all()
    finally:
        store.close()


def test_the_campaigns_own_signals_equal_h5py(tmp_path: Path) -> None:
    """As the campaign writes them (shuffle + deflate, float32 where FLOAT32_SIGNALS says)."""
    store = ResultStore.create(tmp_path / "results.h5", {"runs": 6}, {"campaign": "name: t\n"})
    try:
        store.create_path("p", 0, [Command(0.1, 0.2, 0.0)], {"status": "simulated"})
        shapes = {"t": (50,), "x": (50,), "z": (50,), "wheel.slip": (50, 4)}
        store.allocate_runs("p", 6, shapes, {}, {})
        rng = np.random.default_rng(11)
        for run in range(6):
            store.write_run("p", run, {key: rng.normal(size=shape)
                                       for key, shape in shapes.items()})
        signals = store.path_group("p")["runs"]["signals"]
        assert signals["z"].dtype == np.float32 and signals["x"].dtype == np.float64
        assert all(chunk_layout(signals[key]) is not None for key in shapes)
        with ParallelRuns(store, 2) as runs:
            got = runs.read_runs("p", slice(0, 6))
        expected = store.read_runs("p", slice(0, 6))
        for key in shapes:
            assert same_bits(got[key], expected[key]), key
    finally:
        store.close()


def test_a_dataset_it_cannot_decode_is_read_through_h5py(tmp_path: Path) -> None:
    store = store_with_encodings(tmp_path / "results.h5")
    try:
        signals = store.path_group("p")["runs"]["signals"]
        data = np.arange(RUNS * SAMPLES, dtype=">f8").reshape(RUNS, SAMPLES)
        signals.create_dataset("big-endian", data=data, chunks=(1, SAMPLES), compression="gzip")
        signals.create_dataset("two-runs-a-chunk", data=data, chunks=(2, SAMPLES),
                               compression="gzip")
        signals.create_dataset("fletcher", data=data, chunks=(1, SAMPLES), fletcher32=True)
        for key in ("big-endian", "two-runs-a-chunk", "fletcher"):
            assert chunk_layout(signals[key]) is None
        with ParallelRuns(store, 2) as runs:
            got = runs.read_runs("p", slice(1, 7), ["big-endian", "two-runs-a-chunk",
                                                    "fletcher"])
        for key, values_read in got.items():
            assert values_read.dtype == np.float64, key
            np.testing.assert_array_equal(values_read, data[1:7].astype(np.float64))
    finally:
        store.close()


def test_a_chunk_of_the_wrong_size_is_an_error(tmp_path: Path) -> None:
    store = store_with_encodings(tmp_path / "results.h5")
    try:
        layout = chunk_layout(store.path_group("p")["runs"]["signals"]["deflate.<f8"])
        assert layout is not None
        with pytest.raises(ValueError, match="bytes"):
            decode_rows([zlib.compress(b"\0" * 8)], layout, np.empty((1, SAMPLES)))
    finally:
        store.close()



@pytest.mark.parametrize("threads", [1, 2])
def test_runs_stored_alike_are_copied_and_still_equal_h5py(tmp_path: Path, threads: int) -> None:
    """Chunks whose bytes equal the chunk before them (the shared time grid, a flag no run
    raised) are copied instead of inflated; what comes out is still h5py's reading, also where
    a run differs between equal ones and where equal runs are not neighbours."""
    store = ResultStore.create(tmp_path / "results.h5", {"runs": RUNS}, {"campaign": "name: t\n"})
    try:
        store.create_path("p", 0, [Command(0.1, 0.2, 0.0)], {"status": "simulated"})
        store.allocate_runs("p", RUNS, {"x": (SAMPLES,)}, {}, {})
        signals = store.path_group("p")["runs"]["signals"]
        grid = np.linspace(0.0, 3.6, SAMPLES)
        data = np.tile(grid, (RUNS, 1))
        data[3] += 1e-12  # one run unlike its neighbours, equal runs on both sides of it
        data[6, -1] = 7.0
        dataset = signals.create_dataset("t.shared", shape=data.shape, dtype="<f8",
                                         chunks=(1, SAMPLES), shuffle=True,
                                         compression="gzip", compression_opts=1)
        for run in range(RUNS):
            dataset[run] = data[run]
        chunks = [dataset.id.read_direct_chunk((run, 0))[1] for run in range(RUNS)]
        assert chunks[0] == chunks[1] and chunks[2] != chunks[3] != chunks[4]
        with ParallelRuns(store, threads) as runs:
            for selection in (slice(0, RUNS), np.array([0, 2, 4, 5, 6, 8]), slice(3, 5)):
                got = runs.read_runs("p", selection, ["t.shared"])["t.shared"]
                expected = store.read_runs("p", selection, ["t.shared"])["t.shared"]
                assert same_bits(got, expected), selection
                assert same_bits(got, data[selection if isinstance(selection, slice)
                                           else np.sort(selection)])
    finally:
        store.close()


def test_a_stored_run_holding_a_value_that_is_not_finite_is_damage(tmp_path: Path) -> None:
    """No run is stored unless every output of it is finite: one that holds NaN or an
    infinity was changed after it was written (H004, naming the dataset and the run); a row
    all NaN is the fill of a run not stored, read as it is."""
    store = ResultStore.create(tmp_path / "results.h5", {"runs": 4}, {"campaign": "name: t\n"})
    try:
        store.create_path("p", 0, [Command(0.1, 0.2, 0.0)], {"status": "simulated"})
        store.allocate_runs("p", 4, {"x": (50,)}, {}, {})
        for run, spoilt in ((0, None), (1, np.inf), (2, np.nan)):
            values = np.linspace(0.0, 1.0, 50)
            if spoilt is not None:
                values[7] = spoilt
            store.write_run("p", run, {"x": values})
        with ParallelRuns(store, 2) as runs:
            np.testing.assert_array_equal(runs.read_runs("p", slice(0, 1))["x"][0],
                                          np.linspace(0.0, 1.0, 50))
            assert np.isnan(runs.read_runs("p", slice(3, 4))["x"]).all()  # never written
            for run in (1, 2):
                with pytest.raises(UserInputError) as damaged:
                    runs.read_runs("p", np.array([0, run]))
                assert f"/paths/p/runs/signals/x: run {run} holds values that are not " \
                    "finite" in damaged.value.diagnostics[0].message
    finally:
        store.close()
