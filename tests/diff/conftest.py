"""A small stored campaign for the results diff: the rock-detour example on the built-in rover
FMU, 4 runs per path, simulated once per test session."""

from __future__ import annotations

from pathlib import Path

import pytest

from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.cli import main

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / "tests" / "fixtures" / "rulebooks"
FROZEN = FIXTURES / "idefix-ops-1.1.0.rules"


@pytest.fixture(scope="session")
def stored_results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("diff-campaign") / "rock-detour"
    code = main([str(ROOT / "campaigns" / "rock-detour.yaml"), "--runs", "4", "--out", str(out),
                 "--workers", "2", "--quiet", "--no-report"])
    # the straight chain fails as expected; 0 L2 hits of the wide detour in 4 runs cannot
    # show its chance below 10 % (bounds 0-59.3 %): that expectation is not decided, exit 1
    assert code == 1
    return out / "results.h5"


@pytest.fixture(scope="session")
def campaign_rulebook(stored_results: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The rulebook the stored campaign was evaluated with (its campaign file names the live
    operations rulebook), as the results file keeps it: re-scored under it, nothing changes."""
    store = ResultStore.open(stored_results)
    try:
        text = store.text("rulebook")
    finally:
        store.close()
    path = tmp_path_factory.mktemp("campaign-rulebook") / "campaign.rules"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture(scope="session")
def ops_text() -> str:
    """The frozen operations rulebook 1.1.0 (tests/fixtures/rulebooks), whose exact text the
    variants of the results diff edit."""
    return FROZEN.read_text(encoding="utf-8")
