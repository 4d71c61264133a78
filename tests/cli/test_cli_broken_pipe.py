"""A reader that closes standard output early (``idefix-verify … | head -1``): every command that
writes to stdout ends quietly, with exit 141 (128 + SIGPIPE) and nothing on stderr.

The pipe's read end is closed before the command starts, so its first write fails: the test
does not depend on how much a command prints or on timing.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from idefix_rules.cli.pipes import BROKEN_PIPE_EXIT

REPOSITORY = Path(__file__).resolve().parents[2]
FROZEN = REPOSITORY / "tests" / "fixtures" / "rulebooks" / "idefix-ops-1.1.0.rules"
EARLIER = REPOSITORY / "tests" / "fixtures" / "rulebooks" / "idefix-ops-0.9.0.rules"


def run_into_closed_pipe(*arguments: str, cwd: Path) -> subprocess.CompletedProcess[bytes]:
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        return subprocess.run([sys.executable, "-m", "idefix_rules", *arguments], cwd=cwd,
                              stdout=write_end, stderr=subprocess.PIPE, timeout=120,
                              env={**os.environ, "PYTHONPATH": str(REPOSITORY)}, check=False)
    finally:
        os.close(write_end)


@pytest.mark.parametrize("command", [
    ["explain", str(FROZEN)],
    ["explain", "--format", "json", str(FROZEN)],
    ["check", str(FROZEN)],
    ["check", "--format", "json", str(FROZEN)],
    ["fmt", "--check", "unformatted.rules"],
    ["diff", str(EARLIER), str(FROZEN)],
    ["diff", "--format", "json", str(EARLIER), str(FROZEN)],
    ["diff", "--format", "md", str(EARLIER), str(FROZEN)],
], ids=lambda command: " ".join(Path(a).name for a in command))
def test_a_closed_stdout_ends_the_command_quietly(command: list[str], tmp_path: Path) -> None:
    # fmt --check names the file it would reformat: give it one to name
    (tmp_path / "unformatted.rules").write_text(FROZEN.read_text().replace("\n\n", "\n\n\n"))
    finished = run_into_closed_pipe(*command, cwd=tmp_path)
    assert finished.stderr.decode() == ""
    assert finished.returncode == BROKEN_PIPE_EXIT == 141


def test_an_open_stdout_is_unchanged(tmp_path: Path) -> None:
    """The same command with its reader present still prints and exits 0."""
    finished = subprocess.run([sys.executable, "-m", "idefix_rules", "check", str(FROZEN)],
                              cwd=tmp_path, capture_output=True, timeout=120, check=False,
                              env={**os.environ, "PYTHONPATH": str(REPOSITORY)})
    assert finished.returncode == 0
    assert finished.stdout.decode().strip().endswith(": ok")
