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


FROZEN_OPS = Path(__file__).parents[1] / "fixtures" / "rulebooks" / "idefix-ops-1.1.0.rules"
L3_LEVEL = "  level L3             buffer 10 cm\n"
BLOCKER = '  area blocker keep_out level L1 buffer 1 cm because "Assumption: test area"\n'


def test_an_added_area_is_stricter_and_lists_the_rules_its_collisions_reach(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """An area is an obstacle of its level, counted in ``collision.hits``: adding one to the
    operations rulebook reaches I_obs, the prescreen and the risk verdict through it (it was
    once ``neutral`` with no rule affected, while the re-score showed hit_L1 0 % → 100 %)."""
    monkeypatch.setenv("COLUMNS", "250")
    text = FROZEN_OPS.read_text(encoding="utf-8")
    assert text.count(L3_LEVEL) == 1
    old, new = tmp_path / "old.rules", tmp_path / "new.rules"
    old.write_text(text, encoding="utf-8")
    new.write_text(text.replace('version "1.1.0"', 'version "1.2.0"')
                   .replace(L3_LEVEL, L3_LEVEL + BLOCKER), encoding="utf-8")
    code, out, _ = run(capsys, str(old), str(new))
    assert code == 0
    lines = [" ".join(line.replace("│", " ").split()) for line in out.splitlines()]
    assert "area blocker added stricter kind: keep_out Assumption: test area" in lines
    assert ("index I_obs affected stricter reads changed: collision.contact[L1], "
            "collision.hits[L1] (through blocker) Eq. 4: obstacles hit per body part and level "
            "times the level's factor") in lines
    assert any(line.startswith("prescreen no_clear_collision affected stricter reads changed: "
                               "I_obs (through blocker)") for line in lines)
    assert any(line.startswith("verdict acceptable_risk affected stricter reads changed: "
                               "risk (through blocker)") for line in lines)
    # no verdict reads the chance of an L1 hit; L3's hits are not the area's
    assert any(line.startswith("chance hit_L1 affected neutral") for line in lines)
    assert not any(line.startswith(("chance hit_L3", "verdict rare_l3_hits")) for line in lines)
    assert "1 added, 1 changed, 4 affected; 4 stricter, 2 neutral" in lines
    code, out, _ = run(capsys, str(old), str(new), "--format", "md")
    assert "- added area **blocker**: kind `keep_out`; level `L1`; buffer `1 cm`" in out
    assert ("- affected prescreen **no_clear_collision**: reads `I_obs`, which changed "
            "(through `blocker`)") in out
    code, out, _ = run(capsys, str(old), str(new), "--format", "json")
    rules = json.loads(out)["rules"]
    assert rules["directions"] == {"stricter": 4, "looser": 0, "neutral": 2, "unknown": 0}
    found = {c["name"]: (c["kind"], c["direction"], c["reads_changed"], c["upstream"])
             for c in rules["changes"]}
    assert found["blocker"] == ("added", "stricter", [], [])
    assert found["I_obs"] == ("affected", "stricter",
                              ["collision.contact[L1]", "collision.hits[L1]"], ["blocker"])
    assert found["acceptable_risk"] == ("affected", "stricter", ["risk"], ["blocker"])
