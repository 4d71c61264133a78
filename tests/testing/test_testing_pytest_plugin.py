"""The pytest plugin: case files are collected as items, fixtures load a rulebook."""

from __future__ import annotations

from pathlib import Path

# the frozen operations rulebook 1.1.0 (tests/fixtures/rulebooks), not the live one
RULEBOOK = Path(__file__).parents[1] / "fixtures" / "rulebooks" / "idefix-ops-1.1.0.rules"

CASES = f"""rulebook: {RULEBOOK}
defaults:
  chain:
    - {{max_wheel_rate: 0.04 rad/s, delta_position: 20 cm, delta_heading: 0 deg}}
cases:
  calm:
    expect: {{verdict: pass, risk: 0}}
  slipping:
    signals:
      wheel.slip[FL]: 35 %
    expect: {{indices: {{I_s: 0.9}}}}
"""


def test_case_files_become_items_with_expected_vs_actual(pytester):
    pytester.makefile(".yaml", cases=CASES)
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(passed=1, failed=1)
    result.stdout.fnmatch_lines([
        "*index I_s: expected 0.9 ± 0.005, got 0.5*",
        "*rule: index I_s: value = percentile 95 over time*",
    ])


def test_a_broken_case_file_is_a_located_collection_error(pytester):
    pytester.makefile(".yaml", cases=CASES.replace("wheel.slip[FL]", "wheel.slipp[FL]"))
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(["*cases.yaml:10:7: error[[]T004]*wheel.slipp*"])


def test_other_yaml_files_are_left_alone(pytester):
    pytester.makefile(".yaml", campaign="name: x\npaths: {}\n")
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes()


def test_rulebook_fixtures(pytester):
    pytester.makeini(f"[pytest]\nidefix_rulebook = {RULEBOOK}\n")
    pytester.makepyfile("""
        def test_fixtures(rulebook, compiled_rulebook, load_rulebook):
            assert rulebook.rulebook.header.name == "idefix-ops"
            assert compiled_rulebook.checked.limits["I_s"] == 0.7
            assert load_rulebook(rulebook.rulebook.path).limits == rulebook.limits

        def test_a_broken_rulebook_fails_with_diagnostics(load_rulebook, tmp_path):
            bad = tmp_path / "bad.rules"
            bad.write_text('rulebook "x" version "1"\\n', encoding="utf-8")
            load_rulebook(bad)
    """)
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(passed=1, failed=1)
    result.stdout.fnmatch_lines(["*bad.rules:*error[E*"])


def _git(folder: Path, *args: str) -> None:
    import subprocess

    subprocess.run(["git", "-C", str(folder), "-c", "user.name=t", "-c", "user.email=t@t",
                    *args], check=True, capture_output=True)


def test_the_fixture_loads_a_rulebook_at_a_git_revision(pytester):
    text = RULEBOOK.read_text(encoding="utf-8")
    rules = pytester.path / "rulebooks" / "ops.rules"
    rules.parent.mkdir()
    rules.write_text(text, encoding="utf-8")
    _git(pytester.path, "init", "-q")
    _git(pytester.path, "add", "rulebooks/ops.rules")
    _git(pytester.path, "commit", "-qm", "first")
    rules.write_text(text.replace("const critical_slip            = 70 %",
                                  "const critical_slip            = 60 %"), encoding="utf-8")
    pytester.makepyfile(test_revisions="""
        def test_head_and_working_tree(load_rulebook):
            assert load_rulebook("rulebooks/ops.rules@HEAD").limits["I_s"] == 0.7
            assert load_rulebook("rulebooks/ops.rules").limits["I_s"] == 0.6

        def test_an_unknown_revision_fails_with_its_reason(load_rulebook):
            load_rulebook("rulebooks/ops.rules@nosuchrev")
    """)
    pytester.makeini("[pytest]\nidefix_rulebook = rulebooks/ops.rules@HEAD\n")
    pytester.makepyfile(test_ini="""
        def test_the_ini_rulebook_at_head(rulebook):
            assert rulebook.limits["I_s"] == 0.7
    """)
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(passed=2, failed=1)
    result.stdout.fnmatch_lines(["*D001*ops.rules@nosuchrev: 'nosuchrev' is not a git "
                                 "revision*"])
    assert "Traceback" not in result.stdout.str()
