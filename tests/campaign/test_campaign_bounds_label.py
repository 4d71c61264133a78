"""The console, JUnit, the report and `diff --results` name a verdict's bounds by the
rulebook's confidence and say it is family-wise (every bound of every path and comparison
holds at once, so each alone is wider than a plain interval at that confidence)."""

from __future__ import annotations

import doctest
import html
import json
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from test_campaign_robustness import copy_campaign

from idefix_rules.campaign.input import wording
from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.cli import main
from idefix_rules.report.reading import read_report_data

NINETY = "\ncombine {\n  confidence = 90 %\n}\n"


def test_the_examples_in_the_wording_module_hold() -> None:
    failures, tried = doctest.testmod(wording)
    assert tried > 0 and failures == 0


@pytest.mark.parametrize(("extra", "label"), [("", "95 %"), (NINETY, "90 %")],
                         ids=["default", "90 %"])
def test_the_bounds_are_named_by_the_rulebook_s_family_wise_confidence(
        campaign_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: str,
        label: str) -> None:
    folder = tmp_path / "run"
    path = copy_campaign(campaign_dir, folder)
    rules = folder / "test.rules"
    rules.write_text(rules.read_text() + extra)
    capsys.readouterr()
    main([str(path), "--junit", str(folder / "junit.xml")])
    out = " ".join(capsys.readouterr().out.split())  # the console wraps long lines
    summary = json.loads((folder / "out" / "summary.json").read_text())
    assert summary["alpha"]["alpha"] == pytest.approx(1 - float(label[:2]) / 100)
    other = "90 %" if label == "95 %" else "95 %"
    # the risk's bounds, in the table or the narrow layout, and every rule's bounds
    assert f"{label} family-wise bounds" in out
    assert re.search(rf"\({label} family-wise bounds [\d.]+–[\d.]+ %\)", out), out
    assert f"{other} bounds" not in out and f"{other} family-wise" not in out
    assert "family-wise: every bound shown holds at once" in out
    junit = ET.parse(folder / "junit.xml").getroot()
    texts = " ".join(e.text or "" for e in junit.iter("system-out"))
    assert "mean risk: " in texts and f"({label} family-wise bounds " in texts
    assert f"{other} family-wise" not in texts
    page = (folder / "out" / "report.html").read_text(encoding="utf-8")
    assert f"{label} family-wise bounds [%]" in page and f"{other} family-wise" not in page
    # the report's rule lines are the console's: an undecided rule with the runs that would
    # decide it
    said = [r for p in summary["paths"] for r in p["reasons"] if "runs would decide it" in r]
    assert said and all(html.escape(line) in page for line in said)
    # a results file without the stored summary: the paths' statistics name the confidence
    results = folder / "out" / "results.h5"
    store = ResultStore.open(results, writable=True)
    try:
        assert read_report_data(store).confidence == pytest.approx(float(label[:2]) / 100)
        del store.file["evaluation"].attrs["summary"]
        assert read_report_data(store).confidence == pytest.approx(float(label[:2]) / 100)
    finally:
        store.close()
