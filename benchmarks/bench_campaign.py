"""Benchmark: the rock-detour campaign (3 paths) with N runs per path on 1 and 2 workers.

Prints, per worker count, the wall time of the whole campaign (simulation + evaluation, no
report), runs per second, and the share of the workers' time spent outside the FMU (everything
but ``FmuRunner.run``: pool, pickling, HDF5 writes, sampling); then the speed-up from 1 to 2
workers measured in the same invocation. Targets (DESIGN.md): 3 × 1000 runs in ≤ 5 minutes on
2 cores, ≥ 1.8× speed-up.

    python benchmarks/bench_campaign.py            # 3 × 1000 runs (a few minutes, ~6 GB disk)
    python benchmarks/bench_campaign.py --runs 100 # a quick look
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.runner import run_campaign
from idefix_rules.campaign.simulation.simulate import SimulationOptions

CAMPAIGN = Path(__file__).resolve().parent.parent / "campaigns" / "rock-detour.yaml"


def measure(runs: int, workers: int, folder: Path) -> dict[str, float]:
    campaign = load_campaign(CAMPAIGN).with_overrides(runs=runs, output=folder / f"w{workers}",
                                                      workers=workers)
    result = run_campaign(campaign, SimulationOptions(workers=workers), report=False)
    timings = dict(result.timings)
    shutil.rmtree(folder / f"w{workers}", ignore_errors=True)  # GBs at 1000 runs per path
    return timings


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000, help="runs per path (default 1000)")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()
    walls = {}
    with tempfile.TemporaryDirectory(prefix="bench-campaign-") as tmp:
        for workers in args.workers:
            t = measure(args.runs, workers, Path(tmp))
            total, simulation = t["total"], t["preparation_and_simulation"]
            runs = t["simulated_runs"]
            outside = 1.0 - t["inside_fmu"] / (workers * simulation)
            walls[workers] = total
            print(f"{workers} worker(s): 3 paths x {args.runs} runs in {total:.1f} s "
                  f"(simulation {simulation:.1f} s, evaluation {t['evaluation']:.1f} s); "
                  f"{runs / simulation:.1f} runs/s simulated; inside the FMU "
                  f"{t['inside_fmu']:.1f} s, share of worker time outside the FMU "
                  f"{100 * outside:.0f} %")
    if 1 in walls and len(walls) > 1:
        for workers, wall in walls.items():
            if workers != 1:
                print(f"speed-up 1 -> {workers} workers (whole campaign): "
                      f"{walls[1] / wall:.2f}x")


if __name__ == "__main__":
    main()
