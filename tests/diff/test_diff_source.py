"""Loading the sides of a diff: rulebook files and files at git revisions (a temp repo)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from idefix_rules.diff import load_source, split_spec
from idefix_rules.errors import UserInputError

V1 = """\
rulebook "git-test" version "1.0.0"
purpose "First version"

index I_s "slip" {
  value  = max over time (max over wheels (abs(wheel.slip)))
  limit  = 70 %
  weight = 1
}

verdict acceptable_risk: require risk <= 70 %
"""

V2 = V1.replace('version "1.0.0"', 'version "1.1.0"').replace("limit  = 70 %", "limit  = 65 %")

BROKEN = V1.replace("risk <= 70 %", "risk = 70 %")

needs_git = pytest.mark.skipif(shutil.which("git") is None, reason="git is not installed")


def git(folder: Path, *args: str) -> None:
    subprocess.run(["git", "-C", str(folder), *args], check=True, capture_output=True)


@pytest.fixture
def repo(tmp_path: Path) -> Path:
    """A git repository whose rules/ops.rules has three commits: V1, V2, BROKEN."""
    git(tmp_path, "init", "-q")
    git(tmp_path, "config", "user.email", "rules@example.org")
    git(tmp_path, "config", "user.name", "Rule Engineer")
    rules = tmp_path / "rules" / "ops.rules"
    rules.parent.mkdir()
    for text, message in ((V1, "v1"), (V2, "v2"), (BROKEN, "broken")):
        rules.write_text(text)
        git(tmp_path, "add", "rules/ops.rules")
        git(tmp_path, "commit", "-q", "-m", message)
    rules.write_text(V2)  # the working tree holds V2 again
    return tmp_path


def test_split_spec_takes_the_first_at_unless_the_spec_is_a_file(tmp_path: Path) -> None:
    assert split_spec("rules/ops.rules@HEAD~1") == ("rules/ops.rules", "HEAD~1")
    assert split_spec("rules/ops.rules@HEAD@{1}") == ("rules/ops.rules", "HEAD@{1}")
    assert split_spec("rules/ops.rules") == ("rules/ops.rules", None)
    odd = tmp_path / "v@2.rules"
    odd.write_text(V1)
    assert split_spec(str(odd)) == (str(odd), None)


@needs_git
def test_a_file_at_a_git_revision_is_read_with_git_show(repo: Path,
                                                          monkeypatch: pytest.MonkeyPatch
                                                          ) -> None:
    monkeypatch.chdir(repo)
    older = load_source("rules/ops.rules@HEAD~2")
    assert older.label == "rules/ops.rules@HEAD~2"
    assert older.revision == "HEAD~2"
    assert older.checked.rulebook.header.version == "1.0.0"
    assert older.checked.limits["I_s"] == pytest.approx(0.70)
    newer = load_source("rules/ops.rules@HEAD~1")
    assert newer.checked.limits["I_s"] == pytest.approx(0.65)
    current = load_source("rules/ops.rules")
    assert current.revision is None and current.checked.rulebook.header.version == "1.1.0"


@needs_git
def test_a_path_from_another_folder_is_found_relative_to_its_own_folder(
        repo: Path, tmp_path_factory: pytest.TempPathFactory,
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path_factory.mktemp("elsewhere"))
    source = load_source(f"{repo / 'rules' / 'ops.rules'}@HEAD~2")
    assert source.checked.rulebook.header.version == "1.0.0"


@needs_git
def test_a_bad_revision_is_a_user_error_naming_it(repo: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(repo)
    with pytest.raises(UserInputError) as caught:
        load_source("rules/ops.rules@no-such-rev")
    diagnostic = caught.value.diagnostics[0]
    assert diagnostic.code == "D001"  # git knows no such revision (D004: no such file there)
    assert "rules/ops.rules@no-such-rev: 'no-such-rev' is not a git revision" \
        in diagnostic.message
    # located at the file named, not "<input>"
    assert diagnostic.span is not None and diagnostic.span.path == "rules/ops.rules"
    for typo in ("HAED~1", "HEAD~99", "deadbeef"):
        with pytest.raises(UserInputError) as caught:
            load_source(f"rules/ops.rules@{typo}")
        assert caught.value.diagnostics[0].code == "D001", typo
    with pytest.raises(UserInputError) as caught:  # a revision git knows, without the file
        load_source("rules/gone.rules@HEAD")
    assert caught.value.diagnostics[0].code == "D004"
    assert "does not exist in 'HEAD'" in caught.value.diagnostics[0].message


@needs_git
def test_a_revision_that_looks_like_an_option_is_refused(repo: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(repo)
    with pytest.raises(UserInputError) as caught:
        load_source("rules/ops.rules@--output=x")
    assert caught.value.diagnostics[0].code == "D001"
    assert not (repo / "x").exists()


@needs_git
def test_an_invalid_rulebook_at_a_revision_reports_line_and_column_of_that_text(
        repo: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(repo)
    with pytest.raises(UserInputError) as caught:
        load_source("rules/ops.rules@HEAD")
    rendered = caught.value.render()
    assert rendered.startswith("rules/ops.rules@HEAD:10:")
    assert "verdict acceptable_risk: require risk = 70 %" in rendered  # the source line


def test_a_folder_outside_git_is_a_user_error(tmp_path: Path) -> None:
    (tmp_path / "ops.rules").write_text(V1)
    with pytest.raises(UserInputError) as caught:
        load_source(f"{tmp_path / 'ops.rules'}@HEAD")
    assert caught.value.diagnostics[0].code in ("D003", "D004")


def test_a_missing_file_is_a_user_error(tmp_path: Path) -> None:
    with pytest.raises(UserInputError) as caught:
        load_source(str(tmp_path / "none.rules"))
    assert caught.value.diagnostics[0].code == "E002"
