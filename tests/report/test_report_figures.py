"""Figures drawn in forked processes while the report goes on: the same bytes as drawn in
turn, in the order handed over, and a figure that cannot be drawn says why."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from idefix_rules.report import figures

SERIES = {"a": np.array([0.1, 0.3, 0.2, 0.5]), "b": np.array([0.4, 0.2, 0.6])}


def _draw_three(folder: Path, workers: int) -> list[bytes]:
    drawing = figures.FigureProcesses(workers)
    try:
        drawing.draw(folder / "box.png", figures.box_plot_figure, SERIES, ["a", "b"],
                     "error [m]", "Final error")
        drawing.draw(folder / "dominance.png", figures.dominance_figure,
                     {"a": [("I_s", 3), ("I_obs", 1)], "b": [("I_s", 2)]}, ["a", "b"])
        drawing.draw(folder / "scaled.png", figures.box_plot_figure, SERIES, ["a", "b"],
                     "error [deg]", "Final heading error", scale=2.0)
        return drawing.wait()
    finally:
        drawing.close()


def test_forked_drawing_gives_the_bytes_drawn_in_turn(tmp_path: Path) -> None:
    forked = _draw_three(tmp_path / "forked", 2)
    in_turn = _draw_three(tmp_path / "in_turn", 1)
    assert forked == in_turn
    assert [(tmp_path / "forked" / name).read_bytes() for name in
            ("box.png", "dominance.png", "scaled.png")] == forked
    assert all(png.startswith(b"\x89PNG") for png in forked)
    assert forked[0] != forked[2]  # in the order handed over


def test_a_figure_that_cannot_be_drawn_raises(tmp_path: Path) -> None:
    drawing = figures.FigureProcesses(2)
    try:
        drawing.draw(tmp_path / "bad.png", figures.box_plot_figure, SERIES, ["a", "b"],
                     "error [m]", "Final error", scale="not a number")
        with pytest.raises(TypeError):
            drawing.wait()
    finally:
        drawing.close()
