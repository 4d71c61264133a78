"""Parsing rulebook text into the rule model.

:func:`parse_rulebook` runs lark's LALR parser (grammar loaded once by
:mod:`~idefix_rules.rulebook.grammar`) and lowers the tree at once into the frozen nodes of
:mod:`~idefix_rules.rulebook.model`; the lark tree never leaves this module. Every node gets a
span (line, column, end line, end column). Any mistake, syntax or structure (a missing header,
a repeated section, an index without a limit), raises :class:`~idefix_rules.errors.UserInputError`
carrying all diagnostics found; arbitrary text never raises anything else.

Comments are kept on the declaration they belong to (``comments``; the end of the file goes to
``Rulebook.trailing_comments``), as the text written, starting with ``#``:

* a comment on its own line before a declaration: ``"# text"``;
* a comment at the end of a line of a declaration: ``"@eol # text"``; inside an ``index`` or
  ``combine`` block ``"@ITEM # text"`` where ITEM is the line's item (``value``, ``nominal``,
  ``limit``, ``weight``, ``map``, ``because``, ``run``, ``path``, ``confidence``,
  ``indifference``, ``verdict_indifference``, the block's own keyword for its first line,
  ``}`` for its last);
* a comment on its own line inside such a block: ``"@ITEM^ # text"`` (printed above ITEM);
* a comment before ``settings {`` / ``obstacles {``: ``"@block^ # text"`` on the first entry;
* a comment on its own line after the last entry of such a block, before its ``}``:
  ``"@block$ # text"`` on the last entry (printed before the ``}``).

The formatter (:mod:`~idefix_rules.rulebook.format`) puts each back in its place.

>>> book = parse_rulebook('''
... rulebook "demo" version "0.1.0" purpose "Example"
... index I_s { value = max over time (max over wheels (abs(wheel.slip))) limit = 70 % weight = 1 }
... verdict ok: require risk <= 0.7
... ''', "demo.rules")
>>> book.indices[0].limit
Number(value=70.0, unit='%')
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
from collections.abc import Sequence
from typing import Any

import lark
from lark import Token, Transformer, v_args

from idefix_rules.errors import Diagnostic, Span, UserInputError, error
from idefix_rules.limits import NOT_A_RULEBOOK, check_rulebook_text
from idefix_rules.rulebook import model
from idefix_rules.rulebook.comments import attach_comments
from idefix_rules.rulebook.grammar import collecting_comments, rulebook_parser
from idefix_rules.rulebook.infer import did_you_mean
from idefix_rules.rulebook.syntax_errors import (
    SYNTAX_ERROR,
    blank_failed_declaration,
    error_line,
    syntax_diagnostic,
)
from idefix_rules.units import underflows

NUMBER_OUT_OF_RANGE = "E003"
REPEATED_SECTION = "E004"
MISSING_HEADER = "E500"
INDEX_ITEM = "E006"
UNKNOWN_DOMAIN = "E007"
UNKNOWN_COMBINATION = "E008"
TOO_MANY_ERRORS = "E009"

MAX_SYNTAX_ERRORS = 10
RUN_COMBINATIONS = ("max_weighted",)
PATH_COMBINATIONS = ("mean",)

_QUANTITY = re.compile(r"((?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?)[ \t]*(.*)",
                       re.DOTALL)


def parse_rulebook(text: str, path: str = "<rulebook>") -> model.Rulebook:
    """Parse and lower rulebook ``text`` (read from ``path``, used in spans and messages).

    Raises :class:`UserInputError` with every diagnostic found.
    """
    if not isinstance(text, str):
        raise UserInputError(error("E000", "a rulebook must be text", Span(path)))
    if text.startswith("\ufeff"):  # a byte-order mark some editors write: not content
        text = text[1:]
    check_rulebook_text(text, path)
    tree, comments, diagnostics = _parse_tree(text, path)
    if diagnostics or tree is None:
        diagnostics.sort(key=_position)
        raise UserInputError(_foreign_file(text, path) or diagnostics, sources={path: text})
    lowering = _Lowering(path)
    try:
        declarations = lowering.transform(tree)
    except RecursionError:
        raise UserInputError(error(SYNTAX_ERROR, "expression nested too deeply",
                                   _deepest_declaration(tree, path),
                                   hint="split it into named constants or derived values"),
                             sources={path: text}) from None
    except lark.exceptions.VisitError as failure:  # only our own mistakes can land here
        if isinstance(failure.orig_exc, RecursionError):
            raise UserInputError(error(SYNTAX_ERROR, "expression nested too deeply",
                                       _span(path, getattr(failure.obj, "meta", None))),
                                 sources={path: text}) from None
        raise failure.orig_exc from None
    rulebook = _assemble(declarations, comments, text, path, lowering.diagnostics)
    if lowering.diagnostics:
        lowering.diagnostics.sort(key=_position)
        raise UserInputError(lowering.diagnostics, sources={path: text})
    return rulebook


_FIRST_WORD = re.compile(r"(?:[ \t\n]|#[^\n]*)*([A-Za-z_][A-Za-z0-9_]*|\S)")
_DECLARATION_WORDS = frozenset(("rulebook", "version", "purpose", "const", "settings",
                                "obstacles", "command", "index", "chance", "prescreen",
                                "verdict", "combine", "rank"))


def _foreign_file(text: str, path: str) -> list[Diagnostic]:
    """One diagnostic, quoting at most the first word, for a file whose very first word starts
    no declaration (another kind of file, named by mistake): none of its lines is shown."""
    first = _FIRST_WORD.match(text)
    if first is None or first.group(1) in _DECLARATION_WORDS \
            or difflib.get_close_matches(first.group(1), _DECLARATION_WORDS, cutoff=0.75):
        return []  # a rulebook with a mistake in its first word: the usual diagnostics
    word = first.group(1)[:20]
    return [error(NOT_A_RULEBOOK, f"{path} is not a rulebook: it begins with {word!r}",
                  Span(path), hint='a rulebook begins with `rulebook "name" version "x.y.z"`')]


def _deepest_declaration(tree: lark.Tree[Any], path: str) -> Span:
    """Span of the top-level declaration holding the deepest node (found without recursion)."""
    best, best_depth = None, -1
    for declaration in tree.children:
        if not isinstance(declaration, lark.Tree):
            continue
        stack = [(declaration, 1)]
        while stack:
            node, depth = stack.pop()
            if depth > best_depth:
                best, best_depth = declaration, depth
            stack.extend((child, depth + 1) for child in node.children
                         if isinstance(child, lark.Tree))
    span = _span(path, getattr(best, "meta", None))
    return span if span.line > 0 else Span(path, 1, 1, 1, 2)


def _position(diagnostic: Diagnostic) -> tuple[int, int]:
    span = diagnostic.span
    return (span.line, span.column) if span else (0, 0)


# ----------------------------------------------------------------------------- lark parsing

def _parse_tree(text: str, path: str
                ) -> tuple[lark.Tree[Any] | None, list[Token], list[Diagnostic]]:
    """Parse; on syntax errors blank the failing declaration and try again to find more."""
    parser = rulebook_parser()
    diagnostics: list[Diagnostic] = []
    working = text
    while True:
        comments: list[Token] = []
        try:
            with collecting_comments(comments):
                tree = parser.parse(working)
        except lark.exceptions.UnexpectedInput as failure:
            diagnostics.append(syntax_diagnostic(failure, working, path))
            if len(diagnostics) >= MAX_SYNTAX_ERRORS:
                diagnostics.append(error(TOO_MANY_ERRORS, "stopped after "
                                         f"{MAX_SYNTAX_ERRORS} syntax errors", Span(path)))
                return None, [], diagnostics
            line, column = error_line(failure, working)
            blanked = blank_failed_declaration(working, line, column)
            if blanked == working:
                return None, [], diagnostics
            working = blanked
            continue
        except RecursionError:
            line = 1
            diagnostics.append(error(SYNTAX_ERROR, "expression nested too deeply",
                                     Span(path, line, 1, line, 2)))
            return None, [], diagnostics
        return tree, comments, diagnostics


# ----------------------------------------------------------------------------- lowering

def _span(path: str, meta: Any) -> Span:
    if getattr(meta, "empty", True):
        return model.NO_SPAN
    return Span(path, meta.line, meta.column, meta.end_line, meta.end_column)


def _token_span(path: str, token: Token) -> Span:
    return Span(path, token.line or 0, token.column or 0, token.end_line or 0,
                token.end_column or 0)


def _unquote(token: Token) -> str:
    body = str(token)[1:-1]
    return re.sub(r'\\(["\\])', r"\1", body)


@dataclasses.dataclass
class _Item:
    """An item of a block (``limit = …``, ``because "…"``) before it lands in its node."""

    key: str
    value: Any
    span: Span


@dataclasses.dataclass
class _Section:
    """A ``settings``/``obstacles``/``combine`` block: its entries and where it is."""

    kind: str
    entries: list[Any]
    span: Span


@v_args(meta=True)
class _Lowering(Transformer):  # type: ignore[type-arg]
    """Lark tree → model nodes. Structure problems are collected in ``diagnostics``."""

    def __init__(self, path: str) -> None:
        super().__init__()
        self.path = path
        self.diagnostics: list[Diagnostic] = []

    def _s(self, meta: Any) -> Span:
        return _span(self.path, meta)

    # ---- expressions

    def number(self, meta: Any, children: list[Token]) -> model.Number:
        token = children[0]
        match = _QUANTITY.fullmatch(str(token))
        number_text, unit = (match.group(1), match.group(2)) if match else (str(token), "")
        value = float(number_text)
        span = _token_span(self.path, token)
        if not math.isfinite(value):
            self.diagnostics.append(error(NUMBER_OUT_OF_RANGE, f"number {number_text} is too "
                                          "large", span))
            value = 0.0
        elif underflows(number_text, value):
            self.diagnostics.append(error(
                NUMBER_OUT_OF_RANGE, f"number {str(token).strip()} is too small for a double: "
                                     "it would be read as 0", span,
                hint="write 0 if zero is meant, or a realistic value"))
        return model.Number(value, unit or None, span=span)

    def name(self, meta: Any, children: list[Token]) -> model.Name:
        return model.Name(str(children[0]), span=_token_span(self.path, children[0]))

    def binary(self, meta: Any, children: list[Any]) -> model.Binary:
        left, operator, right = children
        return model.Binary(str(operator), left, right, span=self._s(meta))  # type: ignore[arg-type]

    def unary(self, meta: Any, children: list[Any]) -> model.Unary:
        operator, operand = children
        return model.Unary(str(operator), operand, span=self._s(meta))  # type: ignore[arg-type]

    def select(self, meta: Any, children: list[Any]) -> model.Select:
        operand, *labels = children
        return model.Select(operand, tuple(str(label) for label in labels), span=self._s(meta))

    def callee(self, meta: Any, children: list[Token]) -> str:
        return str(children[0])

    def arguments(self, meta: Any, children: list[Any]) -> tuple[Any, ...]:
        return tuple(children)

    def call(self, meta: Any, children: list[Any]) -> model.Call:
        function, arguments = children
        return model.Call(function, arguments or (), span=self._s(meta))

    def table_entry(self, meta: Any, children: list[Any]) -> tuple[str, Any]:
        return str(children[0]), children[1]

    def table_entries(self, meta: Any, children: list[Any]) -> tuple[Any, ...]:
        return tuple(child for child in children if child is not None)

    def table(self, meta: Any, children: list[Any]) -> model.Table:
        return model.Table(children[0] or (), span=self._s(meta))

    def reducer(self, meta: Any, children: list[Token]) -> str:
        return str(children[0])

    param_reducer = reducer

    def parameter(self, meta: Any, children: list[Any]) -> Any:
        return children[0]

    def reduction(self, meta: Any, children: list[Any]) -> model.Reduce:
        if len(children) == 4:
            reducer, domain, window, operand = children
            parameter = None
        else:
            reducer, parameter, domain, window, operand = children
        domain_text = str(domain)
        if domain_text not in model.DOMAIN_AXES:
            known = list(model.DOMAIN_AXES)
            hint = did_you_mean(domain_text, known)
            self.diagnostics.append(error(
                UNKNOWN_DOMAIN, f"unknown domain '{domain_text}' after 'over'; "
                f"expected {', '.join(known[:-1])} or {known[-1]}",
                _token_span(self.path, domain), hint))
        return model.Reduce(reducer, domain_text, operand, parameter,  # type: ignore[arg-type]
                            window, span=self._s(meta))

    def during_command(self, meta: Any, children: list[Any]) -> model.Window:
        return model.Window("command", children[0], span=self._s(meta))

    def after(self, meta: Any, children: list[Any]) -> model.Window:
        return model.Window("after", children[0], span=self._s(meta))

    def before(self, meta: Any, children: list[Any]) -> model.Window:
        return model.Window("before", children[0], span=self._s(meta))

    # ---- declarations

    def rationale(self, meta: Any, children: list[Token]) -> _Item:
        return _Item("because", _unquote(children[0]), self._s(meta))

    @staticmethod
    def _because(item: _Item | None) -> str | None:
        return item.value if item is not None else None

    def header(self, meta: Any, children: list[Token]) -> model.Header:
        name, version, purpose = (_unquote(child) for child in children)
        name_span, version_span, purpose_span = (_token_span(self.path, child)
                                                 for child in children)
        return model.Header(name, version, purpose, span=self._s(meta), name_span=name_span,
                            version_span=version_span, purpose_span=purpose_span)

    def constant(self, meta: Any, children: list[Any]) -> model.Constant:
        name, value, because = children
        return model.Constant(str(name), value, self._because(because), span=self._s(meta))

    def setting(self, meta: Any, children: list[Any]) -> model.Setting:
        return model.Setting(str(children[0]), children[1], span=self._s(meta))

    def settings(self, meta: Any, children: list[Any]) -> _Section:
        return _Section("settings", children, self._s(meta))

    def level(self, meta: Any, children: list[Any]) -> model.ObstacleLevel:
        name, below, buffer = children
        return model.ObstacleLevel(str(name), below, buffer, span=self._s(meta))

    def keep_out(self, meta: Any, children: list[Any]) -> tuple[str, None]:
        return ("keep_out", None)

    def unknown_surface(self, meta: Any, children: list[Any]) -> tuple[str, None]:
        return ("unknown", None)

    def steep(self, meta: Any, children: list[Any]) -> tuple[str, Any]:
        return ("steep", children[0])

    def area(self, meta: Any, children: list[Any]) -> model.Area:
        name, (kind, above), level, buffer, because = children
        return model.Area(str(name), kind, str(level), buffer, above, self._because(because),
                          span=self._s(meta))

    def obstacles(self, meta: Any, children: list[Any]) -> _Section:
        return _Section("obstacles", children, self._s(meta))

    def command_rule(self, meta: Any, children: list[Any]) -> model.CommandRule:
        name, condition, because = children
        return model.CommandRule(str(name), condition, self._because(because),
                                 span=self._s(meta))

    def prescreen(self, meta: Any, children: list[Any]) -> model.Prescreen:
        name, condition, because = children
        return model.Prescreen(str(name), condition, self._because(because), span=self._s(meta))

    def verdict(self, meta: Any, children: list[Any]) -> model.VerdictRule:
        name, condition, margin, because = children
        return model.VerdictRule(str(name), condition, self._because(because),
                                 span=self._s(meta), indifference=margin)

    def verdict_margin(self, meta: Any, children: list[Any]) -> Any:
        return children[0]

    def chance(self, meta: Any, children: list[Any]) -> model.Chance:
        name, condition, because = children
        return model.Chance(str(name), condition, self._because(because), span=self._s(meta))

    def index_value(self, meta: Any, children: list[Any]) -> _Item:
        return _Item("value", children[0], self._s(meta))

    def index_nominal(self, meta: Any, children: list[Any]) -> _Item:
        return _Item("nominal", children[0], self._s(meta))

    def index_limit(self, meta: Any, children: list[Any]) -> _Item:
        return _Item("limit", children[0], self._s(meta))

    def index_weight(self, meta: Any, children: list[Any]) -> _Item:
        return _Item("weight", children[0], self._s(meta))

    def index_map(self, meta: Any, children: list[Any]) -> _Item:
        return _Item("map", children[0], self._s(meta))

    def _items(self, owner: str, items: Sequence[_Item]) -> dict[str, _Item]:
        found: dict[str, _Item] = {}
        for item in items:
            if item.key in found:
                self.diagnostics.append(error(
                    INDEX_ITEM, f"{owner} gives '{item.key}' twice", item.span,
                    f"the first is on line {found[item.key].span.line}"))
            else:
                found[item.key] = item
        return found

    def index(self, meta: Any, children: list[Any]) -> model.Index:
        name, title, *items = children
        span = self._s(meta)
        found = self._items(f"index '{name}'", items)
        for required in ("value", "limit", "weight"):
            if required not in found:
                self.diagnostics.append(error(
                    INDEX_ITEM, f"index '{name}' has no '{required}'", _token_span(self.path, name),
                    f"add `{required} = …` inside the braces"))
        placeholder = model.Number(0.0)

        def get(key: str) -> Any:
            return found[key].value if key in found else None

        return model.Index(
            str(name), get("value") or placeholder, get("limit") or placeholder,
            get("weight") or placeholder, _unquote(title) if title is not None else None,
            get("map"), get("because"), get("nominal"), span=span)

    def combine_method(self, meta: Any, children: list[Token]) -> Token:
        return children[0]

    def combine_run(self, meta: Any, children: list[Any]) -> _Item:
        return self._method("run", children[0], RUN_COMBINATIONS, meta)

    def combine_path(self, meta: Any, children: list[Any]) -> _Item:
        return self._method("path", children[0], PATH_COMBINATIONS, meta)

    def _method(self, key: str, token: Token, known: tuple[str, ...], meta: Any) -> _Item:
        if str(token) not in known:
            self.diagnostics.append(error(
                UNKNOWN_COMBINATION, f"unknown {key} combination '{token}'; the language knows "
                + ", ".join(known), _token_span(self.path, token)))
        return _Item(key, str(token), self._s(meta))

    def combine_confidence(self, meta: Any, children: list[Any]) -> _Item:
        return _Item("confidence", children[0], self._s(meta))

    def combine_indifference(self, meta: Any, children: list[Any]) -> _Item:
        return _Item("indifference", children[0], self._s(meta))

    def combine_verdict_indifference(self, meta: Any, children: list[Any]) -> _Item:
        return _Item("verdict_indifference", children[0], self._s(meta))

    def combine(self, meta: Any, children: list[_Item]) -> model.Combine:
        found = self._items("combine", children)
        run = found["run"].value if "run" in found else "max_weighted"
        path = found["path"].value if "path" in found else "mean"
        confidence = found["confidence"].value if "confidence" in found else None
        indifference = found["indifference"].value if "indifference" in found else None
        verdicts = (found["verdict_indifference"].value if "verdict_indifference" in found
                    else None)
        return model.Combine(run, path, confidence, indifference,  # type: ignore[arg-type]
                             verdicts, span=self._s(meta))

    def rank_key(self, meta: Any, children: list[Any]) -> model.RankKey:
        expr, descending = children
        return model.RankKey(expr, descending is not None, span=self._s(meta))

    def ranking(self, meta: Any, children: list[model.RankKey]) -> model.Ranking:
        return model.Ranking(tuple(children), span=self._s(meta))

    def start(self, meta: Any, children: list[Any]) -> list[Any]:
        return children


# ----------------------------------------------------------------------------- assembly

_SECTION_NAMES = {
    model.Header: "rulebook header",
    model.Combine: "combine",
    model.Ranking: "rank by",
    "settings": "settings",
    "obstacles": "obstacles",
}


def _assemble(declarations: list[Any], comments: list[Token], text: str, path: str,
              diagnostics: list[Diagnostic]) -> model.Rulebook:
    """Group declarations into the rulebook; singletons checked; comments attached."""
    singles: dict[Any, Any] = {}
    lists: dict[type, list[Any]] = {kind: [] for kind in (
        model.Constant, model.CommandRule, model.Index, model.Chance, model.Prescreen,
        model.VerdictRule)}
    settings: list[model.Setting] = []
    levels: list[model.ObstacleLevel | model.Area] = []
    blocks: list[_Section] = []
    for declaration in declarations:
        key: Any = declaration.kind if isinstance(declaration, _Section) else type(declaration)
        if key in _SECTION_NAMES:
            if key in singles:
                first = singles[key].span
                diagnostics.append(error(
                    REPEATED_SECTION, f"'{_SECTION_NAMES[key]}' appears twice",
                    _first_line(declaration.span),
                    f"the first is on line {first.line}; merge them into one"))
                continue
            singles[key] = declaration
        if isinstance(declaration, _Section):
            blocks.append(declaration)
            (settings if declaration.kind == "settings" else levels).extend(declaration.entries)
        elif type(declaration) in lists:
            lists[type(declaration)].append(declaration)
    header = singles.get(model.Header)
    if header is None:
        diagnostics.append(error(
            MISSING_HEADER, "the rulebook has no header", Span(path, 1, 1, 1, 2),
            'start the file with: rulebook "NAME" version "1.0.0" purpose "…"'))
        header = model.Header("", "", "")
    attached = attach_comments(
        [header, *lists[model.Constant], *settings,
         *(n for n in levels if isinstance(n, model.ObstacleLevel)),
         *(n for n in levels if isinstance(n, model.Area)), *lists[model.CommandRule],
         *lists[model.Index], *lists[model.Chance], singles.get(model.Combine),
         *lists[model.Prescreen], *lists[model.VerdictRule], singles.get(model.Ranking)],
        [(block.entries[0], block.entries[-1], block.span) for block in blocks
         if block.entries], comments, text)
    rulebook = model.Rulebook(
        header=attached.get(id(header), header),
        constants=tuple(attached.get(id(node), node) for node in lists[model.Constant]),
        settings=tuple(attached.get(id(node), node) for node in settings),
        obstacle_levels=tuple(attached.get(id(node), node) for node in levels
                              if isinstance(node, model.ObstacleLevel)),
        areas=tuple(attached.get(id(node), node) for node in levels
                    if isinstance(node, model.Area)),
        command_rules=tuple(attached.get(id(node), node) for node in lists[model.CommandRule]),
        indices=tuple(attached.get(id(node), node) for node in lists[model.Index]),
        chances=tuple(attached.get(id(node), node) for node in lists[model.Chance]),
        combine=attached.get(id(singles.get(model.Combine)), singles.get(model.Combine))
        or model.Combine(),
        prescreens=tuple(attached.get(id(node), node) for node in lists[model.Prescreen]),
        verdicts=tuple(attached.get(id(node), node) for node in lists[model.VerdictRule]),
        ranking=attached.get(id(singles.get(model.Ranking)), singles.get(model.Ranking))
        or model.DEFAULT_RANKING,
        trailing_comments=tuple(attached.get("trailing", ())),
        path=path,
        source=text,
    )
    return rulebook


def _first_line(span: Span) -> Span:
    return Span(span.path, span.line, span.column, span.line, span.column + 1)
