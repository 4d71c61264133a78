"""The results store never throws away a previous campaign's results."""

from pathlib import Path

import h5py

from idefix_rules.campaign.storage.store import ResultStore, previous_results_path


def test_a_new_results_file_keeps_the_previous_one(tmp_path: Path) -> None:
    results = tmp_path / "results.h5"
    first = ResultStore.create(results, {"campaign_name": "first"}, {"campaign": "a: 1"})
    first.close()
    second = ResultStore.create(results, {"campaign_name": "second"}, {"campaign": "a: 2"})
    second.close()
    kept = previous_results_path(results)
    assert kept == tmp_path / "results.previous.h5"
    with h5py.File(kept) as old, h5py.File(results) as new:
        assert old.attrs["campaign_name"] == "first"
        assert new.attrs["campaign_name"] == "second"
