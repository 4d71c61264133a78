"""The console under what a CI runner's environment may hold: a ``COLUMNS`` of no use (0, 1),
``FORCE_COLOR`` in a log, an output encoding without the symbols the output uses. Each command
still prints its whole answer and ends with its own exit code.

The commands run as processes, with the environment variable set for them alone."""

from __future__ import annotations

import fcntl
import json
import os
import pty
import re
import struct
import subprocess
import sys
import termios
import threading
from pathlib import Path

import pytest
from campaign_texts import CAMPAIGN, RULEBOOK

REPOSITORY = Path(__file__).resolve().parents[2]
LOG_COLUMNS = 150  # a log's width when COLUMNS gives none (docs/ci.md)
BROKEN = 'rulebook "x" version 1\n'
BROKEN_REPORT = [
    "broken.rules:1:22: error[E001]: unexpected number '1'; expected a string (\"…\")",
    '    rulebook "x" version 1',
    "                         ^",
    "broken.rules: 1 error",
]
FROZEN = REPOSITORY / "tests" / "fixtures" / "rulebooks" / "idefix-ops-1.1.0.rules"
ESCAPE = re.compile(r"\x1b\[[0-9;?]*([A-Za-z])")
CI_LINE = ("CI verdicts (no expectations: every path must pass): 0 of 3 passed, 1 passing but "
           "not decided (exit 1)")


def verify(*arguments: str, cwd: Path, **environment: str) -> subprocess.CompletedProcess[str]:
    """``idefix-verify ARGUMENTS`` as a process, its output not a terminal."""
    env = {**os.environ, **environment}
    for name in ("COLUMNS", "FORCE_COLOR", "NO_COLOR", "TTY_COMPATIBLE", "PYTHONIOENCODING"):
        if name not in environment:
            env.pop(name, None)
    encoding = environment.get("PYTHONIOENCODING", "utf-8")
    return subprocess.run([sys.executable, "-m", "idefix_rules", *arguments], cwd=cwd, env=env,
                          capture_output=True, text=True, encoding=encoding, timeout=300,
                          check=False)


@pytest.fixture(scope="module")
def toy_campaign(tmp_path_factory: pytest.TempPathFactory, cli_toy_fmu: Path) -> Path:
    folder = tmp_path_factory.mktemp("toy-campaign")
    (folder / "toy.fmu").write_bytes(cli_toy_fmu.read_bytes())
    (folder / "test.rules").write_text(RULEBOOK)
    (folder / "campaign.yaml").write_text(CAMPAIGN)
    return folder / "campaign.yaml"


@pytest.fixture(scope="module")
def toy_results(toy_campaign: Path) -> Path:
    """The toy campaign's stored results (its default 6 runs)."""
    out = toy_campaign.parent / "stored"
    done = verify(str(toy_campaign), "--quiet", "--no-report", "--out", str(out),
                  cwd=toy_campaign.parent)
    assert done.returncode == 1, done.stdout + done.stderr
    return out / "results.h5"


# ----------------------------------------------------------------------------- COLUMNS

@pytest.mark.parametrize("columns", ["0", "1", "39"])
def test_a_columns_too_small_to_print_at_is_ignored(columns: str, tmp_path: Path) -> None:
    (tmp_path / "broken.rules").write_text(BROKEN)
    done = verify("check", "broken.rules", cwd=tmp_path, COLUMNS=columns)
    assert (done.returncode, done.stderr) == (2, "")
    assert done.stdout.splitlines() == BROKEN_REPORT
    (tmp_path / "ugly.rules").write_text((REPOSITORY / "tests" / "fixtures" / "rulebooks" /
                                          "idefix-ops-1.1.0.rules").read_text() + "\n\n\n")
    done = verify("fmt", "--check", "ugly.rules", cwd=tmp_path, COLUMNS=columns)
    assert (done.returncode, done.stderr) == (1, "")
    assert done.stdout.splitlines() == ["would reformat ugly.rules",
                                        "1 file(s) would be reformatted, 0 unchanged"]


@pytest.mark.slow
@pytest.mark.parametrize("columns", ["0", "1"])
def test_a_campaign_under_a_useless_columns_prints_its_answer_at_a_logs_width(
        columns: str, toy_campaign: Path, tmp_path: Path) -> None:
    done = verify(str(toy_campaign), "--quiet", "--no-report", "--out", str(tmp_path / "out"),
                  cwd=tmp_path, COLUMNS=columns)
    assert (done.returncode, done.stderr) == (1, "")
    lines = done.stdout.splitlines()
    assert max(len(line) for line in lines) <= LOG_COLUMNS
    assert lines[0].rstrip() == "Path evaluation"  # the table: it fits 150 columns
    assert "Decision: not settled yet: the verdict of arc, straight is not decided at this " \
           "number of runs (run more to settle it)" in lines
    assert lines[-4:] == [
        "  #1 arc: pass (not decided) · risk 32.3 % · not decided: acceptable_risk",
        "  #2 straight: fail (not decided) · risk 86.0 % · not decided: acceptable_risk",
        "  – too-fast: rejected",
        CI_LINE,
    ]


def _terminal(columns: int) -> tuple[int, int]:
    """A pseudo-terminal ``columns`` wide: (its terminal end, the other end)."""
    controller, terminal = pty.openpty()
    fcntl.ioctl(terminal, termios.TIOCSWINSZ, struct.pack("HHHH", 24, columns, 0, 0))
    return terminal, controller


def test_on_a_terminal_a_columns_too_small_gives_the_terminals_own_width(
        monkeypatch: pytest.MonkeyPatch) -> None:
    from idefix_rules.cli.console import console_width

    terminal, controller = _terminal(97)
    try:
        with os.fdopen(terminal, "w", closefd=False) as stream:
            monkeypatch.setenv("COLUMNS", "0")
            assert console_width(stream) == 97
            monkeypatch.setenv("COLUMNS", "60")
            assert console_width(stream) == 60
            monkeypatch.delenv("COLUMNS")
            assert console_width(stream) is None  # rich follows the terminal as it prints
    finally:
        os.close(terminal)
        os.close(controller)


def test_standard_error_follows_the_same_rule(monkeypatch: pytest.MonkeyPatch) -> None:
    from idefix_rules.cli.console import make_console

    monkeypatch.setenv("COLUMNS", "0")
    assert make_console(stderr=True).width == make_console().width == LOG_COLUMNS
    monkeypatch.setenv("COLUMNS", "72")
    assert make_console(stderr=True).width == make_console().width == 72


# ----------------------------------------------------------------------------- FORCE_COLOR

@pytest.mark.slow
def test_force_color_colours_a_log_but_never_redraws_it(toy_campaign: Path,
                                                        tmp_path: Path) -> None:
    """Rich calls any stream a terminal under FORCE_COLOR: a log then got the bars and
    spinners of a terminal, redrawn with carriage returns and cursor movements."""
    out = tmp_path / "out"
    done = verify(str(toy_campaign), "--runs", "32", "--no-report", "--out", str(out),
                  cwd=tmp_path, FORCE_COLOR="1")
    assert (done.returncode, done.stderr) == (1, "")
    assert "\r" not in done.stdout
    # colour (SGR, "…m") and nothing else: no cursor hidden, moved or line erased
    assert set(ESCAPE.findall(done.stdout)) == {"m"}
    plain = ESCAPE.sub("", done.stdout)
    assert re.search(r"^compiling the rulebook test\.rules \(\d+\.\d s\)$", plain, re.M)
    assert re.search(r"^arc: 32/32 runs \(100 %\), \d+:\d\d$", plain, re.M)
    assert plain.splitlines()[-1] == ("CI verdicts (no expectations: every path must pass): 1 "
                                      "of 3 passed (exit 1)")
    # evaluate's spinner on standard error neither
    done = verify("evaluate", str(out / "results.h5"), cwd=tmp_path, FORCE_COLOR="1")
    assert (done.returncode, done.stderr) == (1, "")
    assert ESCAPE.sub("", done.stdout).splitlines()[-1] == (
        "CI verdicts (no expectations: every path must pass): 1 of 3 passed (exit 1)")


def test_force_color_keeps_explain_in_records_in_a_pipe(tmp_path: Path) -> None:
    """explain prints tables on a wide terminal, records a line each into a pipe (what grep
    reads), coloured or not."""
    done = verify("explain", str(FROZEN), cwd=tmp_path, FORCE_COLOR="1")
    assert (done.returncode, done.stderr) == (0, "")
    plain = ESCAPE.sub("", done.stdout).splitlines()
    assert plain[0] == ("idefix-ops 1.1.0 — Movement rules for manual driving in the first "
                        "mobility phase")
    assert "command wheel_rate_limit" in plain and "constants" in plain
    assert not any(line.startswith(("┏", "│", "┃")) for line in plain)


# ----------------------------------------------------------------------------- encodings

@pytest.mark.slow
@pytest.mark.parametrize(("encoding", "dot", "dash"), [("ascii", "|", "-"),
                                                       ("latin-1", "·", "-")])
def test_an_output_encoding_without_the_symbols_still_gets_the_whole_answer(
        encoding: str, dot: str, dash: str, toy_campaign: Path, tmp_path: Path) -> None:
    """A finished campaign ended in a UnicodeEncodeError ('–') and exit 3, its summary.json
    saying 1: symbols the encoding lacks are written in ASCII, those it has as they are."""
    out = tmp_path / "out"
    done = verify(str(toy_campaign), "--quiet", "--no-report", "--out", str(out),
                  cwd=tmp_path, PYTHONIOENCODING=encoding)
    assert (done.returncode, done.stderr) == (1, "")
    assert json.loads((out / "summary.json").read_text())["exit_code"] == 1
    lines = done.stdout.splitlines()
    assert lines[-4:] == [
        f"  #1 arc: pass (not decided) {dot} risk 32.3 % {dot} not decided: acceptable_risk",
        f"  #2 straight: fail (not decided) {dot} risk 86.0 % {dot} not decided: "
        "acceptable_risk",
        f"  {dash} too-fast: rejected",
        CI_LINE,
    ]
    assert "Decision: not settled yet: the verdict of arc, straight is not decided at this " \
           "number of runs (run more to settle it)" in lines
    assert "-" * LOG_COLUMNS in lines  # the rule above the answer, in ASCII
    assert f"x rule failed {dot} ? rule not decided yet" in done.stdout


def test_diagnostics_on_an_ascii_stream_are_readable_with_their_caret(tmp_path: Path) -> None:
    (tmp_path / "broken.rules").write_text(BROKEN)
    ascii_report = [line.replace("…", "...") for line in BROKEN_REPORT]
    done = verify("check", "broken.rules", cwd=tmp_path, PYTHONIOENCODING="ascii")
    assert (done.returncode, done.stderr, done.stdout.splitlines()) == (2, "", ascii_report)
    # an error the dispatcher says, on standard error (Python's own default there wrote
    # "\u2026")
    done = verify("explain", "broken.rules", cwd=tmp_path, PYTHONIOENCODING="ascii")
    assert (done.returncode, done.stdout) == (2, "")
    assert done.stderr.splitlines() == ascii_report[:3]
    # JSON loses nothing: escapes instead of characters
    done = verify("check", "--format", "json", "broken.rules", cwd=tmp_path,
                  PYTHONIOENCODING="ascii")
    assert (done.returncode, done.stderr) == (2, "")
    assert json.loads(done.stdout)[0]["message"] == \
        "unexpected number '1'; expected a string (\"…\")"
    assert "\\u2026" in done.stdout


def test_help_on_an_ascii_stream(tmp_path: Path) -> None:
    done = verify("run", "--help", cwd=tmp_path, PYTHONIOENCODING="ascii")
    assert (done.returncode, done.stderr) == (0, "")
    assert "  --seed SEED           campaign seed, 0 ... 2^64 - 1 (overrides" in \
        done.stdout.splitlines()


def test_every_symbol_has_an_ascii_stand_in() -> None:
    from idefix_rules.cli.encoding import ascii_text

    assert [ascii_text(c) for c in "–—…·✗✓≈≥≤±×°→"] == [
        "-", "-", "...", "|", "x", "ok", "~", ">=", "<=", "+/-", "x", " deg", "->"]
    assert "".join(ascii_text(c) for c in "┏━┃┡╇└") == "+-|+++"


# ----------------------------------------------------------------------------- --quiet

def _with_stderr_on_a_terminal(*arguments: str, cwd: Path) -> tuple[int, str, str]:
    """``idefix-verify ARGUMENTS`` with standard error on a terminal (where spinners show),
    standard output in a pipe: exit code, standard output, what reached the terminal."""
    terminal, controller = _terminal(100)
    said: list[bytes] = []

    def read() -> None:
        while True:
            try:
                chunk = os.read(controller, 4096)
            except OSError:  # every writer closed its end
                return
            if not chunk:
                return
            said.append(chunk)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    env = {key: value for key, value in os.environ.items()
           if key not in ("COLUMNS", "FORCE_COLOR", "NO_COLOR", "TTY_COMPATIBLE")}
    try:
        done = subprocess.run([sys.executable, "-m", "idefix_rules", *arguments], cwd=cwd,
                              env=env, stdout=subprocess.PIPE, stderr=terminal, text=True,
                              timeout=300, check=False)
    finally:
        os.close(terminal)
    reader.join(timeout=10)
    os.close(controller)
    return done.returncode, done.stdout, b"".join(said).decode("utf-8", "replace")


@pytest.mark.slow
def test_evaluate_quiet_shows_no_spinner(toy_results: Path, tmp_path: Path) -> None:
    """--quiet meant nothing to evaluate: its spinner still turned on a terminal."""
    code, out, terminal = _with_stderr_on_a_terminal("evaluate", str(toy_results),
                                                     cwd=tmp_path)
    assert code == 1 and out.splitlines()[-1] == CI_LINE
    assert "evaluating the stored runs (collision checks, rulebook)" in terminal  # it shows
    code, out, terminal = _with_stderr_on_a_terminal("evaluate", "--quiet", str(toy_results),
                                                     cwd=tmp_path)
    assert (code, terminal) == (1, "")
    assert out.splitlines()[-1] == CI_LINE  # the results are still printed


# ----------------------------------------------------------------------------- long names

LONG = "detour-left-of-the-rock-" + "x" * 69 + "-end-07"  # 100 characters, the longest allowed


@pytest.mark.slow
def test_at_40_columns_a_100_character_name_stays_whole_for_grep(
        toy_campaign: Path, tmp_path: Path) -> None:
    """The short block per path and the answer folded the name into slices of 40 characters:
    ``grep '#1 NAME'`` found nothing. A line holding a name is wrapped only where the name
    stays whole, and printed unwrapped where it cannot be."""
    assert len(LONG) == 100
    for name in ("toy.fmu", "test.rules"):
        (tmp_path / name).write_bytes((toy_campaign.parent / name).read_bytes())
    (tmp_path / "campaign.yaml").write_text(toy_campaign.read_text().replace("  arc:\n",
                                                                             f"  {LONG}:\n"))
    done = verify("campaign.yaml", "--runs", "32", "--quiet", "--no-report", cwd=tmp_path,
                  COLUMNS="40")
    assert (done.returncode, done.stderr) == (1, "")
    lines = done.stdout.splitlines()
    assert f"#1 {LONG}  pass" in lines  # the short block's first line
    assert f"Decision: send {LONG} (passes every verdict, rank 1 of 2)" in lines
    assert f"Ranking: {LONG} > straight" in lines
    assert f"  #1 {LONG}: pass · risk 36.9 %" in lines
    # the rest still wraps at 40 columns
    assert [line for line in lines if len(line) > 40 and LONG not in line] == []
    assert lines[-2:] == ["CI verdicts (no expectations: every path", "must pass): 1 of 3 "
                          "passed (exit 1)"]
