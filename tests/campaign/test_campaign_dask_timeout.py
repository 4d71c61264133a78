"""``--run-timeout`` on Dask: not enforced (Dask cannot stop a running task), said as a warning."""

from __future__ import annotations

from pathlib import Path

import pytest

from idefix_rules.campaign.simulate import SimulationOptions, dask_timeout_warning
from idefix_rules.cli import main


def test_the_timeout_warning_is_given_only_for_dask_with_a_timeout() -> None:
    assert dask_timeout_warning(SimulationOptions(run_timeout=5.0)) is None
    assert dask_timeout_warning(SimulationOptions(dask_local=True)) is None
    assert dask_timeout_warning(SimulationOptions(scheduler="tcp://host:8786")) is None
    for options in (SimulationOptions(run_timeout=5.0, dask_local=True),
                    SimulationOptions(run_timeout=5.0, scheduler="tcp://host:8786")):
        text = dask_timeout_warning(options)
        assert text is not None and "--run-timeout 5 s is not enforced on Dask" in text


@pytest.mark.slow
def test_the_cli_warns_when_a_timeout_is_given_with_dask(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main([str(campaign_dir / "campaign.yaml"), "--dask-local", "--workers", "2",
                 "--run-timeout", "30", "--runs", "2", "--quiet", "--no-report"])
    assert code in (0, 1)
    out = capsys.readouterr().out
    assert "warning:" in out and "--run-timeout 30 s is not enforced on Dask" in out
