"""Rulebook evaluation benchmark: the default rulebook on 1000 runs × 3000 samples × 4 wheels.

Scenario: ``rulebooks/idefix-ops.rules`` without obstacles (its collision-reading indices,
chances and verdicts are left out, as in a campaign without obstacles), synthetic signals of a
300 s drive at 10 Hz for a four-command chain, each run with its own command timing.

Printed (CPU time of this process, median of repeated runs, since the machine is shared):

* the compiled evaluator on all runs at once (target <= 0.5 s);
* baseline A: a per-run Python loop over the same compiled closures (``evaluate`` called with
  one run at a time), measured on ``--loop-runs`` runs and scaled to all runs;
* baseline B: the per-run reference interpreter (plain Python per element), measured on
  ``--interpreter-runs`` runs and scaled;
* the ratios (target >= 50x against a per-run Python loop).

    python benchmarks/bench_rulebook.py [--runs 1000] [--samples 3000]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import statistics
import time
from pathlib import Path

import numpy as np

from idefix_rules.commands import Command, RoverGeometry, command_kinematics
from idefix_rules.rulebook import load_rulebook
from idefix_rules.rulebook.compile import compile_rulebook
from idefix_rules.rulebook.derived import RunContext
from idefix_rules.rulebook.interpret import interpret
from idefix_rules.rulebook.model import Rulebook
from idefix_rules.rulebook.semantics import names_in

ROOT = Path(__file__).resolve().parents[1]
CHAIN = (Command(0.05, 0.7, 0.0), Command(0.05, 0.3, math.radians(30)),
         Command(0.05, 0.0, math.radians(-30)), Command(0.05, 0.2, 0.0))


def without_obstacles(model: Rulebook) -> Rulebook:
    """The rulebook minus everything that reads ``collision.*`` or ``area.*`` (the obstacle
    checker's signals), directly or via a chance."""
    def collides(expr: object) -> bool:
        return any(name.startswith(("collision.", "area.")) for name in names_in(expr))

    indices = tuple(i for i in model.indices if not collides((i.value, i.map)))
    chances = tuple(c for c in model.chances if not collides(c.condition))
    kept = {i.name for i in indices} | {c.name for c in chances} | {
        "risk", "time", "energy", "failed", "runs"}
    def readable(expr: object) -> bool:
        return names_in(expr) <= kept | {c.name for c in model.constants}

    return dataclasses.replace(
        model, indices=indices, chances=chances,
        prescreens=tuple(p for p in model.prescreens if readable(p.condition)),
        verdicts=tuple(v for v in model.verdicts if readable(v.condition)))


def synthetic_runs(runs: int, samples: int, seed: int = 3) -> tuple[dict, RunContext]:
    rng = np.random.default_rng(seed)
    rover = RoverGeometry()
    dt = 0.1
    t = np.arange(samples) * dt
    durations = np.array([command_kinematics(c, rover).duration for c in CHAIN])
    stretch = rng.uniform(1.0, 1.3, (runs, 1))  # slip makes commands last longer
    ends = np.cumsum(durations)[None, :] * stretch
    command = (t[None, :, None] >= ends[:, None, :]).sum(axis=2).astype(float)
    command[command >= len(CHAIN)] = -1.0
    drift = np.cumsum(rng.normal(0.0, 1e-4, (runs, samples)), axis=1)
    progress = np.minimum(t[None, :] / ends[:, -1:], 1.0)
    signals = {
        "t": np.tile(t, (runs, 1)),
        "x": 1.2 * progress + drift,
        "y": 0.1 * np.sin(np.pi * progress) + drift[::-1],
        "z": 0.01 * rng.standard_normal((runs, samples)),
        "roll": 0.05 * rng.standard_normal((runs, samples)),
        "pitch": 0.05 * rng.standard_normal((runs, samples)),
        "yaw": 0.3 * np.sin(np.pi * progress),
        "wheel.slip": rng.uniform(-0.3, 0.8, (runs, samples, 4)),
        "wheel.slip_angle": rng.normal(0.0, 0.1, (runs, samples, 4)),
        "wheel.sinkage": rng.uniform(0.0, 0.03, (runs, samples, 4)),
        "energy": np.cumsum(rng.uniform(0.0, 1e-3, (runs, samples)), axis=1),
        "command": command,
        "stuck": np.zeros((runs, samples)),
    }
    reference = {k: v[0].copy() for k, v in signals.items()}
    return signals, RunContext(CHAIN, rover, 0.02, reference)


def cpu_time(function, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.process_time()
        function()
        times.append(time.process_time() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--samples", type=int, default=3000)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--loop-runs", type=int, default=100)
    parser.add_argument("--interpreter-runs", type=int, default=2)
    args = parser.parse_args()

    model = without_obstacles(load_rulebook(ROOT / "rulebooks" / "idefix-ops.rules"))
    evaluator = compile_rulebook(model)
    signals, context = synthetic_runs(args.runs, args.samples)
    signals = {k: v for k, v in signals.items() if k in evaluator.required_signals}
    print(f"default rulebook without obstacles: {len(evaluator.index_names)} indices "
          f"({', '.join(evaluator.index_names)}), {len(evaluator.chance_names)} chances")
    print(f"signals: {args.runs} runs x {args.samples} samples x 4 wheels, "
          f"{sum(v.nbytes for v in signals.values()) / 1e6:.0f} MB")

    evaluator.evaluate(signals, context)  # warm-up
    vectorised = cpu_time(lambda: evaluator.evaluate(signals, context), args.repeat)

    def one_run_at_a_time(count: int) -> None:
        for run in range(count):
            evaluator.evaluate({k: v[run:run + 1] for k, v in signals.items()}, context)

    loop_runs = min(args.loop_runs, args.runs)
    loop = cpu_time(lambda: one_run_at_a_time(loop_runs), 3) * args.runs / loop_runs

    interpreter_runs = min(args.interpreter_runs, args.runs)
    subset = {k: v[:interpreter_runs] for k, v in signals.items()}
    interpreter = cpu_time(lambda: interpret(evaluator.checked, subset, context), 1) \
        * args.runs / interpreter_runs

    print(f"compiled, all runs at once:        {vectorised:8.3f} s   (target <= 0.5 s)")
    print(f"A: per-run loop, compiled closures: {loop:8.2f} s   "
          f"(measured on {loop_runs} runs, scaled)   ratio {loop / vectorised:6.1f}x")
    print(f"B: per-run reference interpreter:   {interpreter:8.1f} s   "
          f"(measured on {interpreter_runs} runs, scaled)   ratio "
          f"{interpreter / vectorised:6.0f}x   (target >= 50x)")


if __name__ == "__main__":
    main()
