"""The TextMate grammar (``editors/rulebook.tmLanguage.json``): a golden tokenization of the
frozen operations rulebook 1.1.0, and properties the golden file alone would not keep true.

The tokenizer is ``textmate-grammar-python``, a port of the engine VS Code uses (vscode-textmate)
on the Oniguruma regex library, so the test sees what an editor sees. Every pattern of the
grammar is also valid Python ``re`` syntax (checked below), so the grammar stays within what
both engines read alike.

Regenerate after a deliberate change of the grammar with
``IDEFIX_UPDATE_GOLDEN=1 pytest tests/lsp/test_lsp_grammar.py`` and review the diff.
"""

from __future__ import annotations

import json
import logging
import os
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any, get_args

import pytest
from textmate_grammar.parsers.base import LanguageParser

from idefix_rules import signals
from idefix_rules.cli import main
from idefix_rules.rulebook import parse_text
from idefix_rules.rulebook.model import PARAMETRIC_REDUCERS, Domain, Reducer
from idefix_rules.rulebook.types import COMMAND_NAMES, PATH_NAMES

REPOSITORY = Path(__file__).resolve().parents[2]
GRAMMAR = REPOSITORY / "editors" / "rulebook.tmLanguage.json"
# the frozen operations rulebook 1.1.0, not the live one the rule engineers edit
FROZEN_RULEBOOK = REPOSITORY / "tests" / "fixtures" / "rulebooks" / "idefix-ops-1.1.0.rules"
GOLDEN = Path(__file__).parent / "golden" / "idefix-ops-1.1.0.tokens"
UPDATE = os.environ.get("IDEFIX_UPDATE_GOLDEN") == "1"

Token = tuple[int, int, str, str]  # line, column, text, innermost scope


@pytest.fixture(scope="module")
def grammar() -> dict[str, Any]:
    return json.loads(GRAMMAR.read_text(encoding="utf-8"))  # type: ignore[no-any-return]


@pytest.fixture(scope="module")
def tokenize(grammar: dict[str, Any]) -> Any:
    logging.getLogger("textmate_grammar").setLevel(logging.ERROR)  # it logs every string
    parser = LanguageParser(grammar)

    def tokens(text: str) -> list[Token]:
        element = parser.parse_string(text)
        assert element is not None
        found = []
        for (line, column), piece, scopes in element.flatten():
            if piece.strip():
                found.append((line, column, piece, scopes[-1]))
        return found

    return tokens


def _patterns(node: Any) -> Iterator[str]:
    if isinstance(node, dict):
        for key, value in node.items():
            if key in ("match", "begin", "end") and isinstance(value, str):
                yield value
            else:
                yield from _patterns(value)
    elif isinstance(node, list):
        for item in node:
            yield from _patterns(item)


def golden_text(tokens: list[Token], text: str) -> str:
    """Each source line that has tokens, then one token per line: text and scope."""
    lines = text.split("\n")
    out: list[str] = []
    current = -1
    for line, _column, piece, scope in tokens:
        if line != current:
            out.append(f"{line + 1:4d} | {lines[line]}")
            current = line
        out.append(f"       {piece:<28} {scope.removesuffix('.rulebook')}")
    return "\n".join(out) + "\n"


def test_the_frozen_rulebook_tokenizes_as_the_golden_file(tokenize: Any) -> None:
    text = FROZEN_RULEBOOK.read_text(encoding="utf-8")
    produced = golden_text(tokenize(text), text)
    if UPDATE:
        GOLDEN.write_text(produced, encoding="utf-8")
    assert produced == GOLDEN.read_text(encoding="utf-8")


def test_every_pattern_is_also_a_python_regex(grammar: dict[str, Any]) -> None:
    patterns = list(_patterns(grammar))
    assert len(patterns) > 30
    for pattern in patterns:
        re.compile(pattern)  # raises on Oniguruma-only syntax


def test_grammar_identifies_the_language(grammar: dict[str, Any]) -> None:
    assert grammar["scopeName"] == "source.idefix-rules" and grammar["fileTypes"] == ["rules"]
    package = json.loads((REPOSITORY / "editors" / "vscode" / "package.json").read_text())
    [language] = package["contributes"]["grammars"]
    assert language["scopeName"] == grammar["scopeName"]


def _scope_of(tokenize: Any, text: str, word: str) -> str:
    [scope] = {scope for _, _, piece, scope in tokenize(text) if piece == word}
    return str(scope)


# `command` is a reserved word of the language (it starts a command rule): only `ref.command`
# can be written
@pytest.mark.parametrize("name", [*(n for n in signals.SIGNALS if n != "command"),
                                  *(signals.REF_PREFIX + n for n in signals.FMU_SIGNALS)])
def test_every_contract_signal_is_highlighted_as_a_signal(tokenize: Any, name: str) -> None:
    text = f"index I {{ value = max over time ({name}) limit = 1 weight = 1 }}\n"
    assert _scope_of(tokenize, text, name).startswith("support.variable.signal.")


@pytest.mark.parametrize("name", sorted(set(COMMAND_NAMES) | set(PATH_NAMES) - {"time"}))
def test_built_in_names_are_highlighted(tokenize: Any, name: str) -> None:
    scope = _scope_of(tokenize, f"command c: require {name} > 0\n", name)
    assert scope in ("variable.language.rulebook", "support.variable.signal.derived.rulebook",
                     "support.variable.signal.fmu.rulebook")


@pytest.mark.parametrize("reducer", get_args(Reducer))
@pytest.mark.parametrize("domain", get_args(Domain))
def test_every_reducer_and_domain_of_the_language_is_highlighted(tokenize: Any, reducer: str,
                                                                 domain: str) -> None:
    parameter = "50 " if reducer in PARAMETRIC_REDUCERS else ""
    text = f"index I {{ value = {reducer} {parameter}over {domain} (x) limit = 1 weight = 1 }}\n"
    assert _scope_of(tokenize, text, reducer) != "variable.other.rulebook"
    assert _scope_of(tokenize, text, domain) == "support.type.domain.rulebook"


def test_declared_names_and_plain_names_of_the_frozen_rulebook(tokenize: Any) -> None:
    text = FROZEN_RULEBOOK.read_text(encoding="utf-8")
    rulebook = parse_text(text, str(FROZEN_RULEBOOK))
    tokens = tokenize(text)
    entities = {piece for _, _, piece, scope in tokens if scope.startswith("entity.name.")}
    declared = {c.name for c in rulebook.constants} | {i.name for i in rulebook.indices} | {
        c.name for c in rulebook.chances} | {r.name for r in rulebook.command_rules} | {
        p.name for p in rulebook.prescreens} | {v.name for v in rulebook.verdicts} | {
        level.level for level in rulebook.obstacle_levels}
    assert entities == declared
    # whatever is left as a plain name is a name the rulebook declared (or a combine method)
    plain = {piece for _, _, piece, scope in tokens if scope == "variable.other.rulebook"}
    assert plain <= declared | {"max_weighted", "mean"}
    assert "mean" in plain  # `path = mean`: a method, not the reducer or the function


def test_keywords_after_a_number_are_not_its_unit(tokenize: Any) -> None:
    text = "chance c = percentile 95 over time (speed) > 1 cm/s and 0 < 1\n"
    scoped = {piece: scope for _, _, piece, scope in tokenize(text)}
    assert scoped["over"] == "keyword.other.over.rulebook"
    assert scoped["cm/s"] == "keyword.other.unit.rulebook"
    assert scoped["and"] == "keyword.operator.logical.rulebook"
    assert scoped["95"] == "constant.numeric.rulebook"


def test_an_unclosed_string_ends_at_the_end_of_its_line(tokenize: Any) -> None:
    text = 'const a = 1 because "never closed\nconst b = 2\n'
    scoped = {piece: scope for _, _, piece, scope in tokenize(text)}
    assert scoped["b"] == "entity.name.constant.rulebook"


def test_vscode_extension_starts_the_language_server() -> None:
    folder = REPOSITORY / "editors" / "vscode"
    package = json.loads((folder / "package.json").read_text(encoding="utf-8"))
    settings = package["contributes"]["configuration"]["properties"]
    command = settings["idefixRules.server.command"]["default"]
    arguments = settings["idefixRules.server.args"]["default"]
    assert [command, *arguments] == ["idefix-verify", "lsp"]
    assert main([*arguments, "--stdio", "--help"]) == 0  # what the client runs, with its --stdio
    extension = (folder / package["main"]).read_text(encoding="utf-8")
    assert "server.command" in extension and "TransportKind.stdio" in extension
    [language] = package["contributes"]["languages"]
    assert language["extensions"] == [".rules"]
    assert (folder / language["configuration"]).is_file()
    # the grammar the extension ships is built from the one tested here
    [grammar] = package["contributes"]["grammars"]
    assert grammar["path"] == "./syntaxes/rulebook.tmLanguage.json"
    assert "'../rulebook.tmLanguage.json','syntaxes/rulebook.tmLanguage.json'" in \
        package["scripts"]["build"]
