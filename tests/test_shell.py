"""Commands printed to paste into a shell quote every path (a folder with a space, a `$`)."""

from __future__ import annotations

import shlex
from argparse import Namespace
from pathlib import Path

import pytest

from idefix_rules.campaign.simulation.resume import resume_command, stored_resume_command
from idefix_rules.shell import command_line


@pytest.mark.parametrize("word", ["plain.yaml", "my camp.yaml", "a$b", "it's", "ü/x y", ""])
def test_each_word_comes_back_as_one_argument(word: str) -> None:
    assert shlex.split(command_line("idefix-verify", word, "--runs", 8)) == \
        ["idefix-verify", word, "--runs", "8"]


def test_a_plain_word_is_left_as_it_is() -> None:
    assert command_line("idefix-verify", Path("campaigns/rock-detour.yaml"), "--seed", 1) == \
        "idefix-verify campaigns/rock-detour.yaml --seed 1"


def test_resume_and_search_commands_quote_their_paths() -> None:
    """They were pasted as `idefix-verify my camp.yaml --resume --out my out …`."""
    fixed = resume_command(Path("my camp.yaml"), Path("/w/my out"), 8, 1)
    assert fixed == "idefix-verify 'my camp.yaml' --resume --out '/w/my out' --runs 8 --seed 1"
    adaptive = resume_command(Path("my camp.yaml"), Path("o"), 400, 1, min_runs=32)
    assert shlex.split(adaptive)[1:] == ["my camp.yaml", "--resume", "--out", "o", "--runs",
                                         "auto", "--max-runs", "400", "--min-runs", "32",
                                         "--seed", "1"]
    search = stored_resume_command({"runs_mode": "worst", "runs": 64, "seed": 3},
                                   Path("my camp.yaml"), Path("my out"))
    assert search == "idefix-verify worst 'my camp.yaml' --out 'my out' --runs 64 --seed 3"


def test_the_commands_the_command_line_prints_again_quote_their_paths() -> None:
    from idefix_rules.cli import evaluate

    evaluated = evaluate.again(Namespace(results="my out/results.h5", rulebook="new rules.rules",
                                         junit=None, out=None))
    assert evaluated == \
        "idefix-verify evaluate 'my out/results.h5' --rulebook 'new rules.rules'"
