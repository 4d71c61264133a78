"""The decision a campaign supports, in words: which chain to send, none, or not settled yet.

The verdicts say pass/fail per chain and the ranking orders them; operators want one sentence.
The decision is separate from CI's outcome (the exit code follows the campaign's ``expect:``
entries, which may well assert that a chain fails):

- **send**: the best-ranked chain whose verdict passes (or is waived: its only failures are
  waived by the campaign, and the decision says so) and is decided. When a paired campaign
  cannot tell it apart from another passing chain (their per-world risk difference is open, or
  tied within the rulebook's indifference margin), the decision names all of them: any of
  those chains may be the best, and the ranking between them is not a decision.
- **unsettled**: no chain passes decidedly, and some chain's verdict is not decided at this
  number of runs (a threshold lies inside a confidence interval): more runs are needed.
- **marginal**: no chain passes and none is open, but some chain fails no rule decidedly: a
  statistic of it lies within its rule's indifference margin of the limit. It is not shown to
  pass, so it is not sent; the decision names it and the rules, and leaves the call to a
  person (more runs would not settle what the rulebook says does not matter).
- **none**: no chain is acceptable; the best-ranked simulated chain is named as the least bad,
  with the verdicts it fails.

>>> from types import SimpleNamespace as P
>>> paths = [P(name="a", verdict="fail", undecided=False, rank=2, reasons=["r1"]),
...          P(name="b", verdict="pass", undecided=False, rank=1, reasons=[])]
>>> decide(paths).text
'send b (passes every verdict, rank 1 of 2)'
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

from idefix_rules.campaign.evaluation.gate import NEEDS_RUN
from idefix_rules.campaign.evaluation.path_result import CampaignEvaluation, PathResult
from idefix_rules.campaign.input.wording import verdict_reason_items
from idefix_rules.campaign.statistics.pairwise import OPEN, TIED, find
from idefix_rules.campaign.statistics.stopping import MOOT
from idefix_rules.plain import as_plain
from idefix_rules.results.format import is_search

DecisionKind = Literal["send", "none", "unsettled", "marginal"]


@dataclass(frozen=True)
class Decision:
    """What to do with the chains of a campaign."""

    kind: DecisionKind
    path: str | None  # the chain to send, or the least bad one; None when nothing ran
    text: str
    reasons: tuple[str, ...] = field(default=())
    # with ``send``: every chain that could be the best (``path`` first); one unless paired
    # comparisons leave the lead open or tied
    candidates: tuple[str, ...] = field(default=())

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "path": self.path, "text": self.text,
                "reasons": list(self.reasons), "candidates": list(self.candidates)}


def _named(names: Sequence[str]) -> str:
    """``names`` as the subject of a sentence.

    >>> _named(["a"]), _named(["a", "b"])
    ('a was', 'a, b were')
    """
    return f"{', '.join(names)} {'was' if len(names) == 1 else 'were'}"


def _rank(path: Any) -> tuple[bool, int]:
    rank = getattr(path, "rank", None)
    return (rank is None, rank or 0)


def _unsettled_with(best: str, others: Sequence[Any], pairs: Sequence[Any]
                    ) -> list[tuple[str, str]]:
    """The passing chains whose paired comparison with ``best`` is open or tied, each with
    that outcome."""
    found = []
    for other in others:
        pair = find(pairs, best, other.name)
        if pair is not None and pair.outcome in (OPEN, TIED):
            found.append((other.name, pair.outcome))
    return found


def decide(paths: Sequence[Any], pairs: Sequence[Any] = ()) -> Decision:
    """The decision from per-path ``name``, ``verdict`` (pass, waived, fail, marginal,
    rejected, excluded, error), ``undecided``, ``rank`` (None when not ranked), ``reasons`` (failing
    verdicts) and optionally ``waived`` (the rules waived on it: a waived chain may be sent,
    and the decision says it is waived); ``pairs`` the paired comparisons
    (:class:`~idefix_rules.campaign.statistics.pairwise.PairComparison`) of a paired campaign.

    >>> from types import SimpleNamespace as P
    >>> a = P(name="a", verdict="pass", undecided=False, rank=1, reasons=[])
    >>> b = P(name="b", verdict="pass", undecided=False, rank=2, reasons=[])
    >>> decide([a, b], [P(first="a", second="b", outcome="open", margin=0.0)]).text
    'send a or b (each passes every verdict; a ranks first, but in the same drawn worlds \
their risks are not told apart at this number of runs: run more to tell which is safer)'
    >>> w = P(name="w", verdict="waived", undecided=False, rank=1, reasons=[],
    ...       waived=("acceptable_risk",))
    >>> c = P(name="c", verdict="pass", undecided=False, rank=2, reasons=[])
    >>> decide([w, c]).text
    'send c (passes every verdict, rank 2 of 2); w ranks better but passes only under a \
waiver of acceptable_risk'
    >>> decide([w]).text
    'send w (waived: breaks acceptable_risk under a waiver, passes every other verdict, rank 1 \
of 1)'
    """
    ranked = [p for p in paths if getattr(p, "rank", None) is not None]
    total = len(ranked)
    passing = sorted((p for p in paths if p.verdict in ("pass", "waived") and not p.undecided),
                     key=_rank)
    # A chain that passes every verdict is sent before one that passes only under a waiver:
    # a waiver accepts a failure when it is needed, it is no reason to prefer the chain.
    clean = [p for p in passing if p.verdict == "pass"]
    ahead = [p for p in passing if clean and p.verdict == "waived"
             and _rank(p) < _rank(clean[0])]
    if clean:
        passing = clean
    if passing:
        best = passing[0]
        where = f"rank {best.rank} of {total}" if best.rank is not None else "not ranked"
        others = [p.name for p in paths if p.undecided and _rank(p) < _rank(best)]
        note = (f"; {', '.join(others)} ranks better but is not decided yet" if others else "")
        note += "".join(f"; {p.name} ranks better but passes only under a waiver of "
                        f"{', '.join(getattr(p, 'waived', ())) or 'a rule'}" for p in ahead)
        waived = tuple(getattr(best, "waived", ()))
        held = (f"waived: breaks {', '.join(waived)} under a waiver, passes every other "
                "verdict" if best.verdict == "waived" else "passes every verdict")
        rivals = _unsettled_with(best.name, passing[1:], pairs)
        if rivals:
            candidates = [best.name, *(name for name, _ in rivals)]
            margin = next((p.margin for p in pairs if p.outcome == TIED), 0.0)
            because: list[str] = []
            if any(kind == OPEN for _, kind in rivals):
                because.append(f"{best.name} ranks first, but in the same drawn worlds their risks "
                           "are not told apart at this number of runs: run more to tell which "
                           "is safer")
            if any(kind == TIED for _, kind in rivals):
                because.append(f"their risks are tied within ±{100 * margin:.3g} %, the "
                           "rulebook's indifference margin")
            under = [p for p in passing if p.name in candidates and p.verdict == "waived"]
            each = ("each passes every verdict" if not under else
                    "each passes every verdict not waived") + "".join(
                f"; {p.name} breaks {', '.join(getattr(p, 'waived', ()))} under a waiver"
                for p in under)
            return Decision("send", best.name,
                            f"send {' or '.join(candidates)} ({each}; {'; '.join(because)}){note}",
                            tuple(f"waived {rule}" for rule in waived), tuple(candidates))
        return Decision("send", best.name, f"send {best.name} ({held}, {where}){note}",
                        tuple(f"waived {rule}" for rule in waived), (best.name,))
    undecided = sorted((p for p in paths if p.undecided), key=_rank)
    if undecided:
        names = ", ".join(p.name for p in undecided)
        return Decision("unsettled", undecided[0].name,
                        f"not settled yet: the verdict of {names} is not decided at this "
                        "number of runs (run more to settle it)",
                        tuple(undecided[0].reasons))
    marginal = sorted((p for p in paths if p.verdict == "marginal"), key=_rank)
    if marginal:
        near = marginal[0]
        names = ", ".join(p.name for p in marginal)
        rules = "; ".join(near.reasons)
        return Decision("marginal", near.name,
                        f"no chain is shown to pass: {names} "
                        f"{'is' if len(marginal) == 1 else 'are'} within the rulebook's margin "
                        f"of a limit ({near.name}: {rules}); not sent: accepting such a chain "
                        "is a person's call", tuple(near.reasons))
    if not ranked:
        needs = [p.name for p in paths if any(r.endswith(NEEDS_RUN) for r in p.reasons)]
        failed = [p.name for p in paths if p.verdict not in ("rejected", "excluded")
                  and p.name not in needs]
        if not failed:
            return Decision("none", None, "no chain is acceptable (none was scored: every chain "
                            "was rejected or excluded before Monte Carlo" + (
                                ", or needs a run under this rulebook)" if needs else ")"))
        before = [p.name for p in paths if p.verdict in ("rejected", "excluded")]
        unscored = [f"{_named(failed)} left without a run to score (the reference run, or "
                    "every Monte Carlo run, failed)"]
        if before:
            unscored.append(f"{_named(before)} rejected or excluded before Monte Carlo")
        if needs:
            unscored.append(f"{_named(needs)} to be run under this rulebook")
        return Decision("none", None, "no chain is acceptable (none was scored: "
                        + "; ".join(unscored) + ")")
    least = sorted(ranked, key=_rank)[0]
    reasons = tuple(least.reasons)
    why = f": it fails {'; '.join(reasons)}" if reasons else ""
    return Decision("none", least.name,
                    f"no chain is acceptable; least bad is {least.name} (rank 1 of {total})"
                    f"{why}", reasons)


@dataclass(frozen=True)
class PathFacts:
    """What :func:`decide` reads of a path."""

    name: str
    verdict: str
    undecided: bool
    rank: int | None
    reasons: list[str]
    waived: tuple[str, ...] = ()  # rules waived on the path (its verdict is then "waived")


def reasons_of(path: PathResult) -> list[str]:
    """A path's failing (or undecided) verdict rules in words and percent, else its stored
    reasons (a rejected or excluded path says why in ``path.reason``)."""
    return [text for _, text in reason_items(path)]


def rule_name(reason: str) -> str:
    """The rule a reason of :func:`reasons_of` speaks of (the text before its first colon)."""
    return reason.split(":", 1)[0] if ":" in reason else reason


def near_rules(path: PathResult) -> set[str]:
    """The verdict rules of a path that lie within their margin of the limit."""
    return {rule.name for rule in getattr(path.verdict, "rules", ()) if rule.near}


def verdict_parts(path: PathResult) -> list[str]:
    """What follows a path's verdict in one line, by name: its risk, the rules it fails, those
    within their margin of the limit, those not decided yet (the console's verdict line, the
    JUnit message): ``['risk 86.0 %', 'fails acceptable_risk, runs_complete']``."""
    parts = [f"risk {100.0 * path.mean_risk:.1f} %"] if path.mean_risk is not None else []
    items = reason_items(path)
    near = near_rules(path)
    failed = [rule_name(text) for decided, text in items
              if decided and rule_name(text) not in near]
    within = [rule_name(text) for decided, text in items if rule_name(text) in near]
    open_ = [rule_name(text) for decided, text in items if not decided]
    if failed and path.verdict_text != "pass" and path.verdict is not None:
        parts.append("fails " + ", ".join(failed))
    if within:
        parts.append("within the margin: " + ", ".join(within))
    if open_:
        # left open on purpose (an adaptive campaign stopped it: nothing depends on it), not
        # waiting for more runs
        label = ("not decided (no decision depends on it)" if MOOT in path.stop_reason
                 else "not decided")
        parts.append(f"{label}: " + ", ".join(open_))
    return parts


def path_confidence(path: PathResult) -> float:
    """The family-wise confidence a path's bounds were judged at (the rulebook's)."""
    return float(getattr(path.statistics, "confidence", 0.95) or 0.95)


def campaign_confidence(paths: Sequence[PathResult]) -> float:
    """The family-wise confidence of a campaign's bounds (the rulebook's: the same for every
    path judged; 95 % when none was)."""
    return next((path_confidence(p) for p in paths if p.statistics is not None), 0.95)


def reason_items(path: PathResult) -> list[tuple[bool, str]]:
    """:func:`reasons_of` with whether each is decided (``False``: a rule not decided yet at
    this number of runs, which is not a failure)."""
    confidence = path_confidence(path)
    if path.verdict is not None:
        shown = verdict_reason_items(as_plain(path.verdict), confidence, path.runs_needed)
        extra = [(True, r) for r in path.verdict_reasons if r.endswith(" run(s) missing")]
        return shown + extra
    return [(True, r) for r in path.verdict_reasons]


SEARCH_DECISION = ("none from a worst-case search: its runs are the worlds the search chose, "
                   "not draws of the campaign's uncertainty, so its verdicts do not say which "
                   "chain to send; run the campaign for that (the search's findings: its "
                   "worst.json and report)")


def campaign_decision(evaluation: CampaignEvaluation) -> Decision:
    """The decision of an evaluated campaign; a worst-case search's runs decide nothing."""
    if is_search(evaluation.provenance):
        return Decision("unsettled", None, SEARCH_DECISION)
    return decide([PathFacts(p.name, p.verdict_text, p.undecided, p.rank,
                             reasons_of(p) or ([p.reason] if p.reason else []),
                             tuple(w.rule for w in p.waivers)) for p in evaluation.paths],
                  evaluation.pairs)


def verdict_counts(verdicts: Sequence[tuple[str, bool]], code: int) -> str:
    """CI's outcome without expectations, from each path's ``(verdict, held)`` (held: shown
    at this number of runs), as the console and the report both say it."""
    passed = sum(1 for verdict, held in verdicts if held and verdict == "pass")
    waived = sum(1 for verdict, held in verdicts if held and verdict == "waived")
    open_ = sum(1 for verdict, held in verdicts if verdict in ("pass", "waived") and not held)
    also = (f", {waived} waived" if waived else "") + \
        (f", {open_} passing but not decided" if open_ else "")
    return (f"CI verdicts (no expectations: every path must pass): {passed} of "
            f"{len(verdicts)} passed{also} (exit {code})")
