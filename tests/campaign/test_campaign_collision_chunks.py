"""Collision details keep the path's run numbers when runs are evaluated chunk by chunk."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from campaign_texts import RULEBOOK

from idefix_rules.campaign.evaluation.evaluate import evaluate_store
from idefix_rules.campaign.input.campaign_values import initial_position_sigma, rover_geometry
from idefix_rules.campaign.input.environment import read_terrain
from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.preparation import compile_rulebook_file
from idefix_rules.campaign.storage.store import STATUS_COMPLETE, ResultStore
from idefix_rules.cli import main
from idefix_rules.results.collisions import collision_function

pytestmark = pytest.mark.slow

COLLISION_CHANCE = ("chance hit_L2 = any over parts (collision.hits[L2] > 0)\n"
                    '  because "Runs touching an L2 rock"\n')
ROCK = """environment:
  rocks:
    - {x: "0.5 m", y: "0.3 m", radius: "4 cm", level: L2}
  rock_levels: {l1_max_size: "3 cm", l2_max_size: "10 cm"}
"""


def test_collision_details_carry_global_run_numbers_across_chunks(campaign_dir: Path) -> None:
    rulebook = RULEBOOK.replace("prescreen reference_not_critical", COLLISION_CHANCE
                                + "\nprescreen reference_not_critical")
    (campaign_dir / "test.rules").write_text(rulebook)
    path = campaign_dir / "campaign.yaml"
    path.write_text(path.read_text() + ROCK)
    # too-fast is rejected by its command rule (wheel_rate_limit): exit 1
    assert main([str(path), "--quiet", "--no-report"]) == 1

    campaign = load_campaign(path)
    evaluator = compile_rulebook_file(campaign.rulebook)
    collisions = collision_function(campaign.model.environment, evaluator,
                                    read_terrain(campaign.output))
    assert collisions is not None
    store = ResultStore.open(campaign.output / "results.h5", writable=True)
    try:
        store.write_failure("straight", 1, "made to fail by the test")  # a gap in the chunk
        evaluate_store(store, evaluator, rover_geometry(campaign),
                       initial_position_sigma(campaign), collisions, {}, chunk_runs=2)
        status = store.run_status("straight")
        details = store.path_group("straight")["evaluation/collisions/details"][()]
    finally:
        store.close()
    complete = np.flatnonzero(status == STATUS_COMPLETE)
    assert len(complete) == 5 and 1 not in complete  # three chunks: [0, 2], [3, 4], [5]
    for row in complete:
        record = json.loads(details[row])
        assert record["run"] == row
        assert set(record["min_clearance"]) == {"rock1"}
