"""What a campaign hands back: expectation checks, ``summary.json``, JUnit XML, exit code.

Exit codes (DESIGN.md): 0 every expectation holds (no expectations: every path passes),
1 a path or expectation failed, 2 invalid input, 3 infrastructure error.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from idefix_rules import __version__
from idefix_rules.campaign.evaluation import CampaignEvaluation, PathResult, as_plain
from idefix_rules.campaign.schema import (
    CollisionExpectation,
    MeanRiskExpectation,
    PathVerdictExpectation,
    RankFirstExpectation,
)

EXIT_OK = 0
EXIT_FAILED = 1


@dataclass(frozen=True)
class ExpectationResult:
    description: str
    held: bool
    message: str


def _percent(value: float | None) -> str:
    return "n/a" if value is None else f"{100.0 * value:.1f} %"


def check_expectation(expectation: Any, evaluation: CampaignEvaluation) -> ExpectationResult:
    """Whether one ``expect:`` entry holds, with a message saying what was found."""
    if isinstance(expectation, RankFirstExpectation):
        first = evaluation.ranking[0] if evaluation.ranking else None
        return ExpectationResult(f"{expectation.rank_first} ranks first",
                                 first == expectation.rank_first,
                                 f"ranking: {', '.join(evaluation.ranking) or '(none)'}")
    path = evaluation.path(expectation.path)
    if isinstance(expectation, PathVerdictExpectation):
        wanted = expectation.verdict
        got = path.verdict_text
        held = got == wanted or (wanted == "fail" and got in ("rejected", "excluded"))
        message = f"verdict {got}"
        if path.undecided:
            message += " (not decided at this number of runs)"
            held = False
        if path.failed:
            message += f"; {path.failed} failed run(s)"
        return ExpectationResult(f"{path.name} {'passes' if wanted == 'pass' else 'fails'}",
                                 held, message)
    if isinstance(expectation, MeanRiskExpectation):
        bound = expectation.max_mean_risk
        risk = path.mean_risk
        held = risk is not None and risk <= bound and not path.failed
        return ExpectationResult(f"{path.name} mean risk <= {_percent(bound)}", held,
                                 f"mean risk {_percent(risk)}"
                                 + (f"; {path.failed} failed run(s)" if path.failed else ""))
    assert isinstance(expectation, CollisionExpectation)
    problems = []
    found = []
    for level, bound in expectation.max_collision_chance.items():
        chance = _any_collision(path) if level == "any" else path.collision_chance.get(level)
        found.append(f"{level} {_percent(chance)}")
        if chance is None or chance > bound:
            problems.append(level)
    held = not problems and not path.failed and path.status == "simulated"
    bounds = ", ".join(f"{lvl} <= {_percent(b)}"
                       for lvl, b in expectation.max_collision_chance.items())
    return ExpectationResult(f"{path.name} collision chance {bounds}", held,
                             "collision chance " + ", ".join(found))


def _any_collision(path: PathResult) -> float | None:
    for key in ("any", "collision", "hit", "collision.any", "hit_any"):
        if key in path.chances:
            return path.chances[key]
    values = list(path.collision_chance.values())
    # Without a dedicated chance, the largest per-level chance is a lower bound.
    return max(values) if values else None


def check_expectations(expectations: list[Any],
                       evaluation: CampaignEvaluation) -> list[ExpectationResult]:
    return [check_expectation(e, evaluation) for e in expectations]


def exit_code(evaluation: CampaignEvaluation, expectations: list[ExpectationResult],
              has_expectations: bool) -> int:
    if has_expectations:
        return EXIT_OK if all(e.held for e in expectations) else EXIT_FAILED
    return EXIT_OK if all(p.verdict_text == "pass" for p in evaluation.paths) else EXIT_FAILED


def path_record(path: PathResult) -> dict[str, Any]:
    return {
        "name": path.name,
        "index": path.index,
        "status": path.status,
        "reason": path.reason,
        "runs": path.runs,
        "completed_runs": path.completed,
        "failed_runs": path.failed,
        "failures": [{"run": run, "reason": reason} for run, reason in
                     sorted(path.failures.items())],
        "mean_risk": path.mean_risk,
        "risk_ci95": list(path.risk_ci) if path.risk_ci else None,
        "chances": path.chances,
        "collision_chance": path.collision_chance,
        "energy_mAs": None if path.energy is None else path.energy * 1000.0,
        "time_s": path.time,
        "dominant_index": path.dominant_index,
        "verdict": path.verdict_text,
        "undecided": path.undecided,
        "verdict_reasons": path.verdict_reasons,
        "runs_used": path.runs,
        "stop_reason": path.stop_reason,
        "runs_needed": path.runs_needed,
        "rank": path.rank,
        "statistics": as_plain(path.statistics),
    }


def summary(evaluation: CampaignEvaluation, expectations: list[ExpectationResult],
            code: int) -> dict[str, Any]:
    prov = evaluation.provenance
    return {
        "format": "idefix-summary",
        "format_version": 1,
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
        "paths": [path_record(p) for p in evaluation.paths],
        "ranking": evaluation.ranking,
        "expectations": [{"description": e.description, "held": e.held, "message": e.message}
                         for e in expectations],
        "exit_code": code,
    }


def write_summary(path: Path, data: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=2, allow_nan=False, default=str) + "\n",
                    encoding="utf-8")


def junit_xml(evaluation: CampaignEvaluation, expectations: list[ExpectationResult],
              suite_name: str) -> str:
    """One test case per path (passes?) and per expectation (holds?)."""
    suite = ET.Element("testsuite", name=suite_name)
    failures = 0
    errors = 0
    for path in evaluation.paths:
        case = ET.SubElement(suite, "testcase", classname=f"{suite_name}.paths", name=path.name)
        text = path.verdict_text
        detail = _path_detail(path)
        if text == "error":
            errors += 1
            ET.SubElement(case, "error", message=f"path {path.name}: {path.reason or 'error'}",
                          type="error").text = detail
        elif text != "pass":
            failures += 1
            ET.SubElement(case, "failure", message=f"path {path.name}: {text}",
                          type=text).text = detail
        ET.SubElement(case, "system-out").text = detail
    for index, expectation in enumerate(expectations):
        case = ET.SubElement(suite, "testcase", classname=f"{suite_name}.expect",
                             name=f"expect[{index}] {expectation.description}")
        if not expectation.held:
            failures += 1
            ET.SubElement(case, "failure", message=expectation.message,
                          type="expectation").text = expectation.message
    suite.set("tests", str(len(evaluation.paths) + len(expectations)))
    suite.set("failures", str(failures))
    suite.set("errors", str(errors))
    root = ET.Element("testsuites")
    root.append(suite)
    ET.indent(root)
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"


def _path_detail(path: PathResult) -> str:
    lines = [f"status: {path.status}"]
    if path.reason:
        lines.append(f"reason: {path.reason}")
    if path.mean_risk is not None:
        ci = f" (95 % CI {_percent(path.risk_ci[0])}–{_percent(path.risk_ci[1])})" \
            if path.risk_ci else ""
        lines.append(f"mean risk: {_percent(path.mean_risk)}{ci}")
    # An undecided verdict is said by the reasons (each undecided rule's message says it).
    for reason in path.verdict_reasons:
        lines.append(f"verdict: {reason}")
    for run, reason in sorted(path.failures.items()):
        lines.append(f"run {run} failed: {reason}")
    return "\n".join(lines)
