"""A campaign with a waived failure: its report, as headless Chromium shows it, says the path
is waived, with the waiver's reason, approver and expiry, and never that it passes."""

from __future__ import annotations

from datetime import date, timedelta
from pathlib import Path

import pytest
from test_report_browser import check_page, render
from test_report_campaign import CAMPAIGN, RULEBOOK

from idefix_rules.cli import main

# The one verdict fails on both paths; the campaign waives it on 'straight' only.
STRICT = RULEBOOK.replace("require risk <= 70 %", "require risk <= 1 %")
UNTIL = (date.today() + timedelta(days=365)).isoformat()
WAIVERS = f"""\
waivers:
  - rule: acceptable_risk
    path: straight
    reason: "rock at 0.45 m inspected: a contact is harmless"
    approved_by: "J. Doe"
    until: {UNTIL}
"""

# Appended to a copy of the report: what a reader sees of Table 1 and the decision.
READER = """<script>
window.addEventListener("load", function () {
  var out = {errors: [], verdicts: {}};
  try {
    var one = document.querySelector("table.table-one");
    one.querySelectorAll("tbody tr").forEach(function (row) {
      var cell = row.querySelector('td[data-label="Verdict"]');
      var box = cell.getBoundingClientRect();
      out.verdicts[row.querySelector('td[data-label="Path"]').innerText] = {
        text: cell.innerText, colour: getComputedStyle(cell.firstElementChild).color,
        shown: box.width > 0 && box.height > 0};
    });
    out.notes = {};  // the lines under Table 1, by path
    one.closest("section").querySelectorAll("h3").forEach(function (title) {
      out.notes[title.innerText] = Array.prototype.map.call(
        title.nextElementSibling.querySelectorAll("li"),
        function (item) { return item.innerText; });
    });
    out.decision = document.getElementById("decision").innerText;
  } catch (error) { out.errors.push(String(error)); }
  var pre = document.createElement("pre"); pre.id = "check-result";
  pre.textContent = JSON.stringify(out); document.body.appendChild(pre);
});
</script>"""

PASS_GREEN = "rgb(27, 127, 59)"  # .pass in the report's style sheet


@pytest.mark.slow
def test_the_report_shows_a_waived_failure_as_waived_in_chromium(tmp_path: Path) -> None:
    campaign = tmp_path / "waived.yaml"
    campaign.write_text(CAMPAIGN + WAIVERS, encoding="utf-8")
    (tmp_path / "report-e2e.rules").write_text(STRICT, encoding="utf-8")
    assert main(["run", str(campaign), "--quiet", "--workers", "2"]) == 1  # detour fails
    page = tmp_path / "out" / "report.html"
    assert render(page, tmp_path / "screen.png") == []
    said = (f"rock at 0.45 m inspected: a contact is harmless (approved by J. Doe until "
            f"{UNTIL})")
    for width in (800, 1400):  # stacked cells on a narrow page, a table on a wide one
        found = check_page(page, width, tmp_path, READER)
        assert found["errors"] == []
        verdicts = found["verdicts"]
        assert isinstance(verdicts, dict) and set(verdicts) == {"straight", "detour"}
        straight, detour = verdicts["straight"], verdicts["detour"]
        assert straight["text"] == "waived" and straight["shown"]
        assert straight["colour"] != PASS_GREEN
        assert detour["text"].startswith("fail")
        notes = found["notes"]
        assert isinstance(notes, dict)
        assert f"Waived verdict rule acceptable_risk: {said}" in notes["straight"]
        assert not any("Waived" in note for note in notes["detour"])
        decision = str(found["decision"])
        assert "straight" in decision and "breaks acceptable_risk under a waiver" in decision
        assert "passes every verdict," not in decision
