"""The decision names every chain that could be the best when paired comparisons leave the
lead open or tied, and one chain when they settle it."""

from __future__ import annotations

from types import SimpleNamespace as P

from idefix_rules.campaign.outcome.decision import decide


def path(name: str, rank: int, verdict: str = "pass", undecided: bool = False) -> P:
    return P(name=name, verdict=verdict, undecided=undecided, rank=rank, reasons=[])


def pair(first: str, second: str, outcome: str, margin: float = 0.0) -> P:
    return P(first=first, second=second, outcome=outcome, margin=margin)


def test_a_settled_lead_names_one_chain():
    decision = decide([path("a", 1), path("b", 2)], [pair("a", "b", "first safer")])
    assert decision.candidates == ("a",)
    assert decision.text == "send a (passes every verdict, rank 1 of 2)"


def test_an_open_lead_names_the_chains_that_could_be_best():
    decision = decide([path("a", 1), path("b", 2), path("c", 3)],
                      [pair("a", "b", "open"), pair("a", "c", "first safer")])
    assert decision.kind == "send" and decision.path == "a"
    assert decision.candidates == ("a", "b")
    assert decision.text.startswith("send a or b (each passes every verdict; a ranks first")


def test_a_tie_names_both_with_the_margin():
    decision = decide([path("a", 1), path("b", 1)], [pair("b", "a", "tied", 0.02)])
    assert decision.candidates == ("a", "b")
    assert "tied within ±2 %, the rulebook's indifference margin" in decision.text


def test_a_failing_chain_is_never_a_candidate():
    decision = decide([path("a", 1), path("b", 2, "fail")], [pair("a", "b", "open")])
    assert decision.candidates == ("a",)


def test_unpaired_campaigns_have_no_comparisons_and_name_one_chain():
    assert decide([path("a", 1), path("b", 2)]).candidates == ("a",)


def test_no_chain_scored_says_which_failed_and_which_were_rejected() -> None:
    # every Monte Carlo run of 'a' failed (no rank), 'b' was rejected by a command rule: the
    # decision named every chain rejected or excluded, which 'a' was not
    failed = P(name="a", verdict="fail", undecided=False, rank=None, reasons=[])
    rejected = P(name="b", verdict="rejected", undecided=False, rank=None, reasons=["x"])
    assert decide([failed, rejected]).text == (
        "no chain is acceptable (none was scored: a was left without a run to score (the "
        "reference run, or every Monte Carlo run, failed); b was rejected or excluded before "
        "Monte Carlo)")
    assert decide([rejected]).text == ("no chain is acceptable (none was scored: every chain "
                                       "was rejected or excluded before Monte Carlo)")
