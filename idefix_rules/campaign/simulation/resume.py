"""What ``--resume`` simulates again, and the command that continues a campaign.

A run is simulated (again) when it has no stored outcome (killed before it was written), or
when it failed because of the infrastructure rather than for its own reason (its process was
killed from outside again and again, its Dask workers died under it, its result was lost:
reasons starting with ``infrastructure:``); a path whose reference run was lost so starts
again. A campaign is complete when no reference run and no run of a simulated path is left to
simulate.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from idefix_rules.campaign.simulation.processes import INFRASTRUCTURE, is_infrastructure
from idefix_rules.campaign.storage.store import (
    STATUS_COMPLETE,
    STATUS_FAILED,
    STATUS_MISSING,
    decode_reason,
)
from idefix_rules.results.format import attribute_text, is_search
from idefix_rules.shell import command_line

__all__ = ["INFRASTRUCTURE", "continue_command", "execution_options", "interrupted_runs",
           "is_infrastructure", "resume_command", "runs_to_simulate", "search_command",
           "stored_resume_command"]


def runs_to_simulate(store: Any, name: str, reset: bool = False) -> np.ndarray:
    """Indices of the runs of path ``name`` still to simulate.

    With ``reset`` the runs failed for infrastructure are marked missing again first (their
    reason cleared), so the file never shows an old reason beside new data.
    """
    runs = store.path_group(name)["runs"]
    status = np.asarray(runs["status"][()])
    failed = np.flatnonzero(status == STATUS_FAILED)
    again = []
    if failed.size:
        reasons = runs["failure"][()]
        again = [int(j) for j in failed if is_infrastructure(decode_reason(reasons[j]))]
    if reset and again:
        for run in again:
            runs["failure"][run] = b""
            runs["status"][run] = STATUS_MISSING
        store.file.flush()
    return np.union1d(np.flatnonzero(status == STATUS_MISSING),
                      np.asarray(again, dtype=np.int64)).astype(np.int64)


def interrupted_runs(results: Path) -> tuple[int, int] | None:
    """``(runs stored, runs planned)`` of a results file whose campaign was interrupted (its
    state ``running`` or ``interrupted``: killed, stopped, or lost to the infrastructure);
    None when there is no such file, its campaign completed, or it cannot be read. A run
    without ``--resume`` sets such a file aside, and says so first."""
    from idefix_rules.campaign.storage.store import ResultStore

    if not Path(results).is_file():
        return None
    try:
        store = ResultStore.open(Path(results))
    except Exception:  # unreadable: nothing to resume from either
        return None
    try:
        if str(store.attrs.get("state", "complete")) not in ("running", "interrupted") or \
                is_search(store.attrs):  # a search is run again, never resumed
            return None
        stored = planned = 0
        for name in store.path_names:
            if store.has_runs(name):
                status = np.asarray(store.path_group(name)["runs"]["status"][()])
                stored += int(np.sum(status == STATUS_COMPLETE))
                planned += int(status.size)
        return stored, planned
    except Exception:
        return None
    finally:
        store.close()


def root_attributes(results: Path) -> dict[str, Any] | None:
    """A results file's root attributes; None when there is no such file or it cannot be read
    (what a run finds in its folder is named, and said, from them)."""
    import h5py

    if not Path(results).is_file():
        return None
    try:
        with h5py.File(results, "r") as file:
            return dict(file.attrs)
    except Exception:  # unreadable: nothing to name
        return None


def stored_campaign(results: Path) -> str | None:
    """The name of the campaign a results file holds; None when there is no such file or it
    cannot be read (what a run sets aside is named by it)."""
    attrs = root_attributes(results)
    name = None if attrs is None else attrs.get("campaign_name")
    return None if name is None else attribute_text(name)


def stored_search(results: Path) -> bool:
    """Whether a results file holds a worst-case search (False: none, or unreadable)."""
    attrs = root_attributes(results)
    return attrs is not None and is_search(attrs)


def reference_lost(store: Any, name: str) -> bool:
    """Whether path ``name``'s reference run was lost to the infrastructure (``--resume``
    starts the path again)."""
    group = store.path_group(name)
    return str(group.attrs.get("status", "")) == "reference_failed" \
        and is_infrastructure(str(group.attrs.get("reason", "")))


def nothing_left(store: Any, names: list[str]) -> bool:
    """Whether every path of ``names`` has its reference run and all its runs done for good."""
    return all(not (store.has_path(name) and reference_lost(store, name))
               and (not store.has_runs(name) or runs_to_simulate(store, name).size == 0)
               for name in names)


def resume_command(source: Any, output: Any, runs: Any, seed: Any,
                   min_runs: Any = None, execution: Sequence[object] = ()) -> str:
    """The command that continues this campaign into the same results file (``min_runs``
    given: an adaptive campaign, ``runs`` is its cap), with the options of ``execution``
    (:func:`execution_options`: where and how the interrupted command ran)."""
    count = ("--runs", runs) if min_runs is None else (
        "--runs", "auto", "--max-runs", runs, "--min-runs", min_runs)
    return command_line("idefix-verify", source, "--resume", "--out", output, *count,
                        "--seed", seed, *execution)


def execution_options(workers: int | None = None, scheduler: str | None = None,
                      dask_local: bool = False, run_timeout: float | None = None,
                      junit: Any = None, report: bool = True) -> list[object]:
    """The options of a run that a resume of it should be given again: the workers or
    cluster it ran on, its run timeout, its JUnit file and whether it wrote a report (none
    changes a stored number, but an operator continuing a campaign continues it as it ran).

    >>> execution_options(2, None, False, 30.0, "out/junit.xml", report=False)
    ['--workers', 2, '--run-timeout', '30', '--junit', 'out/junit.xml', '--no-report']
    >>> execution_options(scheduler="tcp://10.0.0.5:8786")
    ['--scheduler', 'tcp://10.0.0.5:8786']
    >>> execution_options(run_timeout=1234567.0)  # every digit, as it was given
    ['--run-timeout', '1234567']
    """
    words: list[object] = []
    if workers is not None:
        words += ["--workers", workers]
    if scheduler is not None:
        words += ["--scheduler", scheduler]
    if dask_local:
        words.append("--dask-local")
    if run_timeout is not None:
        words += ["--run-timeout", _number(run_timeout)]
    if junit is not None:
        words += ["--junit", junit]
    if not report:
        words.append("--no-report")
    return words


def search_command(source: Any, output: Any, runs: Any, seed: Any, threshold: Any = None,
                   tail: Any = None, axes: Any = None, rounds: Any = None,
                   execution: Sequence[object] = ()) -> str:
    """The command that runs a worst-case search again into the same folder: its budget,
    seed and shape (``--critical``, ``--tail``, ``--axes``, ``--rounds``: those known), and the
    options of ``execution``.

    >>> search_command("c.yaml", "out", 200, 7, 1.0, 0.01, 2, 3, ["--no-report"])
    'idefix-verify worst c.yaml --out out --runs 200 --seed 7 --critical 1 --tail 0.01 \
--axes 2 --rounds 3 --no-report'
    """
    words: list[object] = ["idefix-verify", "worst", source, "--out", output, "--runs", runs,
                           "--seed", seed]
    for flag, value in (("--critical", threshold), ("--tail", tail)):
        if value is not None:
            words += [flag, _number(float(value))]
    for flag, value in (("--axes", axes), ("--rounds", rounds)):
        if value is not None:
            words += [flag, int(value)]
    return command_line(*words, *execution)


def _number(value: float) -> str:
    """A number as a command takes it back unchanged (``30``, ``0.01``, ``1234567``): a
    whole number without its ``.0``, any other as Python's shortest exact spelling."""
    return str(int(value)) if value.is_integer() else repr(value)


def stored_resume_command(attrs: Any, source: Any, output: Any,
                          execution: Sequence[object] = ()) -> str:
    """The command that continues the campaign of a results file whose root attributes are
    ``attrs``: with its stored run count and seed (an adaptive one's cap and first look),
    whatever the command that found the file asked for (``--resume`` refuses others). A
    worst-case search cannot be resumed: the command that runs it again, into the same
    folder, with its budget and seed."""
    if is_search(attrs):
        return search_command(source, output, attrs.get("runs"), attrs.get("seed"),
                              attrs.get("worst_threshold"), attrs.get("worst_tail"),
                              attrs.get("worst_axes"), attrs.get("worst_rounds"), execution)
    adaptive = str(attrs.get("runs_mode", "fixed")) == "auto"
    return resume_command(source, output, attrs.get("runs"), attrs.get("seed"),
                          attrs.get("min_runs") if adaptive else None, execution)


def continue_command(results: Path, source: Any,
                     execution: Sequence[object] = ()) -> str | None:
    """:func:`stored_resume_command` of the results file ``results`` (its folder as
    ``--out``); None when it cannot be read."""
    attrs = root_attributes(results)
    if attrs is None or "runs" not in attrs or "seed" not in attrs:
        return None
    return stored_resume_command(attrs, source, Path(results).parent, execution)
