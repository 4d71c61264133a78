"""`idefix-verify --version`, `--help` and every command's `--help` read the command line
without importing what the commands need to run (numpy, h5py, rich, the rulebook's parser …):
each command imports its dependencies when it runs. Checked on the modules a new process holds
afterwards, not on a clock (benchmarks/bench_startup.py measures the time)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from idefix_rules import __version__
from idefix_rules.cli import COMMAND_MODULES

# What a command needs only once it runs: each costs 50 ms to seconds to import.
HEAVY = frozenset({"numpy", "h5py", "scipy", "rich", "pydantic", "lark", "matplotlib", "fcl",
                   "yaml", "fmpy", "pygls", "dask", "distributed", "hypothesis"})
COMMAND_NAMES = ("run", "evaluate", "check", "fmt", "explain", "diff", "test", "explain-error",
                 "report", "build-fmu", "lsp", "worst")

PROBE = """\
import json, sys
from idefix_rules.cli import main
try:
    code = main(json.loads(sys.argv[1]))
except SystemExit as exit_request:
    code = exit_request.code
sys.stdout.flush()
print(json.dumps({"code": code, "modules": sorted(sys.modules)}), file=sys.stderr)
"""


def modules_after(argv: list[str]) -> tuple[str, int, set[str]]:
    """What ``idefix-verify ARGV`` printed, its exit code, and every module it imported."""
    done = subprocess.run([sys.executable, "-c", PROBE, json.dumps(argv)], capture_output=True,
                          text=True, timeout=120, check=False)
    report = json.loads(done.stderr.strip().splitlines()[-1])
    return done.stdout, int(report["code"] or 0), set(report["modules"])


def heavy_in(modules: set[str]) -> set[str]:
    return {name for name in modules if name.split(".")[0] in HEAVY}


def test_version_imports_nothing_heavy() -> None:
    out, code, modules = modules_after(["--version"])
    assert code == 0 and out.strip() == f"idefix-rules {__version__}"
    assert not heavy_in(modules)
    # no command module either: --version reads nothing but the version
    assert not {name for name in modules if name.startswith(("idefix_rules.campaign",
                                                             "idefix_rules.rulebook"))}


def test_help_lists_every_command_without_importing_anything_heavy() -> None:
    out, code, modules = modules_after(["--help"])
    assert code == 0
    for name in COMMAND_NAMES:
        assert name in out
    assert not heavy_in(modules)


@pytest.mark.parametrize("name", COMMAND_NAMES)
def test_each_commands_help_imports_nothing_heavy(name: str) -> None:
    out, code, modules = modules_after([name, "--help"])
    assert code == 0 and f"usage: idefix-verify {name}" in out
    assert not heavy_in(modules), sorted(heavy_in(modules))


def test_every_command_module_is_named_here() -> None:
    import importlib

    names = {importlib.import_module(f"idefix_rules.cli.{module}").NAME
             for module in COMMAND_MODULES}
    assert names == set(COMMAND_NAMES)


def test_the_nudge_default_is_the_mutations_one() -> None:
    from idefix_rules.cli.test import DEFAULT_NUDGE_PERCENT
    from idefix_rules.testing.mutations import NUDGE

    assert pytest.approx(DEFAULT_NUDGE_PERCENT) == NUDGE * 100
