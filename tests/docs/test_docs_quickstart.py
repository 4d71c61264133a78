"""docs/quickstart.md works as written: its terrain script and campaign file, run from a folder
beside the rulebooks with the page's adaptive command, give the answer the page shows."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.slow


def _blocks(text: str, language: str) -> list[str]:
    """The fenced blocks of ``text`` in ``language`` ("": the blocks without one), in order."""
    blocks, current, info = [], None, ""
    for line in text.splitlines(keepends=True):
        if line.startswith("```"):
            if current is None:
                current, info = [], line[3:].strip()
            else:
                if info == language:
                    blocks.append("".join(current))
                current = None
        elif current is not None:
            current.append(line)
    return blocks


def test_the_quickstart_campaign_runs_to_a_decision(tmp_path: Path) -> None:
    page = (ROOT / "docs" / "quickstart.md").read_text(encoding="utf-8")
    (tmp_path / "rulebooks").symlink_to(ROOT / "rulebooks")
    script = _blocks(page, "sh")[0]
    assert script.startswith("mkdir my-site\n")
    (tmp_path / "my-site").mkdir()
    python = re.search(r'python -c "\n(.*?)"\n', script, re.S)
    assert python is not None
    subprocess.run([sys.executable, "-c", python.group(1)], cwd=tmp_path, check=True)
    campaign = tmp_path / "my-site" / "campaign.yaml"
    campaign.write_text(_blocks(page, "yaml")[0], encoding="utf-8")
    command = next(line for line in _blocks(page, "sh")[1].splitlines() if "--runs auto" in line)
    arguments = command.split("#")[0].split()[2:]  # the page's options after the campaign
    done = subprocess.run(
        [sys.executable, "-m", "idefix_rules", str(campaign), *arguments, "--workers", "2",
         "--no-report"],
        cwd=tmp_path, env={**os.environ, "COLUMNS": "400", "PYTHONPATH": str(ROOT)},
        capture_output=True, text=True, timeout=600, check=False)
    # without `expect:` every chain must pass for exit 0; neither does
    assert done.returncode == 1, done.stdout + done.stderr
    assert "Traceback" not in done.stderr
    lines = done.stdout.splitlines()
    # the answer the page shows, line by line ("…" stands for figures the page leaves out)
    shown = next(block for block in _blocks(page, "") if "Decision:" in block).splitlines()
    tail = lines[-len(shown):]
    for expected, printed in zip(shown, tail, strict=True):
        if "…" in expected:
            assert printed.startswith(expected.split("…")[0]), (expected, printed)
        else:
            assert printed == expected, (expected, printed)
    summary = json.loads((tmp_path / "results" / "my-site" / "summary.json").read_text())
    paths = {path["name"]: path for path in summary["paths"]}
    assert set(paths) == {"straight", "arc-detour"}
    # the figures the page's prose quotes
    arc = paths["arc-detour"]
    assert f"risk {100 * arc['mean_risk']:.1f} % against the rulebook's 70 %" in \
        " ".join(page.split())
    assert f"meets that rock in {100 * arc['chances']['hit_L2']:.0f} % of its runs" in \
        " ".join(page.split())
