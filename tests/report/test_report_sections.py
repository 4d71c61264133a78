"""The explaining sections of the report: decision banner, sensitivity, indices."""

from __future__ import annotations

from pathlib import Path

import pytest
from report_fixture import write_results

from idefix_rules.campaign.store import ResultStore
from idefix_rules.report import figures
from idefix_rules.report.data import ReportData, read_report_data
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
