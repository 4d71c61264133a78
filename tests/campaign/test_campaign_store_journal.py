"""A writer of the results file cut off where HDF5 leaves it inconsistent recovers: a block
allocation stopped at any of its writes — by a kill, or by a full disk — is rolled back, and a
run's index entries flushed without the superblock are accounted for. Every run stored before
reads back, and writing on gives the same datasets as a writer that was never stopped
(``idefix_rules/campaign/storage/journal.py``)."""

from __future__ import annotations

import errno
import os
import shutil
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest

from idefix_rules.campaign.storage import journal
from idefix_rules.campaign.storage.diskspace import DiskFull
from idefix_rules.campaign.storage.encoded_chunks import encode_chunk
from idefix_rules.campaign.storage.journal import stale_end
from idefix_rules.campaign.storage.revision import Revision
from idefix_rules.campaign.storage.store import STATUS_COMPLETE, ResultStore
from idefix_rules.commands import Command

RUNS = 200
SHAPES = {"x": (40,), "wheel.slip": (40, 4), "command": (40,)}
PARAMETERS = {"soil.cohesion": np.linspace(100.0, 300.0, RUNS)}
STORED = 64  # the first block: run 64 needs the next one


def run(number: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(number)
    return {key: rng.normal(size=shape) for key, shape in SHAPES.items()}


def write(path: Path, runs: range) -> None:
    store = ResultStore.open(path, writable=True) if path.exists() else \
        ResultStore.create(path, {"runs": RUNS}, {"campaign": "name: j\n"})
    try:
        if not store.has_path("p"):
            store.create_path("p", 0, [Command(0.1, 0.2, 0.0)], {"status": "simulated"})
        store.allocate_runs("p", RUNS, SHAPES, PARAMETERS, {})
        for number in runs:
            store.write_run("p", number, run(number))
    finally:
        store.close()


def contents(path: Path) -> dict[str, np.ndarray]:
    store = ResultStore.open(path)
    try:
        group = store.path_group("p")["runs"]
        found = {"status": store.run_status("p"), "failure": group["failure"][()],
                 "parameters": group["parameters/soil.cohesion"][()]}
        found.update(store.read_runs("p", slice(0, RUNS)))
        return found
    finally:
        store.close()


def assert_same(got: dict[str, np.ndarray], expected: dict[str, np.ndarray]) -> None:
    assert got.keys() == expected.keys()
    for key, values in expected.items():
        assert np.array_equal(got[key], values, equal_nan=values.dtype.kind == "f"), key


@pytest.fixture(scope="module")
def stored(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, np.ndarray]]:
    """A file with the first block written, and the datasets of an undisturbed writer."""
    folder = tmp_path_factory.mktemp("journal")
    base = folder / "base.h5"
    write(base, range(STORED))
    whole = folder / "whole.h5"
    shutil.copyfile(base, whole)
    write(whole, range(STORED, RUNS))
    return base, contents(whole)


def journaled_writes(base: Path, tmp_path: Path) -> int:
    """How many writes the next block allocation makes through the journal."""
    copy = tmp_path / "count.h5"
    shutil.copyfile(base, copy)
    original = journal.JournaledFile.write
    count = [0]

    def counting(self: journal.JournaledFile, data: bytes) -> int:
        count[0] += 1
        return original(self, data)

    journal.JournaledFile.write = counting  # type: ignore[method-assign]
    try:
        write(copy, range(STORED, STORED + 1))
    finally:
        journal.JournaledFile.write = original  # type: ignore[method-assign]
    return count[0]


def assert_rolled_back_and_continued(target: Path, base_runs: dict[str, np.ndarray],
                                     expected: dict[str, np.ndarray]) -> None:
    store = ResultStore.open(target, writable=True)  # rolls the cut-off change back
    try:
        assert not journal.undo_path(target).exists()
        status = store.run_status("p")
        assert np.flatnonzero(status == STATUS_COMPLETE).tolist() == list(range(STORED))
        for number in range(STORED):
            got = store.read_runs("p", slice(number, number + 1))
            for key in SHAPES:
                assert np.array_equal(got[key][0], base_runs[key][number]), (number, key)
    finally:
        store.close()
    write(target, range(STORED, RUNS))
    assert_same(contents(target), expected)


def dying_at(kill_at: int) -> Callable[[journal.JournaledFile, bytes], int]:
    """``JournaledFile.write`` ending the process right before its ``kill_at``-th write."""
    original = journal.JournaledFile.write
    count = [0]

    def dying(self: journal.JournaledFile, data: bytes) -> int:
        count[0] += 1
        if count[0] == kill_at:
            os._exit(9)
        return original(self, data)

    return dying


def refusing_from(full_at: int) -> Callable[[int, memoryview, int], None]:
    """``journal._write_at`` meeting a full disk from its ``full_at``-th write on."""
    original = journal._write_at
    count = [0]

    def refusing(handle: int, view: memoryview, offset: int) -> None:
        count[0] += 1
        if count[0] >= full_at:
            raise OSError(errno.ENOSPC, "No space left on device")
        original(handle, view, offset)

    return refusing


@pytest.mark.skipif(not hasattr(os, "fork"), reason="kills a forked writer")
def test_a_block_allocation_killed_at_any_of_its_writes_is_rolled_back(
        stored: tuple[Path, dict[str, np.ndarray]], tmp_path: Path) -> None:
    base, expected = stored
    base_runs = contents(base)
    writes = journaled_writes(base, tmp_path)
    assert writes > 50  # fill chunks, index nodes (the root splits), headers, superblock
    for kill_at in sorted({1, 2, 3, writes - 1, writes, *range(4, writes, 7)}):
        target = tmp_path / f"killed-{kill_at}.h5"
        shutil.copyfile(base, target)
        child = os.fork()
        if child == 0:  # the writer, killed right before its kill_at-th journaled write
            try:
                journal.JournaledFile.write = dying_at(kill_at)  # type: ignore[method-assign]
                write(target, range(STORED, STORED + 1))
            finally:
                os._exit(0)
        _, status = os.waitpid(child, 0)
        assert os.waitstatus_to_exitcode(status) == 9, kill_at
        assert journal.undo_path(target).exists()
        assert_rolled_back_and_continued(target, base_runs, expected)


def test_a_full_disk_inside_a_block_allocation_is_rolled_back(
        stored: tuple[Path, dict[str, np.ndarray]], tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    base, expected = stored
    base_runs = contents(base)
    writes = journaled_writes(base, tmp_path)
    for full_at in (1, writes // 2, writes):
        target = tmp_path / f"full-{full_at}.h5"
        shutil.copyfile(base, target)
        monkeypatch.setattr(journal, "_write_at", refusing_from(full_at))
        store = ResultStore.open(target, writable=True)
        store.allocate_runs("p", RUNS, SHAPES, PARAMETERS, {})
        with pytest.raises(DiskFull, match="to allocate runs 65-128 of path 'p'"):
            store.write_run("p", STORED, run(STORED))
        store.close()
        monkeypatch.undo()
        assert not journal.undo_path(target).exists()  # rolled back at once
        assert_rolled_back_and_continued(target, base_runs, expected)


def test_a_writer_killed_between_a_runs_index_entries_and_the_superblock(
        stored: tuple[Path, dict[str, np.ndarray]], tmp_path: Path) -> None:
    """HDF5 writes index nodes before the superblock: killed in between, the run being
    written points past the end the superblock records. The run is not complete (its status
    comes later); an evaluation and ``--resume`` go on as if the kill had come before it."""
    _, expected = stored
    target = tmp_path / "stale.h5"
    write(target, range(STORED - 1))
    with target.open("rb") as handle:
        header = handle.read(64)
    end = stale_end(header, 1 << 62)
    assert end is not None
    recorded = header[end:end + 8]
    store = ResultStore.open(target, writable=True)  # the last run's data, flushed, no status
    signals = store.path_group("p")["runs/signals"]
    for key, values in run(STORED - 1).items():
        chunk = encode_chunk(key, values).data
        signals[key].id.write_direct_chunk((STORED - 1,) + (0,) * (values.ndim), chunk)
    store.file.flush()
    store.close()
    with target.open("r+b") as handle:  # ... and the superblock as it was before
        handle.seek(end)
        handle.write(recorded)
    assert stale_end(target.read_bytes()[:64], target.stat().st_size) == end
    # an evaluation writes its new version; the stale end is raised in it, not in the original
    with Revision(target) as revision:
        revision.store.file.create_group("evaluation").create_dataset(
            "probe", data=np.arange(10_000.0))
        revision.commit("write the evaluation")
    write(target, range(STORED - 1, RUNS))
    assert_same(contents(target), expected)
    with h5py.File(target, "r") as file:
        assert np.array_equal(file["evaluation/probe"][()], np.arange(10_000.0))
