"""The evaluation as results.h5 stores it: each path's ``evaluation`` group and ``/evaluation``."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

import h5py
import numpy as np

from idefix_rules.campaign.input.waivers import STORED_ATTRIBUTE, WaivedRule, to_store
from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.plain import as_plain
from idefix_rules.results.collisions import CONTACT_COLUMNS

# From this many rows on the evaluation's per-run arrays are stored compressed (shuffle+gzip).
COMPRESSED_ROWS = 1024

# The dataset of /evaluation holding the text of the rulebook it was made with.
EVALUATION_RULEBOOK = "rulebook_text"


def raw_units(evaluator: Any) -> dict[str, str]:
    """Each index's value before normalisation in its SI unit ("1": a ratio or a count)."""
    return {str(name): "1" if kind.dimension.is_dimensionless else str(kind.dimension)
            for name, kind in evaluator.checked.index_types.items()}


def write_path_evaluation(store: ResultStore, name: str, evaluation: Any,
                           extra: dict[str, Any], stats: Any, verdict: Any, runs: int,
                           waived: Sequence[WaivedRule] = (),
                           units: dict[str, str] | None = None) -> None:
    group = store.path_group(name)
    if "evaluation" in group:
        del group["evaluation"]
    target = group.create_group("evaluation")
    rows = extra["rows"]

    def full(values: np.ndarray, fill: float = np.nan, dtype: Any = np.float64) -> np.ndarray:
        values = np.asarray(values)
        out = np.full((runs, *values.shape[1:]), fill, dtype=dtype)
        out[rows] = values
        return out

    def array(group: h5py.Group, key: str, data: np.ndarray) -> None:
        if runs < COMPRESSED_ROWS:  # small: contiguous costs less than a chunk index
            group.create_dataset(key, data=data)
            return
        # rows of runs not (yet) complete are NaN / 0 and compress to almost nothing
        group.create_dataset(key, data=data, compression="gzip", compression_opts=1,
                             shuffle=True)

    index_names = list(getattr(evaluation, "index_names", ()))
    target.attrs["index_names"] = json.dumps(index_names)
    for section in ("values", "raw"):
        data = getattr(evaluation, section, {}) or {}
        sub = target.create_group("indices" if section == "values" else "raw")
        for key, values in data.items():
            array(sub, key, full(values))
            unit = "1" if section == "values" else (units or {}).get(key)
            if unit is not None:
                sub[key].attrs["unit"] = unit
    array(target, "i_max", full(evaluation.i_max))
    target["i_max"].attrs["unit"] = "1"
    array(target, "dominant", full(evaluation.dominant, -1, np.int16))
    array(target, "time", full(evaluation.time))
    target["time"].attrs["unit"] = "s"
    # 1: the chain was complete within the stop time, 0: still driving at it, -1: not known
    finished = extra.get("finished")
    array(target, "finished", full(finished, -1, np.int8) if finished is not None
          else np.full(runs, -1, dtype=np.int8))
    array(target, "energy", full(evaluation.energy))
    target["energy"].attrs["unit"] = "A·s"
    chances = target.create_group("chances")
    for key, values in (getattr(evaluation, "chances", {}) or {}).items():
        array(chances, key, full(values, 0, np.int8))
    if extra.get("hits") is not None:
        collisions = target.create_group("collisions")
        array(collisions, "hits", full(extra["hits"]))
        if extra.get("buffer") is not None:
            array(collisions, "buffer", full(extra["buffer"]))
        _write_details(collisions, runs, extra.get("details", []))
        if extra.get("contact") is not None:  # per-sample contacts as intervals (format 5)
            table = collisions.create_dataset("contact", data=extra["contact"])
            table.attrs["columns"] = list(CONTACT_COLUMNS)
        if extra.get("clearance_profile") is not None:
            array(collisions, "clearance_profile", full(extra["clearance_profile"]))
            collisions["clearance_profile"].attrs["unit"] = "m"
    target.attrs["statistics"] = json.dumps(as_plain(stats))
    target.attrs["verdict"] = json.dumps(as_plain(verdict))
    # the verdict rules waived on the path, which ``verdict`` leaves out: a reader without the
    # summary (report) still tells a waived path from a passing one
    target.attrs[STORED_ATTRIBUTE] = to_store("", waived)
    store.file.flush()


def _write_details(group: h5py.Group, runs: int,
                   chunks: Sequence[tuple[np.ndarray, np.ndarray]]) -> None:
    """The per-run collision details (``""`` for a run without), written a chunk of runs at a
    time so that only one chunk's texts are ever Python strings."""
    dataset = group.create_dataset("details", shape=(runs,), dtype=h5py.string_dtype("utf-8"))
    for rows, texts in chunks:
        if not len(rows):
            continue
        first, stop = int(rows[0]), int(rows[-1]) + 1
        block = np.full(stop - first, "", dtype=object)
        block[np.asarray(rows) - first] = [text.decode("utf-8") for text in texts]
        dataset[first:stop] = block


def drop_evaluation(target: ResultStore, name: str) -> None:
    """A path the rulebook scoring it would not simulate (rejected, excluded) keeps no
    evaluation of the rulebook before: the report and readers would show it as current. Its
    status stays the campaign's (what was simulated, so that the next ``evaluate`` gates it
    again from there); what this rulebook says of it is in the summary."""
    group = target.path_group(name)
    if "evaluation" in group:
        del group["evaluation"]


def write_campaign_evaluation(target: ResultStore, evaluator: Any,
                              rulebook_info: Mapping[str, str], ranking: Sequence[str],
                              ties: Sequence[tuple[str, str]]) -> None:
    """The ``/evaluation`` group's attributes: the rulebook, its text, ranking, ties, time."""
    root = target.file.require_group("evaluation")
    for key, value in rulebook_info.items():
        root.attrs[f"rulebook_{key}"] = value
    # the rulebook text this evaluation used (`evaluate --rulebook` judges with another
    # than /provenance/rulebook): what the report draws its limits and maps with
    if EVALUATION_RULEBOOK in root:
        del root[EVALUATION_RULEBOOK]
    root.create_dataset(EVALUATION_RULEBOOK, data=evaluator.checked.rulebook.source,
                        dtype=h5py.string_dtype("utf-8"))
    root.attrs["ranking"] = json.dumps(ranking)
    root.attrs["ties"] = json.dumps(ties)
    from idefix_rules.timestamps import now_iso

    root.attrs["evaluated"] = now_iso()
    target.file.flush()
