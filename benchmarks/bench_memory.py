"""Benchmark: the campaign process's memory does not grow with the number of runs.

The process that runs a campaign (the parent of the workers, which simulate) records its
resident memory (``/proc/self/status``, Linux):

* its peak during the simulation stage (reference runs, then the Monte Carlo runs streamed to
  the workers and stored as they finish) and its resident memory when that stage ends;
* its peak during the evaluation stage (the peak is reset when the simulation ends, through
  ``/proc/self/clear_refs``).

Each measurement runs in a fresh process, at several sizes; the first is the baseline, and the
ratio of a larger size's figure to it is 1 for memory flat in the run count. The same with the
code before the runs were streamed (:data:`PREVIOUS`, exported once under
``benchmarks/.cache/``) is the second baseline, in the same invocation.

* ``toy``: the whole campaign (simulation and evaluation) of the campaign tests' toy FMU
  (``tests/campaign/toy_fmu``, compiled with gcc) with its two simulated paths (a third is
  rejected by a command rule), at 1,000, 10,000 and 30,000 runs **per path** (twice that in
  all): 10k / 1k is the ratio asked for, 30k / 10k shows what still grows once HDF5's own
  bookkeeping of a file's chunks has reached its bound (docs/operations.md, "Memory");
* ``rock-detour``: the evaluation stage of the example (``campaigns/rock-detour.yaml``, built-in
  rover FMU, four paths, runs of 2,700 to 9,600 samples, collision checks on 2 processes) at
  256, 1,000 and 10,000 runs per path, from its stored campaign of 1,000 runs per path
  (``bench_diff.py``'s, simulated once into ``benchmarks/.cache/`` when missing: about 4,000
  runs): 256 are its first runs, 10,000 a copy whose run ``j`` is the stored run ``j mod 1000``
  (the compressed chunks copied as they are: about 8 GB in the temporary folder). What the
  evaluation holds depends on how many runs there are and how long they are, not on their
  values; simulating 40,000 runs would take about 45 minutes on 2 cores, and the toy shows the
  simulation stage.

    python benchmarks/bench_memory.py                      # about 25 minutes on 2 cores
    python benchmarks/bench_memory.py --no-previous        # the present code only
    python benchmarks/bench_memory.py --toy-runs 200 2000 --rover-runs 0  # a quick look
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
TOY_SOURCES = ROOT / "tests" / "campaign"
# the code before the Monte Carlo tasks were streamed (and before the evaluation's changes)
PREVIOUS = "376c387"


def memory_mb(key: str) -> float:
    """A line of ``/proc/self/status`` in MB (``VmRSS``: now; ``VmHWM``: the peak)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(f"{key}:"):
            return int(line.split()[1]) / 1024
    raise RuntimeError(f"no {key} in /proc/self/status")


def reset_peak() -> None:
    """Start the peak (VmHWM) again from the present resident memory."""
    Path("/proc/self/clear_refs").write_text("5")


class StageMemory:
    """The campaign's progress, used to see where the simulation ends: the runner says
    ``evaluating …`` once every run is stored."""

    def __init__(self) -> None:
        self.simulation_peak: float | None = None
        self.after_simulation: float | None = None

    def message(self, text: str) -> None:
        if text.startswith("evaluating") and self.simulation_peak is None:
            self.simulation_peak = memory_mb("VmHWM")
            self.after_simulation = memory_mb("VmRSS")
            reset_peak()

    def start_path(self, name: str, total: int, done: int) -> None:
        pass

    def run_finished(self, name: str, ok: bool) -> None:
        pass


# --- in the measuring process ---------------------------------------------------------------

def stage_module(now: str, before: str) -> Any:
    """A campaign module where the measured code has it: ``now`` in the campaign's stage
    sub-packages, ``before`` in the flat ``campaign`` package of the code before they were
    split (the second baseline)."""
    import importlib

    try:
        return importlib.import_module(f"idefix_rules.campaign.{now}")
    except ModuleNotFoundError:
        return importlib.import_module(f"idefix_rules.campaign.{before}")


def toy_campaign(folder: Path, runs: int, fmu: Path) -> dict[str, Any]:
    """Run the toy campaign at ``runs`` per path in ``folder``: memory by stage (MB)."""
    sys.path.insert(0, str(TOY_SOURCES))
    from campaign_texts import CAMPAIGN, RULEBOOK

    from idefix_rules.campaign.runner import run_campaign

    load_campaign = stage_module("input.load", "load").load_campaign
    SimulationOptions = stage_module("simulation.simulate", "simulate").SimulationOptions

    (folder / "toy.fmu").write_bytes(fmu.read_bytes())
    (folder / "test.rules").write_text(RULEBOOK)
    (folder / "campaign.yaml").write_text(CAMPAIGN.replace("runs: 6", f"runs: {runs}"))
    campaign = load_campaign(folder / "campaign.yaml").with_overrides(workers=2)
    progress = StageMemory()
    start = memory_mb("VmRSS")
    started = time.perf_counter()
    result = run_campaign(campaign, SimulationOptions(workers=2), progress, report=False)
    seconds = time.perf_counter() - started
    if progress.simulation_peak is None:
        raise RuntimeError("the campaign never said it was evaluating")
    return {"start": start, "simulation_peak": progress.simulation_peak,
            "after_simulation": progress.after_simulation,
            "evaluation_peak": memory_mb("VmHWM"), "seconds": seconds,
            "runs": sum(p.completed for p in result.evaluation.paths)}


def stored_evaluation(results: Path) -> dict[str, Any]:
    """Evaluate a stored campaign as ``run_campaign`` does (collision checks on 2
    processes), without writing: memory (MB)."""
    from idefix_rules.results.campaign import StoredCampaign
    from idefix_rules.rulebook import compile_rulebook

    evaluate_store = stage_module("evaluation.evaluate", "evaluation").evaluate_store
    store = stage_module("storage.store", "store").ResultStore.open(results)
    try:
        stored = StoredCampaign(store)
        evaluator = compile_rulebook(stored.checked_rulebook())
        collisions = stored.collision_function(evaluator)
        start = memory_mb("VmRSS")
        reset_peak()
        started = time.perf_counter()
        evaluation = evaluate_store(store, evaluator, stored.rover, stored.sigma, collisions,
                                    {}, write=False, workers=2)
        seconds = time.perf_counter() - started
    finally:
        store.close()
    return {"start": start, "evaluation_peak": memory_mb("VmHWM"), "seconds": seconds,
            "runs": sum(p.completed for p in evaluation.paths)}


# --- in the benchmark's process ---------------------------------------------------------------

def in_child(tree: Path, *arguments: str) -> dict[str, Any]:
    """This script's ``--child`` measurement in a new process importing the package from
    ``tree``."""
    environment = {**os.environ, "PYTHONPATH": str(tree)}
    done = subprocess.run([sys.executable, __file__, "--child", *arguments], env=environment,
                          capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"the measurement failed:\n{done.stderr[-3000:]}")
    result: dict[str, Any] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


def cut_copy(source: Path, target: Path, runs: int) -> Path:
    """A copy of a stored campaign holding only the first ``runs`` runs of each path (the
    later rows marked not needed, as an adaptive campaign marks the rows it did not use)."""
    import h5py
    import numpy as np

    from idefix_rules.results.format import STATUS_NOT_NEEDED

    shutil.copyfile(source, target)
    with h5py.File(target, "r+") as file:
        for group in file["paths"].values():
            if "runs" in group:
                status = group["runs"]["status"][()]
                status[runs:] = np.where(status[runs:] == 0, 0, STATUS_NOT_NEEDED)
                group["runs"]["status"][...] = status
    return target


def repeated_copy(source: Path, target: Path, runs: int) -> Path:
    """A copy of a stored campaign with ``runs`` runs per path, run ``j`` being the stored run
    ``j mod n`` (its compressed chunks copied unchanged); the paths' evaluations are left out
    (they are what the measured stage writes)."""
    import h5py
    import numpy as np

    def copy_runs(group: h5py.Group, into: h5py.Group) -> None:
        into.attrs.update({key: runs if key == "count" else value
                           for key, value in group.attrs.items()})
        for name, item in group.items():
            if isinstance(item, h5py.Group):
                copy_runs(item, into.create_group(name))
                continue
            stored = item.shape[0]
            made = into.create_dataset(
                name, shape=(runs, *item.shape[1:]), dtype=item.dtype, chunks=item.chunks,
                compression=item.compression, compression_opts=item.compression_opts,
                shuffle=item.shuffle, fillvalue=item.fillvalue)
            made.attrs.update(item.attrs)
            if item.chunks is not None and item.chunks[0] == 1:  # a run's signal: one chunk
                rest = (0,) * (item.ndim - 1)
                for run in range(runs):
                    mask, data = item.id.read_direct_chunk((run % stored, *rest))
                    made.id.write_direct_chunk((run, *rest), data, mask)
            else:
                made[...] = item[()][np.arange(runs) % stored]

    with h5py.File(source, "r") as src, h5py.File(target, "w") as dst:
        dst.attrs.update(src.attrs)
        dst.attrs["runs"] = runs
        for name in src:
            if name != "paths":
                src.copy(src[name], dst, name=name)
        paths = dst.create_group("paths")
        paths.attrs.update(src["paths"].attrs)
        for name, group in src["paths"].items():
            out = paths.create_group(name)
            out.attrs.update(group.attrs)
            for part in group:
                if part == "runs":
                    copy_runs(group[part], out.create_group(part))
                elif part != "evaluation":
                    group.copy(group[part], out, name=part)
    return target


def table(title: str, sizes: list[int], trees: dict[str, list[dict[str, Any]]],
          keys: tuple[tuple[str, str], ...]) -> list[str]:
    """Per code and stage: the figure at each size, the ratio of the second size to the first
    (the baseline) and of the last to the one before, and what a run added between those two
    cost (peak difference / added runs)."""
    columns = [f"{size}/path" for size in sizes]
    head = [*columns, f"ratio {sizes[1]}/{sizes[0]}"]
    if len(sizes) > 2:
        head.append(f"ratio {sizes[-1]}/{sizes[-2]}")
    head.append(f"per added run, {sizes[-2]} → {sizes[-1]}")
    lines = [title, "| code, measure | " + " | ".join(head) + " |",
             "|" + " --- |" * (len(head) + 1)]
    for code, measured in trees.items():
        added = measured[-1]["runs"] - measured[-2]["runs"]
        for key, what in (*keys, ("seconds", "wall time")):
            unit = "s" if key == "seconds" else "MB"
            cells = [f"{m[key]:.0f} {unit}" for m in measured]
            cells.append(f"{measured[1][key] / measured[0][key]:.2f}x")
            if len(sizes) > 2:
                cells.append(f"{measured[-1][key] / measured[-2][key]:.2f}x")
            grown = 1e6 * (measured[-1][key] - measured[-2][key]) / added
            cells.append("" if key == "seconds" else f"{grown:+.0f} B")
            lines.append(f"| {code}: {what} | " + " | ".join(cells) + " |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--toy-runs", type=int, nargs="+", default=[1000, 10_000, 30_000],
                        help="runs per path of the toy campaign (the first: the baseline)")
    parser.add_argument("--rover-runs", type=int, nargs="+", default=[256, 1000, 10_000],
                        help="runs per path of rock-detour's evaluation (0: skip it)")
    parser.add_argument("--no-previous", action="store_true",
                        help=f"skip the code at {PREVIOUS}")
    parser.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child is not None:
        kind, *rest = args.child
        if kind == "toy":
            print(json.dumps(toy_campaign(Path(rest[0]), int(rest[1]), Path(rest[2]))))
        else:
            print(json.dumps(stored_evaluation(Path(rest[0]))))
        return
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    sys.path.insert(0, str(TOY_SOURCES))
    from baseline import baseline_tree
    from campaign_toy_fmu import build_toy_fmu

    trees: dict[str, Path] = {"now": ROOT}
    if not args.no_previous:
        trees[f"previous ({PREVIOUS})"] = baseline_tree(PREVIOUS)
    load = os.getloadavg()
    print(f"load average before: {load[0]:.1f} {load[1]:.1f} {load[2]:.1f} on "
          f"{os.cpu_count()} cores")
    lines: list[str] = []
    with tempfile.TemporaryDirectory(prefix="bench-memory-") as tmp:
        folder = Path(tmp)
        fmu = build_toy_fmu(folder / "toy-fmu")
        toy: dict[str, list[dict[str, Any]]] = {}
        for code, tree in trees.items():
            toy[code] = []
            for runs in args.toy_runs:
                place = folder / f"toy-{len(toy)}-{runs}"
                place.mkdir()
                toy[code].append(in_child(tree, "toy", str(place), str(runs), str(fmu)))
                shutil.rmtree(place)
                print(f"toy, {code}, {runs}/path: {json.dumps(toy[code][-1])}", flush=True)
        lines += table(f"toy campaign, {', '.join(map(str, args.toy_runs))} runs per path "
                       "(2 paths simulated, 2 workers): the campaign's process",
                       args.toy_runs, toy,
                       (("simulation_peak", "peak, simulation"),
                        ("after_simulation", "after the simulation"),
                        ("evaluation_peak", "peak, evaluation")))
        if min(args.rover_runs) > 0:
            from bench_diff import stored_campaign_file

            stored_runs = 1000
            source = stored_campaign_file(stored_runs, 2, rebuild=False)
            cuts = [(cut_copy if runs <= stored_runs else repeated_copy)(
                        source, folder / f"rock-detour-{runs}.h5", runs)
                    for runs in args.rover_runs]
            rover: dict[str, list[dict[str, Any]]] = {}
            for code, tree in trees.items():
                rover[code] = [in_child(tree, "rover", str(cut)) for cut in cuts]
                for runs, measured in zip(args.rover_runs, rover[code], strict=True):
                    print(f"rock-detour evaluation, {code}, {runs}/path: "
                          f"{json.dumps(measured)}", flush=True)
            lines.append("")
            lines += table(
                f"rock-detour, the evaluation of {', '.join(map(str, args.rover_runs))} runs per "
                f"path (4 paths; the first of the {stored_runs} stored, or those repeated; "
                "collision checks on 2 processes): the evaluating process", args.rover_runs, rover,
                (("start", "before evaluating"), ("evaluation_peak", "peak, evaluation")))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
