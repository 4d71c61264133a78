"""Benchmark: the runs and wall time an adaptive campaign needs to reach the decisions of a
fixed campaign, paired and unpaired, measured in one invocation.

For each campaign (the paper's example ``campaigns/rock-detour.yaml``, four chains, and
``campaigns/pebble-field.yaml``, five chains) it runs, on the same machine one after the other:

* the baseline: a fixed campaign of N runs per path (default 1000), paired draws;
* an adaptive paired campaign (``--runs auto --max-runs N``);
* an adaptive unpaired campaign (the same with ``uncertainty: {paired: false}``).

and prints, per campaign and mode, the Monte Carlo runs simulated, the wall time (simulation
and evaluation, no report), the decision, and whether the adaptive campaign reached the same
decisions as the fixed one: every path's verdict (pass, fail, marginal, waived, rejected,
excluded, or open: not decided at its run count) and the ``Decision:`` (its kind and the
chains it names). The order among chains that all fail is shown by every mode but decided by
none (docs/campaign-format.md, "How α is spent"), so it is not compared.

    python benchmarks/bench_decide.py                  # N = 1000 (about 15 minutes on 2 cores)
    python benchmarks/bench_decide.py --runs 300       # a quicker look
    python benchmarks/bench_decide.py --campaign campaigns/rock-detour.yaml
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path
from typing import Any

from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.runner import run_campaign
from idefix_rules.campaign.simulation.simulate import SimulationOptions

ROOT = Path(__file__).resolve().parent.parent
CAMPAIGNS = [ROOT / "campaigns" / "rock-detour.yaml", ROOT / "campaigns" / "pebble-field.yaml"]
PAIRED_LINE = "uncertainty:\n"


def unpaired_copy(source: Path) -> Path:
    """The campaign with ``paired: false``, its relative paths kept (written beside it)."""
    text = source.read_text(encoding="utf-8")
    assert PAIRED_LINE in text, f"{source}: no uncertainty block"
    target = source.with_name(f".bench-unpaired-{source.name}")
    target.write_text(text.replace(PAIRED_LINE, PAIRED_LINE + "  paired: false\n", 1),
                      encoding="utf-8")
    return target


def run(source: Path, folder: Path, runs: int | str, cap: int, workers: int
        ) -> tuple[Any, float]:
    campaign = load_campaign(source).with_overrides(
        runs=runs, max_runs=cap if runs == "auto" else None, output=folder, workers=workers)
    started = time.perf_counter()
    result = run_campaign(campaign, SimulationOptions(workers=workers), report=False)
    return result, time.perf_counter() - started


def simulated_runs(result: Any) -> int:
    return sum(int(p.get("runs_used") or p.get("completed_runs") or 0) + int(p.get(
        "failed_runs") or 0) for p in result.summary["paths"]
        if p.get("status") == "simulated")


def decisions(result: Any) -> dict[str, Any]:
    decision = result.summary.get("decision") or {}
    # a verdict not decided at the campaign's run count is no decision, whatever its point
    # estimates say: "open" (a decided verdict against an open one is a different decision)
    return {"verdicts": {p["name"]: "open" if p.get("undecided") else p["verdict"]
                         for p in result.summary["paths"]},
            "decision": (decision.get("kind"),
                         tuple(sorted(decision.get("candidates") or [decision.get("path")])))}


def describe(found: dict[str, Any]) -> str:
    kind, names = found["decision"]
    return f"{kind} {' or '.join(n for n in names if n) or '-'}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=1000,
                        help="runs per path of the fixed campaign; the adaptive cap")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--campaign", type=Path, action="append",
                        help="a campaign (repeatable; default: the example and pebble-field)")
    args = parser.parse_args()
    lines = [f"{'campaign':<14} {'mode':<18} {'runs':>6} {'wall s':>7} {'x fewer':>8} "
             f"{'same decisions':>15}  decision"]
    for source in args.campaign or CAMPAIGNS:
        source = source.resolve()
        with tempfile.TemporaryDirectory(prefix="bench-decide-") as tmp:
            base = Path(tmp)
            fixed, fixed_s = run(source, base / "fixed", args.runs, args.runs, args.workers)
            want = decisions(fixed)
            fixed_runs = simulated_runs(fixed)
            rows = [("fixed (baseline)", fixed, fixed_s)]
            auto, auto_s = run(source, base / "auto", "auto", args.runs, args.workers)
            rows.append(("adaptive paired", auto, auto_s))
            unpaired = unpaired_copy(source)
            try:
                loose, loose_s = run(unpaired, base / "unpaired", "auto", args.runs,
                                     args.workers)
            finally:
                unpaired.unlink()
            rows.append(("adaptive unpaired", loose, loose_s))
            for mode, result, seconds in rows:
                found = decisions(result)
                count = simulated_runs(result)
                same = "baseline" if result is fixed else (
                    "yes" if found == want else
                    "no: " + ", ".join(f"{name} {want['verdicts'].get(name)}→{verdict}"
                                       for name, verdict in found["verdicts"].items()
                                       if want["verdicts"].get(name) != verdict)
                    or "no: the decision differs")
                lines.append(f"{source.stem:<14} {mode:<18} {count:>6} {seconds:>7.1f} "
                             f"{fixed_runs / max(count, 1):>7.1f}x {same:>15}  "
                             f"{describe(found)}")
                per_path = ", ".join(
                    f"{p['name']} {p.get('runs_used') or p.get('completed_runs') or 0}"
                    for p in result.summary["paths"] if p.get("status") == "simulated")
                lines.append(f"{'':<14} {'':<18} runs per path: {per_path}")
    print(f"fixed campaigns of {args.runs} runs per path against adaptive ones capped at "
          f"{args.runs}, {args.workers} workers, no report")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
