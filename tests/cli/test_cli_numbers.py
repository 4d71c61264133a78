"""The command line's number arguments at their limits: the largest accepted and the first
refused (a usage error, exit 2, through argparse)."""

from __future__ import annotations

import argparse

import pytest

from idefix_rules.cli.numbers import worker_count
from idefix_rules.limits import MAX_WORKERS


def test_worker_count_takes_one_to_its_limit_and_refuses_beyond() -> None:
    assert worker_count("1") == 1
    assert worker_count(str(MAX_WORKERS)) == MAX_WORKERS == 1024
    for text in ("0", str(MAX_WORKERS + 1), "-2"):
        with pytest.raises(argparse.ArgumentTypeError):
            worker_count(text)
