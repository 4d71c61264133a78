"""Fixtures of the report tests."""

from __future__ import annotations

from pathlib import Path

import pytest
from report_fixture import write_results


@pytest.fixture
def synthetic_results(tmp_path: Path) -> Path:
    """A results file of two evaluated paths and one rejected path (see report_fixture)."""
    return write_results(tmp_path / "results.h5")
