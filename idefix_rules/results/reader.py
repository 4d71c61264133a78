"""Reading a results file: :class:`StoredResults` opens one read only and hands back what a
campaign stored (provenance texts, paths, chains, reference runs, run status and signals).

The writer, :class:`idefix_rules.campaign.storage.store.ResultStore`, is this reader plus the
writing; everything that only reads a results file (evaluation, diff, report) goes through
the reading half.
"""

from __future__ import annotations

import contextlib
import re
import zlib
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import TypeGuard, cast

import h5py
import numpy as np
from zlib_ng import zlib_ng

from idefix_rules.commands import Command
from idefix_rules.errors import Span, UserInputError, error
from idefix_rules.results.format import (
    FORMAT,
    STATUS_COMPLETE,
    STATUS_FAILED,
    decode_reason,
)

DAMAGED = "H004"
# What reading a damaged file raises: HDF5's own errors (a chunk that no longer inflates, an
# object that is gone) are OSError or KeyError; a dataset of the wrong kind or shape gives
# ValueError or TypeError where its values are used; the runs' own decoding raises zlib's.
READ_ERRORS: tuple[type[BaseException], ...] = (OSError, KeyError, ValueError, TypeError,
                                                 zlib.error,
                                                 cast(type[BaseException], zlib_ng.error))


def damaged(path: Path, where: str, what: str) -> UserInputError:
    """The exit-2 error of a results file that cannot be read back as written."""
    return UserInputError(error(
        DAMAGED, f"results file {path} is damaged: {where}: {what}", Span(str(path)),
        hint="run the campaign again to write it anew (the file was changed or cut after it "
             "was written: a copy that stopped, a disk error, an edit)"))


def _stored_eof(message: str) -> str | None:
    """The length HDF5 says a truncated file had ("stored_eof = 15020173")."""
    found = re.search(r"stored_eof = (\d+)", message)
    return found.group(1) if found else None


@contextlib.contextmanager
def reading(path: Path, where: str) -> Iterator[None]:
    """Within: a failure to read ``where`` of the results file at ``path`` is :func:`damaged`.
    Used around reads and the few lines that unpack what they read (the readers of this module,
    the runs' decoding, the report's data), so that such a failure is the file's."""
    try:
        yield
    except UserInputError:
        raise
    except READ_ERRORS as failure:
        raise damaged(path, where, f"{type(failure).__name__}: {failure}") from None


def structure_problems(file: h5py.File) -> list[tuple[str, str]]:
    """What a results file lacks of the layout ``docs/results-format.md`` gives (checked on
    open, so that a deleted or replaced object is named instead of failing where it is used):
    the provenance texts stored, each path's index, chain and, where stored, its reference run
    and its runs (status, failure reasons and numeric signals, a row per planned run at most),
    the terrain's heights. Each as (object, what is wrong with it)."""
    problems: list[tuple[str, str]] = []
    provenance = file["provenance"]
    for key in provenance:  # a text missing is named where it is read
        item = provenance[key]
        if not isinstance(item, h5py.Dataset) or item.shape != () or item.dtype.kind not in "OSU":
            problems.append((f"/provenance/{key}", "not a text"))
    paths = file["paths"]
    for name in paths:
        group, where = paths[name], f"/paths/{name}"
        if not isinstance(group, h5py.Group):
            problems.append((where, "not a group"))
            continue
        if "index" not in group.attrs:
            problems.append((where, "no index attribute"))
        chain = group.get("chain")
        if not _numeric(chain) or chain.ndim != 2 or chain.shape[1] != 3:
            problems.append((f"{where}/chain",
                             "missing, or not a table of commands (3 numbers a row)"))
        reference = group.get("reference")
        finished = group.attrs.get("status") == "simulated" \
            and file.attrs.get("state") == "complete"
        if reference is None and finished:
            problems.append((f"{where}/reference", "missing, though the path was simulated"))
        elif reference is not None and reference.attrs.get("status") == STATUS_COMPLETE:
            problems += _signal_problems(reference.get("signals"), f"{where}/reference", None)
        runs = group.get("runs")
        if runs is None or "status" not in runs:  # not allocated yet (or cut off doing it)
            if finished:
                # the object that is gone: the runs' group, or its status beside the rest
                gone = f"{where}/runs" if runs is None or not len(runs) \
                    else f"{where}/runs/status"
                problems.append((gone, "missing, though the campaign finished"))
            continue
        status = runs["status"]
        if not _numeric(status) or status.ndim != 1 or status.dtype.kind not in "iu":
            problems.append((f"{where}/runs/status", "missing, or not a row of run states"))
            continue
        failure = runs.get("failure")
        if not isinstance(failure, h5py.Dataset) or failure.shape != status.shape:
            problems.append((f"{where}/runs/failure", "missing, or not one reason per run"))
        problems += _signal_problems(runs.get("signals"), f"{where}/runs", status.shape[0])
    terrain = file.get("terrain")
    if isinstance(terrain, h5py.Group) and "sha256" in terrain.attrs:  # written to its end
        heights = terrain.get("heights")
        if not _numeric(heights) or heights.ndim != 2:
            problems.append(("/terrain/heights", "missing, or not a grid of heights"))
    return problems


def _numeric(item: object) -> TypeGuard[h5py.Dataset]:
    return isinstance(item, h5py.Dataset) and item.dtype.kind in "fiub"


def _signal_problems(signals: object, where: str, runs: int | None
                     ) -> list[tuple[str, str]]:
    if not isinstance(signals, h5py.Group):
        return [(f"{where}/signals", "missing")]
    problems: list[tuple[str, str]] = []
    for key in signals:
        dataset = signals[key]
        if not _numeric(dataset) or dataset.ndim < (1 if runs is None else 2):
            problems.append((f"{where}/signals/{key}", "not numbers of the samples"))
        elif runs is not None and dataset.shape[0] > runs:
            # rows are allocated in blocks as runs are simulated: at most one per planned run
            problems.append((f"{where}/signals/{key}",
                             f"{dataset.shape[0]} rows for {runs} runs"))
    return problems


class StoredResults:
    """One ``results.h5`` opened to read (layout in ``docs/results-format.md``)."""

    def __init__(self, file: h5py.File, path: Path | None = None) -> None:
        self.file = file
        self.path = Path(path if path is not None else file.filename)

    @classmethod
    def open(cls, path: Path) -> StoredResults:
        """Open an existing results file read only; :class:`UserInputError` (``H001``-``H003``)
        if it is missing or not one."""
        return cls.opened(Path(path), "r")

    @classmethod
    def opened(cls, path: Path, mode: str, damaged_hint: str | None = None
               ) -> StoredResults:
        """The results file at ``path`` opened in h5py ``mode`` and checked to be one
        (``damaged_hint``: what to say when HDF5 cannot read it)."""
        try:
            file = h5py.File(path, mode)
        except FileNotFoundError:
            raise UserInputError(error("H001", f"results file {path} not found",
                                       Span(str(path)))) from None
        except IsADirectoryError:
            raise UserInputError(error("H002", f"cannot open results file {path}: a folder",
                                       Span(str(path)), hint="give its results.h5")) from None
        except OSError as failure:
            if not h5py.is_hdf5(path):
                raise UserInputError(error(
                    "H002", f"cannot open results file {path}: not an HDF5 file", Span(str(path)),
                    hint="give the results.h5 a campaign run wrote")) from None
            if "truncated file" in str(failure):  # HDF5: "truncated file: eof = …"
                # shorter than HDF5 wrote it: a copy that stopped, a disk that filled
                size = path.stat().st_size
                raise damaged(path, "the whole file", f"it is cut short ({size} bytes of the "
                              f"{_stored_eof(str(failure)) or 'more'} HDF5 wrote)") from None
            raise UserInputError(error(
                "H002", f"cannot open results file {path}: {failure}", Span(str(path)),
                hint=damaged_hint)) from None
        store = cls(file, path)
        if file.attrs.get("format") != FORMAT:
            store.close()
            raise UserInputError(error("H003", f"{path} is not an idefix results file",
                                       Span(str(path))))
        missing = [name for name in ("provenance", "paths") if name not in file]
        if missing:
            store.close()
            raise UserInputError(error("H003", f"{path} is an incomplete idefix results file "
                                               f"(no {' or '.join(missing)} group)",
                                       Span(str(path)), hint="run the campaign again"))
        try:
            problems = structure_problems(file)
            # a writer (--resume) mends what a cut-off write left (a block allocated without
            # its states): only metadata that does not read at all stops it
            problems = problems if mode == "r" else []
        except READ_ERRORS as failure:  # the metadata itself does not read
            problems = [("its layout", f"{type(failure).__name__}: {failure}")]
        if problems:
            store.close()
            (where, what), *more = problems
            raise damaged(path, where, what + (f" (and {len(more)} more)" if more else ""))
        return store

    def close(self) -> None:
        if self.file.id.valid:
            self.file.close()

    def __enter__(self) -> StoredResults:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def folder(self) -> Path:
        """The folder of the results file."""
        return self.path.parent

    @property
    def attrs(self) -> h5py.AttributeManager:
        return self.file.attrs

    def text(self, key: str) -> str:
        """A provenance text (``campaign``, ``rulebook``); H004 when not stored."""
        with reading(self.path, f"/provenance/{key}"):
            value = self.file["provenance"][key][()]
            return value.decode("utf-8") if isinstance(value, bytes) else str(value)

    # --- paths ------------------------------------------------------------------------------

    @property
    def path_names(self) -> list[str]:
        group = self.file["paths"]
        return sorted(group, key=lambda name: int(group[name].attrs["index"]))

    def path_group(self, name: str) -> h5py.Group:
        return self.file["paths"][name]

    def has_path(self, name: str) -> bool:
        return name in self.file["paths"]

    def chain(self, name: str) -> tuple[Command, ...]:
        """The path's stored command chain."""
        with reading(self.path, f"/paths/{name}/chain"):
            return tuple(Command(*map(float, row)) for row in self.path_group(name)["chain"][()])

    def reference(self, name: str) -> dict[str, np.ndarray] | None:
        """The path's reference run (None when it failed or is not stored)."""
        group = self.path_group(name).get("reference")
        if group is None or group.attrs.get("status") != STATUS_COMPLETE:
            return None
        with reading(self.path, f"/paths/{name}/reference"):
            signals = {key: dataset[()] for key, dataset in group["signals"].items()}
        for key, values in signals.items():
            # a run is stored only when every output of it is finite (worker.check_outputs)
            if np.asarray(values).dtype.kind in "fc" and not np.all(np.isfinite(values)):
                raise damaged(self.path, f"/paths/{name}/reference/signals/{key}",
                              "holds values that are not finite, which no stored run does")
        return signals

    def has_runs(self, name: str) -> bool:
        group = self.path_group(name).get("runs")
        return group is not None and "status" in group

    def run_status(self, name: str) -> np.ndarray:
        with reading(self.path, f"/paths/{name}/runs/status"):
            return np.asarray(self.path_group(name)["runs"]["status"][()])

    def failures(self, name: str) -> dict[int, str]:
        with reading(self.path, f"/paths/{name}/runs/failure"):
            group = self.path_group(name)["runs"]
            status = group["status"][()]
            reasons = group["failure"][()]
            return {int(j): decode_reason(reasons[j])
                    for j in np.flatnonzero(status == STATUS_FAILED)}

    def signal_names(self, name: str) -> list[str]:
        return list(self.path_group(name)["runs"]["signals"])

    def read_runs(self, name: str, selection: slice | np.ndarray,
                  keys: Sequence[str] | None = None) -> dict[str, np.ndarray]:
        """Signals of the selected runs, ``(runs, samples[, …])`` by contract name, as float64
        whatever their stored precision."""
        datasets = self.path_group(name)["runs"]["signals"]
        wanted = list(datasets) if keys is None else [k for k in keys if k in datasets]
        chosen = np.sort(selection) if isinstance(selection, np.ndarray) else selection
        with reading(self.path, f"/paths/{name}/runs/signals"):
            return {key: np.asarray(datasets[key][chosen], dtype=np.float64) for key in wanted}
