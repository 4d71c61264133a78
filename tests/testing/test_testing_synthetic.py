"""Synthetic runs of a case: the nominal run, keyframes, offsets, collisions, the reference."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from idefix_rules.testing.casefile import parse_case_file
from idefix_rules.testing.synthetic import build_runs

# the frozen operations rulebook 1.1.0 (tests/fixtures/rulebooks), not the live one
RULEBOOK = Path(__file__).parents[1] / "fixtures" / "rulebooks" / "idefix-ops-1.1.0.rules"


def case(body: str):
    text = f"""rulebook: {RULEBOOK}
defaults:
  chain:
    - {{max_wheel_rate: 0.04 rad/s, delta_position: 20 cm, delta_heading: 0 deg}}
cases:
  c:
{body}
    expect: {{verdict: pass}}
"""
    return parse_case_file(text, "cases.yaml").cases[0]


def test_the_nominal_run_follows_the_chain():
    signals, context = build_runs(case("    runs: 2"))
    t = signals["t"][0]
    assert t[0] == 0 and t[-1] == pytest.approx(55.0)  # 50 s of driving, 5 s standing
    assert signals["x"].shape == (2, len(t))
    assert signals["x"][0, 25] == pytest.approx(0.1)  # 4 mm/s for 25 s
    assert signals["x"][0, -1] == pytest.approx(0.2)
    assert set(np.unique(signals["command"])) == {0.0, -1.0}
    assert np.all(signals["wheel.slip"] == 0)
    assert np.all(signals["collision.clearance"] == 1.0)
    np.testing.assert_array_equal(context.reference["x"], signals["x"][0])


def test_keyframes_are_linear_and_held_and_flags_step():
    signals, _ = build_runs(case("""    signals:
      wheel.slip[FL]: {10 s: 10 %, 20 s: 80 %}
      stuck: {0 s: 0, 30 s: 1}"""))
    slip = signals["wheel.slip"][0]
    assert slip[0, 0] == pytest.approx(0.1)       # held before the first keyframe
    assert slip[15, 0] == pytest.approx(0.45)     # linear in between
    assert slip[40, 0] == pytest.approx(0.8)      # held after the last
    assert np.all(slip[:, 1:] == 0)               # the other wheels untouched
    stuck = signals["stuck"][0]
    assert stuck[29] == 0 and stuck[30] == 1 and stuck[15] == 0


def test_offsets_add_and_collisions_count():
    signals, _ = build_runs(case("""    offsets:
      y: {0 s: 0 cm, 10 s: 1 cm}
    collisions:
      - {part: chassis, level: L2, from: 5 s, to: 7 s}
      - {part: wheel, level: L1, buffer: true, at: 9 s}"""))
    assert signals["y"][0, 10] == pytest.approx(0.01)
    assert signals["x"][0, 10] == pytest.approx(0.04)  # x still nominal
    hits = signals["collision.hits"][0]
    assert hits[2, 1] == 1 and hits.sum() == 1
    assert signals["collision.buffer"][0][0, 0] == 1
    contact = signals["collision.contact"][0][:, 2, 1]
    assert contact[5:8].tolist() == [1, 1, 1] and contact.sum() == 3
    assert signals["collision.clearance"][0][6, 2] == 0


def test_the_reference_run_can_be_shaped_and_variants_add_up():
    c = case("""    reference:
      roll: {0 s: 0 deg, 20 s: 10 deg}
    variants:
      - {count: 3}
      - count: 1
        signals: {roll: {0 s: 0 deg, 20 s: 10 deg}}""")
    signals, context = build_runs(c)
    assert signals["roll"].shape[0] == 4 == c.runs
    assert np.all(signals["roll"][:3] == 0)
    assert context.reference["roll"][20] == pytest.approx(np.radians(10))
    np.testing.assert_allclose(signals["roll"][3], context.reference["roll"])


def test_every_signal_holds_its_last_own_sample_after_the_run_ends():
    """The chain ends at 50 s and the pose rests from there: from t = 51 s every signal holds
    (a campaign's runner holds the FMU's outputs so), and a ramp past it shapes nothing, so
    `max` and `percentile 100` read the same value."""
    signals, _ = build_runs(case("""    signals:
      wheel.slip[FL]: {0 s: 0 %, 55 s: 55 %}"""))
    slip = signals["wheel.slip"][0, :, 0]
    assert slip[50] == pytest.approx(0.50) and slip[51] == pytest.approx(0.51)
    assert np.all(slip[51:] == slip[51])
    kept, _ = build_runs(case("""    offsets:
      x: {50 s: 0 cm, 55 s: 1 cm}
    signals:
      wheel.slip[FL]: {0 s: 0 %, 55 s: 55 %}"""))  # still moving to the end: its own
    assert kept["wheel.slip"][0, -1, 0] == pytest.approx(0.55)
    unfinished, _ = build_runs(case("""    unfinished: true
    signals:
      wheel.slip[FL]: {0 s: 0 %, 55 s: 55 %}"""))
    assert unfinished["wheel.slip"][0, -1, 0] == pytest.approx(0.55)
