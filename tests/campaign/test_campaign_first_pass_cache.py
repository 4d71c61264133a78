"""An adaptive campaign's looks fold only their new whole chunks onto the path-level values'
first pass of the looks before (:class:`~idefix_rules.results.scoring.FirstPassCache`): the
per-run values are those of a first pass over every run again, to the bit."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from campaign_texts import CAMPAIGN
from test_campaign_adaptive import ROCK, rock_campaign

from idefix_rules.campaign.input.campaign_values import initial_position_sigma, rover_geometry
from idefix_rules.campaign.input.environment import read_terrain
from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.preparation import compile_rulebook_file
from idefix_rules.campaign.runner import run_campaign
from idefix_rules.campaign.simulation.prescreen import run_context
from idefix_rules.campaign.simulation.run_stage import SimulationOptions
from idefix_rules.campaign.storage.store import (
    STATUS_COMPLETE,
    STATUS_MISSING,
    ResultStore,
)
from idefix_rules.results.collisions import collision_function
from idefix_rules.results.runs import ParallelRuns
from idefix_rules.results.scoring import FirstPassCache, score_chunks

pytestmark = pytest.mark.slow


class Looked(ParallelRuns):
    """The stored runs as a look at run count ``seen`` finds them: the later ones missing."""

    seen = 0

    def run_status(self, name: str) -> np.ndarray:
        status = np.array(super().run_status(name), copy=True)
        status[self.seen:] = STATUS_MISSING
        return status


def test_looks_with_the_first_pass_kept_score_as_a_first_pass_over_every_run(
        campaign_dir: Path, tmp_path: Path) -> None:
    path = rock_campaign(campaign_dir)  # its rulebook: hits and a mean over runs
    path.write_text(CAMPAIGN.replace("runs: 6", "runs: 40") + ROCK)  # every run stored
    campaign = load_campaign(path).with_overrides(output=tmp_path / "out", workers=1)
    run_campaign(campaign, SimulationOptions(workers=1), report=False)
    evaluator = compile_rulebook_file(campaign.rulebook)
    assert evaluator.runs_reductions  # I_mean: a mean over the runs of the path
    collisions = collision_function(campaign.model.environment, evaluator,
                                    read_terrain(campaign.output))
    store = ResultStore.open(campaign.output / "results.h5")
    cache = FirstPassCache()
    runs = Looked(store)
    try:
        name = "straight"
        used = int(np.sum(store.run_status(name) == STATUS_COMPLETE))
        assert used == 40
        context = run_context(store.chain(name), rover_geometry(campaign),
                              initial_position_sigma(campaign), store.reference(name))

        def look(start: int, end: int, kept: FirstPassCache | None) -> tuple[np.ndarray, ...]:
            runs.seen = end  # the runs a look at ``end`` has: those below it
            chunks = list(score_chunks(runs, name, [evaluator], context, [collisions],
                                       chunk_runs=8, within=slice(start, end),
                                       across_chunk_runs=8, across_cache=kept))
            evaluated = [chunk.evaluations[0] for chunk in chunks]
            return (np.concatenate([e.values["I_mean"] for e in evaluated]),
                    np.concatenate([e.i_max for e in evaluated]))

        windows = [(0, 10), (10, 18), (18, 26), (26, used)]
        for start, end in windows:
            again = look(start, end, None)
            folded = look(start, end, cache)
            for a, b in zip(again, folded, strict=True):
                assert np.array_equal(a, b), (start, end)
            covered, _ = cache.get((name, 8, (id(evaluator),)), np.arange(end))
            assert covered == end - end % 8  # the whole chunks are kept for the next look
        # the path-level value moves as runs are added: the looks' values are not all alike
        assert len({float(look(0, end, cache)[0][0]) for _, end in windows}) > 1
    finally:
        runs.close()
        store.close()


def test_a_kept_first_pass_is_used_only_for_the_same_first_rows() -> None:
    cache = FirstPassCache()
    cache.put("key", np.arange(16), ["kept"])
    assert cache.get("key", np.arange(20)) == (16, ["kept"])
    assert cache.get("key", np.arange(16)) == (16, ["kept"])
    assert cache.get("key", np.arange(12)) == (0, None)  # fewer rows than kept
    assert cache.get("key", np.delete(np.arange(20), 3)) == (0, None)  # run 3 not complete
    assert cache.get("other", np.arange(20)) == (0, None)
