"""A damaged results file (an object deleted or replaced, bytes overwritten, as a copy that
stopped or a disk error leaves it) is an exit-2 H004 naming the file and the object, for every
command that reads one, never a traceback; the file is left as it is."""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest
from test_cli_user_errors import RUN, campaign, materialise

from idefix_rules.cli import main

Damage = Callable[[Path], None]


def _delete(name: str) -> Damage:
    def damage(path: Path) -> None:
        with h5py.File(path, "a") as file:
            del file[name]
    return damage


def _replace(name: str, value: np.ndarray) -> Damage:
    def damage(path: Path) -> None:
        with h5py.File(path, "a") as file:
            del file[name]
            file[name] = value
    return damage


def _overwrite_stored_chunk(path: Path) -> None:
    # random bytes over the stored chunk of one run's slip (which the rulebook reads): it
    # no longer inflates
    with h5py.File(path, "r") as file:
        dataset = file["paths/straight/runs/signals/wheel.slip"]
        offset, size = dataset.id.get_chunk_info(0).byte_offset, \
            dataset.id.get_chunk_info(0).size
    data = bytearray(path.read_bytes())
    data[offset:offset + size] = np.random.default_rng(1).bytes(size)
    path.write_bytes(bytes(data))


def _not_finite(name: str, row: int | None, whole: bool = False) -> Damage:
    # one value of a stored run (or of the reference run) set to NaN, as an edit leaves it:
    # no run is stored unless every output of it is finite; ``whole``: every value of it
    def damage(path: Path) -> None:
        with h5py.File(path, "a") as file:
            dataset = file[name]
            values = dataset[()] if row is None else dataset[row]
            values.reshape(-1)[slice(None) if whole else 1] = np.nan
            if row is None:
                dataset[()] = values
            else:
                dataset[row] = values
    return damage


def _cut_short(path: Path) -> None:
    # the first half of the file, as a copy that stopped leaves it
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


DAMAGES: dict[str, tuple[Damage, str]] = {
    "chain-deleted": (_delete("paths/straight/chain"), "/paths/straight/chain: missing"),
    "rulebook-text-deleted": (_delete("provenance/rulebook"), "/provenance/rulebook: KeyError"),
    "reference-deleted": (_delete("paths/straight/reference"),
                          "/paths/straight/reference: missing, though the path was simulated"),
    "path-deleted": (_delete("paths/straight"), "/paths/straight: missing, though the campaign "
                     "finished"),
    "runs-deleted": (_delete("paths/straight/runs"),
                     "/paths/straight/runs: missing, though the campaign finished"),
    "run-status-deleted": (_delete("paths/straight/runs/status"),
                           "/paths/straight/runs/status: missing, though the campaign finished"),
    "chain-of-two-columns": (_replace("paths/straight/chain", np.zeros((1, 2))),
                             "/paths/straight/chain: missing, or not a table of commands"),
    "signal-of-strings": (_replace("paths/straight/runs/signals/x",
                                   np.array([b"a", b"b"])),
                          "/paths/straight/runs/signals/x: not numbers of the samples"),
    "signal-of-more-rows": (_replace("paths/straight/runs/signals/x", np.zeros((3, 4))),
                            "/paths/straight/runs/signals/x: 3 rows for 2 runs"),
    "chunk-overwritten": (_overwrite_stored_chunk, "/paths/straight/runs/signals"),
    "cut-short": (_cut_short, "the whole file: it is cut short"),
    "run-not-finite": (_not_finite("paths/straight/runs/signals/wheel.slip", 1),
                       "/paths/straight/runs/signals/wheel.slip: run 1 holds values that are "
                       "not finite"),
    # a complete run's row all NaN: not the fill of a run never stored
    "run-all-nan": (_not_finite("paths/straight/runs/signals/wheel.slip", 1, whole=True),
                    "/paths/straight/runs/signals/wheel.slip: run 1 holds values that are "
                    "not finite"),
    "reference-not-finite": (_not_finite("paths/straight/reference/signals/y", None),
                             "/paths/straight/reference/signals/y: holds values that are not "
                             "finite"),
}


@pytest.fixture(scope="module")
def stored(tmp_path_factory: pytest.TempPathFactory, cli_toy_fmu: Path) -> Path:
    folder = tmp_path_factory.mktemp("stored")
    materialise(folder, campaign(), cli_toy_fmu)
    here = Path.cwd()
    try:
        import os
        os.chdir(folder)
        assert main(list(RUN)) in (0, 1)  # its verdicts do not matter here
    finally:
        os.chdir(here)
    return folder / "out" / "results.h5"


# diff re-scores with the two rulebooks it is given, and report draws with the rulebook text
# stored with the evaluation (/evaluation/rulebook_text): neither reads the provenance's
CASES = [(damage, command) for damage in DAMAGES for command in ("evaluate", "report", "diff")
         if (damage, command) not in (("rulebook-text-deleted", "diff"),
                                      ("rulebook-text-deleted", "report"))]


@pytest.mark.parametrize(("damage", "command"), CASES, ids=[f"{d}-{c}" for d, c in CASES])
def test_a_damaged_results_file_is_named_with_its_object_and_exit_2(
        damage: str, command: str, stored: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    results = tmp_path / "results.h5"
    shutil.copy(stored, results)
    spoil, fragment = DAMAGES[damage]
    spoil(results)
    before = results.read_bytes()
    rulebook = stored.parents[1] / "test.rules"
    changed = tmp_path / "changed.rules"  # a limit of an index: the runs are read again
    changed.write_text(rulebook.read_text().replace("critical_slip = 70 %",
                                                    "critical_slip = 60 %"))
    argv = {"evaluate": ["evaluate", str(results), "--quiet"],
            "report": ["report", str(results), "-o", str(tmp_path / "report")],
            "diff": ["diff", str(rulebook), str(changed), "--results", str(results)]}[command]
    code = main(argv)
    captured = capsys.readouterr()
    output = " ".join((captured.out + captured.err).split())
    assert "Traceback" not in output
    assert code == 2, output
    assert f"{results}: error[H004]: results file {results} is damaged: " in output, output
    assert fragment in output, output
    assert results.read_bytes() == before


def test_resuming_into_a_damaged_results_file_is_exit_2(
        stored: Path, tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    # every run is stored, so the resume simulates nothing and evaluates: the chunk that no
    # longer inflates is named, where it was "writing … failed" (exit 3) before
    materialise(tmp_path, campaign(), cli_toy_fmu)
    (tmp_path / "out").mkdir()
    shutil.copy(stored, tmp_path / "out" / "results.h5")
    _overwrite_stored_chunk(tmp_path / "out" / "results.h5")
    monkeypatch.chdir(tmp_path)
    code = main([*RUN, "--resume"])
    captured = capsys.readouterr()
    output = " ".join((captured.out + captured.err).split())
    assert "Traceback" not in output
    assert code == 2, output
    assert "error[H004]" in output and "/paths/straight/runs/signals" in output, output
