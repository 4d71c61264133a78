"""Fixtures of the CLI user-error tests: the toy FMU of the campaign tests, built once."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

# The toy FMU builder lives with the campaign tests; import it by name from there.
sys.path.insert(0, str(Path(__file__).parents[1] / "campaign"))

from campaign_toy_fmu import build_toy_fmu


@pytest.fixture(scope="session")
def cli_toy_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_toy_fmu(tmp_path_factory.mktemp("cli-toy-fmu"))
