"""What a campaign hands back: ``summary.json`` and the exit code (the expectation checks are
in :mod:`~idefix_rules.campaign.outcome.expectation_checks`, the JUnit XML in
:mod:`~idefix_rules.campaign.outcome.junit`).

Exit codes (DESIGN.md): 0 every expectation holds (no expectations: every path passes),
1 a path or expectation failed, 2 invalid input, 3 infrastructure error (also when runs failed
because of the cluster: ``--resume`` runs them again).

Outputs never speak for another run: each names the campaign seed and the results file it was
made from, is written to a temporary file and renamed, and a run sets the previous run's
outputs aside (``summary.previous.json`` …) before it simulates anything.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from idefix_rules import __version__
from idefix_rules.campaign.evaluation.path_result import CampaignEvaluation, PathResult
from idefix_rules.campaign.outcome.decision import campaign_decision, reasons_of
from idefix_rules.campaign.outcome.expectation_checks import ExpectationResult
from idefix_rules.campaign.simulation.dask_pool import is_infrastructure
from idefix_rules.errors import Diagnostic
from idefix_rules.files import write_atomic
from idefix_rules.plain import as_plain

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_INPUT = 2  # a mistake of the campaign (a waiver matching nothing shows after evaluation)
EXIT_INFRASTRUCTURE = 3


def infrastructure_failures(evaluation: CampaignEvaluation) -> int:
    """Runs (a reference run too) lost to the infrastructure, not failed for their own reason."""
    return sum(is_infrastructure(reason) for path in evaluation.paths
               for reason in (path.reason, *path.failures.values()))


def exit_code(evaluation: CampaignEvaluation, expectations: list[ExpectationResult],
              has_expectations: bool) -> int:
    if infrastructure_failures(evaluation):
        return EXIT_INFRASTRUCTURE  # not a verdict on the chains: run them again
    if has_expectations:
        return EXIT_OK if all(e.held for e in expectations) else EXIT_FAILED
    # a waived failure counts as held, a pass not decided at this number of runs does not
    return EXIT_OK if all(p.held for p in evaluation.paths) else EXIT_FAILED


# Units of the numbers in a summary's path records (also in docs/results-format.md).
SUMMARY_UNITS = {
    # Fractions here; the console, `diff` and the report show them in percent (× 100).
    "mean_risk": "fraction 0 … 1, shown in % (run risk I_max, 0 safe … 1 critical; "
                 "unrounded)",
    "risk_ci95": "fraction 0 … 1, shown in % (unrounded): the mean risk's bounds at the "
                 "rulebook's family-wise confidence, 1 - alpha.alpha (95 % by default)",
    "chances": "fraction 0 … 1 of the runs, shown in % (unrounded)",
    "collision_chance": "fraction 0 … 1 of the runs per obstacle level, shown in % "
                        "(unrounded)",
    "slip": "fraction 0 … 1 (assumed, measured, wheel_slip, margin), shown in %",
    "energy_mAs": "mAs (unrounded)",
    "time_s": "s (unrounded)",
    "stop_time_s": "s (unrounded)",
    "statistics": "SI, 4 significant digits (risk and chances 1, time s, energy A·s)",
    "sensitivity": "rank correlations, -1 … 1 (3 decimals)",
    "risk_spread": "fractions 0 … 1 (critical, at_limit: of the runs; quartiles, iqr, lowest, "
                   "highest: run risk I_max), 4 decimals",
}


def _plain(value: float | None) -> float | None:
    return None if value is None else float(value)


def significant(obj: Any, digits: int = 4) -> Any:
    """Every float of a plain tree rounded to ``digits`` significant digits.

    >>> significant({"a": [0.123456, 123456.7], "b": 3})
    {'a': [0.1235, 123500.0], 'b': 3}
    """
    if isinstance(obj, float):
        return float(f"{obj:.{digits}g}") if obj == obj and abs(obj) != float("inf") else obj
    if isinstance(obj, dict):
        return {k: significant(v, digits) for k, v in obj.items()}
    if isinstance(obj, list):
        return [significant(v, digits) for v in obj]
    return obj


def path_record(path: PathResult) -> dict[str, Any]:
    return {
        "name": path.name,
        "index": path.index,
        "status": path.status,
        "reason": path.reason,
        "runs": path.runs,
        "completed_runs": path.completed,
        # the rulebook's `failed` statistic counts both: failed_runs + missing_runs
        "failed_runs": path.failed,
        "missing_runs": path.missing,
        "failures": [{"run": run, "reason": reason} for run, reason in
                     sorted(path.failures.items())],
        # unrounded: the report prints these again, and a value rounded twice can differ
        # from the console's in its last digit (0.067464 → 0.0675 → 6.8 % against 6.7 %)
        "mean_risk": _plain(path.mean_risk),
        "risk_ci95": [float(v) for v in path.risk_ci] if path.risk_ci else None,
        "chances": {k: float(v) for k, v in path.chances.items()},
        "collision_chance": {k: float(v) for k, v in path.collision_chance.items()},
        "energy_mAs": None if path.energy is None else float(path.energy) * 1000.0,
        "time_s": _plain(path.time),
        "stop_time_s": _plain(path.stop_time),
        "unfinished_runs": path.unfinished,
        "dominant_index": path.dominant_index,
        "risk_spread": (path.risk_spread.to_dict() if path.risk_spread is not None else None),
        "verdict": path.verdict_text,
        "undecided": path.undecided,
        "verdict_reasons": path.verdict_reasons,
        "waivers": [waived.to_dict() for waived in path.waivers],
        "reasons": reasons_of(path),
        "runs_used": path.runs,
        "stop_reason": path.stop_reason,
        "runs_needed": path.runs_needed,
        "rank": path.rank,
        "statistics": significant(as_plain(path.statistics)),
    }


def summary(evaluation: CampaignEvaluation, expectations: list[ExpectationResult],
            code: int, sensitivity: dict[str, Any] | None = None,
            results: str | None = None,
            problems: Sequence[Diagnostic] = ()) -> dict[str, Any]:
    prov = evaluation.provenance
    return {
        "format": "idefix-summary",
        "format_version": 1,
        "results": results,
        "campaign": {"name": prov.get("campaign_name"), "path": prov.get("campaign_path"),
                     "sha256": prov.get("campaign_sha256")},
        "rulebook": evaluation.rulebook,
        "fmu": {"path": prov.get("fmu_path"), "sha256": prov.get("fmu_sha256")},
        "package_version": __version__,
        "runs": prov.get("runs"),
        "seed": prov.get("seed"),
        "sampling": prov.get("sampling"),
        "started": prov.get("started"),
        "finished": prov.get("finished"),
        "decision": campaign_decision(evaluation).to_dict(),
        "units": SUMMARY_UNITS,
        "paths": [path_record(p) for p in evaluation.paths],
        "ranking": evaluation.ranking,
        "paired": evaluation.paired,
        "indifference": evaluation.indifference,
        "ties": [list(tie) for tie in evaluation.ties],
        "pairs": [as_plain(pair.to_dict()) for pair in evaluation.pairs],  # printed again
        "alpha": (significant(evaluation.budget.to_dict())
                  if evaluation.budget is not None else None),
        "sensitivity": sensitivity or {},
        "expectations": [{"description": e.description, "held": e.held, "message": e.message}
                         for e in expectations],
        "slip": slip_record(evaluation),
        # the campaign's mistakes only its evaluation shows (a waiver matching nothing): why
        # the exit code is 2
        "problems": [problem.to_dict() for problem in problems],
        "exit_code": code,
    }


def slip_record(evaluation: CampaignEvaluation) -> dict[str, Any]:
    """Assumed vs simulated slip (idefix_rules.campaign.evaluation.slip), with the margin it
    warns at."""
    from idefix_rules.campaign.evaluation.slip import SETTING, SLIP_MARGIN, slip_warning

    return {"setting": SETTING, "margin": SLIP_MARGIN, "warning": slip_warning(evaluation.slip),
            "paths": [check.to_dict() for check in evaluation.slip]}


def write_summary(path: Path, data: dict[str, Any]) -> None:
    write_atomic(path, json.dumps(data, indent=2, allow_nan=False, default=str) + "\n")
