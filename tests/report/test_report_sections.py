"""The explaining sections of the report: decision banner, sensitivity, indices."""

from __future__ import annotations

from pathlib import Path

import pytest
from report_fixture import write_results

from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.report import figures
from idefix_rules.report.data import ReportData
from idefix_rules.report.reading import read_report_data
from idefix_rules.report.sections import decision_html, indices_html, sensitivity_html

RECORD = {"p": {"runs": 128, "dominant_index": "I_beta",
                "risk": [{"parameter": "soil.cohesion", "rho": -0.697, "ci95": [-0.784, -0.582],
                          "runs": 128, "significant": True},
                         {"parameter": "initial.y", "rho": 0.044, "ci95": [-0.13, 0.216],
                          "runs": 128, "significant": False}],
                "dominant": [{"parameter": "soil.cohesion", "rho": -0.7, "ci95": [-0.8, -0.6],
                              "runs": 128, "significant": True}]}}


def test_sensitivity_section_marks_what_its_interval_settles() -> None:
    text = sensitivity_html(RECORD, [], {"I_beta": "wheel slip angle"})
    assert "<b>-0.70</b>" in text  # significant: bold
    assert "+0.04</td>" in text and "<b>+0.04</b>" not in text
    assert "ρ with I_beta" in text and "I_beta (wheel slip angle)" in text
    assert sensitivity_html({}, [], {}) == ""
    figure = figures.sensitivity_figure(RECORD, ["p"])
    assert len(figure.axes) == 1 and figure.axes[0].get_title(loc="left") == "p (128 runs)"


@pytest.fixture
def data(tmp_path: Path) -> ReportData:
    store = ResultStore.open(write_results(tmp_path / "r.h5"))
    try:
        return read_report_data(store)
    finally:
        store.close()


def test_the_banner_says_the_stored_decision_then_ci(data: ReportData) -> None:
    data.decision = {"kind": "none", "path": "detour", "text": "no chain is acceptable; …",
                     "reasons": []}
    data.exit_code = 0
    banner = decision_html(data)
    assert 'class="banner none"' in banner and "no chain is acceptable" in banner
    assert "CI expectations: 1 of 1 held (exit 0)" in banner


def test_without_a_stored_decision_it_is_worked_out(data: ReportData) -> None:
    data.decision = None
    banner = decision_html(data)
    assert "<b>Decision:</b>" in banner
    assert any(kind in banner for kind in ("banner send", "banner none", "banner unsettled"))


def test_indices_with_title_limit_and_rationale() -> None:
    text = indices_html({"I_s": {"title": "wheel slip ratio", "rationale": "Slip <70 %"}},
                        {"I_s": "critical_slip = 70 %"})
    assert "I_s — wheel slip ratio" in text and "critical_slip = 70 %" in text
    assert "Slip &lt;70 %" in text


def test_table_one_lists_the_paths_in_rank_order_and_labels_every_cell(
        data: ReportData) -> None:
    import dataclasses
    import re

    from idefix_rules.report.html import table_one_html

    # campaign order straight, detour; make detour the better one
    swapped = [dataclasses.replace(path, row=dataclasses.replace(
        path.row, rank=len(data.paths) - position if path.row.rank is not None else None))
        for position, path in enumerate(data.paths)]
    ranked = [p.name for p in sorted((p for p in swapped if p.row.rank is not None),
                                     key=lambda p: p.row.rank or 0)]
    assert ranked != [p.name for p in data.paths if p.row.rank is not None]
    text = table_one_html(dataclasses.replace(data, paths=swapped))
    shown = re.findall(r'<td data-label="Path"><b>([^<]+)</b>', text)
    assert shown[:len(ranked)] == ranked
    # the unranked (rejected, excluded) come after the ranked
    assert set(shown[len(ranked):]) == {p.name for p in data.paths if p.row.rank is None}
    # every cell says its column, for the stacked layout of a narrow window
    assert text.count("<td") == text.count("data-label=")


def test_a_path_whose_runs_all_score_the_same_says_why_it_has_no_sensitivity() -> None:
    import numpy as np

    from idefix_rules.campaign.evaluation.sensitivity import why_none

    record = {"p": {"runs": 16, "dominant_index": "I_s", "risk": [], "dominant": [],
                    "note": why_none({"a": np.arange(16.0)}, np.full(16, 1.0),
                                     "run risk I_max")}}
    text = sensitivity_html(record, [], {})
    assert "No sensitivity for this path: every run has the same run risk I_max (1)" in text
    assert "<table" not in text  # no bare header
    assert "needs at least 8" in str(why_none({"a": np.arange(3.0)}, np.arange(3.0), "x"))
    assert why_none({"a": np.zeros(9)}, np.arange(9.0), "x") == \
        "no sampled parameter varies between the runs"
    assert why_none({"a": np.arange(9.0)}, np.arange(9.0), "x") is None
