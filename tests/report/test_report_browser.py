"""The report opens in headless Chromium, renders to a screenshot, and logs nothing.

Chromium runs from a fresh profile, offline flags, file:// URL. Console messages are read from
Chromium's own log on stderr (``--enable-logging=stderr``), where every console message and
uncaught exception is a ``CONSOLE`` line; the report has no script, so any such line is an error.
A test page that logs an error proves the detector sees one. Without chromium the test is
skipped, except in CI (``CI`` set), where ``.ci/run`` installs it and its absence is a failure.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import pytest

from idefix_rules.report import write_report

CONSOLE_LINE = re.compile(r":CONSOLE[:(]|Uncaught", re.IGNORECASE)


def _chromium() -> str:
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if found is None:
        if os.environ.get("CI"):
            pytest.fail("chromium is not installed in CI (.ci/run installs Debian's chromium)")
        pytest.skip("chromium not installed (apt-get install chromium); CI installs it")
    return found


def render(page: Path, screenshot: Path, height: int = 2400) -> list[str]:
    """Screenshot ``page`` with headless Chromium; returns the console lines it logged."""
    browser = _chromium()
    with tempfile.TemporaryDirectory() as profile:
        completed = subprocess.run(
            [browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
             "--no-first-run", "--disable-background-networking",
             "--disable-component-update", "--disable-sync", f"--user-data-dir={profile}",
             "--enable-logging=stderr", "--v=0", f"--screenshot={screenshot}",
             f"--window-size=1300,{height}", page.resolve().as_uri()],
            capture_output=True, text=True, timeout=180, check=False)
    assert completed.returncode == 0, completed.stderr[-2000:]
    return [line for line in completed.stderr.splitlines() if CONSOLE_LINE.search(line)]


def test_the_detector_flags_a_console_error(tmp_path: Path) -> None:
    page = tmp_path / "broken.html"
    page.write_text("<!DOCTYPE html><html><body><p>broken</p><script>"
                    "console.error('deliberate error'); notAFunction();</script></body></html>",
                    encoding="utf-8")
    lines = render(page, tmp_path / "broken.png", height=300)
    assert any("deliberate error" in line for line in lines)
    assert any("Uncaught ReferenceError" in line for line in lines)


@pytest.mark.slow
def test_report_renders_without_console_errors(synthetic_results: Path, tmp_path: Path) -> None:
    page = write_report(synthetic_results, tmp_path / "out")
    screenshot = tmp_path / "report.png"
    lines = render(page, screenshot)
    assert lines == []
    data = screenshot.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(data) > 50_000  # a blank page compresses to a few kB
