"""A run into a folder that holds another campaign's finished results keeps them as
``results.previous.h5`` and says so; the next run, which replaces that copy, says that too:
no finished campaign goes without a word (the same campaign run again is set aside silently,
as it always was)."""

from __future__ import annotations

from pathlib import Path

import h5py
import pytest
from test_cli_user_errors import campaign, materialise

from idefix_rules.cli import main

RUN = ["--runs", "2", "--no-report", "--out", "out"]


def _name_of(path: Path) -> str:
    with h5py.File(path, "r") as file:
        return str(file.attrs["campaign_name"])


def test_another_campaigns_results_are_named_when_set_aside_and_when_replaced(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    materialise(tmp_path, campaign(), cli_toy_fmu)
    text = (tmp_path / "campaign.yaml").read_text()
    (tmp_path / "other.yaml").write_text(text.replace("name: cli\n", "name: other\n", 1))
    monkeypatch.chdir(tmp_path)
    results, kept = tmp_path / "out" / "results.h5", tmp_path / "out" / "results.previous.h5"

    def run(name: str) -> str:
        code = main([name, *RUN])
        assert code in (0, 1)  # the verdicts do not matter here
        captured = capsys.readouterr()
        return " ".join((captured.out + captured.err).split())

    assert "another campaign" not in run("campaign.yaml")
    said = run("campaign.yaml")  # the same campaign again: set aside, nothing to say
    assert "another campaign" not in said and _name_of(kept) == "cli"
    said = run("other.yaml")
    assert f"note: {results} held the results of another campaign (cli): they are kept as " \
        "results.previous.h5" in said, said
    assert (_name_of(results), _name_of(kept)) == ("other", "cli")
    said = run("other.yaml")
    assert f"note: {kept}, the results of another campaign (cli), is replaced by the ones " \
        "results.h5 held" in said, said
    assert (_name_of(results), _name_of(kept)) == ("other", "other")
