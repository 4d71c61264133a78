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


def test_worker_count_auto_is_every_core_as_in_a_campaign(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """`--workers auto` overrides a campaign's number with all cores, as `workers: auto`
    means in the campaign; the limit still holds, and a machine that cannot say has one."""
    import os

    monkeypatch.setattr(os, "cpu_count", lambda: 6)
    assert worker_count("auto") == worker_count(" AUTO ") == 6
    monkeypatch.setattr(os, "cpu_count", lambda: MAX_WORKERS + 10)
    assert worker_count("auto") == MAX_WORKERS
    monkeypatch.setattr(os, "cpu_count", lambda: None)
    assert worker_count("auto") == 1
    with pytest.raises(argparse.ArgumentTypeError):
        worker_count("autos")
