"""What a campaign hands back: expectation checks, ``summary.json``, JUnit XML, exit code.

Exit codes (DESIGN.md): 0 every expectation holds (no expectations: every path passes),
1 a path or expectation failed, 2 invalid input, 3 infrastructure error (also when runs failed
because of the cluster: ``--resume`` runs them again).

Outputs never speak for another run: each names the campaign seed and the results file it was
made from, is written to a temporary file and renamed, and a run sets the previous run's
outputs aside (``summary.previous.json`` …) before it simulates anything.
"""

from __future__ import annotations

import dataclasses
import json
import re
import time
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from idefix_rules import __version__
from idefix_rules.campaign.evaluation.path_result import CampaignEvaluation, PathResult
from idefix_rules.campaign.input.expectations import (
    CollisionExpectation,
    MeanRiskExpectation,
    PathVerdictExpectation,
    RankFirstExpectation,
)
from idefix_rules.campaign.input.wording import bounds_label, unfinished_text
from idefix_rules.campaign.outcome.decision import (
    campaign_decision,
    path_confidence,
    reasons_of,
)
from idefix_rules.campaign.simulation.dask_pool import is_infrastructure
from idefix_rules.campaign.statistics import pairwise
from idefix_rules.campaign.statistics.bernoulli import anytime_bounds
from idefix_rules.campaign.statistics.stopping import STOP_FIXED
from idefix_rules.errors import Diagnostic
from idefix_rules.files import write_atomic
from idefix_rules.plain import as_plain

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_INPUT = 2  # a mistake of the campaign (a waiver matching nothing shows after evaluation)
EXIT_INFRASTRUCTURE = 3


@dataclass(frozen=True)
class ExpectationResult:
    description: str
    held: bool
    message: str
    seconds: float = 0.0  # time the check took (JUnit ``time``)


def _percent(value: float | None) -> str:
    return "n/a" if value is None else f"{100.0 * value:.1f} %"


def check_expectation(expectation: Any, evaluation: CampaignEvaluation) -> ExpectationResult:
    """Whether one ``expect:`` entry holds, with a message saying what was found.

    An expectation holds only where the campaign's statistics show it, as a verdict does: a
    mean risk whose upper bound is within the limit, collision chances whose upper bounds
    are, a first rank settled against every other ranked chain. Where the bounds straddle the
    limit (or the rank is open) it does not hold and says it is not decided at this number of
    runs: a campaign of two runs proves nothing (docs/ci.md, "Expectations")."""
    if isinstance(expectation, RankFirstExpectation):
        return _rank_first(expectation.rank_first, evaluation)
    path = evaluation.path(expectation.path)
    if isinstance(expectation, PathVerdictExpectation):
        wanted = expectation.verdict
        got = path.verdict_text
        held = got == wanted or (wanted == "fail" and got in ("rejected", "excluded")) \
            or (wanted == "pass" and got == "waived")  # a waived failure counts as held
        message = f"verdict {got}"
        if path.undecided:
            message += UNDECIDED
            held = False
        if path.failed:
            message += f"; {path.failed} failed run(s)"
        says = {"pass": "passes", "fail": "fails"}.get(wanted, "is within a margin of a limit")
        return ExpectationResult(f"{path.name} {says}", held, message)
    if isinstance(expectation, MeanRiskExpectation):
        bound = expectation.max_mean_risk
        risk = path.mean_risk
        low, high = path.risk_ci if path.risk_ci is not None else (risk, risk)
        held = risk is not None and high is not None and high <= bound and not path.failed
        message = f"mean risk {_percent(risk)}"
        if low is not None and high is not None and path.risk_ci is not None:
            message += f" (bounds {_percent(low)}–{_percent(high)})"
        if risk is not None and not held and low is not None and high is not None \
                and low <= bound < high:
            message += UNDECIDED
        return ExpectationResult(f"{path.name} mean risk <= {_percent(bound)}", held,
                                 message + (f"; {path.failed} failed run(s)" if path.failed
                                            else ""))
    assert isinstance(expectation, CollisionExpectation)
    problems = []
    found = []
    open_levels = []
    alpha = evaluation.budget.alpha if evaluation.budget is not None else DEFAULT_ALPHA
    for level, bound in expectation.max_collision_chance.items():
        bounds = _any_bounds(path, alpha) if level == "any" else (
            None if path.collision_chance.get(level) is None
            else (path.collision_chance[level],
                  *chance_bounds(path.collision_chance[level], path.completed, alpha)))
        if bounds is None:
            found.append(f"{level} {_percent(None)}")
            problems.append(level)
            continue
        chance, low, high = bounds
        found.append(f"{level} {_percent(chance)} (bounds {_percent(low)}–{_percent(high)})")
        if high > bound:
            problems.append(level)
            if low <= bound:
                open_levels.append(level)
    held = not problems and not path.failed and path.status == "simulated"
    shown = ", ".join(f"{lvl} <= {_percent(b)}"
                      for lvl, b in expectation.max_collision_chance.items())
    return ExpectationResult(f"{path.name} collision chance {shown}", held,
                             "collision chance " + ", ".join(found)
                             + (UNDECIDED if open_levels and held is False else ""))


def chance_bounds(chance: float, runs: int, alpha: float) -> tuple[float, float]:
    """A chance's one-sided bounds at ``alpha`` each, valid however the run count was reached
    (a fixed count, or an adaptive campaign's stop, which could fool a Clopper-Pearson
    interval): :func:`~idefix_rules.campaign.statistics.bernoulli.anytime_bounds`."""
    return anytime_bounds(round(chance * runs), runs, alpha)


def _any_bounds(path: PathResult, alpha: float) -> tuple[float, float, float] | None:
    """The chance of a hit of any level, and its bounds: a dedicated chance's where the
    rulebook has one; else from the per-level chances, which the union only bounds: at least
    the largest (its lower bound), at most their sum (the sum of their upper bounds)."""
    for key in ("any", "collision", "hit", "collision.any", "hit_any"):
        if key in path.chances:
            return (path.chances[key], *chance_bounds(path.chances[key], path.completed, alpha))
    values = list(path.collision_chance.values())
    if not values:
        return None
    each = [chance_bounds(value, path.completed, alpha) for value in values]
    return (max(values), max(low for low, _ in each),
            min(1.0, sum(high for _, high in each)))


UNDECIDED = " (not decided at this number of runs)"
DEFAULT_ALPHA = 0.05


def _rank_first(name: str, evaluation: CampaignEvaluation) -> ExpectationResult:
    """``rank_first``: ranked first, and settled so against every other ranked chain: a
    chain shown to pass ranks above one shown not to; else by the risk, compared in the same
    worlds on a paired campaign, by the risks' bounds apart on an unpaired one. A tie with the
    chain ranked first shares the first rank and holds, saying so."""
    description = f"{name} ranks first"
    ranking = ", ".join(evaluation.ranking) or "(none)"
    me = evaluation.path(name) if name in evaluation.ranking else None
    # first in the ranking, or sharing the first rank (a tie, ordered by name there)
    if me is None or (evaluation.ranking[0] != name and me.rank != 1):
        return ExpectationResult(description, False, f"ranking: {ranking}")
    ties: list[str] = []
    open_with: list[str] = []
    shown_to_pass = bool(me.passed) and not me.undecided
    for other in evaluation.paths:
        if other.name == name or other.rank is None:
            continue
        if shown_to_pass and other.passed is False and not other.undecided:
            continue  # passing chains rank first, and these two verdicts are decided
        pair = pairwise.find(evaluation.pairs, name, other.name) if evaluation.pairs else None
        if pair is not None:
            order = pair.order()
            ahead = order if pair.first == name else (None if order is None else -order)
            if ahead == 0:
                ties.append(other.name)
            elif ahead != -1:
                open_with.append(other.name)
        elif me.risk_ci is None or other.risk_ci is None or not me.risk_ci[1] < other.risk_ci[0]:
            open_with.append(other.name)
    message = f"ranking: {ranking}"
    if ties:
        message += f"; tied with {', '.join(ties)} within the indifference margin"
    if open_with:
        message += (f"; its lead over {', '.join(open_with)} is not settled"
                    f"{UNDECIDED}")
    return ExpectationResult(description, not open_with, message)


def check_expectations(expectations: list[Any],
                       evaluation: CampaignEvaluation) -> list[ExpectationResult]:
    results = []
    for expectation in expectations:
        started = time.perf_counter()
        result = check_expectation(expectation, evaluation)
        results.append(dataclasses.replace(result, seconds=time.perf_counter() - started))
    return results


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


def _run_properties(suite: ET.Element, evaluation: CampaignEvaluation,
                    results: str | None) -> None:
    """The campaign seed, run count, results file and input hashes this suite belongs to."""
    properties = ET.SubElement(suite, "properties")
    prov = evaluation.provenance
    for key, value in (("seed", prov.get("seed")), ("runs", prov.get("runs")),
                       ("results", results), ("campaign_sha256", prov.get("campaign_sha256")),
                       ("rulebook_sha256", evaluation.rulebook.get("sha256"))):
        if value is not None:
            ET.SubElement(properties, "property", name=key, value=str(value))


def junit_xml(evaluation: CampaignEvaluation, expectations: list[ExpectationResult],
              suite_name: str, seconds: Mapping[str, float] | None = None,
              results: str | None = None, problems: Sequence[Diagnostic] = ()) -> str:
    """JUnit XML whose failures are exactly what makes the exit code 1 (docs/ci.md).

    Two suites: ``<name>.expectations`` (one case per ``expect:`` entry) and ``<name>.paths``
    (one case per path, its verdict). With expectations, the exit code follows them, so only
    expectation cases fail; path cases report their verdict (property ``verdict``, text) and
    pass. Without expectations, every path must pass: a path that does not, or whose pass is
    not decided at this number of runs, is a failure (an error when its evaluation broke).
    ``seconds``: time spent per path (simulation in the workers and evaluation), the ``time``
    of its case; each expectation case's time is its check. Each suite's properties name
    the campaign seed and the results file.
    """
    seconds = seconds or {}
    asserted_paths = not expectations
    root = ET.Element("testsuites", name=suite_name)
    paths = ET.SubElement(root, "testsuite", name=f"{suite_name}.paths")
    _run_properties(paths, evaluation, results)
    failures = errors = skipped = 0
    for path in evaluation.paths:
        case = ET.SubElement(paths, "testcase", classname=f"{suite_name}.paths", name=path.name,
                             time=f"{seconds.get(path.name, 0.0):.3f}")
        properties = ET.SubElement(case, "properties")
        verdict = path.verdict_text + (" (not decided)" if path.undecided else "")
        ET.SubElement(properties, "property", name="verdict", value=verdict)
        ET.SubElement(properties, "property", name="asserted",
                      value="yes" if asserted_paths else "no: the campaign's expectations "
                      "decide the exit code")
        detail = _path_detail(path)
        if asserted_paths and path.verdict_text == "error":
            errors += 1
            ET.SubElement(case, "error", message=f"path {path.name}: {path.reason or 'error'}",
                          type="error").text = detail
        elif path.verdict_text == "waived" and (path.held or not asserted_paths):
            # neither a pass nor a failure: said as skipped
            skipped += 1
            ET.SubElement(case, "skipped", message="; ".join(
                f"{waived.text()} [{waived.rule}]" for waived in path.waivers))
        elif asserted_paths and not path.held:
            failures += 1
            ET.SubElement(case, "failure", message=f"path {path.name}: {verdict}",
                          type=path.verdict_text).text = detail
        compared = [pairwise.describe(pair, path.name) for pair in evaluation.pairs
                    if path.name in (pair.first, pair.second)]
        ET.SubElement(case, "system-out").text = "\n".join(
            [detail, *(f"pair: {line}" for line in compared)])
    neighbours = pairwise.adjacent(evaluation.ranking, evaluation.pairs)
    if neighbours:  # the ranking's neighbours compared in the same worlds, best first
        ET.SubElement(paths, "system-out").text = "\n".join(
            f"pair: {pairwise.describe(pair, above)}" for above, pair in neighbours)
    _suite_counts(paths, len(evaluation.paths), failures, errors,
                  sum(_milliseconds(seconds.get(p.name, 0.0)) for p in evaluation.paths),
                  skipped)
    if expectations:
        suite = ET.SubElement(root, "testsuite", name=f"{suite_name}.expectations")
        _run_properties(suite, evaluation, results)
        failed = 0
        for index, expectation in enumerate(expectations):
            case = ET.SubElement(suite, "testcase", classname=f"{suite_name}.expect",
                                 name=f"expect[{index}] {expectation.description}",
                                 time=f"{expectation.seconds:.3f}")
            if not expectation.held:
                failed += 1
                ET.SubElement(case, "failure", message=expectation.message,
                              type="expectation").text = expectation.message
            ET.SubElement(case, "system-out").text = expectation.message
        _suite_counts(suite, len(expectations), failed, 0,
                      sum(_milliseconds(e.seconds) for e in expectations))
        failures += failed
    if problems:  # the mistakes that make the exit code 2: a case in error each
        suite = ET.SubElement(root, "testsuite", name=f"{suite_name}.campaign")
        _run_properties(suite, evaluation, results)
        for problem in problems:
            case = ET.SubElement(suite, "testcase", classname=f"{suite_name}.campaign",
                                 name=f"{problem.code} {problem.location()}", time="0.000")
            ET.SubElement(case, "error", message=problem.message,
                          type=problem.code).text = problem.format()
        _suite_counts(suite, len(problems), 0, len(problems), 0.0)
        errors += len(problems)
    _suite_counts(root, len(evaluation.paths) + len(expectations) + len(problems), failures,
                  errors, sum(float(s.get("time", "0")) for s in root.iter("testsuite")),
                  skipped)
    ET.indent(root)
    _xml_safe(root)
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"


# Characters XML 1.0 cannot hold, even escaped (control characters, lone surrogates, U+FFFE/F):
# ElementTree writes them as they are, and the file is then not XML.
_NOT_XML = re.compile("[^\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


def _visible(match: re.Match[str]) -> str:
    code = ord(match.group())
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"


def _xml_safe(root: ET.Element) -> None:
    """Write what XML cannot hold (a control character in a campaign's name, a waiver's
    reason or a message) as its Python escape (``\\x02``), so the file stays well-formed."""
    for element in root.iter():
        if element.text:
            element.text = _NOT_XML.sub(_visible, element.text)
        if element.tail:
            element.tail = _NOT_XML.sub(_visible, element.tail)
        for key, value in element.attrib.items():
            element.attrib[key] = _NOT_XML.sub(_visible, value)


def _milliseconds(seconds: float) -> float:
    """A case's time as its ``time`` attribute shows it, so a suite's is their sum."""
    return round(seconds, 3)


def _suite_counts(element: ET.Element, tests: int, failures: int, errors: int,
                  seconds: float, skipped: int = 0) -> None:
    element.set("tests", str(tests))
    element.set("failures", str(failures))
    element.set("errors", str(errors))
    element.set("skipped", str(skipped))
    element.set("time", f"{seconds:.3f}")


def _path_detail(path: PathResult) -> str:
    lines = [f"status: {path.status}"]
    if path.reason:
        lines.append(f"reason: {path.reason}")
    if path.mean_risk is not None:
        ci = (f" ({bounds_label(path_confidence(path))} {_percent(path.risk_ci[0])}–"
              f"{_percent(path.risk_ci[1])})" if path.risk_ci else "")
        lines.append(f"mean risk: {_percent(path.mean_risk)}{ci}")
    # An undecided verdict is said by the reasons (each undecided rule's message says it);
    # an adaptive campaign says why it stopped the path there (a verdict left open because no
    # decision depends on it, or the cap)
    for reason in reasons_of(path):
        lines.append(f"verdict: {reason}")
    if path.stop_reason and not path.stop_reason.startswith(STOP_FIXED):
        lines.append(f"runs: {path.stop_reason}")
    for waived in path.waivers:
        lines.append(f"{waived.kind} {waived.rule}: {waived.text()}")
    if path.unfinished and path.stop_time is not None:
        lines.append(unfinished_text(path.name, path.unfinished, path.completed,
                                     path.stop_time))
    if path.risk_spread is not None and path.risk_spread.warning:  # its risk tells nothing
        lines.append(f"warning: {path.risk_spread.warning}")
    for run, reason in sorted(path.failures.items()):
        lines.append(f"run {run} failed: {reason}")
    return "\n".join(lines)
