"""An index's ``nominal`` on the command line: check, fmt and explain."""

from __future__ import annotations

from pathlib import Path

from idefix_rules.cli import main

RULEBOOK = """rulebook "graded" version "1.0.0"
purpose "A graded slip index"

const nominal_slip  = 20 %
const critical_slip = 70 %

index I_s "wheel slip ratio" {
  value   = percentile 95 over time (max over wheels (abs(wheel.slip)))
  nominal = nominal_slip
  limit   = critical_slip
  weight  = 1
}

verdict acceptable_risk: require risk <= 70 %
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "graded.rules"
    path.write_text(text, encoding="utf-8")
    return path


def test_check_fmt_and_strict_accept_a_graded_index(tmp_path, capsys):
    path = write(tmp_path, RULEBOOK)
    assert main(["check", "--strict", str(path)]) == 0
    assert main(["fmt", "--check", str(path)]) == 0
    capsys.readouterr()


def test_a_nominal_above_the_limit_exits_2_at_its_line_and_column(tmp_path, capsys):
    path = write(tmp_path, RULEBOOK.replace("const nominal_slip  = 20 %",
                                            "const nominal_slip  = 75 %"))
    assert main(["check", str(path)]) == 2
    out = capsys.readouterr()
    text = out.out + out.err
    assert f"{path}:9:13: error[E408]: the nominal of index 'I_s' must be below its limit" in text


def test_fmt_moves_the_nominal_after_the_value(tmp_path, capsys):
    messy = RULEBOOK.replace("  nominal = nominal_slip\n", "").replace(
        "  weight  = 1\n", "  weight  = 1\n  nominal = nominal_slip\n")
    path = write(tmp_path, messy)
    assert main(["fmt", str(path)]) == 0
    assert path.read_text(encoding="utf-8") == RULEBOOK
    capsys.readouterr()


def test_explain_shows_the_nominal_with_its_si_value(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")  # one table row per line
    path = write(tmp_path, RULEBOOK)
    assert main(["explain", str(path)]) == 0
    out = capsys.readouterr().out
    assert "critical_slip (= 0.7)" in out and "nominal (0.5): nominal_slip (= 0.2)" in out


def test_explain_error_knows_the_nominal_codes(capsys):
    for code in ("E407", "E408", "W614"):
        assert main(["explain-error", code]) == 0
        assert "nominal" in capsys.readouterr().out
