"""Ctrl-C pressed just as a command ends (a long campaign finishing) prints no traceback and
leaves the command's exit code: once the command has said what it had to say, the process
ignores SIGINT while the interpreter shuts down (``idefix_rules.cli.process_main``)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPOSITORY = Path(__file__).resolve().parents[2]

# The interrupt is delivered by the process to itself after the command returned, where a
# user's Ctrl-C at the end of a campaign arrives: no timing involved.
INTERRUPTED_AT_EXIT = """
import os, signal, sys
from idefix_rules.cli import process_main
sys.argv = ["idefix-verify", *sys.argv[1:]]
code = process_main()
os.kill(os.getpid(), signal.SIGINT)
sys.exit(code)
"""


def interrupted_at_exit(*arguments: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", INTERRUPTED_AT_EXIT, *arguments],
                          capture_output=True, text=True, timeout=120, check=False,
                          env={**os.environ, "PYTHONPATH": str(REPOSITORY)})


def test_ctrl_c_after_the_command_keeps_its_exit_code_and_prints_no_traceback() -> None:
    done = interrupted_at_exit("--version")
    assert done.returncode == 0
    assert done.stdout.startswith("idefix-rules ")
    assert "Traceback" not in done.stderr and "KeyboardInterrupt" not in done.stderr


def test_a_failing_command_keeps_its_exit_code_when_interrupted_at_exit(tmp_path: Path) -> None:
    missing = tmp_path / "missing.rules"
    done = interrupted_at_exit("check", str(missing))
    assert done.returncode == 2
    assert "missing.rules" in done.stdout + done.stderr
    assert "Traceback" not in done.stderr


def test_the_console_script_and_the_module_end_through_process_main() -> None:
    text = (REPOSITORY / "pyproject.toml").read_text()
    assert 'idefix-verify = "idefix_rules.cli:process_main"' in text
    assert "process_main()" in (REPOSITORY / "idefix_rules" / "__main__.py").read_text()


def test_an_error_a_ctrl_c_caused_is_an_interrupt_not_an_internal_error(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """Ctrl-C inside a C extension's initialisation (scipy imported as it came) surfaces as
    the ImportError it caused: "interrupted", exit 130, no traceback (it was exit 3, "internal
    error", with scipy's traceback). An error with no interrupt behind it stays exit 3."""
    from idefix_rules import cli
    from idefix_rules.cli import check

    def interrupted_import(args: object) -> int:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as interrupt:
            raise ImportError("initialization failed") from interrupt

    monkeypatch.setattr(check, "run", interrupted_import)
    assert cli.main(["check", "any.rules"]) == 130
    captured = capsys.readouterr()
    assert captured.err == "interrupted\n", captured.err

    def failing(args: object) -> int:
        raise ImportError("initialization failed")

    monkeypatch.setattr(check, "run", failing)
    assert cli.main(["check", "any.rules"]) == 3
    assert "internal error (exit 3)" in capsys.readouterr().err
