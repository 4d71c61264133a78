"""Standard output closed by its reader while a campaign runs (``idefix-verify c.yaml | head
-1``): the command stops quietly with exit 141 (docs/ci.md) at whatever stage it is, and the
files it wrote stay consistent. A broken pipe is an ``OSError``; caught as one, it read as the
results file failing to be written (exit 3, ``writing …/results.h5 failed: ``) or as the
report failing (exit 3).

The reader goes away at a chosen moment: the command runs in a process of its own whose
standard output is switched, right before the ``calls``-th call of a function, to a pipe
whose read end is closed, so its next line meets the broken pipe.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import h5py
import pytest

from idefix_rules.cli.pipes import BROKEN_PIPE_EXIT

REPOSITORY = Path(__file__).resolve().parents[2]


def closed_after(target: str, calls: int) -> str:
    """Patch code: standard output's reader goes away right before the ``calls``-th call of
    ``target`` (``module:Class.method`` or ``module:function``) goes on."""
    module, attribute = target.split(":")
    owner, _, method = attribute.rpartition(".")
    holder = owner or "_module"
    name = method
    return textwrap.dedent(f"""
        import importlib, os
        _module = importlib.import_module({module!r})
        {f"from {module} import {owner}" if owner else ""}
        _original = getattr({holder}, {name!r})
        _calls = [0]
        def _closing(*args, **kwargs):
            _calls[0] += 1
            if _calls[0] == {calls}:
                read_end, write_end = os.pipe()
                os.close(read_end)
                os.dup2(write_end, 1)
                os.close(write_end)
            return _original(*args, **kwargs)
        setattr({holder}, {name!r}, _closing)
    """)


def run_closing(folder: Path, patch: str, *arguments: str) -> subprocess.CompletedProcess[str]:
    code = patch + textwrap.dedent(f"""
        import sys
        from idefix_rules.cli import process_main
        sys.argv = ["idefix-verify", *{list(arguments)!r}]
        sys.exit(process_main())
    """)
    return subprocess.run([sys.executable, "-c", code], cwd=folder, capture_output=True,
                          text=True, timeout=300, check=False,
                          env={**os.environ, "PYTHONPATH": str(REPOSITORY)})


@pytest.mark.slow
def test_a_reader_gone_during_the_simulation_stops_quietly_and_leaves_a_resumable_file(
        campaign_dir: Path) -> None:
    patch = closed_after("idefix_rules.campaign.storage.store:ResultStore.write_run", 3)
    finished = run_closing(campaign_dir, patch, "campaign.yaml", "--runs", "8")
    assert (finished.returncode, finished.stderr) == (BROKEN_PIPE_EXIT, "")
    out = campaign_dir / "out"
    with h5py.File(out / "results.h5", "r") as results:
        assert results.attrs["state"] == "interrupted"
    assert not (out / "summary.json").exists()
    resumed = subprocess.run(
        [sys.executable, "-m", "idefix_rules", "campaign.yaml", "--runs", "8", "--quiet",
         "--resume", "--no-report"], cwd=campaign_dir, capture_output=True, text=True,
        timeout=300, check=False, env={**os.environ, "PYTHONPATH": str(REPOSITORY)})
    assert resumed.returncode == 1, resumed.stderr
    assert "runs stored already" not in resumed.stdout  # --quiet: the outcome only
    with h5py.File(out / "results.h5", "r") as results:
        assert results.attrs["state"] == "complete"


@pytest.mark.slow
def test_a_reader_gone_while_the_report_is_written_stops_quietly(campaign_dir: Path) -> None:
    patch = closed_after("idefix_rules.report:write_report", 1)
    finished = run_closing(campaign_dir, patch, "campaign.yaml", "--runs", "8")
    assert (finished.returncode, finished.stderr) == (BROKEN_PIPE_EXIT, "")
    out = campaign_dir / "out"
    # the campaign is complete: results and summary.json are written, the report is not
    assert json.loads((out / "summary.json").read_text())["exit_code"] == 1
    with h5py.File(out / "results.h5", "r") as results:
        assert results.attrs["state"] == "complete"
    assert not (out / "report.html").exists()
    assert not [path.name for path in out.iterdir() if path.name.endswith(".tmp")]
