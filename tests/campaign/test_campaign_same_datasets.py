"""The built-in rover and the toy FMU simulate exactly the same datasets for the same seed, run
after run of the project: digests first recorded before the bring-your-own-FMU mapping (and
equal after it), recorded again deliberately when the rover model's physics and the results
format (per-run compressed chunks, float32 wheel and tilt signals) changed, and the toy's when
runs began to end one step after their chain (the held samples' ``t`` follows the grid, not the
toy's summed internal steps: 8e-13 s apart; every other dataset equal). A change to either must
re-record them on purpose (``tests/campaign/dataset_digest.py``); anything else that moves
them is a regression."""

from __future__ import annotations

from pathlib import Path

import pytest
from campaign_texts import CAMPAIGN, RULEBOOK
from dataset_digest import ROVER_CAMPAIGN, ROVER_RULEBOOK, results_digest

from idefix_rules.campaign.load import load_campaign
from idefix_rules.campaign.runner import run_campaign
from idefix_rules.fmu.build import source_hash

# Recorded on the closed-loop rover model and results format 2.
ROVER_SOURCE_HASH = "7d4b7266cf9caa0266bbcba5b1f9ee79e3099c7ee921b206081f90cd23bdc1e9"
ROVER_DIGEST = "aec62cf701975a95b67308f82ca7aedaf26697538460fca15d8e4d117cbcfba8"
TOY_DIGEST = "edb3760aa3a09082a67577049f09e94538c76d16d89f750f1abc7ae078679ef5"


def test_toy_fmu_campaign_stores_the_same_datasets(campaign_dir: Path) -> None:
    text = CAMPAIGN.replace("workers: 2", "workers: 1")
    (campaign_dir / "campaign.yaml").write_text(text)
    (campaign_dir / "test.rules").write_text(RULEBOOK)
    result = run_campaign(load_campaign(campaign_dir / "campaign.yaml"), report=False)
    assert results_digest(result.results) == TOY_DIGEST


def test_builtin_rover_campaign_stores_the_same_datasets(tmp_path: Path) -> None:
    if source_hash() != ROVER_SOURCE_HASH:
        pytest.skip("the rover model's sources changed since the digest was recorded: the "
                    "datasets legitimately differ; record a new digest with "
                    "tests/campaign/dataset_digest.py on purpose")
    (tmp_path / "rover.rules").write_text(ROVER_RULEBOOK)
    (tmp_path / "campaign.yaml").write_text(ROVER_CAMPAIGN)
    result = run_campaign(load_campaign(tmp_path / "campaign.yaml"), report=False)
    assert results_digest(result.results) == ROVER_DIGEST
