"""The report of a worst-case search: the worst run's track on the printable result maps and,
dotted and labelled, on the interactive one; the page as headless Chromium shows it."""

from __future__ import annotations

import importlib
import itertools
import json
from pathlib import Path

import numpy as np
import pytest
from test_report_browser import check_page, render
from test_report_campaign import CAMPAIGN, RULEBOOK

from idefix_rules.campaign.input.wording import DisplayUnits
from idefix_rules.cli import main
from idefix_rules.report import figures, prepare_report, write_report
from idefix_rules.report.environment import MapEnvironment
from idefix_rules.report.interactive import payload
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


def test_the_search_s_worst_run_is_held_and_marked_on_the_interactive_map(
        synthetic_results: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # one embedded run per path: the run marked as worst is held besides it
    # (the package's name `prepare` is the function: the module is looked up by its name)
    monkeypatch.setattr(importlib.import_module("idefix_rules.report.prepare"),
                        "EMBEDDED_RUNS", 1)
    data, setup, maps = prepare_report(synthetic_results)
    held = {name: set(series) for name, series in maps.series.items()}
    row = next(run for run in range(4) if run not in held["straight"])
    data, setup, maps = prepare_report(synthetic_results, embed={"straight": row})
    assert set(maps.series["straight"]) == held["straight"] | {row}
    assert set(maps.series["detour"]) == held["detour"]
    units = DisplayUnits()
    marked = {path["name"]: path for path in
              payload(data, setup, maps, units, {"straight": row, "detour": 3})["paths"]}
    assert marked["straight"]["worst"] == row
    assert "worst" not in marked["detour"]  # run 3 failed: not held, not marked
    plain = payload(data, setup, maps, units)["paths"]
    assert all("worst" not in path for path in plain)


def test_a_campaign_s_report_has_no_worst_run_marks(synthetic_results: Path,
                                                    tmp_path: Path) -> None:
    page = write_report(synthetic_results, tmp_path / "out").read_text(encoding="utf-8")
    assert "worst run found by the search" not in page
    assert '"worst":' not in page and 'id="worst"' not in page


# Appended to a copy of a search's report: what a reader sees of the table and the map.
READER = """<script>
window.addEventListener("load", function () {
  var out = {errors: []};
  try {
    var section = document.getElementById("worst"), edge = section.getBoundingClientRect();
    out.firstSection = document.querySelector("main section").id;
    out.rows = Array.prototype.map.call(section.querySelectorAll("table tbody tr"),
      function (row) {
        var box = row.getBoundingClientRect();
        return {path: row.cells[0].innerText, text: row.innerText,
                run: row.getAttribute("data-run"),
                shown: box.width > 0 && box.height > 0 && box.left >= edge.left - 1 &&
                  getComputedStyle(row).visibility !== "hidden"};
      });
    var api = window.idefixReport, canvas = document.querySelector("#imap canvas");
    var box = canvas.getBoundingClientRect(), ctx = canvas.getContext("2d");
    var ratio = canvas.width / box.width;
    function pixel(x, y) {
      return Array.prototype.slice.call(ctx.getImageData(
        Math.round((x - box.left) * ratio), Math.round((y - box.top) * ratio), 1, 1).data);
    }
    out.canvas = {left: box.left, top: box.top, right: box.right, bottom: box.bottom};
    out.marks = api.worst().map(function (m) {
      var found = {path: m.path, run: m.run, text: m.text, colour: m.colour, x: m.x, y: m.y,
                   box: m.box, dot: pixel(m.end.x, m.end.y)};
      canvas.dispatchEvent(new MouseEvent("mousemove", {clientX: m.x, clientY: m.y,
                                                        bubbles: true}));
      found.tip = document.querySelector("#imap .tip").textContent;
      canvas.dispatchEvent(new MouseEvent("click", {clientX: m.x, clientY: m.y,
                                                    bubbles: true}));
      found.opened = document.getElementById("runpanel").getAttribute("data-open");
      return found;
    });
    out.legend = document.getElementById("map-section").innerText;
    var row = section.querySelector("tr.run");
    row.dispatchEvent(new MouseEvent("click", {bubbles: true}));
    out.row = row.getAttribute("data-path") + "/" + row.getAttribute("data-run");
    out.openedFromRow = document.getElementById("runpanel").getAttribute("data-open");
  } catch (error) { out.errors.push(String(error)); }
  var pre = document.createElement("pre"); pre.id = "check-result";
  pre.textContent = JSON.stringify(out); document.body.appendChild(pre);
});
</script>"""


def _rgb(colour: str) -> tuple[int, int, int]:
    return int(colour[1:3], 16), int(colour[3:5], 16), int(colour[5:7], 16)


@pytest.mark.slow
def test_the_search_s_report_shows_its_table_and_worst_runs_in_chromium(
        tmp_path: Path) -> None:
    campaign = tmp_path / "small.yaml"
    campaign.write_text(CAMPAIGN, encoding="utf-8")
    (tmp_path / "report-e2e.rules").write_text(RULEBOOK, encoding="utf-8")
    out = tmp_path / "worst"
    # the smallest search of the two parameters: 36 runs searching, one ray of 4
    code = main(["worst", str(campaign), "--quiet", "--runs", "40", "--axes", "0",
                 "--rounds", "1", "--workers", "2", "--out", str(out)])
    assert code == 0
    record = json.loads((out / "worst.json").read_text(encoding="utf-8"))
    searched = [path for path in record["paths"] if path["status"] == "searched"]
    marked = {path["name"]: path["worst"]["run"] for path in searched
              if path["worst"]["run"] is not None}
    assert marked  # some path's worst world is a searched run, not the nominal world
    page = out / "report.html"
    assert render(page, tmp_path / "screen.png") == []  # no console error, nothing fetched
    for width in (800, 1400):
        found = check_page(page, width, tmp_path, READER)
        assert found["errors"] == []
        # The table per path opens the page, every row shown; a row with a worst run opens it.
        assert found["firstSection"] == "worst"
        rows = found["rows"]
        assert isinstance(rows, list)
        assert [row["path"] for row in rows] == [path["name"] for path in record["paths"]]
        assert all(row["shown"] for row in rows)
        for row, path in zip(rows, record["paths"], strict=True):
            assert f"{100 * path['worst']['risk']:.1f} %" in row["text"]
            assert row["run"] == (None if path["worst"]["run"] is None
                                  else str(path["worst"]["run"]))
        assert found["openedFromRow"] == found["row"]
        # The map marks each path's worst run, once, with its label inside the map.
        marks = found["marks"]
        assert isinstance(marks, list)
        assert {mark["path"]: mark["run"] for mark in marks} == marked
        assert "worst run found by the search" in str(found["legend"])
        canvas = found["canvas"]
        assert isinstance(canvas, dict)
        boxes = []
        for mark in marks:
            assert f"{mark['path']} · worst run {mark['run']} · I_max" in mark["text"]
            assert canvas["left"] <= mark["x"] <= canvas["right"]
            assert canvas["top"] <= mark["y"] <= canvas["bottom"]
            # the dot at the track's end is drawn in the path's colour
            assert max(abs(a - b) for a, b in zip(mark["dot"][:3], _rgb(mark["colour"]),
                                                   strict=True)) <= 40, mark
            # hovering the label explains it; a click on it opens that run
            assert f"worst run {mark['run']}" in mark["tip"] and "click" in mark["tip"]
            assert mark["opened"] == f"{mark['path']}/{mark['run']}"
            boxes.append(mark["box"])
        for first, second in itertools.combinations(boxes, 2):  # no label hides another
            assert (first["left"] + first["w"] <= second["left"]
                    or second["left"] + second["w"] <= first["left"]
                    or first["top"] + first["h"] <= second["top"]
                    or second["top"] + second["h"] <= first["top"])
