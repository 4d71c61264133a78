"""Argument types for the numbers of the command line (counts, seeds, seconds): refused at
parse time with a usage error (exit 2) naming what was expected."""

from __future__ import annotations

import argparse
import math
import os
import re

from idefix_rules.limits import MAX_RUNS, MAX_SEED, MAX_WORKERS


def positive_int(text: str) -> int:
    value = integer(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive whole number, got {text}")
    return value


def worker_count(text: str) -> int:
    """A number of worker processes, or ``auto``: every core (as ``workers: auto`` in a
    campaign), overriding the campaign's number."""
    if text.strip().lower() == "auto":
        return max(1, min(os.cpu_count() or 1, MAX_WORKERS))
    value = positive_int(text)
    if value > MAX_WORKERS:
        raise argparse.ArgumentTypeError(f"at most {MAX_WORKERS} worker processes, got {text}")
    return value


def run_count(text: str) -> int | str:
    if text.strip().lower() == "auto":
        return "auto"
    return run_count_only(text)


def run_count_only(text: str) -> int:
    value = positive_int(text)
    if value > MAX_RUNS:
        raise argparse.ArgumentTypeError(f"at most {MAX_RUNS} runs per path, got {text}")
    return value


def seed_number(text: str) -> int:
    value = integer(text)
    if not 0 <= value <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"a seed is a whole number from 0 to 2^64 - 1 "
                                         f"({MAX_SEED}), got {text}")
    return value


def integer(text: str) -> int:
    # int() would also take '７', '1_000' and a thousand digits; a count or seed is [0-9]+
    if not re.fullmatch(r"[ \t]*[-+]?[0-9]{1,40}[ \t]*", text):
        digits = " written with the digits 0-9" if not text.isascii() else ""
        raise argparse.ArgumentTypeError(f"expected a whole number{digits}, got {text!r}")
    return int(text)


def seconds(text: str) -> float:
    try:
        if not text.isascii():  # float() would take '５'
            raise ValueError(text)
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not 0 <= value < math.inf:  # also refuses nan and inf (no timeout: 0)
        raise argparse.ArgumentTypeError(f"expected a number of seconds >= 0 (0: no timeout), "
                                         f"got {text}")
    return value
