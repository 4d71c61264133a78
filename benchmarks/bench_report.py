"""Benchmark: the example's report (``campaigns/rock-detour.yaml``, 4 paths × 128 runs)
written from its stored results.

Simulates the example once (cached under ``benchmarks/.cache/``, git-ignored), then times
``write_report`` — what ``idefix-verify campaigns/rock-detour.yaml`` does after its
evaluation, and ``idefix-verify report results.h5`` without its imports — and the report
command as a new process. As the baseline, in the same run, the code before the read side
(``baseline.py``: :data:`baseline.BASE_COMMIT`), in a process of its own, and its command.

Target (DESIGN.md): the report written in ≤ 3 s.

    python benchmarks/bench_report.py [--repeat 3] [--profile]
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from baseline import BASE_COMMIT, baseline_tree, timed_in_baseline

from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.runner import run_campaign
from idefix_rules.campaign.simulation.simulate import SimulationOptions
from idefix_rules.report import write_report
from idefix_rules.results.format import FORMAT_VERSION
from idefix_rules.results.reader import StoredResults

ROOT = Path(__file__).resolve().parent.parent
CAMPAIGN = ROOT / "campaigns" / "rock-detour.yaml"
CACHE = Path(__file__).resolve().parent / ".cache"
TARGET_S = 3.0


def example_results(workers: int, rebuild: bool) -> Path:
    """The cached results file of the example campaign (simulated and evaluated if needed)."""
    CACHE.mkdir(exist_ok=True)
    (CACHE / ".gitignore").write_text("*\n")
    folder = CACHE / "rock-detour-example"
    results = folder / "results.h5"
    campaign = load_campaign(CAMPAIGN).with_overrides(output=folder, workers=workers)
    if results.is_file() and not rebuild:
        store = StoredResults.open(results)
        try:
            fresh = (store.attrs.get("state") == "complete"
                     and int(store.attrs.get("format_version", 0)) == FORMAT_VERSION
                     and store.attrs.get("campaign_sha256") == campaign.sha256
                     and "evaluation" in store.file)
        finally:
            store.close()
        if fresh:
            print(f"stored example: {results} (cached)")
            return results
    started = time.perf_counter()
    run_campaign(campaign, SimulationOptions(workers=workers), report=False)
    print(f"stored example: {results} (simulated and evaluated in "
          f"{time.perf_counter() - started:.0f} s)")
    return results


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def time_report(results: Path) -> tuple[float, float, float]:
    """Wall seconds of one report, and the CPU seconds of this process (its reading threads
    included) and of the processes that draw its figures: on a shared machine the CPU time
    says what the report costs when the wall time mostly says how busy the machine was."""
    with tempfile.TemporaryDirectory() as out:
        cpu, children = time.process_time(), _children_cpu()
        started = time.perf_counter()
        write_report(results, Path(out))
        return (time.perf_counter() - started, time.process_time() - cpu,
                _children_cpu() - children)


def time_command(results: Path, tree: Path) -> float:
    """Wall time of ``idefix-verify report results.h5 -o DIR`` as a new process (imports
    included) with the package of ``tree``."""
    environment = {**os.environ, "PYTHONPATH": str(tree)}
    with tempfile.TemporaryDirectory() as out:
        started = time.perf_counter()
        subprocess.run([sys.executable, "-m", "idefix_rules", "report", str(results), "-o",
                        out], env=environment, cwd=tree, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL, check=True)
        return time.perf_counter() - started


def time_baseline(results: Path, repeat: int) -> float:
    setup = ("import tempfile\nfrom pathlib import Path\n"
             "from idefix_rules.report import write_report")
    code = f"write_report(Path({str(results)!r}), Path(tempfile.mkdtemp()))"
    return statistics.median(timed_in_baseline(code, setup)["seconds"] for _ in range(repeat))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2, help="simulation workers")
    parser.add_argument("--repeat", type=int, default=3, help="timed reports (default 3)")
    parser.add_argument("--rebuild", action="store_true", help="simulate the example again")
    parser.add_argument("--profile", action="store_true", help="print a cProfile of one report")
    parser.add_argument("--no-baseline", action="store_true", help="skip the baseline")
    args = parser.parse_args()
    results = example_results(args.workers, args.rebuild)
    print(f"load average before timing: {' '.join(f'{x:.1f}' for x in os.getloadavg())} "
          f"on {os.cpu_count()} cores")
    times = []
    for attempt in range(args.repeat):
        wall, cpu, drawing = time_report(results)
        times.append(wall)
        print(f"report {attempt + 1}: {wall:.2f} s (CPU {cpu:.2f} s in the process, "
              f"{drawing:.2f} s drawing; load {os.getloadavg()[0]:.1f})")
    median = statistics.median(times)
    print(f"the example's report from its stored results: median {median:.2f} s, best "
          f"{min(times):.2f} s (target <= {TARGET_S:.0f} s: "
          f"{'met' if median <= TARGET_S else f'missed by {median / TARGET_S:.1f}x'})")
    command = time_command(results, ROOT)
    print(f"idefix-verify report results.h5 (a new process, imports included): {command:.2f} s"
          f" (load {os.getloadavg()[0]:.1f})")
    if not args.no_baseline:
        baseline = time_baseline(results, max(1, min(args.repeat, 2)))
        print(f"baseline, the code at {BASE_COMMIT} (before the read side): report "
              f"{baseline:.2f} s; now {median:.2f} s: {baseline / median:.1f}x faster "
              f"(load {os.getloadavg()[0]:.1f})")
        before = time_command(results, baseline_tree())
        print(f"baseline command (imports included): {before:.2f} s; now {command:.2f} s: "
              f"{before / command:.1f}x faster (load {os.getloadavg()[0]:.1f})")
    if args.profile:  # of this process: the figures are drawn in processes of their own
        profiler = cProfile.Profile()
        profiler.enable()
        time_report(results)
        profiler.disable()
        pstats.Stats(profiler).sort_stats("cumulative").print_stats(30)


if __name__ == "__main__":
    main()
