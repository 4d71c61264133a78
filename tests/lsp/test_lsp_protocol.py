"""The language server driven through the protocol, as an editor drives it: what the editor
receives for diagnostics, hover, definitions, references, completion, formatting and quick
fixes. Positions are found in the text itself (``at``), never hard-coded."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from lsp_client import LspClient, apply_edits, utf16_column

from idefix_rules.cli import main


def at(text: str, needle: str, occurrence: int = 1, offset: int = 0) -> dict[str, int]:
    """The LSP position of the ``occurrence``-th ``needle`` in ``text`` (plus ``offset``
    characters)."""
    start = -1
    for _ in range(occurrence):
        start = text.index(needle, start + 1)
    start += offset
    line = text.count("\n", 0, start)
    column = start - (text.rfind("\n", 0, start) + 1)
    return {"line": line, "character": utf16_column(text.split("\n")[line], column)}


def span_of(text: str, needle: str, occurrence: int = 1) -> dict[str, dict[str, int]]:
    start = at(text, needle, occurrence)
    return {"start": start, "end": {"line": start["line"],
                                    "character": start["character"] + len(needle)}}


def check_json(path: Path, capsys: pytest.CaptureFixture[str]) -> list[dict[str, object]]:
    capsys.readouterr()
    main(["check", "--strict", "--format", "json", str(path)])
    return json.loads(capsys.readouterr().out)  # type: ignore[no-any-return]


def as_editor_sees(record: dict[str, object], text: str) -> dict[str, object]:
    """What ``check --strict --format json`` says, in the shape of an LSP diagnostic."""
    lines = text.split("\n")
    line, column = int(record["line"]) - 1, int(record["column"]) - 1  # type: ignore[arg-type]
    end_line, end_column = int(record["end_line"]) - 1, int(record["end_column"]) - 1  # type: ignore[arg-type]
    message = str(record["message"]) + (f"\nhint: {record['hint']}" if record["hint"] else "")
    return {
        "code": record["code"],
        "severity": 1 if record["severity"] == "error" else 2,
        "message": message,
        "range": {"start": {"line": line, "character": utf16_column(lines[line], column)},
                  "end": {"line": end_line,
                          "character": utf16_column(lines[end_line], end_column)}},
    }


def editor_view(diagnostic: dict[str, object]) -> dict[str, object]:
    return {key: diagnostic[key] for key in ("code", "severity", "message", "range")}


# a rulebook with mistakes of several kinds, and a non-ASCII title before one of them (UTF-16
# columns differ from character columns after it)
BROKEN = '''rulebook "broken" version "1.0.0"
purpose "Mistakes an editor must show"

const critical_slip = 70 % because "Slip above 70 % is critical"
const unused        = 3 cm
const bad_sum       = 5 cm + 2 deg

index I_s "slip 🚀 ratio" { value = max over time (max over wheels (abs(wheel.slp)))
  limit = critcal_slip weight = 1 }

index I_ds "sinkage" {
  value  = max over time (max over wheels (wheel.sinkage))
  limit  = 5 deg
  weight = 1.5
}

verdict acceptable_risk: require risk <= 70 %
'''

SYNTAX = '''rulebook "syntax" version "1.0.0" purpose "Two syntax errors"
const a = 5 cm because "x"
verdict ok: require risk = 70 %
const b = (3 cm
verdict fine: require risk <= 70 %
'''


# ----------------------------------------------------------------------------- handshake

def test_initialize_announces_every_feature(client: LspClient) -> None:
    capabilities = client.initialize_result["capabilities"]
    assert client.initialize_result["serverInfo"]["name"] == "idefix-rules"
    assert capabilities["hoverProvider"] and capabilities["definitionProvider"]
    assert capabilities["referencesProvider"] and capabilities["documentFormattingProvider"]
    assert capabilities["codeActionProvider"]["codeActionKinds"] == ["quickfix"]
    assert "." in capabilities["completionProvider"]["triggerCharacters"]
    assert capabilities["textDocumentSync"]["openClose"]
    assert capabilities["positionEncoding"] == "utf-16"


# ----------------------------------------------------------------------------- diagnostics

@pytest.mark.parametrize("text", [BROKEN, SYNTAX], ids=["checker", "syntax"])
def test_diagnostics_on_open_are_those_of_check_strict(client: LspClient, tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str],
                                                       text: str) -> None:
    path = tmp_path / "mistakes.rules"
    path.write_text(text, encoding="utf-8")
    expected = [as_editor_sees(record, text) for record in check_json(path, capsys)]
    uri = client.open(path, text)
    received = client.diagnostics(uri, 1)
    assert [editor_view(d) for d in received] == expected
    assert len(expected) >= 2 and all(d["source"] == "idefix-rules" for d in received)


def test_broken_rulebook_shows_each_kind_of_problem_where_it_is(client: LspClient,
                                                                tmp_path: Path) -> None:
    uri = client.open(tmp_path / "broken.rules", BROKEN)
    by_code: dict[str, list[dict[str, object]]] = {}
    for diagnostic in client.diagnostics(uri, 1):
        by_code.setdefault(str(diagnostic["code"]), []).append(diagnostic)
    assert set(by_code) == {"E101", "E201", "E204", "E401", "W601"}
    typo = next(d for d in by_code["E101"] if "wheel.slp" in str(d["message"]))
    # after the emoji (two UTF-16 units) the column is one more than in characters
    assert typo["range"] == span_of(BROKEN, "wheel.slp")
    line = BROKEN.split("\n")[typo["range"]["start"]["line"]]  # type: ignore[index]
    assert typo["range"]["start"]["character"] == line.index("wheel.slp") + 1  # type: ignore[index]
    assert "did you mean 'wheel.slip'?" in str(typo["message"])
    # `critical_slip` is only read through the misspelt name: unused as far as the checker sees
    assert {str(d["message"]) for d in by_code["W601"]} == {
        f"constant '{name}' is never used" for name in ("critical_slip", "unused", "bad_sum")}
    assert {d["severity"] for d in by_code["W601"]} == {2}
    assert by_code["E204"][0]["range"] == span_of(BROKEN, "5 deg")


def test_a_clean_rulebook_has_no_diagnostics(client: LspClient, default_text: str,
                                             tmp_path: Path) -> None:
    uri = client.open(tmp_path / "idefix-ops.rules", default_text)
    assert client.diagnostics(uri, 1) == []


def test_diagnostics_follow_changes(client: LspClient, default_text: str,
                                    tmp_path: Path) -> None:
    uri = client.open(tmp_path / "edited.rules", default_text)
    assert client.diagnostics(uri, 1) == []
    # the editor sends only the changed range: `critical_tilt` -> `critical_tlt` in I_psi
    typo = span_of(default_text, "critical_tilt", occurrence=2)
    client.change_range(uri, 2, typo, "critical_tlt")
    [diagnostic] = client.diagnostics(uri, 2)
    assert diagnostic["code"] == "E101" and diagnostic["range"]["start"] == typo["start"]
    assert diagnostic["range"]["end"]["character"] == typo["start"]["character"] + len(
        "critical_tlt")
    client.change(uri, 3, default_text)
    assert client.diagnostics(uri, 3) == []


def test_diagnostics_are_cleared_when_the_document_closes(client: LspClient,
                                                          tmp_path: Path) -> None:
    uri = client.open(tmp_path / "closing.rules", BROKEN)
    assert client.diagnostics(uri, 1)
    client.notify("textDocument/didClose", {"textDocument": {"uri": uri}})
    cleared = client.wait_for("textDocument/publishDiagnostics",
                              lambda p: p["uri"] == uri and p.get("version") is None)
    assert cleared["diagnostics"] == []


def test_a_burst_of_changes_is_checked_once(default_text: str, tmp_path: Path) -> None:
    # a long debounce: the three changes below arrive well within it
    editor = LspClient({"debounce": 3.0})
    try:
        uri = editor.open(tmp_path / "typing.rules", default_text)
        assert editor.diagnostics(uri, 1) == []
        editor.change(uri, 2, default_text.replace("critical_tilt\n", "c\n", 1))
        editor.change(uri, 3, default_text.replace("critical_tilt\n", "cr\n", 1))
        editor.change(uri, 4, default_text.replace("critical_tilt\n", "cri\n", 1))
        [diagnostic] = editor.diagnostics(uri, 4)
        assert "unknown name 'cri'" in diagnostic["message"]
        versions = [p["version"] for p in editor.received("textDocument/publishDiagnostics")]
        assert versions == [1, 4]
    finally:
        assert editor.close() == 0


# ----------------------------------------------------------------------------- hover

def hover(client: LspClient, uri: str, position: dict[str, int]) -> str:
    result = client.request("textDocument/hover", {"textDocument": {"uri": uri},
                                                   "position": position})
    assert result is not None and result["contents"]["kind"] == "markdown"
    return str(result["contents"]["value"])


def test_hover_on_a_constant_shows_value_unit_si_value_and_rationale(
        client: LspClient, default_text: str, tmp_path: Path) -> None:
    uri = client.open(tmp_path / "hover.rules", default_text)
    # on a use of the constant (the limit of I_s), not on its declaration
    shown = hover(client, uri, at(default_text, "limit  = critical_slip", offset=12))
    assert "const critical_slip" in shown and "`70 %`" in shown
    assert "SI value: `0.7`" in shown and "a ratio" in shown
    assert "Slip above 70 % is critical (paper, section 3.2)" in shown
    tilt = hover(client, uri, at(default_text, "critical_tilt", occurrence=2))
    assert "`15 deg`" in tilt and "`0.261799 rad`" in tilt and "an angle (rad)" in tilt
    levels = hover(client, uri, at(default_text, "f_obs", occurrence=2))
    assert "`{L1: 0.2, L2: 0.6, L3: 1}`" in levels and "risk factor per obstacle level" in levels


def test_hover_on_an_index_shows_formula_limit_weight_and_rationale(
        client: LspClient, default_text: str, tmp_path: Path) -> None:
    uri = client.open(tmp_path / "hover-index.rules", default_text)
    shown = hover(client, uri, at(default_text, "require I_obs", offset=8))  # in a prescreen
    assert "index I_obs" in shown and "obstacle collisions" in shown
    assert "formula: `sum over parts (sum over levels (collision.hits * f_obs))`" in shown
    assert "limit: `1`" in shown and "weight: `1`" in shown
    assert "result map: `max over parts (max over levels (collision.contact * f_obs))`" in shown
    assert "Eq. 4: obstacles hit per body part and level" in shown
    slip = hover(client, uri, at(default_text, "index I_s ", offset=6))
    assert "limit: `critical_slip` = `0.7`" in slip and "a ratio" in slip


def test_hover_on_a_signal_shows_its_contract_entry(client: LspClient, default_text: str,
                                                    tmp_path: Path) -> None:
    uri = client.open(tmp_path / "hover-signal.rules", default_text)
    shown = hover(client, uri, at(default_text, "wheel.slip)", offset=3))
    assert "signal wheel.slip" in shown and "longitudinal slip ratio" in shown
    assert "unit: `1`" in shown and "time × wheel (FL, FR, RL, RR)" in shown
    assert "the rover FMU" in shown
    derived = hover(client, uri, at(default_text, "ref.roll"))
    assert "unit: `rad`" in derived and "reference run: body roll" in derived
    assert "the evaluator" in derived
    command = hover(client, uri, at(default_text, "abs(delta_heading)", offset=4))
    assert "command quantity delta_heading" in command and "an angle (rad)" in command


def test_hover_on_a_problem_explains_its_code(client: LspClient, tmp_path: Path) -> None:
    uri = client.open(tmp_path / "hover-problem.rules", BROKEN)
    client.diagnostics(uri, 1)
    shown = hover(client, uri, at(BROKEN, "5 cm + 2 deg", offset=5))
    assert "error[E201]" in shown and "dimensions do not match" in shown


def test_no_hover_on_a_rationale(client: LspClient, default_text: str,
                                 tmp_path: Path) -> None:
    uri = client.open(tmp_path / "hover-none.rules", default_text)
    result = client.request("textDocument/hover", {"textDocument": {"uri": uri},
                                                   "position": at(default_text, "Nominal slip")})
    assert result is None


# ----------------------------------------------------------------------------- definitions

def definition(client: LspClient, uri: str, position: dict[str, int]) -> dict[str, object]:
    result = client.request("textDocument/definition", {"textDocument": {"uri": uri},
                                                        "position": position})
    assert result is not None and result["uri"] == uri
    return result["range"]  # type: ignore[no-any-return]


@pytest.mark.parametrize(("use", "offset", "declared"), [
    ("limit  = critical_slip", 9, "critical_slip"),   # constant
    ("require I_obs", 8, "I_obs"),                      # index, from a prescreen
    ("chance(hit_L3)", 7, "hit_L3"),                    # chance, from a verdict
    ("not got_stuck", 4, "got_stuck"),                  # chance, from a prescreen
    ("collision.hits[L2]", 15, "L2"),                   # obstacle level, from a selection
    ("{L1: 0.2", 1, "L1"),                              # obstacle level, from a table
])
def test_go_to_definition(client: LspClient, default_text: str, tmp_path: Path, use: str,
                          offset: int, declared: str) -> None:
    uri = client.open(tmp_path / "definition.rules", default_text)
    keyword = {"L2": "level ", "L1": "level ", "I_obs": "index ", "hit_L3": "chance ",
               "got_stuck": "chance "}.get(declared, "const ")
    expected = span_of(default_text, keyword + declared)
    expected["start"]["character"] += len(keyword)
    assert definition(client, uri, at(default_text, use, offset=offset)) == expected


def test_find_references(client: LspClient, default_text: str, tmp_path: Path) -> None:
    uri = client.open(tmp_path / "references.rules", default_text)
    params = {"textDocument": {"uri": uri}, "position": at(default_text, "critical_tilt"),
              "context": {"includeDeclaration": False}}
    places = client.request("textDocument/references", params)
    assert [p["range"] for p in places] == [span_of(default_text, "critical_tilt", 2),
                                           span_of(default_text, "critical_tilt", 3)]
    # an obstacle level: its declaration, the f_obs table and the selection in hit_L1
    params["position"] = at(default_text, "level L1", offset=6)
    params["context"] = {"includeDeclaration": True}
    places = client.request("textDocument/references", params)
    assert [p["range"] for p in places] == [word(default_text, "level L1", 6, 2),
                                           word(default_text, "{L1: 0.2", 1, 2),
                                           word(default_text, "hits[L1]", 5, 2)]


def word(text: str, context: str, offset: int, length: int) -> dict[str, dict[str, int]]:
    """The range of ``length`` characters ``offset`` characters into ``context``."""
    start = at(text, context, offset=offset)
    return {"start": start, "end": {**start, "character": start["character"] + length}}


# ----------------------------------------------------------------------------- completion

def complete(client: LspClient, uri: str, position: dict[str, int]) -> dict[str, dict[str, object]]:
    result = client.request("textDocument/completion", {"textDocument": {"uri": uri},
                                                        "position": position})
    return {item["label"]: item for item in result["items"]}


def test_completion_in_context(client: LspClient, default_text: str, tmp_path: Path) -> None:
    text = default_text.replace("limit  = critical_sinkage", "limit  = 5 c").replace(
        "max over wheels (wheel.sinkage)", "max over wheels (wheel.si")
    uri = client.open(tmp_path / "completion.rules", text)
    units = complete(client, uri, at(text, "limit  = 5 c", offset=12))
    assert {"cm", "mm", "m", "deg", "%"} <= set(units) and "wheel.slip" not in units
    assert units["cm"]["textEdit"]["range"] == word(text, "limit  = 5 c", 11, 1)
    signals = complete(client, uri, at(text, "wheel.si", offset=8))
    assert {"wheel.sinkage", "wheel.slip", "ref.roll", "collision.hits"} <= set(signals)
    assert {"max", "percentile", "any"} <= set(signals) and "critical_tilt" in signals
    assert {"fraction", "time_above", "count"} <= set(signals)  # every reducer of the language
    assert signals["wheel.sinkage"]["textEdit"]["range"] == span_of(text, "wheel.si")
    domains = complete(client, uri, at(text, "max over time (max over wheels (abs(wheel.slip_",
                                       offset=9))
    assert set(domains) == {"time", "wheels", "parts", "levels", "runs"}
    command = complete(client, uri, at(text, "require abs(delta_heading)", offset=12))
    assert "delta_heading" in command and "wheel.slip" not in command
    verdict = complete(client, uri, at(text, "chance(hit_L3)", offset=7))
    assert set(verdict) == {"hit_L1", "hit_L2", "hit_L3", "too_fast", "too_abrupt",
                            "got_stuck"}


# ----------------------------------------------------------------------------- formatting

MESSY = '''rulebook "messy"   version "1.0.0" purpose "Formatting"
verdict ok : require risk<=70%   # the only verdict
index I_s {weight=1 limit=critical_slip
value=max over time(max over wheels(abs(wheel.slip)))}
const critical_slip=70 % because "Slip above 70 % is critical"
'''


@pytest.mark.parametrize("ending", ["\n", "\r\n"])
def test_formatting_gives_what_fmt_writes(client: LspClient, tmp_path: Path, ending: str,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "messy.rules"
    messy = MESSY.replace("\n", ending)
    path.write_bytes(messy.encode("utf-8"))
    uri = client.open(path, messy)
    edits = client.request("textDocument/formatting", {
        "textDocument": {"uri": uri}, "options": {"tabSize": 2, "insertSpaces": True}})
    assert main(["fmt", str(path)]) == 0
    formatted = path.read_bytes().decode("utf-8")  # line endings and all
    assert formatted != messy and apply_edits(messy, edits) == formatted
    assert formatted.count("\n") == formatted.count(ending)
    client.change(uri, 2, formatted)
    again = client.request("textDocument/formatting", {
        "textDocument": {"uri": uri}, "options": {"tabSize": 2, "insertSpaces": True}})
    assert again == []


def test_formatting_a_file_with_a_syntax_error_changes_nothing(client: LspClient,
                                                               tmp_path: Path) -> None:
    uri = client.open(tmp_path / "unformattable.rules", SYNTAX)
    edits = client.request("textDocument/formatting", {
        "textDocument": {"uri": uri}, "options": {"tabSize": 2, "insertSpaces": True}})
    assert edits is None
    shown = client.wait_for("window/showMessage", lambda p: "not formatted" in p["message"])
    assert "unformattable.rules:3" in shown["message"]


# ----------------------------------------------------------------------------- quick fixes

def test_quick_fix_of_a_misspelt_name(client: LspClient, default_text: str,
                                      tmp_path: Path) -> None:
    text = default_text.replace("limit  = critical_slip\n", "limit  = critcal_slip\n")
    uri = client.open(tmp_path / "fix.rules", text)
    [diagnostic] = [d for d in client.diagnostics(uri, 1) if d["code"] == "E101"]
    actions = client.request("textDocument/codeAction", {
        "textDocument": {"uri": uri}, "range": diagnostic["range"],
        "context": {"diagnostics": [diagnostic]}})
    [action] = actions
    assert action["title"] == "replace 'critcal_slip' with 'critical_slip'"
    assert action["kind"] == "quickfix" and action["diagnostics"][0]["code"] == "E101"
    fixed = apply_edits(text, action["edit"]["changes"][uri])
    assert fixed == default_text
    client.change(uri, 2, fixed)
    assert client.diagnostics(uri, 2) == []


def test_no_quick_fix_without_an_obvious_one(client: LspClient, tmp_path: Path) -> None:
    uri = client.open(tmp_path / "nofix.rules", BROKEN)
    diagnostics = client.diagnostics(uri, 1)
    dimension = next(d for d in diagnostics if d["code"] == "E201")
    actions = client.request("textDocument/codeAction", {
        "textDocument": {"uri": uri}, "range": dimension["range"],
        "context": {"diagnostics": [dimension]}})
    assert actions == []
    assert re.search(r"cannot add a length", str(dimension["message"]))


def test_columns_follow_the_encoding_the_client_asks_for(tmp_path: Path) -> None:
    editor = LspClient({"debounce": 0.02}, position_encodings=("utf-32", "utf-16"))
    try:
        assert editor.initialize_result["capabilities"]["positionEncoding"] == "utf-32"
        uri = editor.open(tmp_path / "utf32.rules", BROKEN)
        typo = next(d for d in editor.diagnostics(uri, 1) if "wheel.slp" in d["message"])
        line = BROKEN.split("\n")[typo["range"]["start"]["line"]]
        # UTF-32 columns count characters: the emoji before the name is one, not two
        assert typo["range"]["start"]["character"] == line.index("wheel.slp")
        assert typo["range"]["end"]["character"] == line.index("wheel.slp") + len("wheel.slp")
    finally:
        assert editor.close() == 0


@pytest.mark.parametrize("method", ["textDocument/hover", "textDocument/formatting"])
def test_a_request_for_a_document_neither_open_nor_on_disk_is_invalid_params(
        client: LspClient, tmp_path: Path, method: str) -> None:
    uri = (tmp_path / "nope.rules").as_uri()
    params: dict[str, object] = {"textDocument": {"uri": uri}}
    if method.endswith("hover"):
        params["position"] = {"line": 0, "character": 0}
    else:
        params["options"] = {"tabSize": 2, "insertSpaces": True}
    with pytest.raises(AssertionError) as failed:
        client.request(method, params)
    error = str(failed.value)
    assert "-32602" in error and "is not open and cannot be read" in error
    assert "Traceback" not in error and "FileNotFoundError" not in error
