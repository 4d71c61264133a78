"""Benchmark: the worst-case search against the riskiest run of a Monte Carlo campaign.

On the example campaign (campaigns/rock-detour.yaml) runs, in one invocation, a Monte Carlo
campaign of N runs per path and ``idefix-verify worst`` with a budget of N / 4 runs per path,
and prints per path the riskiest run of the campaign (its I_max and dominant index) beside the
worst world the search found (and the runs it used), with whether the search found a world at
least as risky (issue 21's "done when": at most a quarter of the runs). Then the wall time of
each. No report is written; the campaign's results (about 0.3 MB per run) are deleted at the end.

    python benchmarks/bench_worst.py             # 1000 runs per path against 250 (~10 min)
    python benchmarks/bench_worst.py --runs 200  # a quick look: 200 against 50
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.runner import run_campaign
from idefix_rules.campaign.simulation.simulate import SimulationOptions
from idefix_rules.campaign.worst.pipeline import run_worst
from idefix_rules.campaign.worst.search import SearchSettings
from idefix_rules.campaign.worst.space import QuantileSpace

CAMPAIGN = Path(__file__).resolve().parent.parent / "campaigns" / "rock-detour.yaml"


def riskiest_runs(results: Path) -> dict[str, tuple[float, str, int]]:
    """Per path: the highest I_max of its runs, the index that set it, and the runs scored."""
    found = {}
    with h5py.File(results, "r") as file:
        for name, group in file["paths"].items():
            evaluation = group.get("evaluation")
            if evaluation is None:
                continue
            risks = np.asarray(evaluation["i_max"][()], dtype=float)
            names = json.loads(evaluation.attrs["index_names"])
            row = int(np.nanargmax(risks))
            code = int(evaluation["dominant"][row])
            found[str(name)] = (float(risks[row]), names[code] if code >= 0 else "–",
                                int(np.sum(np.isfinite(risks))))
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000,
                        help="Monte Carlo runs per path (default 1000)")
    parser.add_argument("--budget", type=int, default=None,
                        help="the search's runs per path (default: a quarter of --runs, at "
                             "least what the search needs)")
    parser.add_argument("--workers", type=int, default=None, help="default: all cores")
    args = parser.parse_args()
    campaign = load_campaign(CAMPAIGN)
    settings = SearchSettings(runs=1)
    dimensions = QuantileSpace.of(campaign.model.uncertainty.parameters).dimensions
    budget = args.budget or max(args.runs // 4, settings.minimum_runs(dimensions))
    options = SimulationOptions(workers=args.workers)
    with tempfile.TemporaryDirectory(prefix="bench-worst-") as tmp:
        folder = Path(tmp)
        started = time.perf_counter()
        monte_carlo = run_campaign(campaign.with_overrides(
            runs=args.runs, output=folder / "campaign", workers=args.workers), options,
            report=False)
        campaign_seconds = time.perf_counter() - started
        riskiest = riskiest_runs(monte_carlo.results)
        started = time.perf_counter()
        search = run_worst(campaign.with_overrides(output=folder / "worst",
                                                   workers=args.workers),
                           SearchSettings(runs=budget), options, report=False)
        search_seconds = time.perf_counter() - started
    print(f"{CAMPAIGN.name}: Monte Carlo {args.runs} runs per path against a worst-case "
          f"search of at most {budget} runs per path ({budget / args.runs:.0%})")
    print(f"{'path':15} {'Monte Carlo riskiest run':>30} {'search worst world':>34}  at least as "
          "risky")
    held = 0
    for path in search.record["paths"]:
        name = path["name"]
        if name not in riskiest or path.get("status") != "searched":
            print(f"{name:15} not simulated ({path.get('status')}: {path.get('reason', '')})")
            continue
        risk, dominant, runs = riskiest[name]
        worst = path["worst"]
        ok = worst["risk"] >= round(risk, 4)
        held += ok
        print(f"{name:15} {100 * risk:7.2f} % ({dominant:7} of {runs:5} runs)"
              f" {100 * worst['risk']:8.2f} % ({worst['dominant_index'] or '–':7} "
              f"{path['runs_used']:4} runs) {'yes' if ok else 'NO':>6}")
    print(f"search at least as risky on {held} of {len(riskiest)} paths; wall time: Monte "
          f"Carlo {campaign_seconds:.0f} s, search {search_seconds:.0f} s "
          f"({search.timings['simulated_runs']:.0f} runs simulated)")


if __name__ == "__main__":
    main()
