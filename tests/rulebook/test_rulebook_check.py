"""The checker on hand-built rule models (the parser's golden files test it through text)."""

import math

import pytest

from idefix_rules.errors import Severity, Span
from idefix_rules.rulebook.check import check
from idefix_rules.rulebook.model import (
    Binary,
    Call,
    Chance,
    Combine,
    CommandRule,
    Constant,
    Header,
    Index,
    Name,
    Number,
    ObstacleLevel,
    Prescreen,
    Ranking,
    RankKey,
    Reduce,
    Rulebook,
    Select,
    Setting,
    Table,
    VerdictRule,
    Window,
)

SLIP = Reduce("max", "time", Reduce("max", "wheels", Call("abs", (Name("wheel.slip"),))))
VERDICT = VerdictRule("ok", Binary("<=", Name("risk"), Number(70, "%")))


def rulebook(**parts) -> Rulebook:
    base = dict(
        header=Header("test", "1.0.0", "a test rulebook"),
        indices=(Index("I_s", SLIP, Name("critical_slip"), Number(1.0)),),
        constants=(Constant("critical_slip", Number(70, "%")),),
        verdicts=(VERDICT,),
    )
    base.update(parts)
    return Rulebook(**base)


def codes(book: Rulebook, strict: bool = False) -> list[str]:
    return [d.code for d in check(book, strict=strict).diagnostics]


def test_a_valid_rulebook_resolves_constants_to_si():
    result = check(rulebook())
    assert result.ok, result.diagnostics
    assert result.checked.limits == {"I_s": 0.7}
    assert result.checked.weights == {"I_s": 1.0}
    assert result.checked.index_types["I_s"].axes == ()


def test_adding_a_length_and_an_angle_is_an_error():
    book = rulebook(constants=(
        Constant("critical_slip", Number(70, "%")),
        Constant("bad", Binary("+", Number(5, "cm"), Number(2, "deg")), span=Span("r", 3, 1)),
    ))
    [diagnostic] = check(book).diagnostics
    assert diagnostic.code == "E201"
    assert "a length" in diagnostic.message and "an angle" in diagnostic.message


def test_degrees_and_radians_mix_freely():
    book = rulebook(constants=(
        Constant("critical_slip", Number(70, "%")),
        Constant("turn", Binary("+", Number(90, "deg"), Number(0.5, "rad"))),
    ))
    result = check(book)
    assert result.ok
    assert result.checked.constants["turn"] == pytest.approx(math.pi / 2 + 0.5)


def test_weight_outside_unit_interval():
    book = rulebook(indices=(Index("I_s", SLIP, Name("critical_slip"), Number(1.5)),))
    assert codes(book) == ["E401"]


def test_limit_must_have_the_value_dimension():
    book = rulebook(indices=(Index("I_s", SLIP, Number(5, "cm"), Number(1)),))
    assert codes(book) == ["E204"]


def test_reducer_over_wheels_needs_a_wheel_axis():
    value = Reduce("max", "time", Reduce("max", "wheels", Name("roll")))
    book = rulebook(indices=(Index("I_r", value, Number(30, "deg"), Number(1)),))
    [diagnostic] = check(book).diagnostics
    assert diagnostic.code == "E301" and "wheel axis" in diagnostic.message


def test_index_must_reduce_every_axis():
    value = Reduce("max", "time", Name("wheel.slip"))
    book = rulebook(indices=(Index("I_s", value, Name("critical_slip"), Number(1)),))
    [diagnostic] = check(book).diagnostics
    assert diagnostic.code == "E302" and "wheel" in diagnostic.message


def test_unknown_name_suggests_the_close_one():
    value = Reduce("max", "time", Reduce("max", "wheels", Name("wheel.slp")))
    book = rulebook(indices=(Index("I_s", value, Name("critical_slip"), Number(1)),))
    [diagnostic] = check(book).diagnostics
    assert diagnostic.code == "E101" and diagnostic.hint == "did you mean 'wheel.slip'?"


def test_signals_are_not_visible_in_command_rules():
    rule = CommandRule("bad", Binary("<", Name("roll"), Number(5, "deg")))
    [diagnostic] = check(rulebook(command_rules=(rule,))).diagnostics
    assert diagnostic.code == "E101" and "cannot be used in a command rule" in diagnostic.message


def test_command_rules_see_command_quantities():
    rule = CommandRule("max_turn", Binary("<=", Call("abs", (Name("delta_heading"),)),
                                          Number(90, "deg")))
    assert check(rulebook(command_rules=(rule,))).ok


def test_duplicate_names_across_kinds():
    book = rulebook(chances=(Chance("I_s", Binary(">", Name("risk"), Number(0))),))
    assert "E102" in codes(book)


@pytest.mark.parametrize("kind", ["verdict", "prescreen", "chance"])
def test_no_failed_runs_is_the_verdicts_own_rule_and_no_declaration_takes_it(kind):
    """A verdict named `no_failed_runs` was accepted: the results showed its text with the
    automatic rule's reason, and a case expecting it to pass passed on a failing path."""
    condition = Binary("<=", Name("risk"), Number(50, "%"))
    named = {"verdict": {"verdicts": (VERDICT, VerdictRule("no_failed_runs", condition))},
             "prescreen": {"prescreens": (Prescreen("no_failed_runs", condition),)},
             "chance": {"chances": (Chance("no_failed_runs", Reduce(
                 "any", "time", Binary(">", Name("pitch"), Number(0, "deg")))),)}}
    result = check(rulebook(**named[kind]))
    assert [d.code for d in result.errors] == ["E103"]
    assert result.errors[0].message == (f"{kind} 'no_failed_runs' takes the name of the "
                                        "verdict's own rule for failed runs")


def test_constants_in_a_circle():
    book = rulebook(constants=(
        Constant("critical_slip", Number(70, "%")),
        Constant("a", Name("b")),
        Constant("b", Name("a")),
    ))
    assert "E403" in codes(book)


def test_required_sections():
    book = Rulebook(header=Header("t", "1.0.0", "p"))
    assert set(codes(book)) == {"E501", "E502"}


def test_bad_semantic_version():
    assert codes(rulebook(header=Header("t", "1.0", "p"))) == ["E503"]


def test_level_table_broadcasts_over_parts_and_levels():
    f_obs = Constant("f_obs", Table((("L1", Number(0.2)), ("L2", Number(0.6)),
                                     ("L3", Number(1.0)))))
    value = Reduce("sum", "parts", Reduce("sum", "levels",
                                          Binary("*", Name("collision.hits"), Name("f_obs"))))
    book = rulebook(constants=(Constant("critical_slip", Number(70, "%")), f_obs),
                    indices=(Index("I_obs", value, Number(1), Number(1)),),
                    chances=(Chance("hit_L2", Reduce("any", "parts", Binary(
                        ">", Select(Name("collision.hits"), ("L2",)), Number(0)))),))
    result = check(book)
    assert result.ok, result.diagnostics
    assert result.checked.constants["f_obs"] == {"L1": 0.2, "L2": 0.6, "L3": 1.0}


def test_window_needs_a_duration_and_only_applies_to_time():
    bad_window = Reduce("max", "time", Name("roll"), window=Window("after", Number(5, "cm")))
    book = rulebook(indices=(Index("I_r", bad_window, Number(30, "deg"), Number(1)),))
    assert codes(book) == ["E204"]
    wheel_window = Reduce("max", "time", Reduce("max", "wheels", Name("wheel.slip"),
                                                window=Window("after", Number(5, "s"))))
    book = rulebook(indices=(Index("I_s", wheel_window, Name("critical_slip"), Number(1)),))
    assert codes(book) == ["E305"]


@pytest.mark.parametrize(("command", "expected"), [
    (Number(1), []), (Number(3), []), (Name("second"), []),
    (Number(0), ["E310"]),  # the samples after the chain (command == -1)
    (Number(1.5), ["E310"]), (Number(0.999), ["E310"]), (Number(1.001), ["E310"]),
    (Binary("-", Name("second"), Number(2)), ["E310"]),  # a constant expression: 0
    (Number(2, "s"), ["E204"]),  # not a number at all: said once
])
def test_a_command_window_counts_whole_commands_from_one(command, expected):
    windowed = Reduce("max", "time", Reduce("max", "wheels", Call("abs", (Name("wheel.slip"),))),
                      window=Window("command", command))
    book = rulebook(constants=(Constant("critical_slip", Number(70, "%")),
                               Constant("second", Number(2))),
                    indices=(Index("I_s", windowed, Name("critical_slip"), Number(1)),))
    assert codes(book) == expected


def test_obstacle_levels_resolve_and_classify():
    levels = (
        ObstacleLevel("L1", Number(3, "cm"), Number(2, "cm")),
        ObstacleLevel("L2", Number(10, "cm"), Number(5, "cm")),
        ObstacleLevel("L3", None, Number(10, "cm")),
    )
    result = check(rulebook(obstacle_levels=levels))
    assert result.ok
    checked = result.checked
    assert [checked.level_of_size(s) for s in (0.01, 0.05, 0.5)] == ["L1", "L2", "L3"]
    assert checked.obstacle_levels[1].buffer == 0.05


def test_obstacle_thresholds_must_increase():
    levels = (
        ObstacleLevel("L1", Number(10, "cm"), Number(2, "cm")),
        ObstacleLevel("L2", Number(3, "cm"), Number(5, "cm")),
        ObstacleLevel("L3", None, Number(10, "cm")),
    )
    assert codes(rulebook(obstacle_levels=levels)) == ["E405"]


def test_the_highest_level_takes_no_size_threshold():
    """Every rock above L2's threshold is L3: a 'below' on L3 would be read as a limit that
    is never applied (rocks above it stayed L3)."""
    levels = (
        ObstacleLevel("L1", Number(3, "cm"), Number(2, "cm")),
        ObstacleLevel("L2", Number(10, "cm"), Number(5, "cm")),
        ObstacleLevel("L3", Number(20, "cm"), Number(10, "cm")),
    )
    result = check(rulebook(obstacle_levels=levels))
    assert [d.code for d in result.diagnostics] == ["E405"]
    assert "would never be used" in result.diagnostics[0].message


def test_settings_are_checked_and_defaulted():
    result = check(rulebook(settings=(Setting("tolerance_growth",
                                              Binary("/", Number(5, "cm"), Number(1, "rad"))),)))
    assert result.ok
    assert result.checked.settings == {"theoretical_slip": 0.0, "tolerance_growth": 0.05}
    assert codes(rulebook(settings=(Setting("tolerance_grwth", Number(1)),))) == ["E505"]


def test_verdicts_see_path_statistics_and_chance_calls():
    chance = Chance("hit", Binary(">", Reduce("max", "time", Name("roll")), Number(5, "deg")))
    verdict = VerdictRule("rare", Binary("<=", Call("chance", (Name("hit"),)), Number(5, "%")))
    assert check(rulebook(chances=(chance,), verdicts=(VERDICT, verdict))).ok
    unknown = VerdictRule("rare", Binary("<=", Call("chance", (Name("hot"),)), Number(5, "%")))
    assert codes(rulebook(chances=(chance,), verdicts=(VERDICT, unknown))) == ["E101"]


def test_strict_warns_about_unused_constants_and_zero_weights():
    book = rulebook(constants=(Constant("critical_slip", Number(70, "%")),
                               Constant("spare", Number(1, "cm"))),
                    indices=(Index("I_s", SLIP, Name("critical_slip"), Number(0)),))
    result = check(book, strict=True)
    assert result.ok
    assert [(d.code, d.severity) for d in result.diagnostics] == [
        ("W601", Severity.WARNING), ("W602", Severity.WARNING)]
    assert check(book).diagnostics == []


def test_every_error_of_a_file_is_reported():
    book = rulebook(
        header=Header("t", "one", "p"),
        indices=(Index("I_s", SLIP, Number(5, "cm"), Number(2)),),
    )
    assert sorted(codes(book)) == ["E204", "E401", "E503"]


def test_a_bare_zero_compares_with_any_dimension():
    rule = CommandRule("moves", Binary("or", Binary("!=", Name("delta_position"), Number(0)),
                                       Binary("!=", Name("delta_heading"), Number(0))))
    assert check(rulebook(command_rules=(rule,))).ok
    rule = CommandRule("moves", Binary("!=", Name("delta_position"), Number(1)))
    assert codes(rulebook(command_rules=(rule,))) == ["E201"]


def test_without_an_obstacles_section_there_are_no_size_thresholds():
    checked = check(rulebook()).checked
    assert checked.obstacle_levels == ()


@pytest.mark.parametrize(("margin", "expected"), [
    (None, 0.0), (Number(0, "%"), 0.0), (Number(2, "%"), 0.02), (Number(49.9, "%"), 0.499)])
def test_the_indifference_margin_is_a_ratio_below_half(margin, expected):
    result = check(rulebook(combine=Combine(indifference=margin)))
    assert result.ok, result.diagnostics
    assert math.isclose(result.checked.indifference, expected)


@pytest.mark.parametrize(("margin", "code"), [
    (Number(50, "%"), "E410"), (Number(-1, "%"), "E410"), (Number(2, "cm"), "E204")])
def test_an_indifference_margin_outside_its_range_or_not_a_ratio_is_an_error(margin, code):
    assert codes(rulebook(combine=Combine(indifference=margin))) == [code]


@pytest.mark.parametrize(("keys", "expected"), [
    ((RankKey(Name("risk")), RankKey(Name("time"))), []),
    ((RankKey(Name("risk")), RankKey(Name("time")), RankKey(Name("risk"), True)), ["E413"]),
    ((RankKey(Name("risk")), RankKey(Name("risk"))), ["E413"]),
])
def test_a_rank_key_is_given_once(keys, expected):
    assert codes(rulebook(ranking=Ranking(keys))) == expected


@pytest.mark.parametrize(("margin", "expected"), [
    (Number(49.9, "%"), []), (Number(50, "%"), ["E412"]), (Number(80, "%"), ["E412"]),
    (Number(0, "%"), []),
])
def test_a_ratio_verdicts_own_indifference_lies_below_half_the_scale(margin, expected):
    verdict = VerdictRule("ok", Binary("<=", Name("risk"), Number(70, "%")), indifference=margin)
    assert codes(rulebook(verdicts=(verdict,))) == expected


def test_a_run_count_verdicts_indifference_is_a_number_of_runs():
    verdict = VerdictRule("enough", Binary(">=", Name("runs"), Number(100)),
                          indifference=Number(5))
    assert codes(rulebook(verdicts=(VERDICT, verdict))) == []


def test_a_time_verdicts_indifference_may_be_any_duration():
    verdict = VerdictRule("quick", Binary("<=", Name("time"), Number(10, "min")),
                          indifference=Number(20, "min"))
    assert codes(rulebook(verdicts=(VERDICT, verdict))) == []
