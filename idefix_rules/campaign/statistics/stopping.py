"""When an adaptive campaign (``runs: auto``) stops a path.

At each look every ranked path's statistics carry the one-sided bounds its verdict is judged
on (:mod:`idefix_rules.campaign.statistics.bounds`, at the levels of the campaign's
:class:`~idefix_rules.campaign.statistics.budget.AlphaBudget`), and the rulebook's own verdict
logic runs on them. A path stops when

1. its verdict is decided as the decision reads it, with the campaign's waivers applied:
   every verdict rule passes, fails or lies within its margin of the limit, or one fails
   decidedly or lies within its margin (then the path does not pass, whatever the open rules
   say); a waived rule, open or failing, leaves nothing open, and
2. the comparisons the decision depends on are settled: a path that does not pass needs none
   (the order among chains that fail decides nothing); the chain that leads, of those that
   pass (or pass under a waiver) or may still, must be settled against each of them, and each
   of them against it — passing paths rank first, then those that pass only under a waiver
   (a verdict rule waived, or simulated under a waived command or prescreen rule; the
   decision sends one of them only when no chain passes), a marginal path counts as one that
   may still pass while the levels can rise (:func:`tiers`: some other chain can still be
   shown to fail), and within a group the first
   rank key's intervals do not overlap; in a paired campaign ranking first by risk, the
   confidence sequence of the two paths' per-world risk differences decides instead
   (:mod:`idefix_rules.campaign.statistics.pairwise`): one is safer, or they are tied within the
   rulebook's indifference margin (a tie is a decision too),

or when its verdict, still open (its waivers applied), decides nothing: the leading contender
passes decidedly, stops at this look or has stopped (its figures are final), and ranks above it
whatever its verdict turns out to be (so the chain to send is that one either way), no
``expect:`` entry names it, and the exit code does not wait for it (the campaign has
expectations, or another path is decidedly not passing, rejected or excluded, so it is 1
already); the path keeps its open verdict, with the runs that would decide it,

or when it reaches ``max_runs``. Because the bounds hold at every run count at once, looking
after every batch and stopping on what they say keeps their error rates; a fixed-count
interval re-checked after every batch would not.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

STOP_FIXED = "fixed run count"
# a path stopped with its verdict open because no decision depends on it (its stop reason)
MOOT = "verdict not decided, and no decision depends on it"


@dataclass(frozen=True)
class Settlement:
    """What one look says about a path."""

    verdict_decided: bool
    passed: bool
    unsettled_against: tuple[str, ...]  # paths whose order against this one is open
    contender: bool = True  # passes or may still pass: its rank may decide what to send
    outcome: str = ""  # pass, fail, marginal (within a margin of a limit), or "" when open
    # an open verdict no decision depends on: the chain that passes and ranks above it
    moot_under: str = ""

    @property
    def rank_settled(self) -> bool:
        return not self.unsettled_against

    @property
    def done(self) -> bool:
        return (self.verdict_decided or bool(self.moot_under)) and self.rank_settled


# --- the look ----------------------------------------------------------------------------------

_UNPAIRED = 2  # no paired comparison: the two intervals decide

# What a verdict may end as, best first, as the decision prefers them
# (campaign/outcome/decision.py): a chain that passes is sent before one that passes only
# under a waiver, and one that does not pass is never sent.
PASSES, PASSES_WAIVED, NOT_SENT = 0, 1, 2


def _rule_waived(verdict: Any, held: Any) -> bool:
    """Whether a verdict rule is waived: the waivers take their rules out of ``held``."""
    return len(getattr(held, "rules", ())) != len(getattr(verdict, "rules", ()))


def tiers(verdict: Any, held: Any, *, waived_before: bool = False,
          levels_final: bool = True) -> set[int]:
    """The tiers a path may still end in, from its verdict and its verdict with the
    campaign's waivers applied (``held``; the same verdict when nothing is waived).

    ``waived_before``: the path was simulated under a waived command or prescreen rule, so it
    is ``waived`` whatever its verdict (campaign/evaluation/path_result.py) and never ranks with
    the chains that pass clean. ``levels_final``: the levels cannot rise any more before the
    end (budget.py: as many chains shown to fail as there are comparisons, or no other chain
    can still be shown to fail, :func:`settle`); until then a verdict within a rule's margin
    may still pass at the final levels, whose bounds are narrower: clean, or under the
    waivers when only the verdict with them applied is within a margin.

    >>> from types import SimpleNamespace as V
    >>> marginal = V(passed=False, decided=True, marginal=True)
    >>> sorted(tiers(marginal, marginal)), sorted(tiers(marginal, marginal, levels_final=False))
    ([2], [0, 2])
    >>> failing = V(passed=False, decided=True, marginal=False, rules=("a", "b"))
    >>> within = V(passed=False, decided=True, marginal=True, rules=("b",))  # "a" waived
    >>> sorted(tiers(failing, within, levels_final=False)), sorted(tiers(failing, within))
    ([1, 2], [2])
    >>> clean = V(passed=True, decided=True, marginal=False)
    >>> sorted(tiers(clean, clean)), sorted(tiers(clean, clean, waived_before=True))
    ([0], [1])
    """
    found = set()
    if verdict.passed or not verdict.decided:
        found.add(PASSES)
    if not verdict.passed or not verdict.decided:
        if held.passed or not held.decided:
            found.add(PASSES_WAIVED)
        if not held.passed or not held.decided:
            found.add(NOT_SENT)
    if not levels_final:
        if getattr(verdict, "marginal", False) and not verdict.passed:
            found.add(PASSES)
        if _rule_waived(verdict, held) and getattr(held, "marginal", False) and not held.passed:
            found.add(PASSES_WAIVED)
    if waived_before and PASSES in found:
        found = (found - {PASSES}) | {PASSES_WAIVED}
    return found


def settled_outcome(verdict: Any, held: Any, *, waived_before: bool = False) -> str:
    """The outcome a stop reason names once the verdict with the campaign's waivers applied
    (``held``) is decided, as the evaluation reports it (``PathResult.verdict_text``):
    ``waived`` when it passes with a rule waived (or the path was simulated under a waived
    command or prescreen rule, ``waived_before``), else the outcome of ``held``
    (:func:`outcome_of`); "" while it is open (a waived rule's failure may still be joined by
    an open rule's).

    >>> from types import SimpleNamespace as V
    >>> open_ = V(decided=False, passed=True, rules=("a", "b"))
    >>> fails = V(decided=True, passed=False, marginal=False, rules=("a", "b"))
    >>> passes = V(decided=True, passed=True, rules=("b",))  # "a" waived
    >>> [settled_outcome(*pair) for pair in ((open_, passes), (fails, passes), (open_, open_))]
    ['waived', 'waived', '']
    >>> settled_outcome(fails, fails), settled_outcome(passes, passes, waived_before=True)
    ('fail', 'waived')
    """
    if not held.decided:
        return ""
    if held.passed:
        return "waived" if waived_before or _rule_waived(verdict, held) else "pass"
    return outcome_of(held)


def _order(first: tuple[set[int], tuple[float, float]],
           second: tuple[set[int], tuple[float, float]],
           paired: int | None = _UNPAIRED) -> int | None:
    """-1 when the first path ranks above the second whatever the open verdicts turn out to
    be, 1 when below, 0 when tied, None when it is not settled. Each path comes with the
    tiers it may end in (:func:`tiers`: a lower tier ranks above) and its first rank key's
    interval; ``paired`` is the paired comparison's order (-1, 1, 0 tied, None open) when
    there is one."""
    outcomes: set[int | None] = set()
    (tiers_a, (a_low, a_high)), (tiers_b, (b_low, b_high)) = first, second
    for tier_a in tiers_a:
        for tier_b in tiers_b:
            if tier_a != tier_b:
                outcomes.add(-1 if tier_a < tier_b else 1)
            elif paired != _UNPAIRED:
                outcomes.add(paired)
            elif a_high < b_low:
                outcomes.add(-1)
            elif b_high < a_low:
                outcomes.add(1)
            else:
                outcomes.add(None)
    return outcomes.pop() if len(outcomes) == 1 else None


def settle(evaluator: Any, stats_by_path: Mapping[str, Any],
           pairs: Sequence[Any] = (), *, watched: Collection[str] | None = None,
           waivers: Sequence[Any] = (), waived_before: Collection[str] = (),
           levels_final: bool = True, exit_failing: bool = False,
           running: Collection[str] | None = None) -> dict[str, Settlement]:
    """Each ranked path's settlement from its judged statistics and, in a paired campaign, the
    paired comparisons (:class:`~idefix_rules.campaign.statistics.pairwise.PairComparison`) that
    decide the first rank key. Only the comparisons the decision depends on are asked for: the
    leading contender (a path that passes or may pass, first in the ranking) against each
    other contender.

    ``watched``: the paths the campaign's ``expect:`` entries name, whose verdicts are always
    decided (or run to the cap); None when it has none: the exit code then reads every path's
    verdict, so an open verdict is moot only once another path is decidedly not passing
    (``waivers``, the campaign's, decide which failures count). ``waived_before``: the paths
    simulated under a waived command or prescreen rule; ``exit_failing``: a path the looks do
    not judge (rejected, excluded, its reference run failed for a reason of its own) makes the
    exit code 1 already; ``running``: the paths that may be simulated after this look (None:
    every path; none at the campaign's cap).

    ``levels_final``: the levels are at their floor (budget.py). Otherwise they rise only when
    a chain is shown to fail, and only a chain that goes on running can newly be (a stopped
    chain's runs are final; it can be shown to fail only after another one raised the levels;
    a running chain, even one passing decidedly now, may be, if a later run fails): for a
    path the levels are final when no other chain goes on after this look (:func:`tiers`).
    Which chains go on depends on which are contenders, so the paths are settled again with
    those that go on until that set holds (it only grows: at most one pass per path).

    A path's verdict is decided as the decision reads it: with the waivers applied. A waived
    rule that fails decidedly beside an open rule leaves open whether the chain may be sent;
    an open rule that is waived leaves nothing open (the chain is ``waived``, or passes clean
    if more runs decided the rule: its tiers, and so its rank, say whether that matters)."""
    from idefix_rules.campaign.input.waivers import waive_verdict
    from idefix_rules.campaign.statistics.budget import shown_to_fail
    from idefix_rules.rulebook.statistics import rank_key_intervals

    # what each pass reads and no pass changes: the verdicts, first rank keys and ranking
    verdicts = {}
    first_keys = {}
    for name, stats in stats_by_path.items():
        verdict = evaluator.verdict(stats)
        verdicts[name] = (verdict, waive_verdict(verdict, waivers, name)[0])
        keys = rank_key_intervals(evaluator.rulebook, evaluator.checked.constants, stats)
        first_keys[name] = keys[0] if keys else (math.nan, math.nan)
    ranked = list(evaluator.rank(stats_by_path))
    simulated = set(stats_by_path) if running is None else set(running)
    going_on: set[str] = set()
    while True:
        found = _settle_once(ranked, first_keys, pairs, verdicts, going_on, watched,
                             waived_before, levels_final, exit_failing)
        more = going_on | {name for name in simulated & set(found)
                           if not found[name].done and not shown_to_fail(verdicts[name][1])}
        if more == going_on:
            return found
        going_on = more


def _settle_once(ranked: Sequence[str], first_keys: Mapping[str, tuple[float, float]],
                 pairs: Sequence[Any], verdicts: Mapping[str, tuple[Any, Any]],
                 going_on: set[str],
                 watched: Collection[str] | None, waived_before: Collection[str],
                 levels_final: bool, exit_failing: bool) -> dict[str, Settlement]:
    """:func:`settle` with ``going_on`` the chains that go on after this look (``ranked``:
    the rulebook's ranking, best first)."""
    from idefix_rules.campaign.statistics.pairwise import find

    def paired_order(name: str, other: str) -> int | None:
        pair = find(pairs, name, other)
        if pair is None:
            return _UNPAIRED
        order = pair.order()
        return order if order is None or pair.first == name else -order

    facts = {}
    outcomes = {}
    final = {}
    held_open = set()  # open with its waivers applied too (a waived open rule is held)
    for name, (verdict, held) in verdicts.items():
        final[name] = levels_final or not going_on - {name}
        if not held.decided:
            held_open.add(name)
        outcomes[name] = settled_outcome(verdict, held, waived_before=name in waived_before)
        groups = tiers(verdict, held, waived_before=name in waived_before,
                       levels_final=final[name])
        facts[name] = (bool(held.decided), bool(verdict.passed), groups, first_keys[name])
    ranking = contenders(ranked, facts)
    leader = ranking[0] if ranking else None

    def order(name: str, other: str) -> int | None:
        (_, _, groups, key), (_, _, other_groups, other_key) = facts[name], facts[other]
        return _order((groups, key), (other_groups, other_key), paired_order(name, other))

    leader_open = tuple(other for other in ranking[1:]
                        if order(leader, other) is None) if leader is not None else ()
    open_against: dict[str, tuple[str, ...]] = {}
    for name in facts:
        if name not in ranking:
            open_against[name] = ()
        elif name == leader:
            open_against[name] = leader_open
        else:
            assert leader is not None
            open_against[name] = (leader,) if order(name, leader) is None else ()
    # decidedly not passing, waivers applied: the exit code is 1 (a marginal verdict once it
    # cannot pass any more: the levels are final for it)
    not_held = {name for name, (_, held) in verdicts.items()
                if held.decided and not held.passed and (final[name] or not held.marginal)}

    def moot(name: str) -> bool:
        """Whether the open verdict of ``name``, a contender behind the leader, decides
        nothing: the leader passes decidedly, stops now (or has stopped: its figures are final,
        so its pass and its lead cannot change after ``name`` stops) and ranks above ``name``
        either way, and neither an expectation nor the exit code reads ``name``."""
        assert leader is not None
        # the leader is sent (it passes, or passes under a waiver) whatever more runs say
        leader_sent = len(facts[leader][2]) == 1 and facts[leader][2] < {PASSES, PASSES_WAIVED}
        if not leader_sent or leader_open \
                or order(leader, name) != -1 or name not in held_open:
            return False
        if watched is not None:
            return name not in watched
        return bool(not_held) or exit_failing  # never ``name`` itself: its verdict is open

    settlements = {}
    for name, (decided, passed, _, _) in facts.items():
        moot_under = ""
        if name in ranking and name != leader and not decided and moot(name):
            moot_under = str(leader)
        settlements[name] = Settlement(decided, passed, open_against[name], name in ranking,
                                       outcomes[name], moot_under)
    return settlements


def expected_paths(expectations: Sequence[Any]) -> frozenset[str]:
    """The paths ``expect:`` entries name (``path:`` or ``rank_first:``)."""
    return frozenset(name for e in expectations
                     for name in (getattr(e, "path", None), getattr(e, "rank_first", None))
                     if name)


def contenders(ranked: Sequence[str],
               facts: Mapping[str, tuple[bool, bool, set[int], Any]]) -> list[str]:
    """The paths that pass (or pass under a waiver) or may still, in the rulebook's ranking
    (best first), a path that can pass clean before one that can only pass waived (the
    rulebook's ranking does not know a waived command or prescreen rule)."""
    return sorted((name for name in ranked if facts[name][2] & {PASSES, PASSES_WAIVED}),
                  key=lambda name: min(facts[name][2]))


def outcome_of(verdict: Any) -> str:
    """pass, fail, marginal (within a margin of a limit), or "" when not decided."""
    return ("" if not verdict.decided else "pass" if verdict.passed
            else "marginal" if verdict.marginal else "fail")


def restated(reason: str, outcome: str) -> str:
    """A stop reason with the final verdict added when it says otherwise: a path stopped at
    one look is judged again at the campaign's final levels, which the chains shown to fail
    after it stopped may have raised (statistics/budget.py), so a verdict open or marginal
    then can be decided at the end. ``outcome``: pass, fail, marginal, or "" (open).

    >>> restated("cap of 96 runs reached: verdict not decided", "fail")
    'cap of 96 runs reached: verdict not decided; verdict fail at the final levels'
    >>> restated("decided after 64 runs: verdict fail (no decision depends on its rank)", "fail")
    'decided after 64 runs: verdict fail (no decision depends on its rank)'
    """
    said = "" if "verdict not decided" in reason else next(
        (word for word in ("pass", "fail", "marginal", "waived") if f"verdict {word}" in reason),
        None)
    if said is None or said == outcome:
        return reason
    return f"{reason}; verdict {outcome or 'not decided'} at the final levels"


def stop_reason(settlement: Settlement, runs: int, cap: int) -> str | None:
    """Why a path stops after ``runs`` runs, or None when it goes on."""
    if settlement.done and not settlement.verdict_decided:
        return (f"stopped after {runs} runs: {MOOT} ({settlement.moot_under} passes and ranks "
                "above it whatever its verdict)")
    if settlement.done:
        outcome = settlement.outcome or ("pass" if settlement.passed else "fail")
        if not settlement.contender:
            return (f"decided after {runs} runs: verdict {outcome} (no decision depends on its "
                    "rank)")
        return (f"decided after {runs} runs: verdict {outcome} and rank settled against every "
                "path the decision compares it with")
    if runs < cap:
        return None
    missing = []
    if not settlement.verdict_decided:
        missing.append("verdict not decided")
    if settlement.unsettled_against:
        missing.append("rank against " + ", ".join(settlement.unsettled_against)
                       + " not settled")
    return f"cap of {cap} runs reached: " + "; ".join(missing)
