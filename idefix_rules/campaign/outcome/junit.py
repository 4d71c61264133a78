"""The campaign's JUnit XML: a case per path and expectation, failing where exit code 1 does."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence

from idefix_rules.campaign.evaluation.path_result import CampaignEvaluation, PathResult
from idefix_rules.campaign.input.wording import bounds_label, gate_rules, unfinished_text
from idefix_rules.campaign.outcome.decision import path_confidence, reasons_of, verdict_parts
from idefix_rules.campaign.outcome.expectation_checks import ExpectationResult, percent
from idefix_rules.campaign.simulation.processes import is_infrastructure
from idefix_rules.campaign.statistics import pairwise
from idefix_rules.campaign.statistics.stopping import STOP_FIXED
from idefix_rules.errors import Diagnostic


def _run_properties(suite: ET.Element, evaluation: CampaignEvaluation,
                    results: str | None) -> ET.Element:
    """The campaign seed, run count, results file and input hashes this suite belongs to (its
    ``<properties>``, which the caller may add to)."""
    properties = ET.SubElement(suite, "properties")
    prov = evaluation.provenance
    for key, value in (("seed", prov.get("seed")), ("runs", prov.get("runs")),
                       ("results", results), ("campaign_sha256", prov.get("campaign_sha256")),
                       ("rulebook_sha256", evaluation.rulebook.get("sha256"))):
        if value is not None:
            ET.SubElement(properties, "property", name=key, value=str(value))
    return properties


def junit_xml(evaluation: CampaignEvaluation, expectations: list[ExpectationResult],
              suite_name: str, seconds: Mapping[str, float] | None = None,
              results: str | None = None, problems: Sequence[Diagnostic] = (),
              resume: str | None = None) -> str:
    """JUnit XML whose failures are exactly what makes the exit code 1 (docs/ci.md).

    Two suites: ``<name>.expectations`` (one case per ``expect:`` entry) and ``<name>.paths``
    (one case per path, its verdict). With expectations, the exit code follows them, so only
    expectation cases fail; path cases report their verdict (the first line of their output,
    and the suite's property ``verdict[<path>]``) and pass. Without expectations, every path
    must pass: a path that does not, or whose pass is not decided at this number of runs, is a
    failure whose message names the rules it fails (an error when its evaluation broke).
    What makes the exit code 3 or 2 is an error: a path that lost runs to the infrastructure
    (its case, ``type="infrastructure"``, naming the runs, their reasons and ``resume``, the
    command that runs them again), and an expectation that does not hold on such a path
    (not judged); a mistake only the evaluation shows (``<name>.campaign``).
    ``seconds``: time spent per path (simulation in the workers and evaluation), the ``time``
    of its case; each expectation case's time is its check. Each suite's properties name
    the campaign seed and the results file. The file is valid against the JUnit schema CI
    servers check (the Jenkins xUnit plugin's ``junit-10.xsd``): properties belong to
    suites, and ``<testsuites>`` counts no skipped cases (each suite does).
    """
    seconds = seconds or {}
    asserted_paths = not expectations
    lost = {path.name: path for path in evaluation.paths if _lost_runs(path)}
    root = ET.Element("testsuites", name=suite_name)
    paths = ET.SubElement(root, "testsuite", name=f"{suite_name}.paths")
    properties = _run_properties(paths, evaluation, results)
    ET.SubElement(properties, "property", name="asserted",
                  value="yes" if asserted_paths else "no: the campaign's expectations "
                  "decide the exit code")
    failures = errors = skipped = 0
    for path in evaluation.paths:
        case = ET.SubElement(paths, "testcase", classname=f"{suite_name}.paths", name=path.name,
                             time=f"{seconds.get(path.name, 0.0):.3f}")
        verdict = path.verdict_text + (" (not decided)" if path.undecided else "")
        ET.SubElement(properties, "property", name=f"verdict[{path.name}]", value=verdict)
        summary = _summary_line(path, verdict)
        detail = _path_detail(path)
        if path.name in lost:  # not a verdict: the runs are run again (exit 3)
            errors += 1
            ET.SubElement(case, "error", message=_lost_message(path, resume),
                          type=INFRASTRUCTURE_ERROR).text = _lost_text(path, resume)
        elif asserted_paths and path.verdict_text == "error":
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
            ET.SubElement(case, "failure", message=summary,
                          type=path.verdict_text).text = detail
        compared = [pairwise.describe(pair, path.name) for pair in evaluation.pairs
                    if path.name in (pair.first, pair.second)]
        ET.SubElement(case, "system-out").text = "\n".join(
            [summary, detail, *(f"pair: {line}" for line in compared)])
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
        failed = unjudged = 0
        for index, expectation in enumerate(expectations):
            case = ET.SubElement(suite, "testcase", classname=f"{suite_name}.expect",
                                 name=f"expect[{index}] {expectation.description}",
                                 time=f"{expectation.seconds:.3f}")
            short = [name for name in expectation.paths if name in lost]
            if not expectation.held and short:  # not judged: its runs are run again
                unjudged += 1
                text = (f"not judged: {', '.join(short)} lost runs to the infrastructure "
                        f"({expectation.message}); {_again(resume)}")
                ET.SubElement(case, "error", message=text,
                              type=INFRASTRUCTURE_ERROR).text = text
            elif not expectation.held:
                failed += 1
                ET.SubElement(case, "failure", message=expectation.message,
                              type="expectation").text = expectation.message
            ET.SubElement(case, "system-out").text = expectation.message
        _suite_counts(suite, len(expectations), failed, unjudged,
                      sum(_milliseconds(e.seconds) for e in expectations))
        failures += failed
        errors += unjudged
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
                  None)  # the schema has no skipped count on <testsuites>: the suite has it
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


# The error type of a case whose runs the infrastructure lost (exit code 3).
INFRASTRUCTURE_ERROR = "infrastructure"
# Run numbers a message names before it says how many more.
_NAMED_RUNS = 10


def _lost_runs(path: PathResult) -> list[tuple[str, str]]:
    """What of ``path`` the infrastructure lost: ``(what, reason)`` for its reference run and
    each Monte Carlo run, in run order."""
    lost = [("reference run", path.reason)] if is_infrastructure(path.reason) else []
    return lost + [(f"run {run}", reason) for run, reason in sorted(path.failures.items())
                   if is_infrastructure(reason)]


def _again(resume: str | None) -> str:
    return f"run them again with `{resume}`" if resume else \
        "run them again with the campaign's command and --resume"


def _lost_message(path: PathResult, resume: str | None) -> str:
    """``path arc: runs 1, 4 lost to the infrastructure (2 of 8), not a verdict; run them
    again with `…```."""
    lost = _lost_runs(path)
    if lost[0][0] == "reference run" and len(lost) == 1:
        what = "its reference run was lost to the infrastructure"
    else:
        named = [item.removeprefix("run ") for item, _ in lost if item.startswith("run ")]
        shown = ", ".join(named[:_NAMED_RUNS]) + (
            f" and {len(named) - _NAMED_RUNS} more" if len(named) > _NAMED_RUNS else "")
        runs = f"run {shown}" if len(named) == 1 else f"runs {shown}"
        if lost[0][0] == "reference run":
            runs = f"its reference run and {runs}"
        what = f"{runs} lost to the infrastructure ({len(named)} of {path.runs})"
    return f"path {path.name}: {what}, not a verdict; {_again(resume)}"


def _lost_text(path: PathResult, resume: str | None) -> str:
    """Each run lost with its reason, then the command that runs them again."""
    return "\n".join([*(f"{what} lost: {reason}" for what, reason in _lost_runs(path)),
                      _again(resume)])


def _milliseconds(seconds: float) -> float:
    """A case's time as its ``time`` attribute shows it, so a suite's is their sum."""
    return round(seconds, 3)


def _suite_counts(element: ET.Element, tests: int, failures: int, errors: int,
                  seconds: float, skipped: int | None = 0) -> None:
    element.set("tests", str(tests))
    element.set("failures", str(failures))
    element.set("errors", str(errors))
    if skipped is not None:
        element.set("skipped", str(skipped))
    element.set("time", f"{seconds:.3f}")


def _summary_line(path: PathResult, verdict: str) -> str:
    """The path's verdict in one line, the rules it fails by name (what a CI server's
    summary shows of a failure: its message): ``path straight: fail · risk 86.0 % · fails
    acceptable_risk``; a rejected or excluded path names the command or prescreen rules."""
    parts = [f"path {path.name}: {verdict}", *verdict_parts(path)]
    named = gate_rules(path.reason)
    if path.status == "rejected" and named:
        parts.append("breaks " + ", ".join(named))
    elif path.status == "excluded" and named:
        parts.append("fails prescreen " + ", ".join(named))
    return " · ".join(parts)


def _path_detail(path: PathResult) -> str:
    lines = [f"status: {path.status}"]
    if path.reason:
        lines.append(f"reason: {path.reason}")
    if path.mean_risk is not None:
        ci = (f" ({bounds_label(path_confidence(path))} {percent(path.risk_ci[0])}–"
              f"{percent(path.risk_ci[1])})" if path.risk_ci else "")
        lines.append(f"mean risk: {percent(path.mean_risk)}{ci}")
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
        lines.append(f"run {run} {'lost' if is_infrastructure(reason) else 'failed'}: {reason}")
    return "\n".join(lines)
