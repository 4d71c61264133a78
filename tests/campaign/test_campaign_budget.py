"""The α budget over verdicts and the comparisons the decision depends on, the judged bounds,
what an adaptive campaign waits for, and how a marginal chain is reported."""

from __future__ import annotations

import dataclasses
import doctest
import importlib
import math
from types import SimpleNamespace as P

import numpy as np
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st
from rich.console import Console

from idefix_rules.campaign.evaluation.path_result import CampaignEvaluation, PathResult
from idefix_rules.campaign.evaluation.scoring import decision_pairs, judge_paths
from idefix_rules.campaign.input.schema import Waiver
from idefix_rules.campaign.outcome.decision import decide
from idefix_rules.campaign.outcome.junit import junit_xml
from idefix_rules.campaign.outcome.outputs import exit_code
from idefix_rules.campaign.statistics import pairwise
from idefix_rules.campaign.statistics.bounds import judged_statistics
from idefix_rules.campaign.statistics.budget import alpha_budget
from idefix_rules.campaign.statistics.sequential import one_sided_bound
from idefix_rules.campaign.statistics.stopping import expected_paths, settle, stop_reason
from idefix_rules.cli.outcome import print_answer
from idefix_rules.rulebook.check import check
from idefix_rules.rulebook.compile import compile_rulebook
from idefix_rules.rulebook.parser import parse_rulebook
from idefix_rules.rulebook.results import Estimate, PathStatistics, RunEvaluation

RULES = """rulebook "t" version "1.0.0"
purpose "test"
index I_a { value = max over time (abs(pitch)) limit = 1 rad weight = 1 }
chance stuck_run = any over time (pitch > 1 rad)
verdict acceptable: require risk <= 70 %
verdict rarely_stuck: require chance(stuck_run) <= 5 % indifference 2 %
verdict none_failed: require failed <= 0 %
"""


def evaluator(extra: str = ""):
    result = check(parse_rulebook(RULES + extra, "t.rules"))
    assert result.checked is not None, result.diagnostics
    return compile_rulebook(result.checked)


def runs(risk: np.ndarray, stuck: np.ndarray) -> RunEvaluation:
    n = risk.size
    return RunEvaluation(
        index_names=("I_a",), values={"I_a": risk}, raw={"I_a": risk},
        per_sample={"I_a": np.zeros((n, 0))}, weighted={"I_a": risk}, i_max=risk,
        dominant=np.zeros(n, dtype=int), dominant_sample=np.zeros(n, dtype=int),
        chance_names=("stuck_run",), chances={"stuck_run": stuck},
        time=np.full(n, 100.0), energy=np.full(n, 1.0))


def test_alpha_is_spent_over_paths_and_the_comparisons_the_decision_depends_on():
    rules = evaluator()
    paired = alpha_budget(rules, paths=4, paired=True)
    assert (paired.paths, paired.comparisons) == (4, 3)
    assert paired.pass_alpha == pytest.approx(0.05 / 7)
    # two verdicts judge a statistic on bounds; `failed <= 0 %` reads the runs themselves
    assert paired.judging.units == 2
    assert paired.fail_alpha == pytest.approx(0.05 / 7 / 2)
    assert paired.levels("risk") == (paired.fail_alpha, paired.pass_alpha)
    assert alpha_budget(rules, paths=4, paired=False).comparisons == 4
    assert alpha_budget(rules, paths=1, paired=True).per_path == pytest.approx(0.05)


def test_a_chain_shown_to_fail_gives_its_comparison_share_back():
    rules = evaluator()
    paired = alpha_budget(rules, paths=4, paired=True)  # 4 verdicts + 3 comparisons
    assert paired.recycle(["a"]).pass_alpha == pytest.approx(0.05 / 6)
    assert paired.recycle(["a", "b"]).recycle(["a"]).pass_alpha == pytest.approx(0.05 / 5)
    # never below one share per verdict: four failing chains leave four verdicts
    assert paired.recycle("abc").pass_alpha == pytest.approx(0.05 / 4)
    assert paired.recycle("abcd").pass_alpha == pytest.approx(0.05 / 4)
    assert paired.recycle("abc").fail_alpha == pytest.approx(0.05 / 4 / 2)
    unpaired = alpha_budget(rules, paths=3, paired=False)  # 3 verdicts + 3 own intervals
    assert [unpaired.recycle("abc"[:k]).comparison_alpha for k in range(4)] == \
        pytest.approx([0.05 / 6, 0.05 / 5, 0.05 / 4, 0.05 / 3])
    raised = paired.recycle(["b", "a"])
    assert raised.shown_failing == ("a", "b")
    # the bets stay tuned for the first levels, whatever is shown later
    assert raised.tuned_levels("risk") == paired.levels("risk")
    assert raised.comparison_tuned == paired.comparison_alpha
    assert raised.to_dict()["shown_failing"] == ["a", "b"]
    assert raised.to_dict()["first_pass_alpha"] == pytest.approx(0.05 / 7)
    rng = np.random.default_rng(4)
    evaluation = runs(rng.beta(3, 7, 300), rng.random(300) < 0.02)
    stats = judged_statistics(evaluation, rules.path_statistics(evaluation), 0.0, raised,
                              sequential=True)
    risk = evaluation.i_max
    assert stats.risk.high == one_sided_bound(risk, raised.pass_alpha, "upper",
                                              bet_alpha=paired.pass_alpha)
    assert stats.risk.high != one_sided_bound(risk, raised.pass_alpha, "upper")
    assert stats.risk.high < one_sided_bound(risk, paired.pass_alpha, "upper")


def test_the_paths_are_judged_at_the_levels_their_failures_raise():
    """judge_paths: a path shown to fail raises the others' levels; a waived failure, which
    a campaign may send, does not; the fixed point is reached whatever the path order."""
    rules = evaluator()
    rng = np.random.default_rng(5)
    inputs = {}
    for name, mean in (("ok", 0.3), ("bad", 0.9), ("worse", 0.95)):
        evaluation = runs(np.clip(mean + 0.05 * rng.uniform(-1, 1, 200), 0, 1),
                          np.zeros(200, dtype=bool))
        result = PathResult(name=name, index=0, status="simulated", runs=200, completed=200)
        inputs[name] = (evaluation, result, np.arange(200), 0.0)
    first = alpha_budget(rules, paths=3, paired=True)
    budget, judged = judge_paths(rules, inputs, first, True)
    assert budget.shown_failing == ("bad", "worse")
    assert budget.pass_alpha == pytest.approx(0.05 / 3)
    ok = judged["ok"][0]
    assert ok.risk.high == one_sided_bound(inputs["ok"][0].i_max, 0.05 / 3, "upper",
                                           bet_alpha=0.05 / 5)
    backwards = dict(reversed(list(inputs.items())))
    assert judge_paths(rules, backwards, first, True)[0] == budget
    waived = [Waiver(rule="acceptable", path="bad", **WAIVER)]
    budget, _ = judge_paths(rules, inputs, first, True, waived)
    assert budget.shown_failing == ("worse",)
    assert budget.pass_alpha == pytest.approx(0.05 / 4)


@settings(max_examples=60, deadline=None)
@given(mean=st.floats(0.05, 0.95), spread=st.floats(0.0, 0.3), count=st.integers(2, 300),
       shown=st.integers(1, 3), sequential=st.booleans(), seed=st.integers(0, 2**16))
def test_raised_levels_give_bounds_inside_the_first_ones(mean: float, spread: float,
                                                         count: int, shown: int,
                                                         sequential: bool, seed: int):
    """A chain judged again at a raised level gets bounds inside its first ones (the proof in
    statistics/budget.py rests on it): the bets stay, only the threshold moves."""
    rules = evaluator()
    first = alpha_budget(rules, paths=4, paired=True)
    raised = first.recycle("abc"[:shown])
    rng = np.random.default_rng(seed)
    risk = np.clip(mean + spread * rng.uniform(-1, 1, count), 0, 1)
    evaluation = dataclasses.replace(runs(risk, rng.random(risk.size) < mean / 4),
                                     energy=1.0 + 3.0 * risk)
    stats = rules.path_statistics(evaluation)
    before = judged_statistics(evaluation, stats, 0.0, first, sequential)
    after = judged_statistics(evaluation, stats, 0.0, raised, sequential)
    pairs = [(before.risk, after.risk), (before.energy, after.energy),
             (before.chances["stuck_run"], after.chances["stuck_run"]),
             (before.index_mean["I_a"], after.index_mean["I_a"])]
    for wide, narrow in pairs:
        assert wide.low <= narrow.low <= narrow.high <= wide.high or \
            (math.isinf(wide.low) and math.isinf(narrow.low))
    event(f"risk bounds moved: {after.risk.high < before.risk.high}")


def test_each_statistic_gets_its_bounds_in_the_direction_it_is_judged():
    rules = evaluator()
    budget = alpha_budget(rules, paths=3, paired=True)
    rng = np.random.default_rng(2)
    evaluation = runs(rng.beta(3, 7, 400), rng.random(400) < 0.02)
    failures = np.zeros(401)
    failures[-1] = 1.0
    stats = judged_statistics(evaluation, rules.path_statistics(evaluation, 1), 0.0, budget,
                              sequential=True, failures=failures)
    # `risk <= 70 %`: the lower bound decides a failure (β / U), the upper one a pass (β)
    assert stats.risk.low == one_sided_bound(evaluation.i_max, budget.fail_alpha, "lower")
    assert stats.risk.high == one_sided_bound(evaluation.i_max, budget.pass_alpha, "upper")
    assert stats.failed is not None and stats.failed.low < 1 / 401 < stats.failed.high
    fixed = judged_statistics(evaluation, rules.path_statistics(evaluation), 0.0, budget,
                              sequential=False)
    assert fixed.chances["stuck_run"].high < stats.chances["stuck_run"].high


def statistics(risk: float, stuck: float = 0.0, spread: float = 0.01) -> PathStatistics:
    return PathStatistics(
        runs=400, failed_runs=0, confidence=0.95, risk=Estimate(risk, risk - spread,
                                                                risk + spread),
        risk_std=0.1, index_mean={}, index_max={}, chances={
            "stuck_run": Estimate(stuck, max(0.0, stuck - spread), stuck + spread)},
        time=Estimate(100.0, 99.0, 101.0), energy=Estimate(1.0, 0.9, 1.1),
        dominant_counts={}, failed=Estimate(0.0, 0.0, 0.01))


def pair(first: str, second: str, outcome: str) -> P:
    return P(first=first, second=second, outcome=outcome,
             order=lambda: {"first safer": -1, "second safer": 1, "tied": 0}.get(outcome))


def test_only_the_leading_contender_against_the_others_is_waited_for():
    rules = evaluator()
    stats = {"a": statistics(0.3), "b": statistics(0.4), "c": statistics(0.45),
             "f": statistics(0.9), "g": statistics(0.92)}
    open_among_the_rest = [pair("a", "b", "first safer"), pair("a", "c", "first safer"),
                           pair("b", "c", "open"), pair("f", "g", "open"),
                           pair("a", "f", "open")]
    found = settle(rules, stats, open_among_the_rest)
    assert all(s.done for s in found.values())
    assert not found["f"].contender and found["f"].outcome == "fail"
    lead_open = [pair("a", "b", "open"), pair("a", "c", "first safer"),
                 pair("b", "c", "first safer")]
    found = settle(rules, stats, lead_open)
    assert found["a"].unsettled_against == ("b",) and found["b"].unsettled_against == ("a",)
    assert found["c"].done and found["f"].done


WAIVER = dict(reason="known", approved_by="ops", until="2099-01-01")


@pytest.mark.parametrize(("leader_spread", "moot"), [(0.0099, True), (0.0101, False)])
def test_an_open_verdict_behind_a_chain_that_passes_and_leads_decides_nothing(
        leader_spread: float, moot: bool):
    rules = evaluator()
    # a's risk bounds end just below / just above the 70 % limit: decided pass, or open
    stats = {"a": statistics(0.69, spread=leader_spread), "x": statistics(0.70, spread=0.05),
             "f": statistics(0.9)}
    pairs = [pair("a", "x", "first safer"), pair("a", "f", "first safer"),
             pair("x", "f", "first safer")]
    found = settle(rules, stats, pairs)
    assert not found["x"].verdict_decided and found["x"].contender
    assert found["x"].done is moot and found["x"].moot_under == ("a" if moot else "")
    reason = stop_reason(found["x"], 96, 1000)
    if moot:
        assert reason == ("stopped after 96 runs: verdict not decided, and no decision depends "
                          "on it (a passes and ranks above it whatever its verdict)")
    else:
        assert reason is None
        # with a's verdict open too, which of them ranks first is open as well
        assert stop_reason(found["x"], 1000, 1000) == \
            "cap of 1000 runs reached: verdict not decided; rank against a not settled"


def test_chains_that_pass_only_under_waivers_are_compared_when_no_chain_passes():
    """The decision sends a chain that passes only under a waiver when no chain passes
    (campaign/outcome/decision.py): their order is then what it rests on, so a look waits
    for it; with a chain that passes, it does not."""
    rules = evaluator()
    both = [Waiver(rule="acceptable", path=name, **WAIVER) for name in ("w", "v")]
    stats = {"w": statistics(0.8), "v": statistics(0.85), "f": statistics(0.9)}
    found = settle(rules, stats, [pair("w", "v", "open"), pair("w", "f", "first safer"),
                                  pair("v", "f", "first safer")], waivers=both)
    assert found["w"].contender and found["v"].contender and not found["f"].contender
    assert found["w"].unsettled_against == ("v",) and found["v"].unsettled_against == ("w",)
    assert not found["w"].done and not found["v"].done
    settled = settle(rules, stats, [pair("w", "v", "first safer"),
                                    pair("w", "f", "first safer")], waivers=both)
    assert settled["w"].done and settled["v"].done
    # a chain that passes is sent first whatever the risks: the waived ones decide nothing
    stats["a"] = statistics(0.3)
    found = settle(rules, stats, [pair("w", "v", "open")], waivers=both)
    assert found["a"].done and found["w"].done and found["v"].done


def test_an_open_verdict_is_not_moot_when_the_decision_or_the_exit_code_reads_it():
    rules = evaluator()
    lead, open_, failing = statistics(0.3), statistics(0.70, spread=0.05), statistics(0.9)
    ahead = [pair("a", "x", "first safer"), pair("a", "f", "first safer")]

    def moot(stats, pairs=ahead, **given) -> bool:
        return settle(rules, stats, pairs, **given)["x"].moot_under == "a"

    assert moot({"a": lead, "x": open_, "f": failing})
    # without a failing path, x's verdict decides the exit code (every path must pass)
    assert not moot({"a": lead, "x": open_})
    # unless a path the looks do not judge (rejected, excluded) makes it 1 already
    assert moot({"a": lead, "x": open_}, exit_failing=True)
    # an expectation naming x asks for its verdict; one naming only others does not
    assert not moot({"a": lead, "x": open_, "f": failing}, watched={"x"})
    assert moot({"a": lead, "x": open_}, watched={"a"})
    # f fails only a waived rule: it counts as held, so the exit code waits for x
    waived = [Waiver(rule="acceptable", path="f", **WAIVER)]
    assert not moot({"a": lead, "x": open_, "f": failing}, waivers=waived)
    # x's open rule waived on x: held, so x's verdict is not open (it runs as before)
    assert not moot({"a": lead, "x": open_, "f": failing},
                    waivers=[Waiver(rule="acceptable", path="x", **WAIVER)])
    # the leader still runs, its order against b open: its pass could yet be lost (a failed
    # run), and x would be needed then
    b = statistics(0.35)
    assert not moot({"a": lead, "b": b, "x": open_, "f": failing},
                    [*ahead, pair("a", "b", "open")])
    assert moot({"a": lead, "b": b, "x": open_, "f": failing},
                [*ahead, pair("a", "b", "first safer")])
    # the order against the leader open, or tied: x may be sent with (or instead of) a
    for outcome in ("open", "tied", "second safer"):
        assert not moot({"a": lead, "x": open_, "f": failing},
                        [pair("a", "x", outcome), pair("a", "f", "first safer")])
    assert expected_paths([P(path="x", verdict="pass"), P(rank_first="a")]) == {"x", "a"}


def test_a_marginal_chain_is_not_sent_not_passed_and_said_so():
    rules = evaluator()
    near = statistics(0.3, stuck=0.05, spread=0.01)  # 4–6 %, within 5 % ± 2 %
    verdict = rules.verdict(near)
    assert verdict.marginal and verdict.decided and not verdict.passed
    result = PathResult("near", 0, "simulated", runs=400, completed=400, rank=1)
    result.verdict, result.passed, result.statistics = verdict, False, near
    assert result.verdict_text == "marginal"
    decision = decide([P(name="near", verdict="marginal", undecided=False, rank=1,
                         reasons=["rarely_stuck: within the margin"])])
    assert decision.kind == "marginal" and decision.path == "near"
    assert decision.text.startswith("no chain is shown to pass: near is within the rulebook's "
                                    "margin of a limit")
    evaluation = CampaignEvaluation([result], ["near"], {}, {})
    assert exit_code(evaluation, [], has_expectations=False) == 1
    assert 'type="marginal"' in junit_xml(evaluation, [], "c")
    console = Console(width=150, record=True)
    print_answer(console, evaluation, [], 1)
    text = console.export_text()
    assert "within the margin: rarely_stuck" in text and "Decision: no chain is shown" in text


def test_an_open_comparison_says_how_many_paired_runs_would_settle_it():
    rows = np.arange(200)
    rng = np.random.default_rng(5)
    world = rng.uniform(0, 0.5, 200)
    first = (rows, world + rng.normal(0.0, 0.05, 200))
    second = (rows, world + 0.01 + rng.normal(0.0, 0.05, 200))
    [found] = pairwise.compare_pairs({"a": first, "b": second}, ["a", "b"], 0.01, 0.0)
    assert found.outcome == pairwise.OPEN
    results = [PathResult(name, 0, "simulated", passed=True) for name in ("a", "b")]
    budget = dataclasses.replace(alpha_budget(evaluator(), 2, True), alpha=0.03)
    [marked] = decision_pairs({"a": first, "b": second}, ["a", "b"], results, budget, 0.0,
                              sequential=True)
    assert marked.needed and marked.outcome == pairwise.OPEN
    assert marked.runs_needed is not None and marked.runs_needed > 200
    evaluation = CampaignEvaluation(results, ["a", "b"], {}, {}, paired=True, pairs=[marked])
    console = Console(width=200, record=True)
    print_answer(console, evaluation, [], 0)
    text = console.export_text()
    assert "open: a vs b after 200 paired runs (risk difference " in text
    assert f"about {marked.runs_needed:,} paired runs would settle it at the present spread" \
        in text
    assert marked.to_dict()["runs_needed"] == marked.runs_needed


@pytest.mark.parametrize("name", ["budget", "stopping", "pairwise", "bernoulli", "sequential",
                                  "runs_needed", "bounds"])
def test_the_examples_in_the_statistics_modules_hold(name: str):
    """The docstrings' examples (the budget's levels, a stop reason restated at the final
    levels, a pair in words, …) are run, so they cannot drift from the code."""
    module = importlib.import_module(f"idefix_rules.campaign.statistics.{name}")
    failures, tried = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert tried > 0 and failures == 0


def test_a_waived_failure_beside_an_open_rule_leaves_the_verdict_open():
    """b fails `acceptable` decidedly, which is waived on b, and `rarely_stuck` is open: the
    chain may or may not be sent, so its verdict is not decided. Alone it runs on; behind a
    chain that passes, it stops only where an open verdict may (moot)."""
    rules = evaluator()
    b = statistics(0.9, stuck=0.05, spread=0.04)  # stuck 1–9 %: beyond the 2 % margin
    waived = [Waiver(rule="acceptable", path="b", **WAIVER)]
    alone = settle(rules, {"b": b, "f": statistics(0.95)}, waivers=waived)["b"]
    assert alone.contender and not alone.verdict_decided and not alone.done
    assert alone.outcome == ""  # the rulebook's fail is not what the look names
    assert stop_reason(alone, 1000, 1000) == "cap of 1000 runs reached: verdict not decided"
    assert settle(rules, {"b": b, "f": statistics(0.95)})["b"].done  # unwaived: it fails
    lead = {"a": statistics(0.3), "b": b}
    # a passes and ranks above b whatever b ends as; without a failing chain the exit code
    # reads b, and an expectation naming b asks for its verdict
    assert not settle(rules, lead, waivers=waived)["b"].done
    assert not settle(rules, lead, waivers=waived, watched={"b"})["b"].done
    found = settle(rules, lead, waivers=waived, watched={"a"})["b"]
    assert found.done and found.moot_under == "a"


def test_a_chain_simulated_under_a_waived_command_rule_ranks_below_the_clean_ones():
    """a leads by risk but was simulated under a waived command rule (`waived` whatever its
    verdict): the decision sends b or c, so their order is what the looks wait for."""
    rules = evaluator()
    stats = {"a": statistics(0.10), "b": statistics(0.30), "c": statistics(0.305)}
    pairs = [pair("a", "b", "first safer"), pair("a", "c", "first safer"),
             pair("b", "c", "open")]
    blind = settle(rules, stats, pairs)
    assert all(s.done for s in blind.values())  # as if a were sent
    found = settle(rules, stats, pairs, waived_before={"a"})
    assert found["b"].unsettled_against == ("c",) and found["c"].unsettled_against == ("b",)
    assert found["a"].done and not found["b"].done and not found["c"].done


@pytest.mark.parametrize(("open_other", "levels_final", "waits"),
                         [(True, False, True), (False, False, False), (True, True, False)])
def test_a_marginal_chain_that_may_pass_at_the_final_levels_is_compared(
        open_other: bool, levels_final: bool, waits: bool):
    """m's stuck chance lies within the rule's margin (3.55–5.05 % against 5 % ± 2 %): at
    this look marginal, never sent. While the levels can still rise (not at their floor, and
    another chain, o, goes on with its verdict open: an expectation names it, so it is never
    stopped as moot; its failure would raise the levels) the final, narrower bounds may clear
    the limit and m pass, ranking above `lead` on risk: the look waits for their order. When
    nothing else goes on (lead passes decidedly and stops), the levels m is judged at are
    final already: m stops, never sent."""
    rules = evaluator()
    m = statistics(0.20, stuck=0.043, spread=0.0075)
    assert rules.verdict(m).marginal
    stats = {"lead": statistics(0.25, spread=0.03), "m": m}
    pairs = [pair("lead", "m", "open")]
    if open_other:
        stats["o"] = statistics(0.70, spread=0.05)
        assert not rules.verdict(stats["o"]).decided
        pairs += [pair("lead", "o", "first safer"), pair("m", "o", "first safer")]
    watched = {"o"} if open_other else None
    found = settle(rules, stats, pairs, levels_final=levels_final, watched=watched)
    assert found["m"].verdict_decided and found["m"].outcome == "marginal"
    assert found["m"].contender is waits
    assert found["lead"].unsettled_against == (("m",) if waits else ())
    assert found["m"].done is not waits
    # settled against the leader, a marginal chain stops whatever its final verdict
    pairs[0] = pair("lead", "m", "first safer")
    ahead = settle(rules, stats, pairs, levels_final=False, watched=watched)
    assert ahead["m"].done and ahead["lead"].done
    if open_other and not levels_final:  # unwatched, o stops as moot: nothing goes on
        assert settle(rules, stats, [*pairs[1:], pair("lead", "m", "open")],
                      levels_final=False)["o"].moot_under == "lead"


def test_failed_runs_are_the_rulebook_s_to_judge_and_a_missing_run_fails_the_path():
    """A rulebook that tolerates failed runs (`failed <= 20 %`) passes a path with one; a run
    neither complete nor failed (missing from the results) fails it."""
    from idefix_rules.campaign.evaluation.fill_result import fill_result

    tolerant = check(parse_rulebook(
        'rulebook "t" version "1.0.0"\npurpose "test"\n'
        "index I_a { value = max over time (abs(pitch)) limit = 1 rad weight = 1 }\n"
        "verdict acceptable: require risk <= 70 % and failed <= 20 %\n", "t.rules"))
    assert tolerant.checked is not None
    book = compile_rulebook(tolerant.checked)
    evaluation = runs(np.full(99, 0.3), np.zeros(99, dtype=bool))
    stats = book.path_statistics(evaluation, failed_runs=1)
    verdict = book.verdict(stats)
    assert verdict.passed and verdict.decided
    one_failed = PathResult(name="a", index=0, status="simulated", runs=100, completed=99,
                            failures={5: "solver diverged"})
    fill_result(one_failed, evaluation, stats, verdict)
    assert one_failed.passed and one_failed.verdict_text == "pass"
    missing = PathResult(name="a", index=0, status="simulated", runs=100, completed=99)
    fill_result(missing, evaluation, stats, verdict)
    assert not missing.passed and missing.verdict_reasons[-1] == "1 of 100 run(s) missing"


def test_an_open_rule_that_is_waived_leaves_the_verdict_decided():
    """x's stuck chance (1–9 %) is open against its 5 % limit, and the campaign waives that
    rule on x: the decision reads x as `waived` (it passes under the waiver) whatever more
    runs say, so the look stops it as decided, ranked below the clean leader, instead of
    running it to the cap with an open verdict."""
    rules = evaluator()
    x = statistics(0.50, stuck=0.05, spread=0.04)
    assert not rules.verdict(x).decided
    stats = {"a": statistics(0.30), "x": x, "f": statistics(0.95)}
    pairs = [pair("a", "x", "first safer"), pair("a", "f", "first safer"),
             pair("x", "f", "first safer")]
    waived = [Waiver(rule="rarely_stuck", path="x", **WAIVER)]
    found = settle(rules, stats, pairs, waivers=waived)
    assert found["x"].done and found["x"].verdict_decided and found["x"].outcome == "waived"
    assert stop_reason(found["x"], 64, 1000) == (
        "decided after 64 runs: verdict waived and rank settled against every path the "
        "decision compares it with")
    # its rank against the clean leader matters (x may still pass clean): open, it waits
    unsettled = settle(rules, stats, [pair("a", "x", "open"), *pairs[1:]], waivers=waived)
    assert not unsettled["x"].done and unsettled["x"].unsettled_against == ("a",)
    # without the waiver the same open verdict is moot behind the leader (f fails: exit 1)
    assert settle(rules, stats, pairs)["x"].moot_under == "a"


def test_a_marginal_verdict_under_a_waiver_may_still_pass_waived():
    """w fails `acceptable` decidedly (waived) and is marginal on `rarely_stuck`: while the
    levels can rise (lead and q, both passing, go on: their order is open, and a later failed
    run could still show one to fail) w may end passing under its waiver, a contender (ranked
    below the clean leader whatever happens, so it stops); once nothing goes on, never sent."""
    rules = evaluator()
    w = statistics(0.90, stuck=0.043, spread=0.0075)
    stats = {"lead": statistics(0.25, spread=0.03), "q": statistics(0.27, spread=0.03), "w": w}
    pairs = [pair("lead", "w", "first safer"), pair("q", "w", "first safer")]
    waived = [Waiver(rule="acceptable", path="w", **WAIVER)]
    rising = settle(rules, stats, [pair("lead", "q", "open"), *pairs], waivers=waived,
                    levels_final=False)
    assert rising["w"].contender and rising["w"].done and rising["w"].outcome == "marginal"
    assert not rising["lead"].done and not rising["q"].done
    settled = settle(rules, stats, [pair("lead", "q", "first safer"), *pairs], waivers=waived,
                     levels_final=False)
    assert not settled["w"].contender and all(s.done for s in settled.values())


def test_a_marginal_chain_waits_while_a_passing_chain_goes_on():
    """lead and q pass decidedly but their order is open, so both go on; one failed run of
    either would show it to fail (`no_failed_runs`) and raise the levels, at which m, within
    its margin now, may pass and rank first: m waits for its order against the leader. With
    the leaders' order settled nothing goes on, and m stops, never sent."""
    rules = evaluator()
    m = statistics(0.20, stuck=0.043, spread=0.0075)
    stats = {"lead": statistics(0.25, spread=0.03), "q": statistics(0.27, spread=0.03), "m": m}
    others = [pair("lead", "m", "open"), pair("q", "m", "open")]
    going = settle(rules, stats, [pair("lead", "q", "open"), *others], levels_final=False)
    assert going["m"].contender and not going["m"].done
    assert going["lead"].unsettled_against == ("q", "m")
    stopped = settle(rules, stats, [pair("lead", "q", "first safer"), *others],
                     levels_final=False)
    assert not stopped["m"].contender and all(s.done for s in stopped.values())
    # only a chain still simulated goes on: with lead and q stopped earlier (or at the cap,
    # where nothing goes on) m's levels are final, whatever their open order
    for running in ({"m"}, ()):
        assert not settle(rules, stats, [pair("lead", "q", "open"), *others],
                          levels_final=False, running=running)["m"].contender
    assert settle(rules, stats, [pair("lead", "q", "open"), *others], levels_final=False,
                  running={"lead", "m"})["m"].contender
