"""The report opens in headless Chromium, renders to a screenshot, logs nothing, fetches
nothing, fits narrow (800 px) and wide windows, and answers hover, clicks and path switches.

Chromium runs from a fresh profile, offline flags, file:// URL. Console messages are read from
Chromium's own log on stderr (``--enable-logging=stderr``), where every console message and
uncaught exception is a ``CONSOLE`` line; the report logs nothing, so any such line is an error
(a blocked request is one too: the page's Content-Security-Policy refuses every URL). A test
page that logs an error proves the detector sees one.

Layout and interaction are checked in the page itself: a copy of the report gets a checking
script appended that measures overflow, lists every fetched resource (Resource Timing), hovers
and clicks the map, switches a path off and clicks a worst-runs row, and writes what it found
as JSON into the DOM, which ``--dump-dom`` prints. Without chromium the tests are skipped,
except in CI (``CI`` set), where ``.ci/run`` installs it and its absence is a failure.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import pytest

from idefix_rules.report import write_report

CONSOLE_LINE = re.compile(r":CONSOLE[:(]|Uncaught", re.IGNORECASE)


def _chromium() -> str:
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if found is None:
        if os.environ.get("CI"):
            pytest.fail("chromium is not installed in CI (.ci/run installs Debian's chromium)")
        pytest.skip("chromium not installed (apt-get install chromium); CI installs it")
    return found


def _run_chromium(page: Path, *arguments: str, width: int = 1300,
                  height: int = 2400) -> subprocess.CompletedProcess[str]:
    browser = _chromium()
    with tempfile.TemporaryDirectory() as profile:
        completed = subprocess.run(
            [browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
             "--no-first-run", "--disable-background-networking",
             "--disable-component-update", "--disable-sync", f"--user-data-dir={profile}",
             "--enable-logging=stderr", "--v=0", *arguments,
             f"--window-size={width},{height}", page.resolve().as_uri()],
            capture_output=True, text=True, timeout=180, check=False)
    assert completed.returncode == 0, completed.stderr[-2000:]
    return completed


def render(page: Path, screenshot: Path, height: int = 2400, width: int = 1300) -> list[str]:
    """Screenshot ``page`` with headless Chromium; returns the console lines it logged."""
    completed = _run_chromium(page, f"--screenshot={screenshot}", width=width, height=height)
    return [line for line in completed.stderr.splitlines() if CONSOLE_LINE.search(line)]


# Appended to a copy of the report: measures and drives the page, writes JSON into the DOM.
CHECKER = """<script>
window.addEventListener("load", function () {
  var out = {errors: []};
  try {
    var doc = document.documentElement;
    out.clientWidth = doc.clientWidth; out.scrollWidth = doc.scrollWidth;
    out.overflowing = [];
    document.querySelectorAll("main *").forEach(function (el) {
      if (el.closest(".scroll") || el.closest("script")) { return; }
      var box = el.getBoundingClientRect(), section = el.closest("section");
      var limit = section ? section.getBoundingClientRect().right : doc.clientWidth;
      if (box.width > 0 && box.right > limit + 1) {
        out.overflowing.push(el.tagName + "." + el.className + " " + Math.round(box.right) +
                             " > " + Math.round(limit));
      }
    });
    var maps = document.querySelectorAll('img[alt^="Result map"]');
    out.mapScale = Math.min.apply(null, Array.prototype.map.call(maps, function (img) {
      return img.getBoundingClientRect().width / img.naturalWidth; }));
    out.mapShare = Math.min.apply(null, Array.prototype.map.call(maps, function (img) {
      return img.getBoundingClientRect().width /
        img.closest("section").getBoundingClientRect().width; }));
    out.resources = performance.getEntriesByType("resource").map(function (e) {
      return e.name; });
    var one = document.querySelector("table.table-one"), sect = one.closest("section");
    var edge = sect.getBoundingClientRect();
    out.tableRanks = Array.prototype.map.call(one.querySelectorAll("tbody tr"), function (r) {
      return r.querySelector("td").textContent; });
    out.tableCells = one.querySelectorAll("tbody td").length;
    out.tableHidden = Array.prototype.filter.call(one.querySelectorAll("tbody td"),
      function (td) {
        var box = td.getBoundingClientRect(), style = getComputedStyle(td);
        return box.width < 1 || box.height < 1 || style.display === "none" ||
          style.visibility === "hidden" || box.left < edge.left - 1 || box.right > edge.right + 1;
      }).map(function (td) { return td.getAttribute("data-label"); });
    out.tableLabels = Array.prototype.map.call(one.querySelectorAll("tbody tr:first-child td"),
      function (td) {  // what a reader sees as the column's name: the header, or the label
        var head = one.querySelector("thead");
        return getComputedStyle(head).display === "none" ?
          getComputedStyle(td, "::before").content.replace(/"/g, "") :
          head.querySelectorAll("th")[td.cellIndex].textContent; });
    var api = window.idefixReport, cells = api.cells(), keys = Object.keys(cells);
    out.axes = api.axes();
    out.focusAll = api.focus();
    out.cells = keys.length;
    var key = keys.reduce(function (a, b) {
      return cells[b].runs > cells[a].runs ? b : a; });
    var point = api.at(Number(key)), canvas = document.querySelector("#imap canvas");
    var box = canvas.getBoundingClientRect(), ctx = canvas.getContext("2d");
    var ratio = canvas.width / box.width;
    out.pixel = Array.prototype.slice.call(ctx.getImageData(
      Math.round((point.x - box.left) * ratio), Math.round((point.y - box.top) * ratio),
      1, 1).data);
    canvas.dispatchEvent(new MouseEvent("mousemove", {clientX: point.x, clientY: point.y,
                                                      bubbles: true}));
    out.tip = document.querySelector("#imap .tip").textContent;
    out.expectedRisk = (100 * cells[key].total / cells[key].runs).toFixed(1) + " %";
    out.expectedRuns = cells[key].runs;
    canvas.dispatchEvent(new MouseEvent("click", {clientX: point.x, clientY: point.y,
                                                  bubbles: true}));
    var panel = document.getElementById("runpanel");
    out.openedFromMap = panel.getAttribute("data-open");
    out.focusOpened = api.focus();
    out.charts = Array.prototype.map.call(panel.querySelectorAll(".charts canvas"),
      function (c) { return c.getAttribute("data-series"); });
    var box0 = document.querySelector("#imap-paths input");
    box0.checked = false; box0.dispatchEvent(new Event("change"));
    out.cellsWithoutFirst = Object.keys(api.cells()).length;
    out.firstPath = box0.value;
    var row = document.querySelector("tr.run");
    row.dispatchEvent(new MouseEvent("click", {bubbles: true}));
    out.row = row.getAttribute("data-path") + "/" + row.getAttribute("data-run");
    out.openedFromRow = panel.getAttribute("data-open");
    out.title = panel.querySelector("h3").textContent;
  } catch (error) { out.errors.push(String(error)); }
  var pre = document.createElement("pre"); pre.id = "check-result";
  pre.textContent = JSON.stringify(out); document.body.appendChild(pre);
});
</script>"""


def check_page(page: Path, width: int, tmp: Path, checker: str = CHECKER
               ) -> dict[str, object]:
    """Load a copy of ``page`` with ``checker`` (a script that writes its findings as JSON
    into ``<pre id="check-result">``, :data:`CHECKER` by default) appended; what it found."""
    copy = tmp / f"checked-{width}.html"
    copy.write_text(page.read_text(encoding="utf-8").replace("</body>", checker + "</body>"),
                    encoding="utf-8")
    completed = _run_chromium(copy, "--dump-dom", "--virtual-time-budget=5000", width=width,
                              height=1000)
    match = re.search(r'<pre id="check-result">(.*?)</pre>', completed.stdout, re.S)
    assert match is not None, completed.stdout[-2000:]
    text = match.group(1).replace("&quot;", '"').replace("&lt;", "<").replace(
        "&gt;", ">").replace("&amp;", "&")
    found: dict[str, object] = json.loads(text)
    return found


def test_the_detector_flags_a_console_error(tmp_path: Path) -> None:
    page = tmp_path / "broken.html"
    page.write_text("<!DOCTYPE html><html><body><p>broken</p><script>"
                    "console.error('deliberate error'); notAFunction();</script></body></html>",
                    encoding="utf-8")
    lines = render(page, tmp_path / "broken.png", height=300)
    assert any("deliberate error" in line for line in lines)
    assert any("Uncaught ReferenceError" in line for line in lines)


def test_the_detector_flags_a_blocked_request(tmp_path: Path, synthetic_results: Path) -> None:
    """The report's policy refuses any URL, and the refusal is a console line: a report that
    tried to fetch anything would fail the console check below."""
    page = write_report(synthetic_results, tmp_path / "out")
    leaky = tmp_path / "leaky.html"
    leaky.write_text(page.read_text(encoding="utf-8").replace(
        "</main>", '<img src="http://127.0.0.1:9/x.png" alt="x"></main>'), encoding="utf-8")
    lines = render(leaky, tmp_path / "leaky.png", height=400)
    assert any("Content Security Policy" in line or "Refused" in line for line in lines)


@pytest.mark.slow
@pytest.mark.parametrize("width", [800, 1280])
def test_report_renders_without_console_errors(synthetic_results: Path, tmp_path: Path,
                                               width: int) -> None:
    page = write_report(synthetic_results, tmp_path / "out")
    screenshot = tmp_path / "report.png"
    lines = render(page, screenshot, width=width)
    assert lines == []
    data = screenshot.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(data) > 50_000  # a blank page compresses to a few kB


@pytest.mark.slow
@pytest.mark.parametrize("width", [800, 1280])
def test_report_fits_fetches_nothing_and_answers(synthetic_results: Path, tmp_path: Path,
                                                width: int) -> None:
    page = write_report(synthetic_results, tmp_path / "out")
    found = check_page(page, width, tmp_path)
    assert found["errors"] == []
    # Nothing overflows: no horizontal page scroll, no element past its section (wide
    # tables scroll inside their own box).
    assert int(found["scrollWidth"]) <= int(found["clientWidth"]), found  # type: ignore[call-overload]
    assert found["overflowing"] == []
    # Printable maps take most of the page's width and are not shrunk below 70 % of their
    # drawn size: their 9.5–10 pt labels stay at 10 px or more.
    assert float(found["mapShare"]) > 0.75  # type: ignore[arg-type]
    assert float(found["mapScale"]) >= 0.7  # type: ignore[arg-type]
    assert found["resources"] == []  # not one request, not even for a file next to it
    # The map is drawn: a crossed cell is coloured, not the white background.
    red, green, blue, _ = found["pixel"]  # type: ignore[misc]
    assert (red, green, blue) != (255, 255, 255)
    # Hover: the busiest cell says its risk and its runs.
    tip = str(found["tip"])
    assert f"risk {found['expectedRisk']}" in tip and f"{found['expectedRuns']} run(s)" in tip
    assert "dominant" in tip
    assert re.fullmatch(r"\d+\.\d %", str(found["expectedRisk"]))  # risk in percent
    # Table 1: in rank order, every column there for the reader (the header on a wide page,
    # each cell's label on a narrow one), no cell hidden or cut off.
    ranks = found["tableRanks"]
    numbered = [int(r) for r in ranks if r != "–"]  # type: ignore[union-attr]
    assert numbered == sorted(numbered) and numbered[0] == 1, ranks
    assert found["tableHidden"] == [], found["tableHidden"]
    assert found["tableLabels"][:3] == ["Rank", "Path", "Risk [%]"]  # type: ignore[index]
    assert "Dominant index" in found["tableLabels"]  # type: ignore[operator]
    assert len(found["tableLabels"]) == 14  # type: ignore[arg-type]
    # The map has axes in metres and a scale bar.
    axes = found["axes"]
    assert len(axes["x"]) >= 2 and len(axes["y"]) >= 2, axes  # type: ignore[index]
    assert re.fullmatch(r"\d+(\.\d+)? m|\d+ cm", axes["scale"]), axes  # type: ignore[index]
    # Footprints: none while every path is on; the open run's path's once a run is open.
    assert found["focusAll"] is None
    # Click on the map: the worst run there opens, with its series against the limits.
    assert found["openedFromMap"] and "risk" in found["charts"]  # type: ignore[operator]
    assert found["focusOpened"] == str(found["openedFromMap"]).split("/")[0]
    # Switching a path off removes its cells.
    assert 0 < int(found["cellsWithoutFirst"]) < int(found["cells"])  # type: ignore[call-overload]
    # A worst-runs row opens its run.
    assert found["openedFromRow"] == found["row"]
    assert "I_max" in str(found["title"])
