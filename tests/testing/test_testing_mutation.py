"""``idefix-verify test --mutate`` and ``--coverage`` over several case files of one rulebook:
scores, survivors with their place, exit codes."""

from __future__ import annotations

import json
from pathlib import Path

from idefix_rules.cli import main
from idefix_rules.testing import load_case_file
from idefix_rules.testing.mutation_score import score_mutants

RULEBOOK = """rulebook "tilt" version "1.0.0"
purpose "A roll index"

const critical_tilt = 10 deg

index I_psi "roll deviation" {
  value  = max over time (abs(roll - ref.roll))
  limit  = critical_tilt
  weight = 1
}

verdict acceptable_risk: require risk <= 70 %
"""
HEAD = """rulebook: tilt.rules
defaults:
  chain:
    - {max_wheel_rate: 0.04 rad/s, delta_position: 20 cm, delta_heading: 0 deg}
cases:
"""
HALF = """  half:
    signals: {roll: {0 s: 0 deg, 20 s: 5 deg, 40 s: 0 deg}}
    expect: {indices: {I_psi: 0.5}, risk: 0.5, verdict: pass}
"""
EDGES = """  just_inside:
    signals: {roll: {0 s: 0 deg, 20 s: 6.8 deg, 40 s: 0 deg}}
    expect: {verdict: pass}
  just_outside:
    signals: {roll: {0 s: 0 deg, 20 s: 7.3 deg, 40 s: 0 deg}}
    expect: {verdict: fail}
  tilted_reference:
    reference: {roll: 3 deg}
    signals: {roll: 3 deg}
    expect: {indices: {I_psi: 0}}
"""
BEYOND = """  beyond:
    signals: {roll: 12 deg}
    expect: {indices: {I_psi: 1}, verdict: fail}
"""


def write(folder: Path, **files: str) -> list[Path]:
    (folder / "tilt.rules").write_text(RULEBOOK, encoding="utf-8")
    paths = []
    for name, cases in files.items():
        path = folder / f"{name}.yaml"
        path.write_text(HEAD + cases, encoding="utf-8")
        paths.append(path)
    return paths


def test_survivors_are_listed_with_their_place_and_exit_1(tmp_path, capsys):
    [calm] = write(tmp_path, calm=HALF)
    assert main(["test", "--mutate", str(calm)]) == 1
    out = capsys.readouterr().out
    rules = tmp_path / "tilt.rules"
    assert f"SURVIVED {rules}:7:31 [drop] index I_psi: dropped - ref.roll" in out
    assert f"SURVIVED {rules}:12:34 [threshold] verdict acceptable_risk: threshold 70 % → 77 %" \
        in out
    assert f"SURVIVED {rules}:12:34 [threshold] verdict acceptable_risk: threshold 70 % → 63 %" \
        in out
    assert "mutation score: 72.7 % (8 of 11 mutants killed, 3 survived)" in out


def test_cases_just_inside_and_outside_kill_every_mutant(tmp_path, capsys):
    paths = write(tmp_path, calm=HALF, edges=EDGES)
    assert main(["test", "--mutate", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "SURVIVED" not in out
    assert "mutation score: 100.0 % (11 of 11 mutants killed, 0 survived)" in out
    assert f"against {paths[0]}, {paths[1]}" in out  # both files count


def test_min_mutation_score_gates_the_exit_code(tmp_path, capsys):
    [calm] = write(tmp_path, calm=HALF)
    assert main(["test", "--min-mutation-score", "72", str(calm)]) == 0
    assert main(["test", "--min-mutation-score", "73", str(calm)]) == 1
    assert "(minimum 73 %)" in capsys.readouterr().out
    assert main(["test", "--min-mutation-score", "101", str(calm)]) == 2
    assert main(["test", "--min-mutation-score", "0.73", str(calm)]) == 2  # 73 % meant?
    assert main(["test", "--min-mutation-score", "73%", str(calm)]) == 1
    assert main(["test", "--mutate", "--nudge", "0.5", str(calm)]) == 1  # 0.5 %: survivors
    assert main(["test", "--mutate", "--nudge", "0", str(calm)]) == 2
    err = capsys.readouterr()
    assert "T015" in err.out + err.err


def test_mutation_is_skipped_when_a_case_fails(tmp_path, capsys):
    [calm] = write(tmp_path, calm=HALF.replace("I_psi: 0.5", "I_psi: 0.6"))
    assert main(["test", "--mutate", str(calm)]) == 1
    assert "mutation testing skipped: the cases must pass first" in capsys.readouterr().out


def test_mutation_report_as_json(tmp_path, capsys):
    [calm] = write(tmp_path, calm=HALF)
    assert main(["test", "--mutate", "--format", "json", str(calm)]) == 1
    [report] = json.loads(capsys.readouterr().out)["mutation"]
    assert (report["mutants"], report["killed"], report["survived"]) == (11, 8, 3)
    drop = next(s for s in report["survivors"] if s["category"] == "drop")
    assert (drop["line"], drop["column"], drop["change"]) == (7, 31, "dropped - ref.roll")


def test_a_nudge_is_killed_only_by_cases_closer_to_the_threshold_than_it(tmp_path):
    # the verdict's risk limit 70 %: the cases give 68 % (2.9 % below) and 73 % (4.3 % above);
    # a 5 % nudge (66.5 %, 73.5 %) moves it past both, a 4 % nudge (67.2 %, 72.8 %) only
    # past the one below
    write(tmp_path, calm=HALF, edges=EDGES)
    files = [load_case_file(tmp_path / "calm.yaml"), load_case_file(tmp_path / "edges.yaml")]
    assert score_mutants(files, 0.05).survivors == []
    survivors = {str(r.mutant) for r in score_mutants(files, 0.04).survivors}
    assert survivors == {"verdict acceptable_risk: threshold 70 % → 72.8 %"}


def test_coverage_is_summed_over_the_case_files_of_a_rulebook(tmp_path, capsys):
    calm, beyond = write(tmp_path, calm=HALF, beyond=BEYOND)
    assert main(["test", "--min-coverage", "100", str(calm)]) == 1
    assert main(["test", "--min-coverage", "100", str(beyond)]) == 1
    capsys.readouterr()
    assert main(["test", "--min-coverage", "100", str(calm), str(beyond)]) == 0
    out = capsys.readouterr().out
    assert f"(2 cases from {calm} (1), {beyond} (1))" in out
    assert "rule coverage: 100 % of rules brought across their limit (minimum 100 %)" in out
    assert main(["test", "--coverage", "--format", "json", str(tmp_path)]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["coverage_percent"] == 100.0
    [group] = data["coverage_rulebooks"]
    assert group["files"] == [str(beyond), str(calm)]  # folder order: sorted
    cases = {item["name"]: item["cases"] for item in data["coverage"]}
    assert cases["I_psi"] == ["beyond.yaml:beyond", "calm.yaml:half"]
