"""Fixtures of the campaign tests: the toy FMU (built once) and small campaign folders."""

from __future__ import annotations

from pathlib import Path

import pytest
from campaign_texts import CAMPAIGN, RULEBOOK
from campaign_toy_fmu import build_toy_fmu


@pytest.fixture(scope="session")
def toy_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_toy_fmu(tmp_path_factory.mktemp("toy-fmu"))


@pytest.fixture
def campaign_dir(tmp_path: Path, toy_fmu: Path) -> Path:
    """A folder with the toy FMU, the test rulebook and ``campaign.yaml``."""
    (tmp_path / "toy.fmu").write_bytes(toy_fmu.read_bytes())
    (tmp_path / "test.rules").write_text(RULEBOOK)
    (tmp_path / "campaign.yaml").write_text(CAMPAIGN)
    return tmp_path
