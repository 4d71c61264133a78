"""``idefix-verify test``: exit codes, located mistakes, expected-vs-actual failures."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from idefix_rules.cli import main

# the frozen operations rulebook 1.1.0 (tests/fixtures/rulebooks), not the live one
RULEBOOK = Path(__file__).parents[1] / "fixtures" / "rulebooks" / "idefix-ops-1.1.0.rules"

HEAD = f"""rulebook: {RULEBOOK}
defaults:
  chain:
    - {{max_wheel_rate: 0.04 rad/s, delta_position: 20 cm, delta_heading: 0 deg}}
cases:
"""


def write(tmp_path: Path, body: str, name: str = "cases.yaml") -> Path:
    path = tmp_path / name
    path.write_text(HEAD + body, encoding="utf-8")
    return path


def test_a_passing_file_exits_0_with_the_summary(tmp_path, capsys):
    path = write(tmp_path, """  slip:
    signals: {"wheel.slip[FL]": 35 %}
    expect: {indices: {I_s: 0.5}, dominant: I_s}
""")
    assert main(["test", str(path)]) == 0
    assert capsys.readouterr().out.strip().splitlines()[-1].startswith("1 passed in ")


def test_summary_counts_passed_and_failed_and_exits_1(tmp_path, capsys):
    path = write(tmp_path, """  slip_ok:
    signals: {"wheel.slip[FL]": 35 %}
    expect: {indices: {I_s: 0.5}}
  slip_wrong:
    signals: {"wheel.slip[FL]": 35 %}
    expect: {indices: {I_s: 0.7}}
""")
    assert main(["test", str(path)]) == 1
    out = capsys.readouterr().out
    assert out.strip().splitlines()[-1].startswith("1 failed, 1 passed in ")
    assert "FAILED" in out and "slip_wrong" in out
    assert f"{path}:11:" in out  # the expectation's line
    assert "index I_s: expected 0.7 ± 0.005, got 0.5" in out
    assert "rule: index I_s: value = percentile 95 over time" in out
    assert "raw value 0.35 against the limit 0.7" in out


def test_threshold_just_inside_and_just_outside_the_tolerance(tmp_path, capsys):
    inside = write(tmp_path, """  c:
    signals: {"wheel.slip[FL]": 35 %}
    expect: {indices: {I_s: {value: 0.504, tolerance: 0.005}}}
""", "inside.yaml")
    outside = write(tmp_path, """  c:
    signals: {"wheel.slip[FL]": 35 %}
    expect: {indices: {I_s: {value: 0.506, tolerance: 0.005}}}
""", "outside.yaml")
    assert main(["test", str(inside)]) == 0
    assert main(["test", str(outside)]) == 1


@pytest.mark.parametrize(("body", "code", "where", "words"), [
    ("""  c:
    signals: {"wheel.slp[FL]": 35 %}
    expect: {verdict: pass}
""", "T004", ":7:15:", "did you mean 'wheel.slip'"),
    ("""  c:
    signals: {"area.highly_inclned.inside": 1}
    expect: {chances: {on_steep: false}}
""", "T004", ":7:15:", "the rulebook declares no area 'highly_inclned'"),
    ("""  c:
    signals: {"wheel.slip[FL]": 35 %, "wheel.slip[ FL ]": 5 %}
    expect: {verdict: pass}
""", "T006", ":7:39:", "'wheel.slip[ FL ]' shapes what 'wheel.slip[FL]' already shapes"),
    ("""  c:
    signals: {"wheel.slip[FL]": 35 %, "wheel.slip": 5 %}
    expect: {verdict: pass}
""", "T006", ":7:39:", "'wheel.slip' shapes what 'wheel.slip[FL]' already shapes"),
    ("""  c:
    collisions: [{part: wheel, level: L2, at: 3 s, from: 2 s, to: 4 s}]
    expect: {verdict: pass}
""", "T010", ":7:", "not both"),
    ("""  c:
    signals: {"wheel.slip[FL]": 35 %}
    expect: {indices: {I_s: {value: 0.5, at_least: 0.4}}}
""", "T009", ":8:", "not both"),
    ("""  c:
    chain: [{max_wheel_rate: 0 rad/s, delta_position: 20 cm, delta_heading: 0 deg}]
    expect: {verdict: pass}
""", "T007", ":7:", "max_wheel_rate must be above 0 rad/s"),
    ("""  c:
    signals: {roll: {0 s: 0 deg, 20 s: 20}}
    expect: {verdict: pass}
""", "T005", ":7:", "must be an angle"),
    ("""  c:
    signals: {roll: {10 s: 0 deg, 5 s: 2 deg}}
    expect: {verdict: pass}
""", "T006", ":7:", "increase"),
    ("""  c:
    expect: {indices: {I_slip: 0.5}}
""", "T008", ":7:24:", "did you mean 'I_s'"),
    ("""  c:
    expect: {verdict: maybe}
""", "T009", ":7:", "expected pass or fail"),
    ("""  c:
    collisions: [{part: wing, level: L2, at: 3 s}]
    expect: {verdict: pass}
""", "T010", ":7:", "part must be one of"),
    ("""  c:
    expectt: {verdict: pass}
""", "T011", ":7:5:", "unknown key 'expectt'"),
    ("""  c:
    runs: 0
    expect: {verdict: pass}
""", "T012", ":7:", "whole number"),
    ("""  c:
    chain: [{max_wheel_rate: 0.04, delta_position: 20 cm, delta_heading: 0 deg}]
    expect: {verdict: pass}
""", "T005", ":7:", "an angular rate"),
    ("""  c:
    signals: {"wheel.slip[FL]": 35 %}
""", "T002", ":6:3:", "expects nothing"),
    # 'done' is read only where a run has no 'command', and a case's runs have one
    ("""  c:
    signals: {done: 0}
    expect: {verdict: pass}
""", "T004", ":7:15:", "follows the chain's commands (a run whose chain does not finish: "
        "'unfinished: true')"),
    # a keyframe after the run's end shaped nothing (a slip ramp dropped, a hit moved to the end)
    ("""  c:
    duration: 10 s
    signals: {"wheel.slip[FL]": {0 s: 0 %, 10.5 s: 90 %}}
    expect: {verdict: pass}
""", "T005", ":7:", "a keyframe or collision at 10.5 s lies after the run's end (duration 10 s)"),
    ("""  c:
    duration: 10 s
    collisions: [{part: wheel, level: L3, at: 30 s}]
    expect: {verdict: fail}
""", "T005", ":7:", "at 30 s lies after the run's end"),
    # this rulebook reads `failed` (runs_complete): it gets no no_failed_runs rule
    ("""  c:
    expect: {verdicts: {no_failed_runs: pass}}
""", "T008", ":7:25:", "the rulebook has no verdict 'no_failed_runs'"),
    ("""  c:
    expect: {rejected: {min_motion: [2]}}
""", "T009", ":7:", "command 2 of 'min_motion': the case's chain has 1 command"),
    # a hit before the run counted as one (I_obs 1, hit_L3 true): refused at its time
    ("""  c:
    collisions: [{part: chassis, level: L3, at: -5 s}]
    expect: {verdict: fail}
""", "T010", ":7:", "a collision at -5 s lies before the run's start"),
    ("""  c:
    collisions: [{part: chassis, level: L3, from: -10 s, to: -5 s}]
    expect: {verdict: fail}
""", "T010", ":7:", "a collision from -10 s lies before the run's start"),
    ("""  c:
    collisions: [{part: chassis, level: L3, from: 0 s, to: 1 s}]
    expect: {indices: {I_s: {at_least: 0.6, at_most: 0.4}}}
""", "T009", ":8:", "the expected range (≥ 0.6 and ≤ 0.4) is empty"),
    ("""  c:
    expect: {indices: {I_s: 1.5}}
""", "T009", ":7:", "an index or a risk lies in [0, 1], so the expected 1.5 ± "),
    ("""  c:
    expect: {risk: {at_least: 70}}
""", "T009", ":7:", "so the expected ≥ 70 can never hold"),
    # a keyframe time is a value: one without its unit is said so, read as written
    ("""  c:
    signals: {"wheel.slip[FL]": {0: 10 %, 20 s: 80 %}}
    expect: {verdict: pass}
""", "T005", ":7:33:", "keyframe time '0' must be a duration, got a ratio (a bare number)"),
    # a case's name is a name: one YAML reads as a number is refused at it, quoted in the hint
    ("""  1:
    expect: {verdict: pass}
""", "T001", ":6:3:", 'the key 1 is read by YAML as a whole number, not as a name\n'),
    ("""  c:
    variants:
      - {count: 1, offsets: {x: {0 s: 0 cm, 1.5: 1 cm}}}
    expect: {verdict: pass}
""", "T005", ":8:", "keyframe time '1.5' must be a duration"),
    # longer than a double: T005 like any chain too long, not an OverflowError
    ("""  c:
    chain: [{max_wheel_rate: 0.04 rad/s, delta_position: 1e308 m, delta_heading: 0 deg}]
    expect: {verdict: pass}
""", "T005", ":6:", "the case's run would have inf samples"),
])
def test_a_broken_case_file_exits_2_naming_line_and_column(tmp_path, capsys, body, code,
                                                              where, words):
    path = write(tmp_path, body)
    assert main(["test", str(path)]) == 2
    err = capsys.readouterr()
    text = err.out + err.err
    assert f"[{code}]" in text
    assert f"{path}{where}" in text
    assert words in text
    assert "Traceback" not in text


@pytest.mark.parametrize("name", ["ops.rules", "ops.txt"])
def test_a_rulebook_named_as_the_case_file_is_said_to_be_one(tmp_path, capsys, name):
    """`idefix-verify test rulebooks/idefix-ops.rules` said only 'invalid YAML: mapping values
    are not allowed here' at a line of the rulebook."""
    rulebook = tmp_path / name
    rulebook.write_text(RULEBOOK.read_text(encoding="utf-8"), encoding="utf-8")
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "ops.yaml").write_text(
        f"rulebook: ../{name}\ncases: {{c: {{expect: {{verdict: pass}}}}}}\n", encoding="utf-8")
    assert main(["test", str(rulebook)]) == 2
    out = capsys.readouterr().out
    assert f"{rulebook}: error[T001]: {rulebook} is a rulebook, not a case file" in out
    assert f"its case files: {tmp_path / 'tests' / 'ops.yaml'};" in out
    assert "YAML:" not in out and "Traceback" not in out


def test_invalid_yaml_and_missing_rulebook_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("rulebook: x.rules\ncases: [\n", encoding="utf-8")
    assert main(["test", str(bad)]) == 2
    assert "[T001]" in capsys.readouterr().out
    missing = tmp_path / "missing.yaml"
    missing.write_text("rulebook: nowhere.rules\ncases: {c: {expect: {verdict: pass}}}\n",
                       encoding="utf-8")
    assert main(["test", str(missing)]) == 2
    out = capsys.readouterr().out
    assert "[T003]" in out and f"{missing}:1:" in out
    assert main(["test", str(tmp_path / "none")]) == 2


def test_no_case_files_in_a_folder_exits_2(tmp_path, capsys):
    assert main(["test", str(tmp_path)]) == 2
    assert "[T013]" in capsys.readouterr().err


def test_json_output_carries_mismatches(tmp_path, capsys):
    path = write(tmp_path, """  c:
    signals: {"wheel.slip[FL]": 35 %}
    expect: {dominant: I_pos}
""")
    assert main(["test", "--format", "json", str(path)]) == 1
    data = json.loads(capsys.readouterr().out)
    mismatch = data["files"][0]["cases"][0]["mismatches"][0]
    assert (mismatch["expected"], mismatch["actual"]) == ("I_pos", "I_s")
    assert data["failed"] == 1 and data["exit_code"] == 1


def test_min_coverage_gates_the_exit_code(tmp_path, capsys):
    path = write(tmp_path, """  c:
    signals: {"wheel.slip[FL]": 80 %}
    expect: {indices: {I_s: 1}}
  d:
    expect: {indices: {I_s: 0}}
""")
    assert main(["test", "--min-coverage", "5", str(path)]) == 0
    assert main(["test", "--min-coverage", "50", str(path)]) == 1
    out = capsys.readouterr().out
    assert "rule coverage:" in out and "(minimum 50 %)" in out
    assert main(["test", "--min-coverage", "150", str(path)]) == 2
    # the sign may be written; a bare fraction is refused, since a 0.5 % gate passes anything
    assert main(["test", "--min-coverage", "50%", str(path)]) == 1
    assert main(["test", "--min-coverage", "5%", str(path)]) == 0
    capsys.readouterr()
    assert main(["test", "--min-coverage", "0.5", str(path)]) == 2
    err = capsys.readouterr()
    assert "error[T014]: --min-coverage 0.5 would be 0.5 %, which looks like a fraction" \
        in err.out + err.err
    assert "write --min-coverage 50 for 50 %, or --min-coverage 0.5% if 0.5 % is meant" \
        in err.out + err.err
    assert main(["test", "--min-coverage", "0.5%", str(path)]) == 0  # said so: 0.5 %
    assert main(["test", "--min-coverage", "1", str(path)]) == 0  # 1 %: no fraction
    assert main(["test", "--min-coverage", "1.0", str(path)]) == 2  # 100 % meant?
    assert main(["test", "--min-coverage", "most", str(path)]) == 2


def test_coverage_states_across_near_and_untouched(tmp_path, capsys):
    path = write(tmp_path, """  c:
    signals: {"wheel.slip[FL]": 80 %, roll: {0 s: 0 deg, 20 s: 10 deg}}
    expect: {indices: {I_s: 1}}
  d:
    expect: {indices: {I_s: 0}}
""")
    assert main(["test", "--coverage", "--format", "json", str(path)]) == 0
    states = {item["name"]: item["state"] for item in json.loads(capsys.readouterr().out)
              ["coverage"]}
    assert states["I_s"] == "across"       # 80 % and 0 %: both sides of 70 %
    assert states["I_psi"] == "near"       # 10 deg: within a factor 2 of 15 deg
    assert states["I_ds"] == "untouched"   # never sank
    assert states["min_motion"] == "untouched"  # 20 cm against 5 cm: a factor 4 away


@pytest.mark.parametrize("body", [
    "  c:\n    duration: -5 s\n    expect: {verdict: pass}\n",
    "  c:\n    duration: 1000000 s\n    expect: {verdict: pass}\n",
    "  c:\n    step: 0 s\n    expect: {verdict: pass}\n",
    "  c:\n    runs: 1000000000\n    expect: {verdict: pass}\n",
    "  c:\n    signals: {roll: {1000000000 s: 1 deg}}\n    expect: {verdict: pass}\n",
    "  c:\n    signals: {stuck: {0 s: true}}\n    expect: {verdict: pass}\n",
    "  c:\n    signals: {roll: [1, 2]}\n    expect: {verdict: pass}\n",
    "  c:\n    expect: {indices: 5}\n",
    "  c:\n    chain: x\n    expect: {verdict: pass}\n",
    "  c:\n    runs: 2\n    variants: [{count: 1}]\n    expect: {verdict: pass}\n",
    "  c: 5\n",
    "  c:\n    expect: {rejected: {min_motion: [0]}}\n",
    "  c:\n    unfinished: 5\n    expect: {verdict: pass}\n",
])
def test_odd_case_files_are_user_errors_never_tracebacks(tmp_path, capsys, body):
    path = write(tmp_path, body)
    assert main(["test", str(path)]) == 2
    captured = capsys.readouterr()
    assert "Traceback" not in captured.out + captured.err
    assert f"{path}:" in captured.out


def test_a_zero_tolerance_is_kept(tmp_path):
    path = write(tmp_path, "  c:\n    signals: {\"wheel.slip[FL]\": 35 %}\n"
                           "    expect: {indices: {I_s: 0.5}}\n")
    path.write_text(path.read_text(encoding="utf-8").replace("defaults:", "tolerance: 0\n"
                                                             "defaults:"), encoding="utf-8")
    assert main(["test", str(path)]) == 0  # 0.35 / 0.7 is exactly 0.5


def test_a_chance_failure_says_where_its_time_reduction_found_the_value(tmp_path, capsys):
    path = write(tmp_path, """  jolt:
    offsets:
      x: {10 s: 0 cm, 12 s: 2 cm}
    expect: {chances: {too_fast: false}}
  stuck:
    signals: {stuck: {0 s: 0, 30 s: 1}}
    expect: {chances: {got_stuck: false}}
""")
    assert main(["test", str(path)]) == 1
    out = capsys.readouterr().out
    assert "chance too_fast: expected does not hold, got holds" in out
    assert "from: run 1: speed is highest at t = 11 s (sample 11): 0.014 (SI)" in out
    assert "from: run 1: stuck > 0 first holds at t = 30 s (sample 30)" in out


PATH_LEVEL = '''rulebook "avg" version "1.0.0"
purpose "a path-level chance"
index I_x "x" {
  value  = final over time (x)
  limit  = 1 m
  weight = 1
  because "x"
}
chance off_course = final over time (abs(mean over runs (y - ref.y))) > 1 cm
  because "the average position of the runs"
verdict kept: require chance(off_course) < 50 %
  because "kept"
'''


def test_coverage_of_a_chance_over_the_runs_of_a_path_is_computed(tmp_path, capsys):
    # a chance reading a reduction over runs needs its path-level value before its leaves can
    # be compared: coverage computes it over the case's runs, as the evaluation does
    rules = tmp_path / "avg.rules"
    rules.write_text(PATH_LEVEL, encoding="utf-8")
    cases = tmp_path / "avg.yaml"
    cases.write_text(f"""rulebook: {rules}
defaults:
  chain:
    - {{max_wheel_rate: 0.04 rad/s, delta_position: 20 cm, delta_heading: 0 deg}}
cases:
  inside:
    runs: 2
    offsets: {{y: {{0 s: 0 mm, 50 s: 6 mm}}}}
    expect: {{chances: {{off_course: false}}}}
  outside:
    runs: 2
    offsets: {{y: {{0 s: 0 mm, 50 s: 14 mm}}}}
    expect: {{chances: {{off_course: true}}}}
""", encoding="utf-8")
    assert main(["test", "--coverage", "--format", "json", str(cases)]) == 0
    captured = capsys.readouterr()
    assert "Traceback" not in captured.out + captured.err
    states = {item["name"]: item["state"] for item in json.loads(captured.out)["coverage"]}
    assert states["off_course"] == "across"  # 6 and 14 mm: both sides of 1 cm


def test_a_keyframe_at_the_runs_end_shapes_its_last_sample(tmp_path, capsys):
    """Just inside: a keyframe at the duration itself is the run's last sample."""
    path = write(tmp_path, """  at_the_end:
    duration: 10 s
    signals: {"wheel.slip[FL]": {0 s: 0 %, 10 s: 90 %}}
    expect: {verdict: fail}
""")
    assert main(["test", str(path)]) == 0, capsys.readouterr().out


def test_a_folder_is_searched_for_case_files_only_and_each_file_counts_once(tmp_path, capsys):
    """A project folder holds campaign files too (YAML naming a rulebook, but no `cases:`):
    they are no case files. A case file named twice (itself and its folder) runs once."""
    cases = write(tmp_path, """  slip:
    signals: {"wheel.slip[FL]": 35 %}
    expect: {verdict: pass}
""")
    campaigns = tmp_path / "campaigns"
    campaigns.mkdir()
    (campaigns / "site.yaml").write_text(f"name: site\nrulebook: {RULEBOOK}\npaths: {{}}\n")
    assert main(["test", str(tmp_path), str(cases)]) == 0
    out = capsys.readouterr().out
    assert "1 passed" in out and "site.yaml" not in out


def test_no_case_files_with_json_output_is_json(tmp_path, capsys):
    assert main(["test", "--format", "json", str(tmp_path)]) == 2
    data = json.loads(capsys.readouterr().out)
    assert data["exit_code"] == 2 and data["broken"][0]["code"] == "T013"


def test_a_case_file_over_its_size_limit_is_refused_before_it_is_read(tmp_path, capsys):
    from idefix_rules.limits import MAX_CASE_FILE_BYTES

    path = write(tmp_path, """  slip:
    signals: {"wheel.slip[FL]": 35 %}
    expect: {verdict: pass}
""")
    padding = MAX_CASE_FILE_BYTES - path.stat().st_size
    path.write_text(path.read_text() + "#" * (padding - 1) + "\n")  # just at the limit
    assert main(["test", str(path)]) == 0
    path.write_text(path.read_text() + "#\n")  # just over it
    assert main(["test", str(path)]) == 2
    assert "error[T001]: case file" in capsys.readouterr().out


def test_flags_in_a_case_file_take_yes_and_no_as_before(tmp_path, capsys):
    """Case files read only true/false as booleans (YAML 1.2), but a flag (unfinished, a
    collision's buffer, decided, a chance's expectation) still takes yes/no/on/off."""
    path = write(tmp_path, """  calm:
    unfinished: no
    collisions: [{part: wheel, level: L1, at: 3 s, buffer: yes}]
    expect: {chances: {hit_L3: no}, decided: no}
""")
    assert main(["test", str(path)]) == 0, capsys.readouterr().out


def test_a_huge_yaml_file_in_a_folder_is_refused_unread(tmp_path, monkeypatch, capsys):
    from idefix_rules.limits import MAX_CASE_FILE_BYTES
    from idefix_rules.testing import casefile

    huge = tmp_path / "big.yaml"
    huge.write_bytes(b"#" * (MAX_CASE_FILE_BYTES + 10))
    read: list[str] = []
    real = Path.read_text

    def watched(self: Path, *args: object, **kwargs: object) -> str:
        read.append(self.name)
        return real(self, *args, **kwargs)

    monkeypatch.setattr(casefile.Path, "read_text", watched)
    assert main(["test", str(tmp_path)]) == 2
    assert "big.yaml" not in read and "error[T001]" in capsys.readouterr().out


def test_a_mistake_in_the_defaults_is_said_once_not_once_per_case(tmp_path, capsys):
    path = write(tmp_path, """  a:
    expect: {risk: 0}
  b:
    expect: {risk: 0}
""")
    path.write_text(path.read_text().replace("defaults:\n", "defaults:\n  step: 0 s\n"))
    assert main(["test", str(path)]) == 2
    out = capsys.readouterr()
    assert (out.out + out.err).count("error[T005]: step must be above 0 s") == 1
