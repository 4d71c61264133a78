"""Benchmark: results that stay small and fast at scale, and adaptive against fixed run counts.

Prints one table; each figure with its baseline measured in the same invocation:

* MB per stored run and write throughput (runs/s, the campaign's per-run write protocol: data,
  flush, status, flush) of the example campaign's real runs, written in format 2 (chunked,
  shuffle + gzip, float32 where enough) against format 1 (contiguous float64, the baseline);
* evaluation throughput (runs/s) and peak RSS of evaluating a synthetic results file of 1k, 10k
  and 100k stored runs (each in a fresh process; baseline: the 1k file), plus the write
  throughput of building it in blocks;
* the share of the simulation time the writer is busy storing runs streamed back from a local
  Dask cluster (baseline: the local process pool);
* runs an adaptive campaign (``--runs auto --max-runs N``) needs to reach the decisions of a
  fixed campaign of N runs per path on the example (baseline: the fixed campaign).

    python benchmarks/bench_scale.py                     # N = 128, scale 1k 10k 100k
    python benchmarks/bench_scale.py --fixed-runs 1000   # the DESIGN target (3000 FMU runs)
    python benchmarks/bench_scale.py --scale 1000 10000  # skip the 100k file
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.runner import run_campaign
from idefix_rules.campaign.simulation.simulate import SimulationOptions
from idefix_rules.campaign.storage.dataset_layout import signal_attrs
from idefix_rules.campaign.storage.encoded_chunks import encode_run
from idefix_rules.campaign.storage.store import STATUS_COMPLETE, ResultStore
from idefix_rules.commands import Command

ROOT = Path(__file__).resolve().parent.parent
CAMPAIGN = ROOT / "campaigns" / "rock-detour.yaml"
SAMPLES = 300  # per synthetic run (30 s at 10 Hz)
BLOCK = 1000  # synthetic runs written per block

# A rulebook on the stored signals only (no collisions), so the scale part measures reading and
# evaluating, not the obstacle checker (bench_collisions.py measures that).
RULEBOOK = """\
rulebook "scale" version "1.0.0"
purpose "Scale benchmark: stored signals only"
settings {
  theoretical_slip = 20 %
  tolerance_growth = 5 cm/rad
}
index I_pos "position drift" {
  value = final over time (global_error / tolerance_radius)
  limit = 1
  weight = 1
}
index I_s "wheel slip ratio" {
  value = percentile 95 over time (max over wheels (abs(wheel.slip)))
  limit = 70 %
  weight = 1
}
index I_ds "wheel sinkage" {
  value = max over time (max over wheels (wheel.sinkage))
  limit = 5 cm
  weight = 1
}
chance got_stuck = any over time (stuck > 0)
verdict acceptable_risk: require risk <= 70 %
verdict rarely_stuck: require chance(got_stuck) <= 1 %
rank by risk, time, energy
"""


# --- 1. the example: fixed against adaptive --------------------------------------------------

def run_example(folder: Path, runs: int | str, max_runs: int, workers: int,
                dask: bool = False) -> Any:
    campaign = load_campaign(CAMPAIGN).with_overrides(runs=runs, max_runs=max_runs
                                                      if runs == "auto" else None,
                                                      output=folder, workers=workers)
    started = time.perf_counter()
    result = run_campaign(campaign, SimulationOptions(workers=workers, dask_local=dask),
                          report=False)
    return result, time.perf_counter() - started


def decisions(result: Any) -> dict[str, Any]:
    return {"verdicts": {p.name: (p.verdict_text, p.undecided) for p in result.evaluation.paths},
            "ranking": list(result.evaluation.ranking)}


# --- 2. format 1 against format 2 on the example's runs ------------------------------------

def rewrite(source: Path, target: Path, legacy: bool) -> tuple[float, float, float]:
    """Write every complete run of ``source`` into a new file, run by run with the campaign's
    protocol; (MB per run, runs/s of the writer, worker seconds per run spent compressing).
    Format 2 is written as a campaign does: each run compressed where it was simulated
    (:func:`encode_run`, timed apart), the parent writing the chunks. ``legacy``: format 1
    (contiguous float64 arrays)."""
    reader = ResultStore.open(source)
    store = ResultStore.create(target, {"runs": 0}, {"campaign": reader.text("campaign")})
    written, seconds, encoding = 0, 0.0, 0.0
    try:
        for index, name in enumerate(reader.path_names):
            if not reader.has_runs(name):
                continue
            complete = np.flatnonzero(reader.run_status(name) == STATUS_COMPLETE)
            signals = reader.read_runs(name, complete)
            store.create_path(name, index, [Command(0.05, 1.0, 0.0)], {})
            shapes = {key: values.shape[1:] for key, values in signals.items()}
            runs: list[dict[str, Any]] = []
            for row in range(len(complete)):
                arrays = {key: values[row] for key, values in signals.items()}
                started = time.perf_counter()
                runs.append(arrays if legacy else encode_run(arrays))
                encoding += time.perf_counter() - started
            started = time.perf_counter()
            if legacy:
                _allocate_format_1(store, name, len(complete), shapes)
            else:
                store.allocate_runs(name, len(complete), shapes, {}, {})
            for row, run in enumerate(runs):
                store.write_run(name, row, run)
            seconds += time.perf_counter() - started
            written += len(complete)
    finally:
        reader.close()
        store.close()
    return target.stat().st_size / written / 1e6, written / seconds, encoding / written


def _allocate_format_1(store: ResultStore, name: str, runs: int,
                       shapes: dict[str, tuple[int, ...]]) -> None:
    """The run datasets as format 1 made them: contiguous float64, allocated at creation."""
    def early() -> Any:  # a fresh list each time: h5py stores the fill value in it
        dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
        dcpl.set_alloc_time(h5py.h5d.ALLOC_TIME_EARLY)
        return dcpl

    group = store.path_group(name).create_group("runs")
    group.attrs["count"] = runs
    signals = group.create_group("signals", track_order=True)
    for key, shape in shapes.items():
        dataset = signals.create_dataset(key, shape=(runs, *shape), dtype=np.float64,
                                         fillvalue=np.nan, dcpl=early())
        for attr, value in signal_attrs(key).items():
            dataset.attrs[attr] = value
    group.create_dataset("failure", shape=(runs,), dtype="S240", dcpl=early())
    group.create_dataset("status", shape=(runs,), dtype=np.int8, fillvalue=0, dcpl=early())
    store.file.flush()


# --- 3. synthetic files of 1k … 100k runs --------------------------------------------------------

def synthetic_signals(rng: np.random.Generator, runs: int) -> dict[str, np.ndarray]:
    """Plausible runs of a 0.3 m straight drive: per-run slip, heading and noise."""
    t = np.arange(SAMPLES) * 0.1
    slip = rng.uniform(0.1, 0.4, (runs, 1))
    speed = 0.01 * (1.0 - slip)
    yaw = rng.normal(0.0, 0.02, (runs, 1)) + 0.001 * rng.standard_normal((runs, SAMPLES))
    x = speed * t + rng.normal(0.0, 0.01, (runs, 1))
    y = np.cumsum(speed * 0.1 * np.sin(yaw), axis=1) + rng.normal(0.0, 0.01, (runs, 1))
    wheel = slip[:, :, None] + 0.05 * rng.standard_normal((runs, SAMPLES, 4))
    return {
        "t": np.broadcast_to(t, (runs, SAMPLES)), "x": x, "y": y,
        "z": 0.001 * rng.standard_normal((runs, SAMPLES)),
        "roll": 0.01 * rng.standard_normal((runs, SAMPLES)),
        "pitch": 0.01 * rng.standard_normal((runs, SAMPLES)), "yaw": yaw,
        "wheel.rate": np.full((runs, SAMPLES, 4), 0.05),
        "wheel.slip": wheel, "wheel.slip_angle": 0.1 * rng.standard_normal((runs, SAMPLES, 4)),
        "wheel.sinkage": np.abs(0.01 + 0.002 * rng.standard_normal((runs, SAMPLES, 4))),
        "energy": np.cumsum(np.full((runs, SAMPLES), 0.01), axis=1),
        "command": np.where(t < 25.0, 0.0, -1.0)[None, :].repeat(runs, axis=0),
        "stuck": (rng.random((runs, 1)) < 0.005) * (t > 20.0)[None, :],
    }


def build_synthetic(path: Path, runs: int) -> float:
    """A results file of ``runs`` synthetic runs (format 2), written a block at a time;
    returns runs/s."""
    rng = np.random.default_rng(runs)
    store = ResultStore.create(path, {"runs": runs, "campaign_name": "synthetic"},
                               {"campaign": "name: synthetic\n", "rulebook": RULEBOOK})
    try:
        store.create_path("p", 0, [Command(0.05, 0.3, 0.0)],
                          {"status": "simulated", "stop_time": SAMPLES * 0.1 - 0.1,
                           "samples": SAMPLES})
        reference = {k: np.asarray(v[0]) for k, v in synthetic_signals(rng, 1).items()}
        store.write_reference("p", reference, {})
        started = time.perf_counter()
        store.allocate_runs("p", runs, {k: v.shape for k, v in reference.items()}, {}, {})
        datasets, status, _ = store._run_handles("p")
        for first in range(0, runs, BLOCK):
            count = min(BLOCK, runs - first)
            for key, values in synthetic_signals(rng, count).items():
                datasets[key][first:first + count] = values
            store.file.flush()
            status[first:first + count] = STATUS_COMPLETE
            store.file.flush()
        return runs / (time.perf_counter() - started)
    finally:
        store.close()


def peak_rss_mb() -> float:
    """This process's peak resident memory (VmHWM: unlike ``ru_maxrss``, not inherited from
    the parent that started it)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def evaluate_file(path: Path) -> dict[str, float]:
    """Evaluate a synthetic file in this process; runs/s and peak RSS (MB)."""
    from idefix_rules.campaign.evaluation.evaluate import evaluate_store
    from idefix_rules.commands import RoverGeometry
    from idefix_rules.rulebook import compile_rulebook
    from idefix_rules.rulebook.parser import parse_rulebook

    evaluator = compile_rulebook(parse_rulebook(RULEBOOK, "scale.rules"))
    store = ResultStore.open(path)
    try:
        before = peak_rss_mb()
        started = time.perf_counter()
        evaluation = evaluate_store(store, evaluator, RoverGeometry(), 0.01, None, {},
                                    write=False)
        seconds = time.perf_counter() - started
    finally:
        store.close()
    runs = evaluation.paths[0].completed
    peak = peak_rss_mb()
    return {"runs": runs, "runs_per_s": runs / seconds, "peak_rss_mb": peak,
            "rss_before_mb": before}


def evaluate_in_child(path: Path) -> dict[str, float]:
    output = subprocess.run([sys.executable, __file__, "--evaluate", str(path)], check=True,
                            capture_output=True, text=True).stdout
    result: dict[str, float] = json.loads(output.strip().splitlines()[-1])
    return result


# --- the table -----------------------------------------------------------------------------------

def row(what: str, value: str, baseline: str, ratio: str) -> str:
    return f"| {what} | {value} | {baseline} | {ratio} |"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fixed-runs", type=int, default=128,
                        help="runs per path of the fixed campaign; the adaptive cap (128)")
    parser.add_argument("--scale", type=int, nargs="+", default=[1000, 10_000, 100_000],
                        help="stored runs of the synthetic files (first one: the baseline)")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--dask-runs", type=int, default=32,
                        help="runs per path of the campaign run on a local Dask cluster")
    parser.add_argument("--evaluate", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.evaluate is not None:
        print(json.dumps(evaluate_file(args.evaluate)))
        return
    lines = ["| measure | value | baseline (same run) | ratio |", "| --- | --- | --- | --- |"]
    with tempfile.TemporaryDirectory(prefix="bench-scale-") as tmp:
        folder = Path(tmp)
        fixed, fixed_s = run_example(folder / "fixed", args.fixed_runs, 0, args.workers)
        auto, auto_s = run_example(folder / "auto", "auto", args.fixed_runs, args.workers)
        fixed_runs = sum(p.runs for p in fixed.evaluation.paths)
        auto_runs = sum(p.runs for p in auto.evaluation.paths)
        same = decisions(fixed) == decisions(auto)
        print(f"fixed {args.fixed_runs}/path: {decisions(fixed)} in {fixed_s:.0f} s")
        print(f"adaptive (max {args.fixed_runs}): {decisions(auto)} in {auto_s:.0f} s; "
              + "; ".join(f"{p.name}: {p.stop_reason}" for p in auto.evaluation.paths
                          if p.stop_reason))
        lines.append(row(f"example: runs to the decisions (adaptive, cap {args.fixed_runs})",
                         f"{auto_runs} ({'same' if same else 'DIFFERENT'} decisions)",
                         f"{fixed_runs} (fixed {args.fixed_runs}/path)",
                         f"{fixed_runs / auto_runs:.1f}x fewer"))
        lines.append(row("example: campaign wall time (adaptive)", f"{auto_s:.0f} s",
                         f"{fixed_s:.0f} s (fixed)", f"{fixed_s / auto_s:.1f}x faster"))
        source = folder / "fixed" / "results.h5"
        stored = fixed.results.stat().st_size / fixed_runs / 1e6
        new_mb, new_rate, encode_s = rewrite(source, folder / "format2.h5", legacy=False)
        old_mb, old_rate, _ = rewrite(source, folder / "format1.h5", legacy=True)
        lines.append(row("example: results.h5 MB per stored run (campaign's own file)",
                         f"{stored:.3f}", f"{old_mb:.3f} (format 1)",
                         f"{old_mb / stored:.1f}x smaller"))
        lines.append(row("example: run signals rewritten, MB per run (format 2)",
                         f"{new_mb:.3f}", f"{old_mb:.3f} (format 1)",
                         f"{old_mb / new_mb:.1f}x smaller"))
        lines.append(row("example: writer throughput, per-run protocol",
                         f"{new_rate:.0f} runs/s", f"{old_rate:.0f} runs/s (format 1)",
                         f"{new_rate / old_rate:.2f}x"))
        lines.append(row("example: compression per run, in the workers",
                         f"{1000 * encode_s:.1f} ms", "0 ms (format 1)", "–"))
        simulated = fixed.timings["simulated_runs"] / fixed.timings["preparation_and_simulation"]
        lines.append(row("example: writer throughput against the simulation rate",
                         f"{new_rate:.0f} runs/s written",
                         f"{simulated:.1f} runs/s simulated ({args.workers} workers)",
                         f"{new_rate / simulated:.0f}x headroom"))
        on_dask, _ = run_example(folder / "dask", args.dask_runs, 0, args.workers, dask=True)
        busy = on_dask.timings["writing"] / on_dask.timings["preparation_and_simulation"]
        local_busy = fixed.timings["writing"] / fixed.timings["preparation_and_simulation"]
        lines.append(row(f"example on Dask ({args.dask_runs}/path): writer busy",
                         f"{100 * busy:.1f} % of the simulation time",
                         f"{100 * local_busy:.1f} % (local pool, {args.fixed_runs}/path)",
                         f"{busy / local_busy:.2f}x" if local_busy else "–"))
        base: dict[str, float] | None = None
        for runs in args.scale:
            path = folder / f"synthetic-{runs}.h5"
            rate = build_synthetic(path, runs)
            size = path.stat().st_size / runs / 1e6
            measured = evaluate_in_child(path)
            path.unlink()
            base = base or measured
            label = f"{runs // 1000}k"
            lines.append(row(f"synthetic {label}: build (blocks of {BLOCK}), MB/run",
                             f"{rate:.0f} runs/s, {size:.3f} MB/run", "–", "–"))
            lines.append(row(f"synthetic {label}: evaluation throughput",
                             f"{measured['runs_per_s']:.0f} runs/s",
                             f"{base['runs_per_s']:.0f} runs/s (1k)",
                             f"{measured['runs_per_s'] / base['runs_per_s']:.2f}x"))
            lines.append(row(f"synthetic {label}: peak RSS of the evaluation process",
                             f"{measured['peak_rss_mb']:.0f} MB (before evaluating: "
                             f"{measured['rss_before_mb']:.0f} MB)",
                             f"{base['peak_rss_mb']:.0f} MB (1k)",
                             f"{measured['peak_rss_mb'] / base['peak_rss_mb']:.2f}x"))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
