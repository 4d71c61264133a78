"""The version in use is always kept: ``rulebooks/history/`` holds a copy of the operational
rulebook under its declared version, so ``idefix-verify diff`` can compare against it later.

This is a rule engineers' check (docs/testing-rulebooks.md, "whose tests fail"): releasing a
version means copying it there with the ``# EARLIER VERSION`` header of the others.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from idefix_rules.rulebook import load_checked

RULEBOOKS = Path(__file__).resolve().parents[2] / "rulebooks"


def history_problem(live: Path, history: Path) -> str | None:
    """Why ``history`` keeps no identical copy of ``live``'s declared version (None: it does).

    The copy is ``history/NAME-VERSION.rules``: a header of comment lines starting with
    ``# EARLIER VERSION VERSION``, then the live text byte for byte."""
    header = load_checked(live).rulebook.header
    copy = history / f"{header.name}-{header.version}.rules"
    if not copy.is_file():
        return f"{copy.name} is missing: the version in use ({header.version}) is not kept"
    text, kept = live.read_text(encoding="utf-8"), copy.read_text(encoding="utf-8")
    if not kept.endswith(text):
        return f"{copy.name} differs from {live.name} (same version {header.version})"
    lines = kept[:len(kept) - len(text)].splitlines()
    if not lines or not lines[0].startswith(f"# EARLIER VERSION {header.version} ") \
            or not all(line.startswith("#") for line in lines):
        return f"{copy.name} lacks the '# EARLIER VERSION {header.version}' comment header"
    return None


def test_the_version_in_use_is_kept_in_history() -> None:
    assert history_problem(RULEBOOKS / "idefix-ops.rules", RULEBOOKS / "history") is None


LIVE = """\
# comment of the live file
rulebook "ops" version "1.3.0"
purpose "Ops"

const critical_slip = 60 % because "Slip above 60 % is critical"

index I_s "slip" {
  value  = max over time (max over wheels (abs(wheel.slip)))
  limit  = critical_slip
  weight = 1
}

verdict acceptable_risk: require risk <= 70 %
"""
HEADER = ("# EARLIER VERSION 1.3.0 of rulebooks/ops.rules, kept so that results can be compared\n"
          "# across rulebook versions (diff).\n")


@pytest.mark.parametrize(("kept", "problem"), [
    (HEADER + LIVE, None),
    (None, "ops-1.3.0.rules is missing: the version in use (1.3.0) is not kept"),
    (HEADER + LIVE.replace("60 %", "70 %"), "ops-1.3.0.rules differs from ops.rules "
                                             "(same version 1.3.0)"),
    (HEADER + LIVE + "\n", "ops-1.3.0.rules differs from ops.rules (same version 1.3.0)"),
    (LIVE, "ops-1.3.0.rules lacks the '# EARLIER VERSION 1.3.0' comment header"),
    (HEADER.replace("1.3.0", "1.2.0", 1) + LIVE,
     "ops-1.3.0.rules lacks the '# EARLIER VERSION 1.3.0' comment header"),
], ids=["kept", "missing", "other text", "trailing line", "no header", "header of 1.2.0"])
def test_the_check_fails_unless_an_identical_copy_is_kept(tmp_path: Path, kept: str | None,
                                                          problem: str | None) -> None:
    live, history = tmp_path / "ops.rules", tmp_path / "history"
    live.write_text(LIVE, encoding="utf-8")
    history.mkdir()
    if kept is not None:
        (history / "ops-1.3.0.rules").write_text(kept, encoding="utf-8")
    assert history_problem(live, history) == problem
