"""Benchmark: the results diff of two rulebook versions over a stored 3 × 1000-run campaign.

Builds (once, cached under ``benchmarks/.cache/``, git-ignored) the rock-detour campaign with
N runs per path on the real rover FMU (its four paths: three chains to the target and the
approach), then times ``idefix-verify diff OLD NEW --results results.h5`` of
``rulebooks/history/idefix-ops-0.9.0.rules`` → ``rulebooks/idefix-ops.rules``:

* the diff in this process (``diff_results``), and the command as a process of its own;
* the same with every run scored under both rulebooks (``reuse=False``: the campaign was
  evaluated with the new rulebook, whose per-run values the diff otherwise reads back);
* as the baseline, in the same run, the code before the read side (``baseline.py``:
  :data:`baseline.BASE_COMMIT`), in a process of its own, and its command.

Target (DESIGN.md): ≤ 2 s, no re-simulation.

    python benchmarks/bench_diff.py              # 3 × 1000 runs (first time: simulate, ~4 min)
    python benchmarks/bench_diff.py --runs 100   # a quick look
    python benchmarks/bench_diff.py --profile    # where the diff's time goes (cProfile)
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import statistics
import subprocess
import sys
import time
from pathlib import Path

from baseline import BASE_COMMIT, baseline_tree, timed_in_baseline

from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.runner import run_campaign
from idefix_rules.campaign.simulation.simulate import SimulationOptions
from idefix_rules.diff import load_source
from idefix_rules.diff.results import diff_results
from idefix_rules.results.format import FORMAT_VERSION
from idefix_rules.results.reader import StoredResults

ROOT = Path(__file__).resolve().parent.parent
CAMPAIGN = ROOT / "campaigns" / "rock-detour.yaml"
OLD = ROOT / "rulebooks" / "history" / "idefix-ops-0.9.0.rules"
NEW = ROOT / "rulebooks" / "idefix-ops.rules"
CACHE = Path(__file__).resolve().parent / ".cache"
TARGET_S = 2.0


def stored_campaign_file(runs: int, workers: int, rebuild: bool) -> Path:
    """The cached results file of the campaign with ``runs`` per path (simulated if needed)."""
    CACHE.mkdir(exist_ok=True)
    (CACHE / ".gitignore").write_text("*\n")
    folder = CACHE / f"rock-detour-{runs}"
    results = folder / "results.h5"
    campaign = load_campaign(CAMPAIGN).with_overrides(runs=runs, output=folder, workers=workers)
    if results.is_file() and not rebuild:
        store = StoredResults.open(results)
        try:
            fresh = (store.attrs.get("state") == "complete"
                     and int(store.attrs.get("runs", -1)) == runs
                     and int(store.attrs.get("format_version", 0)) == FORMAT_VERSION
                     and store.attrs.get("campaign_sha256") == campaign.sha256)
        finally:
            store.close()
        if fresh:
            print(f"stored campaign: {results} (cached)")
            return results
    started = time.perf_counter()
    run_campaign(campaign, SimulationOptions(workers=workers), report=False)
    print(f"stored campaign: {results} (simulated 3 paths x {runs} runs in "
          f"{time.perf_counter() - started:.0f} s)")
    return results


def time_diff(results: Path, threads: int, reuse: bool = True
              ) -> tuple[float, float, dict[str, float]]:
    """Wall time, CPU time of this process (all threads) and the diff's own breakdown."""
    old, new = load_source(str(OLD)), load_source(str(NEW))
    started, cpu = time.perf_counter(), time.process_time()
    diff = diff_results([results], old, new, threads=threads, reuse=reuse)
    return time.perf_counter() - started, time.process_time() - cpu, diff.files[0].timings


def time_command(results: Path, tree: Path) -> float:
    """Wall time of ``idefix-verify diff OLD NEW --results`` as a new process (imports
    included) with the package of ``tree``."""
    environment = {**os.environ, "PYTHONPATH": str(tree)}
    started = time.perf_counter()
    subprocess.run([sys.executable, "-m", "idefix_rules", "diff", str(OLD), str(NEW),
                    "--results", str(results), "--format", "json"], env=environment,
                   cwd=tree, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
    return time.perf_counter() - started


def time_baseline(results: Path, repeat: int) -> float:
    """The diff as the code before the read side did it (median of ``repeat``)."""
    code = (f"diff_results([Path({str(results)!r})], load_source({str(OLD)!r}), "
            f"load_source({str(NEW)!r}), threads=2)")
    setup = ("from pathlib import Path\nfrom idefix_rules.diff import load_source\n"
             "from idefix_rules.diff.results import diff_results")
    return statistics.median(timed_in_baseline(code, setup)["seconds"] for _ in range(repeat))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000, help="runs per path (default 1000)")
    parser.add_argument("--workers", type=int, default=2, help="simulation workers")
    parser.add_argument("--repeat", type=int, default=3, help="timed diffs (default 3)")
    parser.add_argument("--rebuild", action="store_true", help="simulate the campaign again")
    parser.add_argument("--profile", action="store_true", help="print a cProfile of one diff")
    parser.add_argument("--no-baseline", action="store_true", help="skip the baseline")
    parser.add_argument("--threads", type=int, default=2, help="diff threads (default 2)")
    args = parser.parse_args()
    results = stored_campaign_file(args.runs, args.workers, args.rebuild)
    size = results.stat().st_size / 1e9
    print(f"results file: {size:.2f} GB")
    print(f"load average before timing: {' '.join(f'{x:.1f}' for x in os.getloadavg())} "
          f"on {os.cpu_count()} cores")
    times = []
    for attempt in range(args.repeat):
        elapsed, cpu, parts = time_diff(results, args.threads)
        times.append(elapsed)
        shown = ", ".join(f"{k} {v:.2f} s" for k, v in parts.items())
        print(f"diff {attempt + 1} ({args.threads} thread(s)): {elapsed:.2f} s wall, "
              f"{cpu:.2f} s CPU ({shown})")
    median = statistics.median(times)
    print(f"diff of two rulebook versions over 3 x {args.runs} stored runs: median "
          f"{median:.2f} s, best {min(times):.2f} s (target <= {TARGET_S:.0f} s: "
          f"{'met' if median <= TARGET_S else f'missed by {median / TARGET_S:.1f}x'})")
    rescored, cpu, _ = time_diff(results, args.threads, reuse=False)
    print(f"the same, every run scored under both rulebooks: {rescored:.2f} s wall, "
          f"{cpu:.2f} s CPU")
    command = time_command(results, ROOT)
    print(f"idefix-verify diff OLD NEW --results (a new process, imports included): "
          f"{command:.2f} s")
    if not args.no_baseline:
        baseline = time_baseline(results, max(1, min(args.repeat, 2)))
        print(f"baseline, the code at {BASE_COMMIT} (before the read side): diff "
              f"{baseline:.2f} s; now {median:.2f} s: {baseline / median:.1f}x faster")
        before = time_command(results, baseline_tree())
        print(f"baseline command (imports included): {before:.2f} s; now {command:.2f} s: "
              f"{before / command:.1f}x faster")
    if args.profile:
        profiler = cProfile.Profile()
        profiler.enable()
        time_diff(results, 1)
        profiler.disable()
        pstats.Stats(profiler).sort_stats("tottime").print_stats(25)


if __name__ == "__main__":
    main()
