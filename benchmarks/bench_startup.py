"""Start-up benchmark: ``idefix-verify --version``, ``--help`` and each command's ``--help``.

Each figure is the wall-clock time of a new process (the best of ``--repeat`` runs, since the
machine is shared), with the CPU time (user + system) of that best run and the number of
modules the process imported. Measured in the same run, as baselines:

* the interpreter alone (``python -c pass``): the floor no command can go below;
* the eager imports the tool used to make before any command ran (numpy, h5py, scipy.stats,
  pydantic, lark, rich, yaml, fmpy): what ``--version`` cost when the CLI imported every
  command's dependencies up front.

Target: ``--version`` and ``--help`` in at most 0.3 s of wall-clock time.

    python benchmarks/bench_startup.py [--repeat 7]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGET_SECONDS = 0.3
EAGER_IMPORTS = ("numpy", "h5py", "scipy.stats", "pydantic", "lark", "rich.console", "yaml",
                 "fmpy")
COMMANDS = ("run", "evaluate", "check", "fmt", "explain", "diff", "test", "explain-error",
            "report", "build-fmu", "lsp")
# Prints how many modules the process imported, after the command ran (argparse exits).
COUNT_MODULES = "import atexit, sys; atexit.register(lambda: print(len(sys.modules), " \
                "file=sys.stderr))"


def measure(arguments: list[str], repeat: int) -> tuple[float, float, int]:
    """Best wall-clock seconds of ``repeat`` runs, the CPU seconds of that run, and the number
    of modules imported."""
    environment = {**os.environ, "PYTHONPATH": str(ROOT)}
    best = (float("inf"), 0.0)
    for _ in range(repeat):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        started = time.perf_counter()
        subprocess.run(arguments, cwd=ROOT, env=environment, check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        wall = time.perf_counter() - started
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        best = min(best, (wall, cpu))
    modules = subprocess.run([sys.executable, "-c", f"{COUNT_MODULES}\n{_body(arguments)}"],
                             cwd=ROOT, env=environment, capture_output=True, text=True)
    count = int(modules.stderr.strip().splitlines()[-1]) if modules.stderr.strip() else 0
    return best[0], best[1], count


def _body(arguments: list[str]) -> str:
    """The Python text a measured command line runs, for the module count."""
    if arguments[1] == "-c":
        return arguments[2]
    rest = arguments[arguments.index("idefix_rules") + 1:] if "idefix_rules" in arguments \
        else arguments[1:]
    return f"import sys\nfrom idefix_rules.cli import main\nsys.exit(main({rest!r}))"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    python = sys.executable
    tool = [python, "-m", "idefix_rules"]
    available = [name for name in EAGER_IMPORTS if _importable(name)]
    rows = [("python -c pass (interpreter floor)", [python, "-c", "pass"]),
            ("eager imports (baseline)", [python, "-c", f"import {', '.join(available)}"]),
            ("idefix-verify --version", [*tool, "--version"]),
            ("idefix-verify --help", [*tool, "--help"])]
    rows += [(f"idefix-verify {name} --help", [*tool, name, "--help"]) for name in COMMANDS]
    script = Path(sys.executable).with_name("idefix-verify")
    if script.is_file():  # the installed entry point, started as a shell starts it
        rows.append(("installed idefix-verify --version", [str(script), "--version"]))
    print(f"python {sys.version.split()[0]}, best of {args.repeat}, target <= "
          f"{TARGET_SECONDS} s for --version and --help")
    print(f"eager imports: import {', '.join(available)}")
    print(f"{'command':<36} {'wall s':>7} {'cpu s':>6} {'modules':>7}")
    figures = {}
    for label, arguments in rows:
        wall, cpu, modules = measure(arguments, args.repeat)
        figures[label] = wall
        mark = ""
        if label in ("idefix-verify --version", "idefix-verify --help"):
            mark = "  ok" if wall <= TARGET_SECONDS else "  OVER TARGET"
        print(f"{label:<36} {wall:7.3f} {cpu:6.3f} {modules:7d}{mark}")
    floor = figures["python -c pass (interpreter floor)"]
    version = figures["idefix-verify --version"]
    eager = figures["eager imports (baseline)"]
    print(f"--version above the interpreter floor: {version - floor:.3f} s; the eager imports "
          f"alone: {eager - floor:.3f} s above it")


def _importable(name: str) -> bool:
    import importlib.util

    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:
        return False


if __name__ == "__main__":
    main()
