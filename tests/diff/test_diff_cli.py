"""``idefix-verify diff`` on rules only: text, JSON, exit codes and user errors (exit 2)."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import h5py
import pytest

from idefix_rules.cli import main

OLD = """\
rulebook "cli-test" version "1.0.0"
purpose "Diff through the command line"

const critical_slip = 70 % because "Slip above 70 % is critical"

index I_s "slip" {
  value  = max over time (max over wheels (abs(wheel.slip)))
  limit  = critical_slip
  weight = 1
}

verdict acceptable_risk: require risk <= 75 % because "Risk limit"
"""

NEW = OLD.replace('version "1.0.0"', 'version "1.1.0"').replace("= 70 %", "= 65 %") \
    .replace("risk <= 75 %", "risk <= 70 %")


@pytest.fixture
def rules(tmp_path: Path) -> tuple[Path, Path]:
    old, new = tmp_path / "old.rules", tmp_path / "new.rules"
    old.write_text(OLD)
    new.write_text(NEW)
    return old, new


def run(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main(["diff", *args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_a_rule_diff_prints_changes_with_si_values_and_rationales(
        rules: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, str(rules[0]), str(rules[1]))
    assert code == 0  # a rule diff alone never fails
    assert "cli-test 1.0.0" in out and "cli-test 1.1.0" in out
    assert "70 % → 65 %" in out
    assert "[0.7 → 0.65]" in out
    assert "risk <= 75 % → risk <= 70 %" in out
    assert "Slip above 70 % is critical" in out
    assert "reads changed: critical_slip" in out


def test_identical_rules_say_so(rules: tuple[Path, Path],
                                capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, str(rules[0]), str(rules[0]))
    assert code == 0
    assert "the rules are the same" in out


def test_json_output_is_the_data(rules: tuple[Path, Path],
                                 capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, str(rules[0]), str(rules[1]), "--format", "json")
    data = json.loads(out)
    assert code == 0 and data["exit_code"] == 0
    assert data["results"] is None
    assert data["rules"]["new"]["version"] == "1.1.0"
    kinds = {(c["section"], c["name"]): c["kind"] for c in data["rules"]["changes"]}
    assert kinds == {("header", "header"): "changed", ("constant", "critical_slip"): "changed",
                     ("index", "I_s"): "changed", ("verdict", "acceptable_risk"): "changed"}


def test_help_describes_the_command(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["diff", "--help"]) == 0
    out = capsys.readouterr().out
    assert "--results" in out and "--fail-on" in out and "PATH@REV" in out


def test_a_missing_rulebook_exits_2(rules: tuple[Path, Path], tmp_path: Path,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, str(tmp_path / "nope.rules"), str(rules[1]))
    assert code == 2
    assert "rulebook file not found" in err and "Traceback" not in err


@pytest.mark.parametrize(("spec", "said"), [
    ("@HEAD", "@HEAD: error[D005]: the path before '@' is empty"),
    ("{folder}/@HEAD", "{folder}/@HEAD: error[D005]: the path before '@' names the folder "
                       "{folder}/"),
    ("{folder}@v1", "{folder}@v1: error[D005]: the path before '@' names the folder {folder}")])
def test_a_revision_without_a_rulebook_file_before_it_exits_2(
        spec: str, said: str, rules: tuple[Path, Path], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, spec.format(folder=tmp_path), str(rules[1]))
    assert code == 2
    assert said.format(folder=tmp_path) in err and "Traceback" not in err
    assert "not a rulebook" not in err  # git's listing of a folder is never read as one


def test_an_invalid_rulebook_exits_2_with_line_and_column(
        rules: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    rules[1].write_text(NEW.replace("risk <= 70 %", "risk = 70 %"))
    code, _, err = run(capsys, str(rules[0]), str(rules[1]))
    assert code == 2
    assert f"{rules[1]}:12:" in err and "error[E001]" in err


def test_results_that_are_not_ours_exit_2(rules: tuple[Path, Path], tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as file:
        file.attrs["format"] = "something-else"
    code, _, err = run(capsys, str(rules[0]), str(rules[1]), "--results", str(foreign))
    assert code == 2 and "is not an idefix results file" in err
    text = tmp_path / "notes.h5"
    text.write_text("not HDF5")
    code, _, err = run(capsys, str(rules[0]), str(rules[1]), "--results", str(text))
    assert code == 2 and "cannot open results file" in err
    code, _, err = run(capsys, str(rules[0]), str(rules[1]), "--results",
                       str(tmp_path / "missing.h5"))
    assert code == 2 and "not found" in err and "Traceback" not in err


def test_bad_options_exit_2(rules: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, str(rules[0]), str(rules[1]), "--top", "-1")
    assert code == 2 and "--top" in err
    code, _, _ = run(capsys, str(rules[0]), str(rules[1]), "--fail-on", "sometimes")
    assert code == 2


@pytest.mark.skipif(shutil.which("git") is None, reason="git is not installed")
def test_a_bad_git_revision_exits_2_naming_it(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    subprocess.run(["git", "-C", str(tmp_path), "init", "-q"], check=True)
    (tmp_path / "ops.rules").write_text(OLD)
    code, _, err = run(capsys, f"{tmp_path / 'ops.rules'}@v9.9.9", str(tmp_path / "ops.rules"))
    assert code == 2
    assert "error[D001]: " in err  # git knows no v9.9.9 (in a repository without commits)
    assert "ops.rules@v9.9.9: 'v9.9.9' is not a git revision" in err


def test_waivers_whose_rule_changed_are_listed(rules: tuple[Path, Path],
                                               capsys: pytest.CaptureFixture[str]) -> None:
    old, new = rules
    campaign = old.parent / "campaign.yaml"
    campaign.write_text(
        "rulebook: old.rules\n"
        "paths:\n"
        "  straight:\n"
        "    - {max_wheel_rate: \"0.1 rad/s\", delta_position: \"1 m\", delta_heading: \"0 deg\"}\n"
        "waivers:\n"
        "  - {rule: acceptable_risk, path: straight, reason: benign slope,"
        " approved_by: J. Doe, until: 2026-12-01}\n")
    assert main(["diff", str(old), str(new), "--waivers", str(campaign)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert ("waivers[0] (acceptable_risk on straight, approved by J. Doe until 2026-12-01): "
            "the rule is changed") in out
    assert main(["diff", str(old), str(new), "--waivers", str(campaign),
                 "--format", "json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["waivers"] == [{"number": 0, "rule": "acceptable_risk", "path": "straight",
                                "approved_by": "J. Doe", "until": "2026-12-01",
                                "change": "changed"}]
    assert main(["diff", str(old), str(old), "--waivers", str(campaign)]) == 0
    assert "whose rule changed: none" in capsys.readouterr().out
