"""Numbers the docs quote from the example campaign agree with each other and with a run of it.

The README, docs/ci.md and docs/results-format.md say how much a run of the example writes; a
change of the stored format or of the rover model that moves it must move the docs too."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
RUNS = 8  # per path: quick; the per-run size is measured on the Monte Carlo runs alone


def _text(name: str) -> str:
    return " ".join((ROOT / name).read_text(encoding="utf-8").split())


def quoted_per_run() -> dict[str, float]:
    """MB per run as each doc quotes it."""
    found = {
        "README.md": re.search(r"about (\d+\.\d+) MB per Monte Carlo run", _text("README.md")),
        "docs/ci.md": re.search(r"about (\d+\.\d+) MB per run for the example campaign",
                                _text("docs/ci.md")),
        "docs/results-format.md": re.search(r"(\d+\.\d+) MB per stored run for the example",
                                            _text("docs/results-format.md")),
    }
    missing = [name for name, match in found.items() if match is None]
    assert not missing, f"no per-run size quoted in {missing}"
    return {name: float(match.group(1)) for name, match in found.items() if match}


def test_the_docs_quote_one_size_per_run_and_the_readme_its_total() -> None:
    sizes = quoted_per_run()
    measured = sizes["docs/results-format.md"]
    for name, value in sizes.items():
        assert abs(value - measured) <= 0.01, (name, value, measured)
    total = re.search(r"about (\d+) MB, nearly all of it `results.h5`", _text("README.md"))
    assert total is not None
    # 3 paths × 128 runs of the example
    assert abs(float(total.group(1)) - 384 * measured) <= 0.1 * 384 * measured


@pytest.mark.slow
def test_a_run_of_the_example_writes_what_the_docs_say(tmp_path: Path) -> None:
    """Two short runs; the difference is what the extra Monte Carlo runs stored (the reference
    runs and fixed overhead cancel)."""
    sizes = []
    for runs in (RUNS, 2 * RUNS):
        out = tmp_path / f"runs-{runs}"
        done = subprocess.run(
            [sys.executable, "-m", "idefix_rules", str(ROOT / "campaigns" / "rock-detour.yaml"),
             "--runs", str(runs), "--workers", "2", "--no-report", "--quiet", "--out", str(out)],
            cwd=ROOT, capture_output=True, text=True, timeout=600, check=False)
        # (8 and 16 runs cannot show the wide detour's L2 chance below 10 %: exit 1)
        assert done.returncode == 1, done.stdout + done.stderr
        sizes.append((out / "results.h5").stat().st_size)
    per_run = (sizes[1] - sizes[0]) / (3 * RUNS) / 1e6
    quoted = quoted_per_run()["README.md"]
    assert 0.75 * quoted <= per_run <= 1.25 * quoted, (per_run, quoted)
