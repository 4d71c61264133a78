"""The code before the read side (``idefix_rules.results``), for the baselines of
``bench_diff.py`` and ``bench_report.py``: the package exported from :data:`BASE_COMMIT` into
``benchmarks/.cache/`` and timed in a process of its own (``PYTHONPATH`` set to it), in the
same run as the present code.

    from baseline import timed_in_baseline
    seconds = timed_in_baseline("from idefix_rules.report import write_report\\n"
                                "write_report(results, out)", results=..., out=...)
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CACHE = Path(__file__).resolve().parent / ".cache"
# main before the read side was written: results read back in three places, h5py reading
BASE_COMMIT = "f6d263a"

TIMER = """
import json, sys, time
started = time.perf_counter()
import idefix_rules
assert idefix_rules.__file__.startswith({tree!r}), idefix_rules.__file__
{setup}
ready = time.perf_counter()
{code}
print(json.dumps({{"seconds": time.perf_counter() - ready,
                  "with_imports": time.perf_counter() - started}}))
"""


def baseline_tree(commit: str = BASE_COMMIT) -> Path:
    """The package as it was at ``commit``, exported once under ``benchmarks/.cache/``."""
    target = CACHE / f"baseline-{commit}"
    if (target / "idefix_rules" / "__init__.py").is_file():
        return target
    CACHE.mkdir(exist_ok=True)
    (CACHE / ".gitignore").write_text("*\n")
    with tempfile.TemporaryFile() as archive:
        subprocess.run(["git", "archive", "--format=tar", commit, "idefix_rules", "grammar"],
                       cwd=ROOT, stdout=archive, check=True)
        archive.seek(0)
        with tarfile.open(fileobj=archive) as tar:
            tar.extractall(target, filter="data")
    return target


def timed_in(tree: Path, code: str, setup: str = "") -> dict[str, float]:
    """Seconds ``code`` takes (after ``setup``) in a new process importing the package from
    ``tree``; ``with_imports`` counts the process's imports too."""
    program = TIMER.format(tree=str(tree), setup=setup, code=code)
    environment = {**os.environ, "PYTHONPATH": str(tree)}
    done = subprocess.run([sys.executable, "-c", program], env=environment, cwd=tree,
                          capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"the baseline failed:\n{done.stderr[-3000:]}")
    result: dict[str, float] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


def timed_in_baseline(code: str, setup: str = "", commit: str = BASE_COMMIT
                      ) -> dict[str, float]:
    """:func:`timed_in` on the package at ``commit``."""
    return timed_in(baseline_tree(commit), code, setup)


def timed_now(code: str, setup: str = "") -> dict[str, float]:
    """:func:`timed_in` on the present package (this work tree), in a process of its own."""
    return timed_in(ROOT, code, setup)
