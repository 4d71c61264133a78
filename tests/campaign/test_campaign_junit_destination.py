"""Which existing files --junit may replace: a JUnit report (ours or another tool's) or an
empty file, never anything else (the file is set aside and replaced by XML)."""

from __future__ import annotations

from pathlib import Path

import pytest

from idefix_rules.files import is_junit_report

REPLACEABLE = {
    "empty (touch, mktemp)": b"",
    "blank": b" \n",
    "ours": b'<?xml version="1.0" encoding="utf-8"?>\n<testsuites name="c"><testsuite/>'
            b"</testsuites>\n",
    "one suite, no declaration": b'<testsuite name="c" tests="1"/>',
    "a stylesheet, a comment and a document type first":
        b'<?xml version="1.0"?>\n<?xml-stylesheet type="text/xsl" href="junit.xsl"?>\n'
        b"<!-- generated -->\n<!DOCTYPE testsuites>\n<testsuites>\n</testsuites>\n",
    "UTF-16 with its byte order mark (PowerShell)":
        '<?xml version="1.0" encoding="utf-16"?>\r\n<testsuites/>'.encode("utf-16"),
}
KEPT = {
    "a campaign": b"name: c\nrulebook: r.rules\n",
    "a rulebook": b'rulebook "r" version "1.0.0"\n',
    "another XML document": b'<?xml version="1.0"?>\n<data/>\n',
    "an element whose name only starts like one": b"<testsuitesummary/>",
    "HTML": b"<!DOCTYPE html>\n<html></html>\n",
    "HDF5": b"\x89HDF\r\n\x1a\n" + bytes(64),
}


@pytest.mark.parametrize("name", list(REPLACEABLE))
def test_a_junit_report_or_an_empty_file_may_be_replaced(tmp_path: Path, name: str) -> None:
    (tmp_path / "junit.xml").write_bytes(REPLACEABLE[name])
    assert is_junit_report(tmp_path / "junit.xml")


@pytest.mark.parametrize("name", list(KEPT))
def test_any_other_file_is_kept(tmp_path: Path, name: str) -> None:
    (tmp_path / "junit.xml").write_bytes(KEPT[name])
    assert not is_junit_report(tmp_path / "junit.xml")
