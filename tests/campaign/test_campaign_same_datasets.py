"""The built-in rover and the toy FMU simulate exactly the same datasets as before the
bring-your-own-FMU mapping (digests recorded at commit e741e59 with the same seed)."""

from __future__ import annotations

from pathlib import Path

import pytest
from campaign_texts import CAMPAIGN, RULEBOOK
from dataset_digest import ROVER_CAMPAIGN, ROVER_RULEBOOK, results_digest

from idefix_rules.campaign.load import load_campaign
from idefix_rules.campaign.runner import run_campaign
from idefix_rules.fmu.build import source_hash

# Recorded before the mapping checks, chain delivery modes and FMI 3.0 support were added.
ROVER_SOURCE_HASH = "ffc2f4b714e0e2b7c0f1d72b3db0da0037f52de48d3d7cfc73b1d516a2fcfe41"
ROVER_DIGEST = "49cbc744a9bc80af4c2c4dcb4496550c848decb91fdac8bb619c8e4d53f322d0"
TOY_DIGEST = "c6f85bdde89e5b7e060dc912b4d69c848bd15461957ee3afb2712f7316728d7d"


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
                    "tests/campaign/dataset_digest.py on the base of the model change")
    (tmp_path / "rover.rules").write_text(ROVER_RULEBOOK)
    (tmp_path / "campaign.yaml").write_text(ROVER_CAMPAIGN)
    result = run_campaign(load_campaign(tmp_path / "campaign.yaml"), report=False)
    assert results_digest(result.results) == ROVER_DIGEST
