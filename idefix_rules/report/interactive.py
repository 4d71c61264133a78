"""The data of the report's interactive map and run panel, as one JSON document in the page.

The page's own script (:mod:`.script`) draws from it; nothing is fetched. Contents: the map grid
and, per path, each crossed cell's sum of run maxima, runs, dominant index and worst embedded
run; reference, ideal and wheel tracks; contacts; the embedded runs (thinned, display units);
for a worst-case search, the embedded run that is the path's worst (``worst``); obstacles; and
each time series' limit from the rulebook (the limit of the index that reads the series'
signal, converted to the series' unit).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from idefix_rules.campaign.input.wording import DisplayUnits, parameter_text
from idefix_rules.report.data import ReportData
from idefix_rules.report.figures import path_colour
from idefix_rules.report.prepare import WHEEL_WIDTH, MapSet, Setup
from idefix_rules.report.runs import MAX_CONTACTS, SERIES


def _track(x: np.ndarray, y: np.ndarray, points: int = 300) -> list[list[float]]:
    """A polyline thinned to about ``points`` vertices (mm resolution)."""
    keep = np.isfinite(x) & np.isfinite(y)
    x, y = np.asarray(x)[keep], np.asarray(y)[keep]
    if x.size > points:
        pick = np.unique(np.linspace(0, x.size - 1, points).round().astype(int))
        x, y = x[pick], y[pick]
    return [[round(float(v), 4) for v in x], [round(float(v), 4) for v in y]]


def index_info(setup: Setup) -> dict[str, dict[str, str]]:
    """Title and rationale of every index of the stored rulebook."""
    rulebook = getattr(setup.checked, "rulebook", None)
    return {index.name: {"title": index.title or "", "rationale": index.rationale or ""}
            for index in getattr(rulebook, "indices", ())}


def series_limits(setup: Setup) -> dict[str, float]:
    """Per series key: the limit of the index reading its signal, in the series' unit."""
    from idefix_rules.rulebook.semantics import names_in

    rulebook = getattr(setup.checked, "rulebook", None)
    limits = dict(getattr(setup.checked, "limits", {}) or {})
    found: dict[str, float] = {}
    for index in getattr(rulebook, "indices", ()):
        names = names_in(index.value)
        for spec in SERIES:
            if spec.key in found or index.name not in limits:
                continue
            if spec.signal in names and spec.key != "clearance":
                found[spec.key] = limits[index.name] * spec.scale
    found.setdefault("clearance", 0.0)  # 0 = contact
    return found


def _sparse_cells(maps: MapSet, name: str, names: list[str]) -> list[list[Any]]:
    accumulator = maps.per_path[name]
    rows = []
    for cell, runs, dominant, count, worst in maps.cells[name].cells(names):
        rows.append([cell, round(float(accumulator.total[cell]), 4), runs, dominant, count,
                     worst])
    return rows


def payload(data: ReportData, setup: Setup, maps: MapSet, units: DisplayUnits,
            worst: Mapping[str, int] | None = None) -> dict[str, Any]:
    """Everything the page's script reads; ``worst``: per path, the row of the worst run a
    worst-case search found (the page marks it when it holds that run)."""
    grid = maps.grid
    order = [path.name for path in data.paths]
    paths = []
    for position, path in enumerate(data.paths):
        entry: dict[str, Any] = {"name": path.name, "colour": path_colour(position),
                                 "verdict": path.row.verdict or path.status}
        if path.name in maps.reference_tracks:
            entry["reference"] = _track(*maps.reference_tracks[path.name])
        if path.name in maps.ideal_tracks:
            entry["ideal"] = _track(*maps.ideal_tracks[path.name])
        if path.name in maps.wheel_tracks:
            entry["wheels"] = {wheel: _track(*track)
                               for wheel, track in maps.wheel_tracks[path.name].items()}
        if path.name in maps.cells:
            entry["cells"] = _sparse_cells(maps, path.name, path.index_names)
            contacts = maps.contacts.get(path.name, [])
            entry["contacts"] = contacts[:MAX_CONTACTS]
            entry["contacts_total"] = len(contacts)
            runs = {}
            for run, series in maps.series.get(path.name, {}).items():
                position_ = int(path.dominant[run])
                dominant = (path.index_names[position_]
                            if 0 <= position_ < len(path.index_names) else None)
                runs[str(run)] = {
                    **series, "i_max": round(float(path.i_max[run]), 4), "dominant": dominant,
                    "parameters": [
                        [key, parameter_text(key, float(values[run]),
                                             path.parameter_units.get(key, ""), units)]
                        for key, values in path.parameters.items()
                        if math.isfinite(float(values[run]))]}
            entry["runs"] = runs
            row = (worst or {}).get(path.name)
            if row is not None and str(row) in runs:
                entry["worst"] = int(row)
        paths.append(entry)
    env = setup.environment
    return {
        "grid": {"x0": grid.x0, "y0": grid.y0, "cell": grid.cell, "nx": grid.nx,
                 "ny": grid.ny},
        "order": order,
        "indices": index_info(setup),
        "series": [{"key": s.key, "title": s.title, "unit": s.unit} for s in SERIES],
        "limits": series_limits(setup),
        "rover": {"half_track": setup.rover.half_track,
                  "half_wheelbase": setup.rover.half_wheelbase, "wheel_width": WHEEL_WIDTH},
        "rocks": [{"name": r.name, "x": r.x, "y": r.y, "a": r.a, "b": r.b, "level": r.level,
                   "buffer": r.buffer} for r in env.rocks],
        "areas": [{"name": a.name, "polygon": np.round(a.polygon, 4).tolist(),
                   "level": a.level, "buffer": a.buffer} for a in env.areas],
        "paths": paths,
    }


def payload_json(value: Mapping[str, Any]) -> str:
    """JSON safe inside a ``<script type="application/json">`` element."""
    text = json.dumps(value, allow_nan=False, separators=(",", ":"))
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")
