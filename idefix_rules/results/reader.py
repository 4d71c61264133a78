"""Reading a results file: :class:`StoredResults` opens one read only and hands back what a
campaign stored (provenance texts, paths, chains, reference runs, run status and signals).

The writer, :class:`idefix_rules.campaign.storage.store.ResultStore`, is this reader plus the
writing; everything that only reads a results file (evaluation, diff, report) goes through
the reading half.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import h5py
import numpy as np

from idefix_rules.commands import Command
from idefix_rules.errors import Span, UserInputError, error
from idefix_rules.results.format import (
    FORMAT,
    STATUS_COMPLETE,
    STATUS_FAILED,
    decode_reason,
)


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
        """A provenance text (``campaign``, ``rulebook``); KeyError when not stored."""
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
        return tuple(Command(*map(float, row)) for row in self.path_group(name)["chain"][()])

    def reference(self, name: str) -> dict[str, np.ndarray] | None:
        """The path's reference run (None when it failed or is not stored)."""
        group = self.path_group(name).get("reference")
        if group is None or group.attrs.get("status") != STATUS_COMPLETE:
            return None
        return {key: dataset[()] for key, dataset in group["signals"].items()}

    def has_runs(self, name: str) -> bool:
        group = self.path_group(name).get("runs")
        return group is not None and "status" in group

    def run_status(self, name: str) -> np.ndarray:
        return np.asarray(self.path_group(name)["runs"]["status"][()])

    def failures(self, name: str) -> dict[int, str]:
        group = self.path_group(name)["runs"]
        status = group["status"][()]
        reasons = group["failure"][()]
        return {int(j): decode_reason(reasons[j]) for j in np.flatnonzero(status == STATUS_FAILED)}

    def signal_names(self, name: str) -> list[str]:
        return list(self.path_group(name)["runs"]["signals"])

    def read_runs(self, name: str, selection: slice | np.ndarray,
                  keys: Sequence[str] | None = None) -> dict[str, np.ndarray]:
        """Signals of the selected runs, ``(runs, samples[, …])`` by contract name, as float64
        whatever their stored precision."""
        datasets = self.path_group(name)["runs"]["signals"]
        wanted = list(datasets) if keys is None else [k for k in keys if k in datasets]
        chosen = np.sort(selection) if isinstance(selection, np.ndarray) else selection
        return {key: np.asarray(datasets[key][chosen], dtype=np.float64) for key in wanted}
