"""A small stored campaign for the results diff: the rock-detour example on the built-in rover
FMU, 4 runs per path, simulated once per test session."""

from __future__ import annotations

from pathlib import Path

import pytest

from idefix_rules.cli import main

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def stored_results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("diff-campaign") / "rock-detour"
    code = main([str(ROOT / "campaigns" / "rock-detour.yaml"), "--runs", "4", "--out", str(out),
                 "--workers", "2", "--quiet", "--no-report"])
    assert code in (0, 1)
    return out / "results.h5"


@pytest.fixture(scope="session")
def ops_text() -> str:
    return (ROOT / "rulebooks" / "idefix-ops.rules").read_text(encoding="utf-8")
