"""A rule engineer's routine change breaks none of the project's tests.

New information says the regolith is softer: the critical slip goes from 70 % to 60 %, the
obstacle factors become L1 0.3 and L2 0.8, and a sinkage-change index is added; the engineer
formats the file, raises the version and keeps it in ``rulebooks/history/``. On a copy of the
repository so changed, the fast suites that once hard-coded the operational rulebook (parser,
checker, diff, language server, grammar, case runner, command line) must pass. Only the
engineer's own cases (``tests/testing/test_testing_default_cases.py``) are left out: they
describe the old rules and are the engineer's to update.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

REPOSITORY = Path(__file__).resolve().parents[1]
# in two halves of about a minute each, run side by side (one per core)
SUITES = (("tests/rulebook",),
          ("tests/diff", "tests/lsp", "tests/testing", "tests/cli", "tests/test_units.py"))
ENGINEERS_OWN = ("tests/testing/test_testing_default_cases.py",
                 "tests/test_rule_engineer_change.py")
_NOT_COPIED = shutil.ignore_patterns(".git", "__pycache__", "*.pyc", ".pytest_cache",
                                     ".mypy_cache", ".ruff_cache", ".hypothesis", "*.egg-info",
                                     "build", "out", "*.h5")


def ignored(folder: str, names: list[str]) -> set[str]:
    """What the copy leaves out: caches, builds, results files, and the campaigns' output
    folder ``results/`` at the top (not the ``results`` packages of the code and tests)."""
    left_out = set(_NOT_COPIED(folder, names))
    if Path(folder).resolve() == REPOSITORY.resolve() and "results" in names:
        left_out.add("results")
    return left_out

NEW_INDEX = """
index I_dsc "sinkage change" {
  value  = max over time (max over wheels (wheel.sinkage)) - initial over time (max over wheels (wheel.sinkage))
  limit  = critical_sinkage
  weight = 1
  because "Assumption: sinkage the drive adds to the static sinkage; the softer regolith lets a wheel dig in"
}
"""  # noqa: E501 (a line as an engineer writes it; fmt keeps it)


def replace_once(text: str, before: str, after: str) -> str:
    assert text.count(before) == 1, f"the operational rulebook no longer has {before!r}"
    return text.replace(before, after)


def edit_like_a_rule_engineer(repository: Path) -> str:
    """Change the operational rulebook of ``repository``; return its new version."""
    live = repository / "rulebooks" / "idefix-ops.rules"
    text = live.read_text(encoding="utf-8")
    version = text.split('version "', 1)[1].split('"', 1)[0]
    major, minor, _ = version.split(".")
    new_version = f"{major}.{int(minor) + 1}.0"
    text = replace_once(text, f'version "{version}"', f'version "{new_version}"')
    text = replace_once(text, "critical_slip            = 70 %", "critical_slip            = 60 %")
    text = replace_once(text, '"Slip above 70 % is critical', '"Slip above 60 % is critical')
    text = replace_once(text, "sustained slip above 70 % critical",
                        "sustained slip above 60 % critical")
    text = replace_once(text, "{L1: 0.2, L2: 0.6, L3: 1}", "{L1: 0.3, L2: 0.8, L3: 1}")
    text = replace_once(text, "\nindex I_obs ", NEW_INDEX + "\nindex I_obs ")
    live.write_text(text, encoding="utf-8")
    return new_version


def start(repository: Path, *arguments: str) -> subprocess.Popen[str]:
    environment = {**os.environ, "PYTHONPATH": str(repository), "PYTHONDONTWRITEBYTECODE": "1"}
    return subprocess.Popen([sys.executable, *arguments], cwd=repository, env=environment,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def finish(process: subprocess.Popen[str]) -> subprocess.CompletedProcess[str]:
    try:
        out, err = process.communicate(timeout=900)
    except subprocess.TimeoutExpired:
        process.kill()
        out, err = process.communicate()
    return subprocess.CompletedProcess(process.args, process.returncode, out, err)


def run(repository: Path, *arguments: str) -> subprocess.CompletedProcess[str]:
    return finish(start(repository, *arguments))


def keep_in_history(repository: Path, version: str) -> None:
    text = (repository / "rulebooks" / "idefix-ops.rules").read_text(encoding="utf-8")
    header = (f"# EARLIER VERSION {version} of rulebooks/idefix-ops.rules, kept so that results "
              "can be compared\n# across rulebook versions (diff). Do not edit: the current rules "
              "are in rulebooks/idefix-ops.rules.\n")
    history = repository / "rulebooks" / "history" / f"idefix-ops-{version}.rules"
    history.write_text(header + text, encoding="utf-8")


def test_a_routine_rule_change_passes_the_projects_fast_suites(tmp_path: Path) -> None:
    copy = tmp_path / "repository"
    shutil.copytree(REPOSITORY, copy, ignore=ignored)
    version = edit_like_a_rule_engineer(copy)
    formatted = run(copy, "-m", "idefix_rules", "fmt", "rulebooks/idefix-ops.rules")
    assert formatted.returncode == 0, formatted.stdout + formatted.stderr
    checked = run(copy, "-m", "idefix_rules", "check", "--strict", "rulebooks/idefix-ops.rules")
    assert checked.returncode == 0, checked.stdout + checked.stderr
    keep_in_history(copy, version)

    halves = [start(copy, "-m", "pytest", *half, "-m", "not slow", "-q", "-x",
                    "-p", "no:cacheprovider", *(f"--ignore={own}" for own in ENGINEERS_OWN))
              for half in SUITES]
    for suites in map(finish, halves):
        assert suites.returncode == 0, suites.stdout[-6000:] + suites.stderr[-2000:]
        assert " passed" in suites.stdout.splitlines()[-1]
