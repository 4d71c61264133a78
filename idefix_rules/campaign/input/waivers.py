"""Waivers: a known, accepted failure of one rule on a path of this plan, signed and dated.

A waiver (``waivers:`` in the campaign, docs/campaign-format.md) names a verdict or prescreen
rule of the rulebook (a command rule only with ``command_rules: true``), a path or ``all``, a
reason, who approved it and until when. A waived failure counts as held for the exit code and
the decision, and is reported as ``waived``, never as ``pass``.

Checked before anything is simulated, and again before ``evaluate`` scores a stored campaign
(:func:`waiver_problems`: unknown rule or path, expired, a command rule without
``command_rules: true``), and after the evaluation (:func:`unused`: a waiver whose rule held on
every path it names is an error at its line, exit 2).

>>> from datetime import date
>>> WaivedRule("acceptable_risk", "verdict", "site survey", "J. Doe", "2026-12-01").text()
'waived: site survey (approved by J. Doe until 2026-12-01)'
"""

from __future__ import annotations

import dataclasses
import difflib
import json
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from datetime import date
from typing import TYPE_CHECKING, Any, Literal, TypeVar

from idefix_rules.errors import Diagnostic, Span, error

if TYPE_CHECKING:
    from idefix_rules.campaign.evaluation.path_result import CampaignEvaluation
    from idefix_rules.campaign.input.load import Campaign
    from idefix_rules.campaign.input.schema import Waiver

RuleKind = Literal["verdict", "prescreen", "command"]
# results.h5 (JSON): a path group's prescreen and command waivers, its evaluation's verdict ones
STORED_ATTRIBUTE = "waived"

Finding = TypeVar("Finding")


@dataclass(frozen=True)
class WaivedRule:
    """A rule failure a waiver covers on one path."""

    rule: str
    kind: str  # verdict, prescreen or command
    reason: str
    approved_by: str
    until: str  # ISO date

    def text(self) -> str:
        return f"waived: {self.reason} (approved by {self.approved_by} until {self.until})"

    def to_dict(self) -> dict[str, str]:
        return dataclasses.asdict(self)

    @classmethod
    def of(cls, waiver: Waiver, kind: str) -> WaivedRule:
        return cls(waiver.rule, kind, waiver.reason, waiver.approved_by,
                   waiver.until.isoformat())


def rule_kinds(rulebook: Any) -> dict[str, RuleKind]:
    """``{rule name: kind}`` of the rules a waiver may name (``Rulebook``)."""
    kinds: dict[str, RuleKind] = {rule.name: "command" for rule in rulebook.command_rules}
    kinds.update({rule.name: "prescreen" for rule in rulebook.prescreens})
    kinds.update({rule.name: "verdict" for rule in rulebook.verdicts})
    return kinds


def waiver_problems(campaign: Campaign, rulebook: Any, today: date | None = None,
                    stored: bool = False) -> list[Diagnostic]:
    """Mistakes of ``waivers:`` found before simulating (or, ``stored``, before evaluating a
    stored campaign again): an unknown rule (C211), an unknown path (C212), a waiver past its
    ``until`` (C213; the day itself is still valid) and a command rule waived without
    ``command_rules: true`` (C214)."""
    today = today or date.today()
    renew = ("the waiver is the one stored with the results: renew it in the campaign file "
             "(a new date, approved again) and run the campaign again" if stored
             else "renew it (a new date, approved again) or remove it")
    kinds = rule_kinds(rulebook)
    problems = []
    for number, waiver in enumerate(campaign.model.waivers):
        where = f"waivers[{number}]"
        kind = kinds.get(waiver.rule)
        if kind is None:
            close = difflib.get_close_matches(waiver.rule, list(kinds), n=1)
            problems.append(error(
                "C211", f"{where}.rule: the rulebook has no verdict, prescreen or command rule "
                        f"{waiver.rule!r}", campaign.span(("waivers", number, "rule")),
                hint=f"did you mean {close[0]!r}?" if close else
                f"rules: {', '.join(kinds) or 'none'}"))
        elif kind == "command" and not waiver.command_rules:
            problems.append(error(
                "C214", f"{where}.rule: {waiver.rule!r} is a command rule; a waiver matches "
                        "a rejected command rule only with 'command_rules: true'",
                campaign.span(("waivers", number, "rule")),
                hint="add 'command_rules: true' to the waiver if the chain may really be sent "
                     "with a command that breaks it"))
        if waiver.path != "all" and waiver.path not in campaign.model.paths:
            problems.append(error(
                "C212", f"{where}.path: unknown path {waiver.path!r} (paths: "
                        f"{', '.join(campaign.model.paths)}, or all)",
                campaign.span(("waivers", number, "path"))))
        if today > waiver.until:
            problems.append(error(
                "C213", f"{where}.until: the waiver expired on {waiver.until.isoformat()} "
                        f"(today is {today.isoformat()})",
                campaign.span(("waivers", number, "until")),
                hint=renew))
    return problems


def waiver_for(waivers: Sequence[Waiver], path: str, rule: str, kind: RuleKind
               ) -> Waiver | None:
    """The first waiver covering ``rule`` on ``path`` (a command rule only when it says so)."""
    for waiver in waivers:
        if waiver.rule == rule and waiver.covers(path) \
                and (kind != "command" or waiver.command_rules):
            return waiver
    return None


def split(waivers: Sequence[Waiver], path: str, kind: RuleKind, findings: Iterable[Finding],
          rule_of: Callable[[Finding], str]) -> tuple[list[Finding], list[WaivedRule]]:
    """Findings of one path (command violations, prescreen findings) into those that stand
    and the waived rules."""
    standing: list[Finding] = []
    waived: dict[str, WaivedRule] = {}
    for finding in findings:
        waiver = waiver_for(waivers, path, rule_of(finding), kind)
        if waiver is None:
            standing.append(finding)
        else:
            waived.setdefault(waiver.rule, WaivedRule.of(waiver, kind))
    return standing, list(waived.values())


def waive_verdict(verdict: Any, waivers: Sequence[Waiver], path: str
                  ) -> tuple[Any, list[WaivedRule]]:
    """A path's verdict without the rules waived on it, and those rules. A waiver covers a
    rule that fails or is not decided; a rule that passes decidedly needs none."""
    waived: list[WaivedRule] = []
    standing = []
    for rule in verdict.rules:
        waiver = None if rule.passed and rule.decided \
            else waiver_for(waivers, path, rule.name, "verdict")
        if waiver is None:
            standing.append(rule)
        else:
            waived.append(WaivedRule.of(waiver, "verdict"))
    if not waived:
        return verdict, []
    passed = all(rule.passed for rule in standing)
    decided = all(rule.decided for rule in standing) \
        or any(not rule.passed and rule.decided for rule in standing)
    return dataclasses.replace(verdict, passed=passed, decided=decided,
                               rules=tuple(standing)), waived


def stored(text: str) -> list[WaivedRule]:
    """Waived rules as stored in a path's attribute (JSON)."""
    return [WaivedRule(**item) for item in json.loads(text or "[]")]


def recorded(group: Any) -> list[WaivedRule]:
    """Every waived rule a results file holds for a path (its ``h5py`` group): the prescreen
    and command waivers of its simulation, then the verdict waivers of its evaluation."""
    rules = stored(str(group.attrs.get(STORED_ATTRIBUTE, "")))
    evaluation = group.get("evaluation")
    if evaluation is not None:
        rules += stored(str(evaluation.attrs.get(STORED_ATTRIBUTE, "")))
    return rules


def to_store(existing: str, added: Sequence[WaivedRule]) -> str:
    """The attribute's new JSON with ``added`` joined to what it held."""
    rules = stored(existing)
    rules += [rule for rule in added if rule not in rules]
    return json.dumps([rule.to_dict() for rule in rules])


def unused(waivers: Sequence[Waiver], evaluation: CampaignEvaluation,
           locate: Callable[[tuple[str | int, ...]], Span]) -> list[Diagnostic]:
    """Waivers that matched nothing (C215): their rule held on every path they name (or the
    path never reached the stage the rule judges)."""
    applied = {(path.name, rule.rule) for path in evaluation.paths for rule in path.waivers}
    problems = []
    for number, waiver in enumerate(waivers):
        names = [p.name for p in evaluation.paths if waiver.covers(p.name)]
        if any((name, waiver.rule) in applied for name in names):
            continue
        on = "any path" if waiver.path == "all" else f"path {waiver.path!r}"
        problems.append(error(
            "C215", f"waivers[{number}]: the waiver matches nothing: rule {waiver.rule!r} did "
                    f"not fail on {on}", locate(("waivers", number)),
            hint="remove the waiver: a waiver is for a failure that happens"))
    return problems
