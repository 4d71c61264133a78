"""The built-in rover and the toy FMU simulate exactly the same datasets for the same seed, run
after run of the project: digests first recorded before the bring-your-own-FMU mapping (and
equal after it), recorded again deliberately when the rover model's physics and the results
format (per-run compressed chunks, float32 wheel and tilt signals) changed, the toy's when
runs began to end one step after their chain (the held samples' ``t`` follows the grid, not the
toy's summed internal steps: 8e-13 s apart; every other dataset equal), and both when the default
stop limit became 3 × the ideal duration + 5 s (longer runs: the earlier samples equal, the
added ones held; the rover's on its recorded sources, where its turn chain now finishes in every
run), and both when campaigns became paired (run ``j`` of every path draws from the stream
``()``: with the earlier derivation, ``spawn_key=(path index, j)``, both old digests were
reproduced exactly before they were replaced), and the toy's when results format 5 stored
``z`` and ``energy`` as float32 (with the format 4 precision it still gave the old digest,
checked before it was replaced), and the rover's when a wheel on a rock got its support at the
contact point and a wheel sliding off a rock left the chassis on the other three (the old
digest reproduced on the old sources before it was replaced; the rut window of a lifted wheel,
fixed after, left it unchanged: only the source hash was recorded again), and the rover's when
a wheel on a rock was compared with the soil at the depth the soil would carry it there instead
of at zero sinkage (a wheel at a rock's edge no longer alternates between the two every step;
its 4 cm rock meets it); where the balance search fails the rover now follows Newton's second
law over the step instead of the search's last iterate (no run of the digest's campaign meets a
failed search: the digest reproduced, the source hash recorded again), and the rover's when the
load solve counted a soil support from its static share's sinkage (one datum with a rock's) and
a wheel on a rock took its lateral friction on the contact's normal force (the old fingerprint
reproduced on the old sources before it was replaced), and the rover's when a wheel on a rock
took its rim's friction (the motor's torque, its current and energy) on that normal force too,
bounded by what the other wheels can push with. A change to either must
re-record them on purpose (``tests/campaign/dataset_digest.py``); anything else that moves
them is a regression.

The digests were bit-exact, and so held on one platform only: on a machine whose processor
gave glibc's libm and numpy's SIMD math other variants (the same sources, compiler and
packages; the commit the digest was recorded on gave another digest there) they no longer
matched. They are now fingerprints (``dataset_digest.results_fingerprint``: every dataset's
dtype and shape exactly, its values to a relative 1e-6), recorded from the same code on such a
machine; between glibc's FMA and AVX variants they differ by at most one float32 ulp.
``IDEFIX_RECORD_FINGERPRINTS=1 pytest tests/campaign/test_campaign_same_datasets.py`` records
them again, on purpose only."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from campaign_texts import CAMPAIGN, RULEBOOK
from dataset_digest import (
    ROVER_CAMPAIGN,
    ROVER_RULEBOOK,
    expected_fingerprint,
    fingerprint_differences,
    record,
    results_fingerprint,
)

from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.runner import run_campaign
from idefix_rules.fmu.build import source_hash

# Recorded on the rover model with feed-forward arcs, displacement-mobilised bulldozing, the
# first-touch rock contact, the loads of a rigid chassis with a rock's support at its contact and
# a wheel on a rock compared with the soil at its supporting depth, ruts kept per cell as the
# pressed fraction and mean depth, soil supports counted from their static sinkage, rock
# friction (lateral and the rim's) on the bounded normal force; results format 2, default
# stop limit 3 × ideal, held after the chain.
ROVER_SOURCE_HASH = "775cff41be452beb81acc2632691c91c98bdbeb3e14a4ab532c003eb33fbcad4"


def _same_as_recorded(name: str, results: Path) -> None:
    if os.environ.get("IDEFIX_RECORD_FINGERPRINTS") == "1":
        pytest.skip(f"recorded {record(name, results)}")
    assert fingerprint_differences(results_fingerprint(results),
                                   expected_fingerprint(name)) == []


def test_toy_fmu_campaign_stores_the_same_datasets(campaign_dir: Path) -> None:
    text = CAMPAIGN.replace("workers: 2", "workers: 1")
    (campaign_dir / "campaign.yaml").write_text(text)
    (campaign_dir / "test.rules").write_text(RULEBOOK)
    result = run_campaign(load_campaign(campaign_dir / "campaign.yaml"), report=False)
    _same_as_recorded("toy", result.results)


def test_builtin_rover_campaign_stores_the_same_datasets(tmp_path: Path) -> None:
    if source_hash() != ROVER_SOURCE_HASH:
        pytest.skip("the rover model's sources changed since the digest was recorded: the "
                    "datasets legitimately differ; record a new fingerprint with "
                    "IDEFIX_RECORD_FINGERPRINTS=1 on purpose")
    (tmp_path / "rover.rules").write_text(ROVER_RULEBOOK)
    (tmp_path / "campaign.yaml").write_text(ROVER_CAMPAIGN)
    result = run_campaign(load_campaign(tmp_path / "campaign.yaml"), report=False)
    _same_as_recorded("rover", result.results)
