"""The campaign extracts its FMU once; every worker's runner uses that folder."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import fmpy
import pytest

from idefix_rules.cli import main

pytestmark = pytest.mark.slow


def test_a_campaign_extracts_the_fmu_once_for_all_workers(
        campaign_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    log = campaign_dir / "extractions.log"
    original = fmpy.extract

    def logged(filename: Any, unzipdir: Any = None, include: Any = None) -> Any:
        folder = original(filename, unzipdir, include)
        with log.open("a") as handle:  # workers are other processes: log to a file
            handle.write(f"{os.getpid()} {folder}\n")
        return folder

    monkeypatch.setattr(fmpy, "extract", logged)  # forked workers inherit the patch
    code = main([str(campaign_dir / "campaign.yaml"), "--workers", "2", "--quiet",
                 "--no-report"])
    assert code == 1  # too-fast breaks the command rule wheel_rate_limit: rejected, exit 1
    extractions = log.read_text().splitlines()
    # reference runs and Monte Carlo runs, two workers each: still one extraction
    assert len(extractions) == 1
    pid, folder = extractions[0].split(" ", 1)
    assert int(pid) == os.getpid()
    assert not Path(folder).exists()  # removed when the campaign ends
