"""The warnings `diff --results` gives on one results file, said in its text and in its JSON
(imported by name, as the other helpers of the campaign tests)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from idefix_rules.cli import main


def diff_warnings(rulebook: Path, results: Path,
                  capsys: pytest.CaptureFixture[str]) -> tuple[str, list[str]]:
    """A rulebook diffed against itself over ``results`` (no verdict changes: exit 0): the
    console's words and the file's JSON ``warnings``."""
    argv = ["diff", str(rulebook), str(rulebook), "--results", str(results)]
    assert main(argv) == 0
    captured = capsys.readouterr()
    words = " ".join((captured.out + captured.err).split())
    assert main([*argv, "--format", "json"]) == 0
    [diffed] = json.loads(capsys.readouterr().out)["results"]["files"]
    return words, list(diffed["warnings"])
