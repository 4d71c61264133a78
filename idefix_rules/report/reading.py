"""The report's data read back from results.h5 and its stored summary."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from idefix_rules.campaign.input.waivers import recorded
from idefix_rules.campaign.statistics.pairwise import PairComparison
from idefix_rules.report.data import Header, PathReport, ReportData, TableRow
from idefix_rules.results.format import STATUS_COMPLETE, STATUS_FAILED, drawn_paired
from idefix_rules.results.reader import StoredResults, reading


def _text(value: Any) -> str:
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    return "" if value is None else str(value)


def _json(value: Any, default: Any) -> Any:
    if value is None:
        return default
    try:
        return json.loads(_text(value))
    except (TypeError, ValueError):
        return default


def _float_or_none(value: Any) -> float | None:
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if np.isfinite(number) else None


def _int_or_none(value: Any) -> int | None:
    return int(value) if isinstance(value, int | float) and np.isfinite(value) else None


def read_header(file: h5py.File) -> Header:
    attrs = file.attrs
    evaluation = file.get("evaluation")
    rulebook_attrs: Mapping[str, Any] = {}
    provenance = file.get("provenance")
    if provenance is not None and "rulebook" in provenance:
        rulebook_attrs = provenance["rulebook"].attrs
    ev_attrs: Mapping[str, Any] = evaluation.attrs if evaluation is not None else {}

    def rulebook(key: str) -> str:
        return _text(ev_attrs.get(f"rulebook_{key}", rulebook_attrs.get(key, "")))

    return Header(
        campaign_name=_text(attrs.get("campaign_name", "")),
        campaign_path=_text(attrs.get("campaign_path", "")),
        campaign_sha256=_text(attrs.get("campaign_sha256", "")),
        rulebook_name=rulebook("name"),
        rulebook_version=rulebook("version"),
        rulebook_sha256=rulebook("sha256"),
        fmu_path=_text(attrs.get("fmu_path", "")),
        fmu_sha256=_text(attrs.get("fmu_sha256", "")),
        package_version=_text(attrs.get("package_version", "")),
        runs=int(attrs.get("runs", 0)),
        seed=int(attrs.get("seed", 0)),
        sampling=_text(attrs.get("sampling", "")),
        started=_text(attrs.get("started", "")),
        finished=_text(attrs.get("finished", "")),
        state=_text(attrs.get("state", "")),
        evaluated=_text(ev_attrs.get("evaluated", "")),
        results=str(Path(file.filename).resolve()),
        runs_mode=_text(attrs.get("runs_mode", "")),
    )


def row_from_summary(entry: Mapping[str, Any]) -> TableRow:
    ci = entry.get("risk_ci95")
    rank = entry.get("rank")
    return TableRow(
        path=str(entry.get("name", "")),
        status=str(entry.get("status", "")),
        runs=int(entry.get("runs") or 0),
        completed_runs=int(entry.get("completed_runs") or 0),
        failed_runs=int(entry.get("failed_runs") or 0),
        mean_risk=_float_or_none(entry.get("mean_risk")),
        risk_ci95=(float(ci[0]), float(ci[1])) if ci and None not in ci[:2] else None,
        chances={str(k): float(v) for k, v in (entry.get("chances") or {}).items()
                 if _float_or_none(v) is not None},
        energy_mAs=_float_or_none(entry.get("energy_mAs")),
        time_s=_float_or_none(entry.get("time_s")),
        verdict=str(entry.get("verdict", "")),
        undecided=bool(entry.get("undecided", False)),
        rank=int(rank) if isinstance(rank, int | float) else None,
        dominant_index=entry.get("dominant_index") or None,
        verdict_reasons=tuple(str(r) for r in entry.get("verdict_reasons") or ()),
        reason=str(entry.get("reason", "")),
        stop_reason=str(entry.get("stop_reason") or ""),
        unfinished_runs=_int_or_none(entry.get("unfinished_runs")),
        stop_time_s=_float_or_none(entry.get("stop_time_s")),
        waivers=tuple({str(k): str(v) for k, v in item.items()}
                      for item in entry.get("waivers") or () if isinstance(item, Mapping)),
        reasons=tuple(str(r) for r in entry.get("reasons") or ()),
        spread_warning=str((entry.get("risk_spread") or {}).get("warning") or ""),
    )


def _estimate(stats: Mapping[str, Any],
              key: str) -> tuple[float | None, tuple[float, float] | None]:
    """(value, (low, high)) of a ``PathStatistics`` estimate stored as a dict."""
    item = stats.get(key)
    if not isinstance(item, Mapping):
        return None, None
    low, high = _float_or_none(item.get("low")), _float_or_none(item.get("high"))
    interval = (low, high) if low is not None and high is not None else None
    return _float_or_none(item.get("value")), interval


def _undecided(verdict: Mapping[str, Any]) -> bool:
    """Not decided at this number of runs: some rule is undecided and no failing rule is
    decided (a rule failing with its threshold outside the interval decides the path)."""
    rules = [rule for rule in verdict.get("rules", []) if isinstance(rule, Mapping)]
    failed_for_sure = any(not rule.get("passed", True) and rule.get("decided", True)
                          for rule in rules)
    return not bool(verdict.get("decided", True)) and not failed_for_sure


def row_from_arrays(name: str, group: h5py.Group, path: PathReport) -> TableRow:
    """Table 1 row when ``summary.json`` is not stored: the path's stored statistics,
    verdict and waivers (a path that passes only under waivers is ``waived``, never
    ``pass``), else means over the complete runs."""
    evaluation = group.get("evaluation")
    complete = path.complete if path.evaluated else np.zeros(0, dtype=bool)
    stats = _json(evaluation.attrs.get("statistics"), {}) if evaluation is not None else {}
    verdict = _json(evaluation.attrs.get("verdict"), {}) if evaluation is not None else {}
    mean_risk, interval = _estimate(stats, "risk")
    energy, _ = _estimate(stats, "energy")
    time, _ = _estimate(stats, "time")
    if complete.any() and evaluation is not None:
        if mean_risk is None:
            mean_risk = float(np.mean(path.i_max[complete]))
        if energy is None and "energy" in evaluation:
            energy = float(np.mean(evaluation["energy"][()][complete]))
        if time is None and "time" in evaluation:
            time = float(np.mean(evaluation["time"][()][complete]))
    chances = {key: value for key in (stats.get("chances") or {})
               if (value := _estimate(stats["chances"], key)[0]) is not None}
    if not chances and complete.any():
        chances = {key: float(np.mean(values[complete] > 0))
                   for key, values in path.chances.items()}
    passed = verdict.get("passed")
    waived = recorded(group)
    said = "fail" if not passed else "waived" if waived else "pass"
    status = _text(group.attrs.get("status", ""))
    reasons = tuple(str(rule.get("message", "")) for rule in verdict.get("rules", [])
                    if isinstance(rule, Mapping) and not rule.get("passed", True))
    return TableRow(
        path=name, status=status, runs=int(path.status_codes.size),
        completed_runs=int(np.sum(path.status_codes == STATUS_COMPLETE)),
        failed_runs=int(np.sum(path.status_codes == STATUS_FAILED)),
        mean_risk=mean_risk, risk_ci95=interval, chances=chances,
        energy_mAs=energy * 1000.0 if energy is not None else None, time_s=time,
        verdict=said if passed is not None else status,
        undecided=_undecided(verdict), rank=None,
        dominant_index=(path.dominance()[0][0] if complete.any() else None),
        verdict_reasons=reasons, reason=_text(group.attrs.get("reason", "")),
        unfinished_runs=_unfinished(evaluation, complete),
        stop_time_s=_float_or_none(group.attrs.get("stop_time")),
        waivers=tuple(rule.to_dict() for rule in waived),
    )


def _unfinished(evaluation: h5py.Group | None, complete: np.ndarray) -> int | None:
    """Complete runs the stored evaluation marks as still driving at the stop limit (None:
    not stored, or not known for these runs)."""
    if evaluation is None or "finished" not in evaluation or not complete.any():
        return None
    finished = np.asarray(evaluation["finished"][()])[complete]
    return None if np.any(finished < 0) else int(np.sum(finished == 0))


def read_path(name: str, group: h5py.Group, summary_rows: Mapping[str, TableRow]) -> PathReport:
    status = _text(group.attrs.get("status", ""))
    placeholder = TableRow(path=name, status=status, runs=0, completed_runs=0, failed_runs=0,
                           mean_risk=None, risk_ci95=None, chances={}, energy_mAs=None,
                           time_s=None, verdict=status, undecided=False, rank=None,
                           dominant_index=None, reason=_text(group.attrs.get("reason", "")))
    path = PathReport(name=name, index=int(group.attrs.get("index", 0)), status=status,
                      reason=_text(group.attrs.get("reason", "")), row=placeholder)
    runs = group.get("runs")
    if runs is not None and "status" in runs:
        codes = np.asarray(runs["status"][()])
        path.status_codes = codes
        path.complete = codes == STATUS_COMPLETE
        for key, dataset in runs.get("parameters", {}).items():
            path.parameters[key] = np.asarray(dataset[()], dtype=float)
            path.parameter_units[key] = _text(dataset.attrs.get("unit", ""))
    evaluation = group.get("evaluation")
    if evaluation is not None and "i_max" in evaluation:
        path.index_names = list(_json(evaluation.attrs.get("index_names"), []))
        path.i_max = np.asarray(evaluation["i_max"][()], dtype=float)
        count = path.i_max.size
        if path.complete.size != count:
            path.complete = np.isfinite(path.i_max)
        path.complete = path.complete & np.isfinite(path.i_max)
        path.dominant = (np.asarray(evaluation["dominant"][()]) if "dominant" in evaluation
                         else np.full(count, -1, dtype=np.int16))
        for key, dataset in evaluation.get("indices", {}).items():
            path.indices[key] = np.asarray(dataset[()], dtype=float)
        for key, dataset in evaluation.get("raw", {}).items():
            path.raw[key] = np.asarray(dataset[()], dtype=float)
        path.verdict = dict(_json(evaluation.attrs.get("verdict"), {}) or {})
        for key, dataset in evaluation.get("chances", {}).items():
            path.chances[key] = np.asarray(dataset[()])
    summary_row = summary_rows.get(name)
    path.row = summary_row or row_from_arrays(name, group, path)
    if summary_row is not None and summary_row.reason:
        # the evaluation's word: `evaluate --rulebook` gates the paths again, and a chain its
        # rulebook rejects was simulated (no reason of its own in the file)
        path.reason = summary_row.reason
    return path


def _stored_confidence(store: StoredResults) -> float | None:
    """The rulebook's confidence as a path's stored statistics hold it, or None."""
    for name in store.path_names:
        evaluation = store.path_group(name).get("evaluation")
        stats = _json(evaluation.attrs.get("statistics"), {}) if evaluation is not None else {}
        confidence = stats.get("confidence") if isinstance(stats, Mapping) else None
        if isinstance(confidence, (int, float)):
            return float(confidence)
    return None


def read_report_data(store: StoredResults) -> ReportData:
    """Everything the report shows except the figures' derived data (maps, box plots); H004
    when the results file does not read back."""
    with reading(store.path, "the stored evaluation"):
        return _read_report_data(store)


def _read_report_data(store: StoredResults) -> ReportData:
    file = store.file
    evaluation = file.get("evaluation")
    summary = _json(evaluation.attrs.get("summary"), {}) if evaluation is not None else {}
    rows = {str(entry.get("name")): row_from_summary(entry)
            for entry in summary.get("paths", []) if isinstance(entry, Mapping)}
    paths = [read_path(name, store.path_group(name), rows) for name in store.path_names]
    ranking = summary.get("ranking") or (_json(evaluation.attrs.get("ranking"), [])
                                         if evaluation is not None else [])
    code = summary.get("exit_code")
    alpha = (summary.get("alpha") or {}).get("alpha")
    # no summary: the paths' stored statistics say
    confidence = 1.0 - float(alpha) if isinstance(alpha, (int, float)) \
        else _stored_confidence(store)
    return ReportData(header=read_header(file), paths=paths, ranking=list(ranking),
                      expectations=list(summary.get("expectations", [])),
                      decision=summary.get("decision"),
                      exit_code=int(code) if isinstance(code, int) else None,
                      # a search's file of an earlier version stored pairs of unpaired runs
                      pairs=[PairComparison.from_dict(pair) for pair in summary.get("pairs", [])
                             if isinstance(pair, Mapping) and drawn_paired(file.attrs)],
                      confidence=0.95 if confidence is None else confidence,
                      problems=[dict(problem) for problem in summary.get("problems", [])
                                if isinstance(problem, Mapping)])
