"""Benchmark: what fault handling costs, measured against a baseline in the same run.

1. Refusing inputs that are too large: the wall time of ``idefix-verify check`` on a 50 MB
   rulebook (refused, exit 2) against the same command on the operations rulebook (parsed and
   checked, exit 0). A refusal should cost about as much as checking a normal rulebook.
2. Executors: the rock-detour campaign with N runs per path on the local process pool and on
   a local Dask cluster (every Dask run in a child process of its worker, with a timeout): runs
   per second on each and the ratio.

    python benchmarks/bench_faults.py              # 40 runs per path
    python benchmarks/bench_faults.py --runs 100
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from idefix_rules.campaign.load import load_campaign
from idefix_rules.campaign.runner import run_campaign
from idefix_rules.campaign.simulate import SimulationOptions

ROOT = Path(__file__).resolve().parent.parent
CAMPAIGN = ROOT / "campaigns" / "rock-detour.yaml"
RULEBOOK = ROOT / "rulebooks" / "idefix-ops.rules"


def timed_check(path: Path) -> tuple[float, int]:
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "idefix_rules", "check", str(path)],
                          capture_output=True, timeout=600)
    return time.perf_counter() - started, done.returncode


def refusal(folder: Path) -> None:
    huge = folder / "huge.rules"
    with huge.open("wb") as handle:  # the operations rulebook, then zeros up to 50 MB
        handle.write(RULEBOOK.read_bytes())
        handle.truncate(50 * 1024 * 1024)
    normal, normal_code = timed_check(RULEBOOK)
    refused, refused_code = timed_check(huge)
    print(f"check {RULEBOOK.name} ({RULEBOOK.stat().st_size} bytes): {normal:.2f} s, exit "
          f"{normal_code}")
    print(f"check a 50 MB rulebook: {refused:.2f} s, exit {refused_code} "
          f"(ratio to the normal check: {refused / normal:.2f})")


def campaign_rate(runs: int, folder: Path, options: SimulationOptions, name: str) -> float:
    campaign = load_campaign(CAMPAIGN).with_overrides(runs=runs, output=folder / name,
                                                      workers=2)
    result = run_campaign(campaign, options, report=False)
    seconds = result.timings["preparation_and_simulation"]
    rate = result.timings["simulated_runs"] / seconds
    print(f"{name}: {int(result.timings['simulated_runs'])} runs simulated in {seconds:.1f} s "
          f"(reference runs and start-up included): {rate:.1f} runs/s")
    return rate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=40, help="runs per path (default 40)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-faults-") as name:
        folder = Path(name)
        refusal(folder)
        local = campaign_rate(args.runs, folder, SimulationOptions(workers=2), "process pool")
        dask = campaign_rate(args.runs, folder, SimulationOptions(workers=2, dask_local=True),
                             "local Dask cluster")
        print(f"Dask / process pool: {dask / local:.2f}")


if __name__ == "__main__":
    main()
