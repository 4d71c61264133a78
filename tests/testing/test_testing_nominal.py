"""Rule tests of a graded index (``nominal``): case files, failure texts and mutants."""

from __future__ import annotations

from pathlib import Path

from idefix_rules.cli import main
from idefix_rules.rulebook import check, check_text
from idefix_rules.testing.mutations import mutants

RULEBOOK = """rulebook "graded" version "1.0.0"
purpose "A graded slip index"

index I_s "wheel slip ratio" {
  value   = percentile 95 over time (max over wheels (abs(wheel.slip)))
  nominal = 20 %
  limit   = 70 %
  weight  = 1
}

verdict acceptable_risk: require risk <= 70 %
"""


def write(tmp_path: Path, cases: str) -> Path:
    (tmp_path / "graded.rules").write_text(RULEBOOK, encoding="utf-8")
    path = tmp_path / "cases.yaml"
    path.write_text("rulebook: graded.rules\ndefaults:\n  chain:\n"
                    "    - {max_wheel_rate: 0.04 rad/s, delta_position: 20 cm, "
                    "delta_heading: 0 deg}\ncases:\n" + cases, encoding="utf-8")
    return path


def test_cases_see_the_graded_index(tmp_path, capsys):
    path = write(tmp_path, """  expected_slip:
    signals: {"wheel.slip[FL]": 20 %}
    expect: {indices: {I_s: 0.5}}
  between:
    signals: {"wheel.slip[FL]": 45 %}
    expect: {indices: {I_s: 0.75}}
""")
    assert main(["test", str(path)]) == 0
    assert capsys.readouterr().out.strip().splitlines()[-1].startswith("2 passed in ")


def test_a_failure_names_the_nominal_and_the_limit(tmp_path, capsys):
    path = write(tmp_path, """  between:
    signals: {"wheel.slip[FL]": 45 %}
    expect: {indices: {I_s: 0.643}}
""")
    assert main(["test", str(path)]) == 1
    out = capsys.readouterr().out
    assert "index I_s: expected 0.643 ± 0.005, got 0.75" in out
    assert "nominal = 20 % (= 0.2 SI); limit = 70 % (= 0.7 SI)" in out
    assert "raw value 0.45 against the nominal 0.2 (0.5) and the limit 0.7 (1)" in out
    assert "on the index's 0..1 scale" in out


def test_every_mutant_of_a_graded_index_is_a_valid_rulebook():
    model = check_text(RULEBOOK, "graded.rules").checked
    assert model is not None
    found = {m.change: check(m.rulebook) for m in mutants(model.rulebook) if m.rule == "I_s"}
    assert {"limit 70 % → 77 %", "limit 70 % → 63 %", "limit and nominal × 0.9",
            "nominal 20 % → 22 %", "nominal 20 % → 18 %", "weight 1 → 0.5",
            "max over wheels → sum over wheels",
            "percentile 95 over time → percentile 90 over time"} <= set(found)
    assert "max over wheels → final over wheels" not in found  # final only over time
    assert all(result.ok for result in found.values()), [
        change for change, result in found.items() if not result.ok]
    lowered = found["limit and nominal × 0.9"].checked
    assert lowered is not None
    assert (lowered.limits["I_s"], lowered.nominals["I_s"]) == (0.63, 0.18)
