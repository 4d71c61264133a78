"""The walk-through of docs/testing-rulebooks.md, replayed: the limit changed as it says, the
cases fail as it shows, and the edits it gives make them pass again."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "testing-rulebooks.md"


def _test(folder: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "idefix_rules", "test", "rulebooks/tests"],
                          cwd=folder, capture_output=True, text=True, env={
                              "PATH": "/usr/bin:/bin", "COLUMNS": "200", "NO_COLOR": "1",
                              "PYTHONPATH": str(ROOT)}, check=False)


def test_the_walk_through_shows_the_cases_that_fail_and_the_edits_that_mend_them(tmp_path):
    doc = DOC.read_text(encoding="utf-8")
    shutil.copytree(ROOT / "rulebooks", tmp_path / "rulebooks")
    rules = tmp_path / "rulebooks" / "idefix-ops.rules"
    text = rules.read_text(encoding="utf-8")
    assert "const critical_slip            = 70 %" in text
    rules.write_text(text.replace("const critical_slip            = 70 %",
                                  "const critical_slip            = 50 %"), encoding="utf-8")
    failed = _test(tmp_path)
    assert failed.returncode == 1, failed.stdout + failed.stderr
    shown = doc[doc.index("### 3. Run the example cases"):doc.index("### 4.")]
    # the failures and their numbers, as the page prints them
    for line in failed.stdout.splitlines():
        if line.startswith("FAILED") or "expected" in line:
            assert line.strip() in shown, f"the page does not show: {line.strip()}"
    summary = re.search(r"\d+ failed, \d+ passed", failed.stdout)
    assert summary is not None and summary.group(0) in shown
    # the edits the page gives: the two cases keep meaning what their descriptions say
    cases = tmp_path / "rulebooks" / "tests" / "idefix-ops.yaml"
    body = cases.read_text(encoding="utf-8")
    edited = body.replace(
        '  slip_steady_45:\n    description: "45 % slip, half-way from the nominal 20 % to the '
        'critical 70 %: 0.75"\n    signals:\n      wheel.slip[FL]: 45 %',
        '  slip_steady_35:\n    description: "35 % slip, half-way from the nominal 20 % to the '
        'critical 50 %: 0.75"\n    signals:\n      wheel.slip[FL]: 35 %')
    edited = edited.replace(
        '"Every run slips 50 % (0.8 on the graded scale): path risk 0.8"\n    runs: 10\n'
        '    signals:\n      wheel.slip[FL]: 50 %',
        '"Every run slips 38 % (0.8 on the graded scale): path risk 0.8"\n    runs: 10\n'
        '    signals:\n      wheel.slip[FL]: 38 %')
    assert edited.count("35 %") > body.count("35 %") and "slips 38 %" in edited
    assert 'description: "35 % slip, half-way from the nominal 20 % to the critical 50 %: ' \
        '0.75"' in shown and "38 %" in shown
    cases.write_text(edited, encoding="utf-8")
    mended = _test(tmp_path)
    assert mended.returncode == 0, mended.stdout + mended.stderr
