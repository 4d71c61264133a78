"""Collision index benchmark: 1000 runs × 3000 poses × 20 rocks on one core (target ≤ 10 s).

Scenario (the paper's kind of drive): the rover drives 1.5 m straight ahead at 5 mm/s, 10 Hz
output (3000 samples), start position and heading scattered per run (σ 5 cm, 1°), a slow roll
and pitch wobble from rough terrain. Twenty rocks, radius 3-15 cm, lie in an 8 m × 8 m field
around the start (what the navigation cameras map), one of them on the path of the right wheels;
the output says how many lie near the path.

Baseline, measured in the same run: the exhaustive check (fcl distance of every body to every
rock at every pose, no broad phase), timed on a few runs and extrapolated to all runs.

    python benchmarks/bench_collisions.py [--runs 1000] [--baseline-runs 2]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from idefix_rules.obstacles import ObstacleSet, RoverBodies, collision_signals
from idefix_rules.obstacles.reference import reference_collision_signals


def scenario(runs: int, samples: int = 3000, seed: int = 7
             ) -> tuple[dict[str, np.ndarray], ObstacleSet]:
    rng = np.random.default_rng(seed)
    t = np.arange(samples) * 0.1
    speed = 1.5 / t[-1]
    y0 = rng.normal(0.0, 0.05, (runs, 1))
    yaw0 = rng.normal(0.0, np.radians(1.0), (runs, 1))
    distance = speed * t[None, :] * rng.uniform(0.9, 1.0, (runs, 1))  # slip 0-10 %
    phase = rng.uniform(0, 2 * np.pi, (runs, 2))
    poses = {
        "t": np.broadcast_to(t, (runs, samples)).copy(),
        "x": distance * np.cos(yaw0),
        "y": y0 + distance * np.sin(yaw0),
        "z": np.full((runs, samples), RoverBodies().body_centre_height),
        "roll": np.radians(2.0) * np.sin(0.05 * t[None, :] + phase[:, :1]),
        "pitch": np.radians(2.0) * np.sin(0.03 * t[None, :] + phase[:, 1:]),
        "yaw": np.broadcast_to(yaw0, (runs, samples)).copy(),
    }
    rocks = [{"name": "path_rock", "x": 0.9, "y": -0.26, "z": 0.0, "radius": 0.07,
              "level": "L2"}]
    field = np.random.default_rng(seed + 1)
    while len(rocks) < 20:
        x, y = field.uniform(-3.0, 5.0), field.uniform(-4.0, 4.0)
        radius = field.uniform(0.03, 0.15)
        rocks.append({"name": f"rock{len(rocks)}", "x": x, "y": y, "z": 0.0, "radius": radius,
                      "level": "L1" if radius < 0.06 else ("L2" if radius < 0.11 else "L3")})
    return poses, ObstacleSet.from_rocks(rocks, buffer_margins={"L1": 0.02, "L2": 0.05,
                                                                  "L3": 0.10})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--samples", type=int, default=3000)
    parser.add_argument("--baseline-runs", type=int, default=2)
    args = parser.parse_args()
    poses, obstacles = scenario(args.runs, args.samples)
    start, start_cpu = time.perf_counter(), time.process_time()
    result = collision_signals(poses, obstacles)
    elapsed, cpu = time.perf_counter() - start, time.process_time() - start_cpu
    hits = result.signals["collision.hits"]
    print(f"collision check: {args.runs} runs × {args.samples} poses × "
          f"{len(obstacles.obstacles)} rocks, 7 bodies: {elapsed:.2f} s wall, {cpu:.2f} s CPU "
          f"on one core (target ≤ 10 s), {args.runs * args.samples / elapsed / 1e3:.0f} k "
          "poses/s")
    near = sum(1 for o in obstacles.obstacles if -0.5 < o.pieces[0].centre[0] < 2.0
               and abs(o.pieces[0].centre[1]) < 0.9)
    print(f"rocks within 0.5 m of the rover's swept corridor: {near}; "
          f"runs with a hit: {np.mean(hits.sum(axis=(1, 2)) > 0):.1%}; "
          f"wheel hits per level (mean): {hits[:, 0].mean(axis=0).round(3).tolist()}")
    few = {name: array[:args.baseline_runs] for name, array in poses.items()}
    start = time.perf_counter()
    reference = reference_collision_signals(few, obstacles)
    baseline = (time.perf_counter() - start) * args.runs / args.baseline_runs  # wall, like above
    agree = np.array_equal(reference.signals["collision.hits"], hits[:args.baseline_runs])
    print(f"baseline without broad phase (every body × every rock × every pose), measured on "
          f"{args.baseline_runs} runs and extrapolated to {args.runs}: {baseline:.0f} s")
    print(f"speed-up against the baseline (wall time): {baseline / elapsed:.0f}×; "
          f"hits identical on the measured runs: {agree}")


if __name__ == "__main__":
    main()
