"""``idefix-verify worst CAMPAIGN.yaml``: the worst case of each chain, and how far it is.

Prints, per path, the nominal world's run risk, the worst world found (its risk, dominant index
and how rare it is) and the smallest change from the nominal world found to make the chain
critical; then each path's worst world parameter by parameter (value and quantile) and its
failure boundary along every ray searched. ``worst.json`` holds the same as data
(docs/worst-case.md). The search and its output live in :mod:`idefix_rules.cli.worst_command`,
imported when the command runs.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from idefix_rules.cli.destinations import output_folder, scheduler_address
from idefix_rules.cli.numbers import integer, positive_int, seconds, seed_number, worker_count
from idefix_rules.limits import MAX_WORKERS

NAME = "worst"
HELP = ("Search each chain's uncertainty for the worlds of highest run risk (cross-entropy "
        "method on the campaign's FMU and pool) and the smallest change from the nominal "
        "world that makes it critical; stores the searched runs (results.h5, for evaluate, "
        "diff and report) and worst.json in <output>/worst. Exit 0 when searched, 2 invalid "
        "input, 3 infrastructure error.")

DEFAULT_RUNS = 250


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("campaign", type=Path, help="campaign file (YAML)")
    parser.add_argument("--runs", type=positive_int, default=DEFAULT_RUNS, metavar="N",
                        help="run budget per path, search and boundary together (default "
                             f"{DEFAULT_RUNS}: a quarter of a 1000-run campaign)")
    parser.add_argument("--seed", type=seed_number, help="seed of the search, 0 … 2^64 - 1 "
                        "(default: the campaign's `uncertainty.seed`)")
    parser.add_argument("--workers", type=worker_count,
                        help=f"worker processes, at most {MAX_WORKERS}, or auto: all cores "
                             "(default: the campaign's `workers`, else all cores)")
    parser.add_argument("--out", type=output_folder,
                        help="output folder (default: the campaign's output folder + /worst)")
    parser.add_argument("--critical", type=_level, default=1.0, metavar="LEVEL",
                        help="run risk I_max at which a run counts as critical, in (0, 1] or "
                             "as a percentage (default 1: an index at its critical limit)")
    parser.add_argument("--tail", type=_tail, default=None, metavar="P",
                        help="search worlds whose every parameter lies within its P … 1-P "
                             "quantiles (default 0.0001)")
    parser.add_argument("--axes", type=_count, default=2, metavar="K",
                        help="most sensitive parameters whose axis the failure boundary is "
                             "also searched along (default 2)")
    parser.add_argument("--rounds", type=positive_int, default=3, metavar="R",
                        help="bisection rounds of the failure boundary, each shrinking its "
                             "bracket to a quarter (default 3)")
    parser.add_argument("--run-timeout", type=seconds, metavar="SECONDS",
                        help="a run taking longer is killed and recorded as failed (default: "
                             "as for a campaign; 0: none)")
    parser.add_argument("--quiet", action="store_true", help="no progress")
    parser.add_argument("--no-report", action="store_true", help="skip the HTML report")
    cluster = parser.add_mutually_exclusive_group()
    cluster.add_argument("--scheduler", metavar="ADDRESS", type=scheduler_address,
                         help="run on a Dask distributed cluster (scheduler address)")
    cluster.add_argument("--dask-local", action="store_true",
                         help="run on a local Dask cluster instead of the process pool")


def _level(text: str) -> float:
    raw = text.strip()
    scale = 1.0
    if raw.endswith("%"):
        raw, scale = raw[:-1].strip(), 0.01
    try:
        if not raw.isascii():
            raise ValueError(raw)
        value = float(raw) * scale
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a run risk such as 1, 0.9 or 90 %, "
                                         f"got {text!r}") from None
    if not 0.0 < value <= 1.0:
        # `--critical 90 %` unquoted: the shell hands over 90 and a stray %
        percent = (f"; for {raw} %, write it as one argument: --critical {raw}% or "
                   f"--critical \"{raw} %\"" if scale == 1.0 and 1.0 < value <= 100.0 else "")
        raise argparse.ArgumentTypeError(f"a run risk lies in (0, 1] (0 % … 100 %), got "
                                         f"{text}{percent}")
    return value


def _tail(text: str) -> float:
    try:
        if not text.isascii():
            raise ValueError(text)
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a probability such as 0.0001, got "
                                         f"{text!r}") from None
    if not 0.0 < value < 0.5:
        raise argparse.ArgumentTypeError(f"a tail probability lies in (0, 0.5), got {text}")
    return value


def _count(text: str) -> int:
    value = integer(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0, got {text}")
    return value


def run(args: argparse.Namespace) -> int:
    from idefix_rules.cli.worst_command import run as search

    return search(args)
