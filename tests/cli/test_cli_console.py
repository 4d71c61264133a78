"""What a person reads on the console after a campaign: a decision, CI's outcome apart from it,
whole path names at 80 columns, and a rejected command in the campaign's units."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from campaign_texts import CAMPAIGN, RULEBOOK

from idefix_rules.cli import main

pytestmark = pytest.mark.slow

LONG = "detour-left-of-the-rock-with-arcs"
TURN_RULE = ("command max_turn_angle: require abs(delta_heading) <= 90 deg\n"
             "  because \"Largest allowed turn angle per command\"\n")
PATHS = f"""\
  {LONG}:
    - {{max_wheel_rate: "0.1 rad/s", delta_position: "0.1 m", delta_heading: "20 deg"}}
  point-turn-120:
    - {{max_wheel_rate: "0.1 rad/s", delta_position: "0 m", delta_heading: "120 deg"}}
"""


def _campaign(folder: Path, toy: Path, expect: str) -> Path:
    (folder / "toy.fmu").write_bytes(toy.read_bytes())
    (folder / "test.rules").write_text(RULEBOOK.replace("index I_pos", TURN_RULE + "\nindex I_pos"))
    head, _, _ = CAMPAIGN.partition("paths:\n")
    _, _, tail = CAMPAIGN.partition("simulation:\n")
    (folder / "campaign.yaml").write_text(f"{head}paths:\n{PATHS}simulation:\n{tail}{expect}")
    return folder / "campaign.yaml"


def _run(campaign: Path, columns: int, monkeypatch: pytest.MonkeyPatch,
         capsys: pytest.CaptureFixture[str], *extra: str) -> tuple[int, str]:
    monkeypatch.setenv("COLUMNS", str(columns))
    code = main([str(campaign), "--quiet", "--no-report", *extra])
    return code, capsys.readouterr().out


def test_80_columns_keep_names_and_say_the_decision(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    campaign = _campaign(tmp_path, cli_toy_fmu,
                         "expect:\n  - {path: point-turn-120, verdict: fail}\n")
    code, out = _run(campaign, 80, monkeypatch, capsys)
    assert code == 0
    lines = out.splitlines()
    assert max(len(line) for line in lines) <= 80, max(lines, key=len)
    assert "…" not in out
    assert LONG in out and "point-turn-120" in out
    decision = next(i for i, line in enumerate(lines) if line.startswith("Decision: "))
    table = next(i for i, line in enumerate(lines) if line.startswith("Path evaluation"))
    # The details first, the answer last: decision, ranking, a verdict per path, CI's line.
    assert table < decision
    assert lines[-1] == "CI expectations: 1 of 1 held (exit 0)"
    answer = lines[decision:]
    assert any(line.startswith("Ranking: ") for line in answer)
    # At this number of runs the detour's risk limit lies inside its interval: not decided,
    # which is no failure: its own mark, explained once, and said so in its verdict line.
    joined = " ".join(" ".join(answer).split())
    assert f"#1 {LONG}: pass (not decided) · risk" in joined
    assert "not decided: acceptable_risk" in joined
    assert "  ? acceptable_risk: risk" in out and "✗ acceptable_risk" not in out
    assert sum("· ? rule not decided yet" in line
               for line in lines) == 1
    # the rejected chain has no rank
    assert "  – point-turn-120: rejected" in answer
    assert "fixed run count" not in out  # a fixed count is no news
    # The 120° point turn is explained in degrees, as the campaign wrote it.
    words = " ".join(out.split())
    assert "command 1 breaks rule 'max_turn_angle' (delta_heading = 120 deg)" in words
    assert "2.0944" not in out
    # Index symbols come with their titles.
    assert re.search(r"I_(pos|s) \((position drift|wheel slip ratio)\)", out)


def test_a_wide_console_shows_the_table_and_a_failed_expectation(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    campaign = _campaign(tmp_path, cli_toy_fmu,
                         "expect:\n  - {path: point-turn-120, verdict: pass}\n")
    junit = tmp_path / "junit.xml"
    code, out = _run(campaign, 200, monkeypatch, capsys, "--junit", str(junit))
    assert code == 1
    # JUnit agrees with the exit code: one failure, the expectation; paths only report.
    root = ET.parse(junit).getroot()
    assert root.get("failures") == "1"
    failing = [c.get("name") for c in root.iter("testcase") if c.find("failure") is not None]
    assert failing == ["expect[0] point-turn-120 passes"]
    simulated = next(c for c in root.iter("testcase") if c.get("name") == LONG)
    assert float(simulated.get("time", "0")) > 0.0  # its runs and its evaluation took time
    assert "┃ path" in out  # the table layout
    assert "CI expectations: 0 of 1 held (exit 1)" in out.splitlines()
    assert "Decision: " in out


def test_progress_keeps_whole_names_at_80_columns() -> None:
    import io

    from rich.console import Console

    from idefix_rules.cli.progress import RichProgress

    out = io.StringIO()
    console = Console(file=out, width=80, force_terminal=True, color_system=None)
    progress = RichProgress(console, quiet=False)
    name = "a-very-long-path-name-for-the-detour-left-of-the-rock-with-arcs"
    progress.message("compiling the rulebook idefix-ops.rules")
    progress.start_path(name, total=128, done=0)
    for _ in range(128):
        progress.run_finished(name, ok=True)
    progress.message(f"evaluating {name}: 128 runs (collision checks and rulebook)")
    progress.stop()
    text = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", out.getvalue())
    lines = [line for line in re.split(r"[\r\n]", text) if line.strip()]
    assert max(len(line) for line in lines) <= 80
    assert "…" not in text
    assert "128/128" in text
    # The step lines say how long each step took; a folded name is still whole.
    assert re.search(r"compiling the rulebook idefix-ops.rules \(\d+\.\d s\)", text)
    assert name in "".join(line.strip() for line in lines)


def test_the_last_screen_of_the_example_at_80_by_40_shows_the_decision_and_ranking(
        tmp_path: Path) -> None:
    """The example campaign as README runs it, in an 80 × 40 window: what stays on the screen
    is the answer. Its output is not a terminal here, so the progress is plain lines."""
    import os
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "COLUMNS": "80", "LINES": "40"}
    done = subprocess.run(
        [sys.executable, "-m", "idefix_rules", str(root / "campaigns" / "rock-detour.yaml"),
         "--runs", "4", "--workers", "2", "--no-report", "--out", str(tmp_path / "out")],
        cwd=root, env=env, capture_output=True, text=True, timeout=600, check=False)
    # 4 runs cannot show the wide detour's L2 chance below 10 %: that expectation is not
    # decided (exit 1); the straight chain fails as expected
    assert done.returncode == 1, done.stdout + done.stderr
    assert "Traceback" not in done.stderr
    lines = (done.stdout + done.stderr).splitlines()
    screen = lines[-40:]
    assert max(len(line) for line in screen) <= 80
    assert any(line.startswith("Decision: ") for line in screen)
    ranking = next(line for line in screen if line.startswith("Ranking: "))
    assert set(ranking.removeprefix("Ranking: ").split(" > ")) == \
        {"straight", "wide-detour", "smooth-detour", "approach"}
    assert screen[-1] == "CI expectations: 1 of 2 held (exit 1)"
    text = " ".join(done.stdout.split())
    # The slip assumption is the rulebook's: one warning for the four paths, said once.
    assert text.count("assumes theoretical_slip") == 1
    assert done.stdout.count("warning:") == 1
    assert "fixed run count" not in text
    # A log gets plain progress: a line per phase with its duration, per 10 % of runs.
    assert re.search(r"^compiling the rulebook idefix-ops\.rules \(\d+\.\d s\)$",
                     done.stdout, re.M)
    assert re.search(r"^Monte Carlo runs of 4 path\(s\): 16 runs \(\d+\.\d s\)$",
                     done.stdout, re.M)
    assert re.search(r"^straight: 4/4 runs \(100 %\), \d+:\d\d$", done.stdout, re.M)
    assert re.search(r"^evaluating 16 runs of 4 path\(s\) .*\(\d+\.\d s\)$", done.stdout, re.M)
    assert "\r" not in done.stdout and "\x1b[" not in done.stdout
