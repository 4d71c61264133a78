"""The result map of a path-level index (a reduction over runs) shows the path's value: the
report computes it over every run of the path before it evaluates the runs chunk by chunk."""

from __future__ import annotations

import importlib
from pathlib import Path

import h5py
import numpy as np
import pytest
from report_fixture import RULEBOOK, write_results

from idefix_rules.report import prepare_report

prepare = importlib.import_module("idefix_rules.report.prepare")

PATH_LEVEL = RULEBOOK.replace('verdict acceptable_risk', '''index I_pos "position drift" {
  value  = max over time (hypot(mean over runs (x - ref.x), mean over runs (y - ref.y))) / 10 cm
  limit  = 1
  weight = 1
}

verdict acceptable_risk''')


@pytest.fixture
def path_level_results(tmp_path: Path) -> Path:
    target = write_results(tmp_path / "results.h5")
    with h5py.File(target, "a") as file:
        attrs = dict(file["provenance/rulebook"].attrs)
        del file["provenance/rulebook"]
        stored = file["provenance"].create_dataset("rulebook", data=PATH_LEVEL,
                                                   dtype=h5py.string_dtype())
        stored.attrs.update(attrs)
    return target


def test_the_map_of_a_path_level_index_does_not_depend_on_the_chunk_size(
        path_level_results: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _, setup, whole = prepare_report(path_level_results)
    assert setup.evaluator is not None and setup.evaluator.runs_reductions
    monkeypatch.setattr(prepare, "CHUNK_RUNS", 1)  # one run per chunk
    _, _, one_by_one = prepare_report(path_level_results)
    monkeypatch.undo()
    for name, accumulator in whole.per_path.items():
        np.testing.assert_allclose(one_by_one.per_path[name].values(), accumulator.values(),
                                   equal_nan=True, err_msg=name)
    assert np.nanmax(whole.combined.values()) > 0
