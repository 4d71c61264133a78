"""The report of a worst-case search: the worst run's track on the result map."""

from __future__ import annotations

import numpy as np

from idefix_rules.report import figures
from idefix_rules.report.environment import MapEnvironment
from idefix_rules.report.riskmap import RiskGrid


def _legend(overlay: figures.MapOverlay) -> list[str]:
    grid = RiskGrid(x0=-0.5, y0=-0.5, cell=0.25, nx=8, ny=4)
    figure = figures.risk_map_figure(np.zeros((4, 8)), grid, MapEnvironment(), overlay,
                                     ["p"], "p", "test grid", highlight="p")
    axes = figure.axes[0]
    return [text.get_text() for text in axes.get_legend().get_texts()]


def test_the_worst_run_is_drawn_and_named_in_the_legend_only_when_there_is_one() -> None:
    reference = {"p": (np.linspace(0, 1, 5), np.zeros(5))}
    plain = figures.MapOverlay(reference)
    searched = figures.MapOverlay(reference, worst={"p": (np.linspace(0, 1, 5),
                                                          np.full(5, 0.1))})
    assert "worst world found (body centre)" not in _legend(plain)
    assert "worst world found (body centre)" in _legend(searched)
    lines = figures.risk_map_figure(np.zeros((4, 8)), RiskGrid(x0=-0.5, y0=-0.5, cell=0.25,
                                                              nx=8, ny=4),
                                    MapEnvironment(), searched, ["p"], "p", "g",
                                    highlight="p").axes[0].get_lines()
    assert any(np.allclose(line.get_ydata(), 0.1) for line in lines if len(line.get_ydata()))
