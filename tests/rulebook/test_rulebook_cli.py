"""`idefix-verify check`, `fmt` and `explain`, and the default rulebook they ship with."""

import json
import re
from pathlib import Path

import pytest

from idefix_rules.cli import main
from idefix_rules.rulebook import load_rulebook
from idefix_rules.rulebook.format import format_rulebook
from idefix_rules.rulebook.parser import parse_rulebook

ROOT = Path(__file__).resolve().parents[2]
# The shipped rulebooks, which their rule engineers edit: only their own checks read them
DEFAULT = ROOT / "rulebooks" / "idefix-ops.rules"
EARLIER = ROOT / "rulebooks" / "history" / "idefix-ops-0.9.0.rules"
# Frozen copies (tests/fixtures/rulebooks) for the tests that name what a rulebook declares
FIXTURES = ROOT / "tests" / "fixtures" / "rulebooks"
FROZEN = FIXTURES / "idefix-ops-1.1.0.rules"
FROZEN_EARLIER = FIXTURES / "idefix-ops-0.9.0.rules"

VALID = """rulebook "cli" version "1.0.0"
purpose "CLI test"
const critical_slip = 70 %
index I_s "slip" {
  value  = max over time (max over wheels (abs(wheel.slip)))
  limit  = critical_slip
  weight = 1
}
verdict ok: require risk <= 70 %
"""
UNFORMATTED = VALID.replace("const critical_slip = 70 %", "const   critical_slip=70 %")


@pytest.fixture
def write(tmp_path):
    def _write(name: str, text: str) -> Path:
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        return path
    return _write


# ----------------------------------------------------------------------------- check

def test_check_accepts_a_valid_rulebook(write, capsys):
    assert main(["check", str(write("ok.rules", VALID))]) == 0
    assert "ok.rules: ok" in capsys.readouterr().out


def test_check_reports_every_error_of_every_file_with_exit_2(write, capsys):
    good = write("good.rules", VALID)
    bad = write("bad.rules", VALID.replace("limit  = critical_slip", "limit  = 5 cm")
                .replace("weight = 1", "weight = 1.5"))
    assert main(["check", str(good), str(bad)]) == 2
    out = capsys.readouterr().out
    assert re.search(r"bad\.rules:6:\d+: error\[E204\]", out)
    assert re.search(r"bad\.rules:7:\d+: error\[E401\]", out)
    assert "good.rules: ok" in out and "bad.rules: 2 errors" in out
    assert "    ^" in out  # the caret under the source line


def test_check_json_lists_the_diagnostics(write, capsys):
    bad = write("bad.rules", VALID.replace("critical_slip\n", "critcal_slip\n"))
    assert main(["check", "--format", "json", str(bad)]) == 2
    [record] = json.loads(capsys.readouterr().out)
    assert record["code"] == "E101" and record["line"] == 6
    assert record["path"] == str(bad) and "critical_slip" in record["hint"]


def test_check_strict_turns_warnings_into_a_failure(write, capsys):
    path = write("w.rules", VALID + "const unused = 3 cm\n")
    assert main(["check", str(path)]) == 0
    assert main(["check", "--strict", str(path)]) == 2
    assert "W601" in capsys.readouterr().out


def test_check_of_a_missing_or_binary_file_is_exit_2_not_a_traceback(write, tmp_path, capsys):
    junk = tmp_path / "junk.rules"
    junk.write_bytes(b"\xff\xfe\x00rulebook")
    assert main(["check", str(tmp_path / "missing.rules"), str(junk)]) == 2
    captured = capsys.readouterr()
    assert "Traceback" not in captured.out + captured.err
    assert "not found" in captured.out


def test_check_of_a_case_file_says_it_is_no_rulebook(write, capsys):
    """A case file begins with `rulebook:`: check said only "unexpected ':'; expected a
    string" at its first key."""
    path = write("cases.yaml", "# cases\nrulebook: ../ops.rules\ncases:\n  c: {}\n")
    assert main(["check", str(path)]) == 2
    out = capsys.readouterr().out
    assert f"error[E902]: {path} is not a rulebook: it begins with the YAML key 'rulebook:'" \
        in out
    assert "E001" not in out


def test_check_of_a_syntax_error_is_exit_2(write, capsys):
    assert main(["check", str(write("s.rules", VALID + "verdict x: require risk = 1\n"))]) == 2
    assert "use '==' to compare" in capsys.readouterr().out


# ----------------------------------------------------------------------------- fmt

def test_fmt_rewrites_in_place(write, capsys):
    path = write("f.rules", UNFORMATTED)
    assert main(["fmt", str(path)]) == 0
    assert path.read_text() == format_rulebook(parse_rulebook(UNFORMATTED, str(path)))
    assert "reformatted" in capsys.readouterr().out
    assert main(["fmt", "--check", str(path)]) == 0


def test_fmt_keeps_a_files_crlf_line_endings(tmp_path, capsys):
    path = tmp_path / "windows.rules"
    path.write_bytes(UNFORMATTED.replace("\n", "\r\n").encode())
    assert main(["fmt", str(path)]) == 0
    formatted = format_rulebook(parse_rulebook(UNFORMATTED, str(path)))
    assert path.read_bytes() == formatted.replace("\n", "\r\n").encode()
    assert main(["fmt", "--check", str(path)]) == 0  # formatted, CRLF and all
    assert "0 file(s) would be reformatted, 1 unchanged" in capsys.readouterr().out
    # a file with CRLF and LF mixed is written with CRLF alone, as the editor formats it
    path.write_bytes(formatted.replace("\n", "\r\n", 1).encode())
    assert main(["fmt", "--diff", str(path)]) == 0
    assert f"{path}: line endings only" in capsys.readouterr().out
    assert main(["fmt", str(path)]) == 0
    assert path.read_bytes() == formatted.replace("\n", "\r\n").encode()


def test_fmt_check_exits_1_names_the_file_and_writes_nothing(write, capsys):
    path = write("f.rules", UNFORMATTED)
    assert main(["fmt", "--check", str(path)]) == 1
    assert f"would reformat {path}" in capsys.readouterr().out
    assert path.read_text() == UNFORMATTED


def test_fmt_diff_shows_the_change(write, capsys):
    path = write("f.rules", UNFORMATTED)
    assert main(["fmt", "--check", "--diff", str(path)]) == 1
    out = capsys.readouterr().out
    assert "-const   critical_slip=70 %" in out and "+const critical_slip = 70 %" in out


def test_fmt_diff_alone_writes_nothing_as_black_and_ruff(write, capsys):
    path = write("f.rules", UNFORMATTED)
    assert main(["fmt", "--diff", str(path)]) == 0
    out = capsys.readouterr().out
    assert "+const critical_slip = 70 %" in out and f"would reformat {path}" in out
    assert "1 file(s) would be reformatted" in out
    assert path.read_text() == UNFORMATTED


def test_fmt_of_an_invalid_file_is_exit_2_and_leaves_it_alone(write, capsys):
    text = VALID + "verdict broken require\n"
    path = write("b.rules", text)
    assert main(["fmt", str(path)]) == 2
    assert path.read_text() == text
    assert "error[E001]" in capsys.readouterr().out


def test_fmt_help_says_what_check_does(capsys):
    assert main(["fmt", "--help"]) == 0
    help_text = " ".join(capsys.readouterr().out.split())
    assert "--check" in help_text and "exit 1 if any would" in help_text


# ----------------------------------------------------------------------------- explain

def test_explain_lists_every_rule(capsys):
    assert main(["explain", str(FROZEN)]) == 0
    out = capsys.readouterr().out
    for name in ("I_pos", "I_theta", "I_psi", "I_phi", "I_s", "I_beta", "I_ds", "I_obs",
                 "max_turn_angle", "min_motion", "hit_L3", "no_clear_collision",
                 "acceptable_risk", "rank by risk, time, energy"):
        assert name in out, name


def test_explain_marks_the_path_level_position_index():
    from idefix_rules.cli.explain import rows
    from idefix_rules.rulebook import load_checked

    marked = {row[1].split("\n")[0] for row in rows(load_checked(FROZEN))
              if "path-level" in row[2]}
    assert marked == {"I_pos"}  # only I_pos reduces over runs


def test_explain_of_an_invalid_rulebook_is_exit_2(write, capsys):
    assert main(["explain", str(write("x.rules", "rulebook"))]) == 2


# ----------------------------------------------------------------------------- shipped rulebooks
# The rule engineers' own checks of the files they edit (docs/testing-rulebooks.md)

def test_default_rulebooks_are_valid_strict_and_formatted(capsys):
    assert main(["check", "--strict", str(DEFAULT)]) == 0
    # the archived versions are kept as they were: valid, but --strict may find a rationale
    # that disagrees with its value (0.9.0 does: tests/rulebook/test_rulebook_lints.py)
    history = sorted(str(path) for path in (ROOT / "rulebooks" / "history").glob("*.rules"))
    assert str(EARLIER) in history
    assert main(["check", *history]) == 0
    assert main(["fmt", "--check", str(DEFAULT), *history]) == 0


def test_every_declaration_of_the_default_rulebook_has_a_rationale():
    book = load_rulebook(DEFAULT)
    declarations = [*book.constants, *book.command_rules, *book.indices, *book.chances,
                    *book.prescreens, *book.verdicts]
    assert all(d.rationale for d in declarations), [d.name for d in declarations
                                                    if not d.rationale]


# ----------------------------------------------------------------------------- frozen rulebooks

def test_the_frozen_rulebook_loads_with_the_papers_rules():
    book = load_rulebook(FROZEN)
    assert {i.name for i in book.indices} == {"I_pos", "I_theta", "I_psi", "I_phi", "I_s",
                                              "I_beta", "I_ds", "I_obs"}
    assert {"max_turn_angle", "min_motion"} <= {r.name for r in book.command_rules}
    assert {"hit_L1", "hit_L2", "hit_L3"} <= {c.name for c in book.chances}
    assert {level.level for level in book.obstacle_levels} == {"L1", "L2", "L3"}
    slip = {c.name: c.value for c in book.constants}
    assert slip["nominal_slip"].value == 20 and slip["critical_slip"].value == 70


def test_the_earlier_version_differs_and_says_so():
    current, earlier = load_rulebook(FROZEN), load_rulebook(FROZEN_EARLIER)
    assert earlier.header.name == current.header.name
    assert earlier.header.version == "0.9.0" != current.header.version
    assert earlier != current
    assert "EARLIER VERSION" in FROZEN_EARLIER.read_text()


# ----------------------------------------------------------------------------- documentation

DOC = (ROOT / "docs" / "rulebook-language.md").read_text(encoding="utf-8")
DOC_HEADER = 'rulebook "doc" version "1.0.0"\npurpose "documentation example"\n'


def _blocks(kind: str) -> list[str]:
    return re.findall(rf"```{kind}\n(.*?)```", DOC, re.S)


def test_complete_examples_in_the_language_reference_are_valid():
    from idefix_rules.rulebook import check_text

    complete = _blocks("rules")
    assert complete
    for text in complete:
        assert check_text(text, "doc.rules").diagnostics == []


def test_every_example_fragment_in_the_language_reference_parses():
    fragments = _blocks("rules-fragment")
    assert len(fragments) >= 15
    for fragment in fragments:
        text = fragment if fragment.startswith("rulebook") else DOC_HEADER + fragment
        parse_rulebook(text, "fragment.rules")


def test_the_reference_lists_every_unit_signal_and_diagnostic_code():
    from idefix_rules import signals, units

    for atom in units._ATOMS:
        assert f"`{atom}`" in DOC, atom
    for name in signals.SIGNALS:
        assert f"`{name}`" in DOC or f"`{name.split('.')[0]}." in DOC, name
    # every module of the rulebook package: a new one is read without being listed here
    codes = set()
    for source in sorted((ROOT / "idefix_rules" / "rulebook").glob("*.py")):
        codes |= set(re.findall(r'"([EW]\d{3})"', source.read_text(encoding="utf-8")))
    missing = sorted(code for code in codes if f"| {code} |" not in DOC)
    assert not missing, missing


def test_check_json_gives_the_end_of_each_span(write, capsys):
    bad = write("bad.rules", VALID.replace("critical_slip\n", "critcal_slip\n"))
    main(["check", "--format", "json", str(bad)])
    [record] = json.loads(capsys.readouterr().out)
    line = bad.read_text().splitlines()[record["line"] - 1]
    assert record["end_line"] == record["line"]
    assert line[record["column"] - 1:record["end_column"] - 1] == "critcal_slip"


def test_explain_into_a_pipe_prints_a_record_a_line_not_folded_tables(capsys):
    """Piped (CI logs, grep), the tables would fold every cell into slivers at 80 columns:
    each rule is a record, each field on one line, its formula and rationale whole."""
    assert main(["explain", str(FROZEN)]) == 0
    out = capsys.readouterr().out
    assert "┃" not in out and "│" not in out
    lines = out.splitlines()
    assert "command max_turn_angle" in lines
    at = lines.index("command max_turn_angle")
    assert lines[at + 1] == "  formula: abs(delta_heading) <= max_turn"
    assert any(line.startswith("  critical_slip = ") for line in lines)
