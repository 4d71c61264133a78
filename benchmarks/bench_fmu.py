"""Rover FMU benchmark: a 300 s drive at 10 Hz output through FmuRunner, on one core.

Scenario: the paper's kind of move on a rough, slightly sloped 4 m × 4 m terrain with rocks:
0.6 m straight, a 30° left arc, a point turn back, 0.2 m straight (300 s of simulated time,
3001 output samples, internal step 0.05 s).

Printed (CPU time of this process, median of interleaved runs, since the machine is shared):
runs per second through the runner (target >= 10 per core), and the share of the run time spent
outside the model (target <= 25 %), measured against the same FMU instance driven without
per-step overhead: one fmi2DoStep over the whole 300 s (same internal steps, no output
sampling). Also the time of plain ``fmpy.simulate_fmu`` for one run (extracts and instantiates
every time), as the baseline the runner replaces.

    python benchmarks/bench_fmu.py [--runs 50]
"""

from __future__ import annotations

import argparse
import math
import statistics
import tempfile
import time
from pathlib import Path

from idefix_rules.commands import Command
from idefix_rules.fmu import FmuRunner, Rock, default_fmu_path, synthetic_terrain, write_terrain

CHAIN = [Command(0.05, 0.6, 0.0), Command(0.05, 0.3, math.radians(30)),
         Command(0.05, 0.0, math.radians(-30)), Command(0.05, 0.2, 0.0)]
STOP, INTERVAL = 300.0, 0.1


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=50)
    args = parser.parse_args()
    fmu = default_fmu_path()
    with tempfile.TemporaryDirectory() as tmp:
        terrain = write_terrain(Path(tmp) / "bench.terrain", synthetic_terrain(
            size=4.0, cell=0.02, slope=math.radians(5), slope_direction=-1.2, roughness=0.005,
            seed=11, rocks=[Rock(0.6, -0.26, 0.06, 0.06, 0.04), Rock(1.2, 0.5, 0.1, 0.08, 0.06),
                            Rock(-0.5, 0.3, 0.05, 0.05, 0.03)]))
        parameters = {"terrain.file": str(terrain)}
        runner = FmuRunner(fmu)
        out = runner.run(parameters, CHAIN, STOP, INTERVAL)  # warm-up: terrain load, page-in
        done = out["command"] < 0
        finished = float(out["t"][done.argmax()]) if done.any() else STOP

        # Interleaved, so load from other processes hits both alike; CPU time of this process
        # (the machine is shared), medians over the runs.
        runner_cpu, model_cpu, runner_wall = [], [], []
        for _ in range(args.runs):
            wall, cpu = time.perf_counter(), time.process_time()
            runner.run(parameters, CHAIN, STOP, INTERVAL)
            runner_cpu.append(time.process_time() - cpu)
            runner_wall.append(time.perf_counter() - wall)
            # same instance, no per-step overhead: reset, set up, one doStep over the drive
            cpu = time.process_time()
            runner.run(parameters, CHAIN, 0.0, INTERVAL)
            status = runner._do_step(runner._slave.component, 0.0, STOP, 1)
            model_cpu.append(time.process_time() - cpu)
            assert status == 0
        per_run = statistics.median(runner_cpu)
        model_only = statistics.median(model_cpu)
        wall_per_run = statistics.median(runner_wall)

        from fmpy import simulate_fmu

        start = time.process_time()
        simulate_fmu(str(fmu), stop_time=STOP, output_interval=INTERVAL,
                     start_values={"terrain.file": str(terrain), "chain.count": len(CHAIN),
                                   **{f"chain.{f}[{i}]": getattr(c, f)
                                      for i, c in enumerate(CHAIN)
                                      for f in ("max_wheel_rate", "delta_position",
                                                "delta_heading")}})
        plain = time.process_time() - start
        runner.close()

    overhead = max(per_run - model_only, 0.0) / per_run
    print(f"rover FMU, {STOP:.0f} s drive at {1 / INTERVAL:.0f} Hz output, {len(CHAIN)} commands "
          f"(chain done at {finished:.1f} s), {args.runs} runs, one core")
    print(f"  FmuRunner:                  {per_run * 1e3:8.2f} ms/run  "
          f"{1 / per_run:7.1f} runs/s   (target >= 10; CPU time, median)")
    print(f"  FmuRunner, wall clock:      {wall_per_run * 1e3:8.2f} ms/run  "
          f"{1 / wall_per_run:7.1f} runs/s   (shared machine)")
    print(f"  model only (one doStep):    {model_only * 1e3:8.2f} ms/run  "
          f"{1 / model_only:7.1f} runs/s")
    print(f"  time outside the model:     {overhead * 100:8.1f} %        (target <= 25 %)")
    print(f"  plain fmpy.simulate_fmu:    {plain * 1e3:8.2f} ms/run  "
          f"(runner is {plain / per_run:.1f}x faster)")


if __name__ == "__main__":
    main()
