"""Golden cases of the compiled evaluator, each also run through the per-run interpreter."""

import math

import numpy as np
import pytest

from idefix_rules.commands import Command
from idefix_rules.errors import UserInputError
from idefix_rules.rulebook.check import check
from idefix_rules.rulebook.compile import compile_rulebook
from idefix_rules.rulebook.derived import RunContext
from idefix_rules.rulebook.interpret import interpret
from idefix_rules.rulebook.parser import parse_rulebook
from idefix_rules.rulebook.results import RunEvaluation

HEADER = 'rulebook "t" version "1.0.0"\npurpose "test"\n'
FOOTER = "\nverdict ok: require risk <= 70 %\n"
CHAIN = (Command(0.1, 0.2, 0.0), Command(0.1, 0.1, 0.0))


def rulebook(body: str):
    result = check(parse_rulebook(HEADER + body + FOOTER, "t.rules"))
    assert result.checked is not None, [d.format() for d in result.errors]
    return result.checked


def batch(runs: int = 2, samples: int = 6, **overrides):
    """t = 0..5 s; commands 0,0,1,1,-1,-1; every other signal 0 unless overridden."""
    t = np.arange(samples, dtype=float)
    command = np.array([0, 0, 1, 1, -1, -1][:samples] + [-1] * max(0, samples - 6), dtype=float)
    signals = {"t": np.tile(t, (runs, 1)), "command": np.tile(command, (runs, 1))}
    for name in ("x", "y", "z", "roll", "pitch", "yaw", "energy"):
        signals[name] = np.zeros((runs, samples))
    for name in ("wheel.slip", "wheel.sinkage", "wheel.slip_angle", "wheel.rate"):
        signals[name] = np.zeros((runs, samples, 4))
    signals["collision.hits"] = np.zeros((runs, 3, 3))
    signals["collision.contact"] = np.zeros((runs, samples, 3, 3))
    for name, value in overrides.items():
        signals[name.replace("__", ".")] = np.asarray(value, dtype=float)
    reference = {k: v[0] * 0 for k, v in signals.items() if not k.startswith("collision")}
    reference["t"], reference["command"] = t, command
    return signals, RunContext(CHAIN, initial_position_sigma=0.1, reference=reference)


def evaluate(checked, signals, context) -> RunEvaluation:
    """Compiled evaluation, asserted equal to the interpreter's."""
    compiled = compile_rulebook(checked).evaluate(signals, context)
    slow = interpret(checked, signals, context)
    for name in compiled.index_names:
        for field in ("values", "raw", "per_sample", "weighted"):
            np.testing.assert_allclose(getattr(compiled, field)[name],
                                       getattr(slow, field)[name], rtol=1e-12, atol=1e-15,
                                       err_msg=f"{field}[{name}]")
    for name in compiled.chance_names:
        np.testing.assert_array_equal(compiled.chances[name], slow.chances[name])
    for field in ("i_max", "dominant", "dominant_sample", "time", "energy"):
        np.testing.assert_allclose(getattr(compiled, field), getattr(slow, field),
                                   err_msg=field)
    return compiled


PITCH = [[0.0, 0.1, -0.3, 0.2, 0.0, 0.05], [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]]


@pytest.mark.parametrize(("value", "expected"), [
    ("max over time (abs(pitch))", 0.3),
    ("min over time (pitch)", -0.3),
    ("final over time (pitch)", 0.05),
    ("initial over time (pitch + 1 rad)", 1.0),
    ("sum over time (pitch)", 0.05),
    ("mean over time (pitch)", 0.05 / 6),
    ("rms over time (pitch)", math.sqrt((0.01 + 0.09 + 0.04 + 0.0025) / 6)),
    ("integral over time (abs(pitch))", 0.05 + 0.2 + 0.25 + 0.1 + 0.025),
    ("time_above 0.09 rad over time (abs(pitch))", 3.0),  # samples 1, 2, 3 hold 1 s each
    ("percentile 50 over time (pitch)", 0.025),
    ("percentile 100 over time (pitch)", 0.2),
    ("max over time during command 2 (abs(pitch))", 0.3),
    ("max over time during command 1 (abs(pitch))", 0.1),
    ("max over time during command 3 (abs(pitch))", 0.0),  # empty window → 0
    ("final over time before 2 s (pitch)", 0.1),
    ("sum over time after 3 s (pitch)", 0.25),
    ("integral over time during command 2 (pitch)", -0.05),
])
def test_time_reducers_and_windows(value, expected):
    limit = "10 rad*s" if "integral" in value else "10 s" if "time_above" in value else "10 rad"
    checked = rulebook(f"index I {{ value = {value} limit = {limit} weight = 1 }}")
    result = evaluate(checked, *batch(pitch=PITCH))
    assert result.raw["I"][0] == pytest.approx(expected, abs=1e-12)


def test_values_are_normalised_by_the_limit_and_clamped():
    checked = rulebook("""
index I_low  { value = max over time (pitch) limit = 0.4 rad weight = 1 }
index I_high { value = max over time (abs(pitch)) limit = 0.1 rad weight = 0.5 }
index I_neg  { value = min over time (pitch) limit = 1 rad weight = 1 }
""")
    result = evaluate(checked, *batch(pitch=PITCH))
    assert result.values["I_low"][0] == pytest.approx(0.5)
    assert result.values["I_high"][0] == 1.0  # 0.3 / 0.1 clamped
    assert result.values["I_neg"][0] == 0.0  # negative clamped
    assert result.weighted["I_high"][0] == 0.5
    assert result.i_max[0] == pytest.approx(0.5)
    assert result.index_names[result.dominant[0]] == "I_low"  # first of the tied maxima
    assert result.dominant_sample[0] == 3  # where pitch peaks (0.2)


def test_per_sample_value_replaces_time_reductions_by_their_operand():
    checked = rulebook("""
index I { value = max over time after 2 s (abs(pitch)) limit = 0.4 rad weight = 1 }
""")
    result = evaluate(checked, *batch(pitch=PITCH))
    # outside the window the per-sample value is 0; inside |pitch| / 0.4
    np.testing.assert_allclose(result.per_sample["I"][0], [0, 0, 0.75, 0.5, 0, 0.125])


def test_wheel_quantifiers_and_selection():
    slip = np.zeros((2, 6, 4))
    slip[0, 2] = [0.1, -0.8, 0.3, 0.2]
    slip[1, 4] = [0.35, 0, 0, 0]
    checked = rulebook("""
const critical_slip = 70 %
index I_s  { value = max over time (max over wheels (abs(wheel.slip))) limit = critical_slip
             weight = 1 }
index I_fl { value = max over time (wheel.slip[FL]) limit = 70 % weight = 0.2 }
chance any_high = any over wheels (max over time (abs(wheel.slip)) > 50 %)
chance all_low = all over wheels (max over time (wheel.slip) < 50 %)
""")
    result = evaluate(checked, *batch(wheel__slip=slip))
    np.testing.assert_allclose(result.values["I_s"], [1.0, 0.5])
    np.testing.assert_allclose(result.raw["I_fl"], [0.1, 0.35])
    assert result.chances["any_high"].tolist() == [True, False]
    assert result.chances["all_low"].tolist() == [True, True]


def test_obstacle_index_with_level_factors():
    hits = np.zeros((2, 3, 3))
    hits[0, 0, 1] = 1  # wheel hits an L2 rock
    hits[0, 2, 0] = 2  # chassis hits two L1 rocks
    contact = np.zeros((2, 6, 3, 3))
    contact[0, 3, 0, 1] = 1
    checked = rulebook("""
const f_obs = {L1: 0.2, L2: 0.6, L3: 1.0}
index I_obs {
  value = sum over parts (sum over levels (collision.hits * f_obs))
  limit = 1
  weight = 1
  map = max over parts (max over levels (collision.contact * f_obs))
}
chance hit_L2 = any over parts (collision.hits[L2] > 0)
""")
    evaluator = compile_rulebook(checked)
    assert evaluator.needs_collisions
    assert {"collision.hits", "collision.contact"} <= evaluator.required_signals
    result = evaluate(checked, *batch(collision__hits=hits, collision__contact=contact))
    np.testing.assert_allclose(result.raw["I_obs"], [1.0, 0.0])
    np.testing.assert_allclose(result.per_sample["I_obs"][0], [0, 0, 0, 0.6, 0, 0])
    assert result.dominant_sample[0] == 3
    assert result.chances["hit_L2"].tolist() == [True, False]


def test_non_finite_signal_makes_the_index_critical():
    pitch = np.array(PITCH)
    pitch[1, 0] = np.nan  # the first sample: not the one final reads
    checked = rulebook("""
index I { value = final over time (pitch) limit = 1 rad weight = 0.5 }
index J { value = max over time (abs(roll)) limit = 1 rad weight = 1 }
chance tilted = max over time (abs(pitch)) > 1 rad
""")
    result = evaluate(checked, *batch(pitch=pitch))
    assert result.values["I"].tolist() == [0.05, 1.0]
    assert math.isnan(result.raw["I"][1])
    assert result.per_sample["I"][1, 0] == 1.0
    assert np.isfinite(result.per_sample["I"]).all()
    assert result.chances["tilted"].tolist() == [False, True]
    assert result.i_max.tolist() == [0.025, 0.5]


def test_zero_over_zero_is_critical_not_nan():
    checked = rulebook("index I { value = final over time (pitch / roll) limit = 1 weight = 1 }")
    result = evaluate(checked, *batch())
    assert result.values["I"].tolist() == [1.0, 1.0]


def test_time_and_energy_at_the_end_of_the_chain():
    energy = np.tile([0.0, 0.1, 0.2, 0.3, 0.4, 0.4], (2, 1))
    command = np.array([[0, 0, 1, 1, -1, -1], [0, 0, 1, 1, 1, 1]], dtype=float)
    checked = rulebook("index I { value = max over time (abs(pitch)) limit = 1 rad weight = 1 }")
    result = evaluate(checked, *batch(energy=energy, command=command))
    assert result.time.tolist() == [4.0, 5.0]
    np.testing.assert_allclose(result.energy, [0.4, 0.4])


def test_required_signals_follow_derived_inputs():
    checked = rulebook("""
settings { tolerance_growth = 5 cm/rad }
index I_pos { value = final over time (global_error / tolerance_radius) limit = 1 weight = 1 }
""")
    evaluator = compile_rulebook(checked)
    # command, energy and z are used when present, not required
    assert evaluator.required_signals == {"t", "x", "y"}
    assert not evaluator.needs_collisions
    assert evaluator.name == "t" and evaluator.version == "1.0.0"
    assert len(evaluator.source_hash) == 64


def test_plain_rule_model_is_checked_before_compiling():
    model = parse_rulebook(HEADER + "index I { value = max over time (pitch) limit = 5 cm "
                                    "weight = 1 }" + FOOTER, "bad.rules")
    with pytest.raises(UserInputError) as caught:
        compile_rulebook(model)
    assert caught.value.diagnostics[0].span.path == "bad.rules"


def test_check_chain_reports_rule_command_number_and_values():
    checked = rulebook("""
command max_turn: require abs(delta_heading) <= 90 deg because "Largest turn"
command min_motion: require delta_position >= 5 cm or abs(delta_heading) >= 10 deg
index I { value = max over time (abs(pitch)) limit = 1 rad weight = 1 }
""")
    chain = [Command(0.1, 0.5, 0.0), Command(0.1, 0.0, 2.0), Command(0.1, 0.01, 0.0)]
    violations = compile_rulebook(checked).check_chain(chain)
    assert [(v.rule, v.command_number) for v in violations] == [("max_turn", 2),
                                                                 ("min_motion", 3)]
    assert violations[0].values == {"delta_heading": 2.0}
    assert violations[0].rationale == "Largest turn"
    assert violations[1].to_dict()["values"] == {"delta_heading": 0.0, "delta_position": 0.01}


def test_prescreen_on_the_reference_run():
    checked = rulebook("""
index I { value = max over time (abs(pitch)) limit = 0.3 rad weight = 1 }
chance tilted = max over time (abs(pitch)) > 0.25 rad
prescreen calm: require I < 1 because "Reference run already critical"
prescreen upright: require not tilted
prescreen low_risk: require risk < 2
""")
    evaluator = compile_rulebook(checked)
    signals, context = batch(pitch=PITCH)
    findings = evaluator.prescreen(evaluator.evaluate(signals, context))
    assert [f.rule for f in findings] == ["calm", "upright"]
    assert findings[0].values == {"I": 1.0}
    assert findings[0].rationale == "Reference run already critical"
    quiet, _ = batch()
    assert evaluator.prescreen(evaluator.evaluate(quiet, context)) == []


def test_chunks_concatenate_and_rows_are_plain():
    checked = rulebook("index I { value = max over time (abs(pitch)) limit = 1 rad weight = 1 }"
                       "\nchance c = max over time (pitch) > 0.1 rad")
    evaluator = compile_rulebook(checked)
    signals, context = batch(pitch=PITCH)
    whole = evaluator.evaluate(signals, context)
    parts = [evaluator.evaluate({k: v[i:i + 1] for k, v in signals.items()}, context)
             for i in range(2)]
    joined = RunEvaluation.concat(parts)
    np.testing.assert_array_equal(joined.i_max, whole.i_max)
    np.testing.assert_array_equal(joined.per_sample["I"], whole.per_sample["I"])
    row = joined.row(0)
    assert row.dominant == "I" and row.chances == {"c": True}
    assert row.to_dict()["values"] == {"I": 0.3}
    assert whole.to_dict()["dominant"] == ["I", "I"]
    assert "per_sample" in whole.to_dict(per_sample=True)


def test_missing_signal_is_a_user_error():
    checked = rulebook("index I { value = max over time (abs(pitch)) limit = 1 rad weight = 1 }")
    signals, context = batch()
    del signals["pitch"]
    with pytest.raises(UserInputError, match="pitch"):
        compile_rulebook(checked).evaluate(signals, context)


def test_per_sample_keeps_time_reductions_inside_the_outer_one():
    checked = rulebook("""
index I { value = max over time (pitch - mean over time (pitch)) limit = 1 rad weight = 1 }
""")
    result = evaluate(checked, *batch(pitch=PITCH))
    mean = 0.05 / 6
    np.testing.assert_allclose(result.per_sample["I"][0],
                               np.clip(np.array(PITCH[0]) - mean, 0, 1))
    assert result.raw["I"][0] == pytest.approx(0.2 - mean)


def test_compiled_rulebook_pickles_for_worker_processes():
    import pickle

    checked = rulebook("index I { value = max over time (abs(pitch)) limit = 1 rad weight = 1 }")
    evaluator = compile_rulebook(checked)
    copy = pickle.loads(pickle.dumps(evaluator))
    signals, context = batch(pitch=PITCH)
    np.testing.assert_array_equal(copy.evaluate(signals, context).i_max,
                                  evaluator.evaluate(signals, context).i_max)
    assert copy.source_hash == evaluator.source_hash


# ---------------------------------------------------------------- reductions over runs
X3 = [[0.0, 0.0, 0.1, 0.2, 0.3, 0.3], [0.0, 0.0, 0.0, 0.0, -0.1, -0.1],
      [0.0, 0.0, 0.0, 0.0, 0.0, 0.05]]  # final x: 0.3, -0.1, 0.05 (reference: 0)


@pytest.mark.parametrize(("value", "expected"), [
    ("mean over runs (final over time (x))", 0.25 / 3),
    ("max over runs (final over time (x))", 0.3),
    ("min over runs (final over time (x))", -0.1),
    ("sum over runs (final over time (x))", 0.25),
    ("rms over runs (final over time (x))", math.sqrt((0.09 + 0.01 + 0.0025) / 3)),
    ("percentile 50 over runs (final over time (x))", 0.05),
    ("count over runs (final over time (x) > 0 m) * 1 m", 2.0),
    ("fraction over runs (final over time (x) > 0 m) * 1 m", 2 / 3),
    ("final over time (mean over runs (x))", 0.25 / 3),  # the mean trajectory, then its end
    ("max over time (mean over runs (x))", 0.25 / 3),
    ("final over time (hypot(mean over runs (x - ref.x), mean over runs (y - ref.y)))",
     0.25 / 3),
    ("hypot(3 m, 4 m)", 5.0),
])
def test_a_reduction_over_runs_gives_one_value_for_the_path(value, expected):
    checked = rulebook(f"index I_a {{\n  value = {value}\n  limit = 1 m\n  weight = 1\n}}\n")
    signals, context = batch(3, x=X3)
    evaluation = evaluate(checked, signals, context)
    np.testing.assert_allclose(evaluation.raw["I_a"], [expected] * 3, rtol=1e-12)


def test_a_run_can_be_compared_with_the_path_and_counted_as_a_fraction():
    checked = rulebook(
        "index I_f {\n  value = fraction over runs (final over time (abs(x)) > 5 cm)\n"
        "  limit = 100 %\n  weight = 1\n}\n"
        "index I_t {\n  value = fraction over time (abs(x) > 5 cm)\n  limit = 1\n"
        "  weight = 1\n}\n"
        "chance above_mean = final over time (x) > mean over runs (final over time (x))\n")
    signals, context = batch(3, x=X3)
    evaluation = evaluate(checked, signals, context)
    np.testing.assert_allclose(evaluation.raw["I_f"], [2 / 3] * 3)  # 0.3 and 0.1 are > 5 cm
    np.testing.assert_allclose(evaluation.raw["I_t"], [4 / 6, 2 / 6, 0.0])
    assert evaluation.chances["above_mean"].tolist() == [True, False, False]


def test_the_map_of_a_path_level_index_follows_the_mean_trajectory():
    checked = rulebook("index I_pos {\n  value = final over time (hypot(mean over runs "
                       "(x - ref.x), mean over runs (y - ref.y)) / tolerance_radius)\n"
                       "  limit = 1\n  weight = 1\n}\n")
    signals, context = batch(3, x=X3)  # sigma 0.1 m, no growth: the tolerance stays 0.1 m
    evaluation = evaluate(checked, signals, context)
    mean_x = np.mean(np.asarray(X3), axis=0)
    for run in range(3):  # the same map in every run: the path's value, sample by sample
        np.testing.assert_allclose(evaluation.per_sample["I_pos"][run], np.abs(mean_x) / 0.1)


def test_a_chunked_evaluation_reads_the_path_level_value_of_every_run():
    checked = rulebook("index I_m {\n  value = mean over runs (final over time (x))\n"
                       "  limit = 1 m\n  weight = 1\n}\n")
    evaluator = compile_rulebook(checked)
    signals, context = batch(3, x=X3)
    first, rest = ({k: v[:1] for k, v in signals.items()}, {k: v[1:] for k, v in signals.items()})
    across = evaluator.across_runs(rest, context, into=evaluator.across_runs(first, context))
    assert across.runs == 3
    chunk = evaluator.evaluate(first, context, across=across)
    np.testing.assert_allclose(chunk.raw["I_m"], [0.25 / 3])
    # Without the first pass, a chunk alone is the whole path: its own mean.
    np.testing.assert_allclose(evaluator.evaluate(first, context).raw["I_m"], [0.3])


def test_a_non_finite_value_across_runs_makes_a_path_level_index_critical_in_every_run():
    checked = rulebook("index I_m {\n  value = abs(mean over runs (final over time (x)))\n"
                       "  limit = 1 m\n  weight = 1\n}\n")
    x = np.asarray(X3)
    x[1, 5] = np.nan  # the value the mean reads: the path-level value is NaN
    evaluation = evaluate(checked, *batch(3, x=x))
    assert evaluation.values["I_m"].tolist() == [1.0, 1.0, 1.0]
    x = np.asarray(X3)
    x[1, 3] = np.nan  # a sample the mean does not read: only that run is critical
    evaluation = evaluate(checked, *batch(3, x=x))
    assert evaluation.values["I_m"][1] == 1.0
    np.testing.assert_allclose(evaluation.values["I_m"][[0, 2]], 0.25 / 3)


@pytest.mark.parametrize(("reduction", "unread_sample"), [
    # a truth value lost its NaN in a comparison: the signal it read counts, as it does for a
    # run's own chance, even at a sample `final` does not use
    ("fraction over runs (final over time (x) > 0.2 m) > 0.5", [True] * 3),
    ("any over runs (final over time (x) > 0.2 m)", [True] * 3),
    # a number carries its NaN: a sample it does not use spoils only its own run
    ("mean over runs (final over time (x)) > 0.2 m", [False, True, False]),
])
def test_a_non_finite_value_across_runs_makes_a_chance_hold_in_every_run(reduction,
                                                                          unread_sample):
    """Non-finite data is read conservatively: a chance reading a path-level value that some
    run's non-finite signal spoilt holds in every run, as the run's own non-finite signals make
    it hold there (a comparison with NaN is false: the spoilt run counted as not holding)."""
    checked = rulebook(f"chance off = {reduction}\n"
                       "index I { value = max over time (abs(pitch)) limit = 1 rad weight = 1 }\n")
    x = np.asarray([[0.0] * 6, [0.0] * 6, [0.0] * 6])  # no run ends beyond 0.2 m
    assert evaluate(checked, *batch(3, x=x)).chances["off"].tolist() == [False] * 3
    x[1, 5] = np.nan  # the value the path-level value reads
    assert evaluate(checked, *batch(3, x=x)).chances["off"].tolist() == [True] * 3
    x[1, 5] = 0.0
    x[1, 3] = np.inf  # a sample `final` does not use
    assert evaluate(checked, *batch(3, x=x)).chances["off"].tolist() == unread_sample


def test_a_path_level_value_spoilt_in_one_chunk_is_spoilt_for_every_chunk():
    checked = rulebook("chance off = fraction over runs (final over time (x) > 0.2 m) > 0.5\n"
                       "index I { value = max over time (abs(pitch)) limit = 1 rad weight = 1 }\n")
    evaluator = compile_rulebook(checked)
    x = np.zeros((3, 6))
    x[2, 5] = np.nan
    signals, context = batch(3, x=x)
    first, rest = ({k: v[:1] for k, v in signals.items()}, {k: v[1:] for k, v in signals.items()})
    across = evaluator.across_runs(first, context)
    across.merge(evaluator.across_runs(rest, context))
    assert evaluator.evaluate(first, context, across=across).chances["off"].tolist() == [True]
    assert evaluator.evaluate(first, context, across=across.copy()).chances["off"].tolist() == \
        [True]
    clean = evaluator.across_runs(first, context)  # the first chunk alone is finite
    assert evaluator.evaluate(first, context, across=clean).chances["off"].tolist() == [False]


def test_signals_near_the_largest_double_are_finite():
    """Finiteness is judged value by value: two finite values whose sum overflows are finite."""
    checked = rulebook("index I { value = max over time (x) / max over time (y) limit = 2 "
                       "weight = 1 }\n")
    x = np.full((1, 6), 1e308)
    y = np.full((1, 6), 1e308)
    evaluation = evaluate(checked, *batch(1, x=x, y=y))
    assert evaluation.raw["I"].tolist() == [1.0]
    assert evaluation.values["I"].tolist() == [0.5]


def test_forward_acceleration_is_the_ramp_of_the_body_centre():
    """The fastest wheel ramps at wheel_acceleration; the centre follows in proportion:
    a straight drive at 0.05 rad/s on 10 cm wheels speeds up at 0.1 m/rad · 0.015 rad/s²."""
    from idefix_rules.commands import RoverGeometry, forward_acceleration
    rover = RoverGeometry()
    assert forward_acceleration(Command(0.05, 1.0, 0.0), rover) == pytest.approx(1.5e-3)
    # an arc's centre is slower than its outer wheel: R / (R + b) of the straight ramp
    arc = forward_acceleration(Command(0.05, 0.6, 1.0), rover)
    assert arc == pytest.approx(1.5e-3 * 0.6 / (0.6 + 0.26))
    assert forward_acceleration(Command(0.05, 0.0, 1.0), rover) == 0.0  # point turn
    assert forward_acceleration(Command(0.05, -1.0, 0.0), rover) == pytest.approx(1.5e-3)
    steps = RoverGeometry(wheel_acceleration=0.0)
    assert forward_acceleration(Command(0.05, 1.0, 0.0), steps) == math.inf


def test_forward_acceleration_rule_just_inside_and_outside():
    checked = rulebook("""
command gentle_start: require forward_acceleration <= 1.5 mm/s^2
index I { value = max over time (abs(pitch)) limit = 1 rad weight = 1 }
""")
    compiled = compile_rulebook(checked)
    # 0.05 rad/s straight: 1.49 mm/s^2 with a ramp of 0.0149 rad/s^2 (held), 1.51 mm/s^2
    # with 0.0151 rad/s^2 (broken)
    from idefix_rules.commands import RoverGeometry
    slower = RoverGeometry(wheel_acceleration=0.0149)
    assert compiled.check_chain([Command(0.05, 1.0, 0.0)], slower) == []
    faster = RoverGeometry(wheel_acceleration=0.0151)
    violations = compiled.check_chain([Command(0.05, 1.0, 0.0)], faster)
    assert [v.rule for v in violations] == ["gentle_start"]
    assert violations[0].values["forward_acceleration"] == pytest.approx(1.51e-3)


def test_rover_geometry_ramp_matches_the_fmu_parameter_default():
    from idefix_rules.commands import RoverGeometry
    from idefix_rules.fmu.variables import VARIABLES_BY_NAME
    assert RoverGeometry().wheel_acceleration == \
        VARIABLES_BY_NAME["controller.wheel_acceleration"].start


# ---------------------------------------------------------------- per-sample values alone
def test_per_sample_values_are_the_evaluations_and_read_only_their_signals():
    checked = rulebook("""
settings { tolerance_growth = 5 cm/rad }
index I_pos { value = final over time (global_error / tolerance_radius) limit = 1 weight = 1 }
index I_s { value = percentile 95 over time (max over wheels (abs(wheel.slip))) limit = 1
            weight = 1 }
chance fast = max over time (speed) > 1 cm/s
chance far = final over time (mean over runs (x)) > 1 m
""")
    evaluator = compile_rulebook(checked)
    signals, context = batch(3, x=X3, wheel__slip=np.full((3, 6, 4), 0.25))
    signals["z"] = np.tile([0.0, 0.0, 0.01, 0.02, 0.02, 0.02], (3, 1))
    # the chances read x and y and reduce over runs; the per-sample values read no more than
    # their own signals (z, which a global error adds when stored), and nothing over runs
    assert evaluator.sample_signals == {"t", "x", "y", "wheel.slip"}
    assert evaluator.sample_optional_signals == {"z"}
    assert evaluator.sample_runs_reductions == ()
    read = {name: signals[name] for name in ("t", "command", "x", "y", "z", "wheel.slip")}
    alone = evaluator.per_sample_values(read, context)
    whole = evaluator.evaluate(signals, context).per_sample
    assert alone.keys() == whole.keys()
    for name, values in whole.items():
        np.testing.assert_array_equal(alone[name], values, err_msg=name)


def test_per_sample_values_of_a_path_level_map_use_the_values_over_runs():
    checked = rulebook("index I_m {\n  value = final over time (abs(x))\n  limit = 1 m\n"
                       "  weight = 1\n  map = abs(mean over runs (x))\n}\n"
                       "chance pitched = max over time (abs(pitch)) > mean over runs "
                       "(max over time (abs(pitch)))\n")
    evaluator = compile_rulebook(checked)
    assert len(evaluator.runs_reductions) == 2 and len(evaluator.sample_runs_reductions) == 1
    signals, context = batch(3, x=X3)
    whole = evaluator.evaluate(signals, context)
    # without the pitch only the chance reads, the map's own reduction over runs alone
    without = {name: values for name, values in signals.items() if name != "pitch"}
    np.testing.assert_array_equal(evaluator.per_sample_values(without, context)["I_m"],
                                  whole.per_sample["I_m"])
    # the first chunk's values with the path's mean over all three runs
    across = evaluator.across_runs(signals, context)
    chunk = {name: values[:1] for name, values in signals.items()}
    np.testing.assert_array_equal(evaluator.per_sample_values(chunk, context, across=across)
                                  ["I_m"], whole.per_sample["I_m"][:1])
    np.testing.assert_array_equal(evaluator.per_sample_values(signals, context)["I_m"],
                                  whole.per_sample["I_m"])


@pytest.mark.parametrize("domain", ["time", "runs"])
def test_a_percentile_may_name_a_constant(domain):
    """Reducer parameters take constants (`const p = 50`), over time and over runs alike, with
    the same value as the number written in place."""
    operand = "abs(x)" if domain == "time" else "final over time (abs(x))"
    named = rulebook(f"const p = 50\nindex I {{\n  value = percentile p over {domain} "
                     f"({operand})\n  limit = 1 m\n  weight = 1\n}}\n")
    written = rulebook(f"index I {{\n  value = percentile 50 over {domain} ({operand})\n"
                       "  limit = 1 m\n  weight = 1\n}\n")
    signals, context = batch(3, x=X3)
    np.testing.assert_array_equal(evaluate(named, signals, context).raw["I"],
                                  evaluate(written, signals, context).raw["I"])


def test_a_constant_percentile_outside_0_to_100_is_E308_at_its_name():
    result = check(parse_rulebook(HEADER + "const p = 150\nindex I {\n  value = percentile p "
                                  "over time (abs(x))\n  limit = 1 m\n  weight = 1\n}\n" + FOOTER,
                                  "t.rules"))
    assert [(d.code, d.message) for d in result.errors] == [
        ("E308", "percentile needs a number from 0 to 100, got 150")]
    assert (result.errors[0].span.line, result.errors[0].span.column) == (5, 22)
