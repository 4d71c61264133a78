"""Benchmark: what fault handling costs, measured against a baseline in the same run.

1. Refusing inputs that are too large: the wall time of ``idefix-verify check`` on a 50 MB
   rulebook (refused, exit 2) against the same command on the operations rulebook (parsed and
   checked, exit 0). A refusal should cost about as much as checking a normal rulebook.
2. Checking is linear in what is accepted: the time to check generated rulebooks of 16, 32, 64
   and 128 KiB (the limit), constants holding sums of 250 lengths, per KiB; the ratio of the
   largest to the smallest per-KiB figure is about 1 when the time is linear in the size.
3. Executors: the rock-detour campaign with N runs per path on the local process pool and on
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

from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.runner import run_campaign
from idefix_rules.campaign.simulation.simulate import SimulationOptions

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


def generated_rulebook(size: int) -> str:
    """The operations rulebook plus constants with long sums until ``size`` bytes."""
    text = RULEBOOK.read_text(encoding="utf-8")
    lines = []
    index = 0
    while len(text) + sum(map(len, lines)) < size - 2 * 1100:
        lines.append(f"const generated_{index} = " + " + ".join(["1 m"] * 250) + "\n")
        index += 1
    return text + "".join(lines)


def linearity() -> None:
    from idefix_rules.rulebook import check_text

    per_kib = []
    for kib in (16, 32, 64, 128):
        text = generated_rulebook(kib * 1024)
        started = time.perf_counter()
        result = check_text(text, "generated.rules")
        seconds = time.perf_counter() - started
        assert result.checked is not None, result.errors[:1]
        per_kib.append(seconds / (len(text) / 1024))
        print(f"check a {len(text) / 1024:.0f} KiB rulebook: {seconds:.2f} s "
              f"({1000 * per_kib[-1]:.1f} ms per KiB)")
    print(f"per-KiB time, 128 KiB against 16 KiB: {per_kib[-1] / per_kib[0]:.2f}")


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
        linearity()
        local = campaign_rate(args.runs, folder, SimulationOptions(workers=2), "process pool")
        dask = campaign_rate(args.runs, folder, SimulationOptions(workers=2, dask_local=True),
                             "local Dask cluster")
        print(f"Dask / process pool: {dask / local:.2f}")


if __name__ == "__main__":
    main()
