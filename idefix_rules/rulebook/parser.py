"""Parsing rulebook text into the rule model.

:func:`parse_rulebook` runs lark's LALR parser (grammar loaded once by
:mod:`~idefix_rules.rulebook.grammar`) and lowers the tree at once into the frozen nodes of
:mod:`~idefix_rules.rulebook.model` (:mod:`~idefix_rules.rulebook.lowering` makes the nodes,
:mod:`~idefix_rules.rulebook.assembly` the rulebook); the lark tree never leaves these modules.
Every node gets a span (line, column, end line, end column). Any mistake, syntax or structure (a
missing header, a repeated section, an index without a limit), raises
:class:`~idefix_rules.errors.UserInputError` carrying all diagnostics found; arbitrary text never
raises anything else. :func:`lower_rulebook` raises for syntax errors only and returns the
structure problems with the rulebook, for the checker to report with its own.

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

import difflib
import re
from typing import Any

import lark
from lark import Token

from idefix_rules.errors import Diagnostic, Span, UserInputError, error
from idefix_rules.limits import NOT_A_RULEBOOK, check_rulebook_text
from idefix_rules.rulebook import model
from idefix_rules.rulebook.assembly import assemble
from idefix_rules.rulebook.grammar import collecting_comments, rulebook_parser
from idefix_rules.rulebook.lowering import Lowering, meta_span
from idefix_rules.rulebook.syntax_errors import (
    SYNTAX_ERROR,
    blank_failed_declaration,
    error_line,
    syntax_diagnostic,
)

TOO_MANY_ERRORS = "E009"

MAX_SYNTAX_ERRORS = 10


def parse_rulebook(text: str, path: str = "<rulebook>") -> model.Rulebook:
    """Parse and lower rulebook ``text`` (read from ``path``, used in spans and messages).

    Raises :class:`UserInputError` with every diagnostic found.
    """
    rulebook, problems = lower_rulebook(text, path)
    if problems:
        raise UserInputError(problems, sources={path: text})
    return rulebook


def lower_rulebook(text: str, path: str = "<rulebook>"
                   ) -> tuple[model.Rulebook, list[Diagnostic]]:
    """Parse and lower ``text``; the structure problems (a repeated section, an index without
    a limit, an unknown domain …) come back with the rulebook, sorted, each part that failed
    to lower an :class:`~idefix_rules.rulebook.model.Invalid` in it, so that the checker can
    report the rest of the file with them. Raises :class:`UserInputError` for syntax errors
    (no rulebook then)."""
    if not isinstance(text, str):
        raise UserInputError(error("E000", "a rulebook must be text", Span(path)))
    if text.startswith("\ufeff"):  # a byte-order mark some editors write: not content
        text = text[1:]
    check_rulebook_text(text, path)
    tree, comments, diagnostics = _parse_tree(text, path)
    if diagnostics or tree is None:
        diagnostics.sort(key=_position)
        raise UserInputError(_foreign_file(text, path) or diagnostics, sources={path: text})
    lowering = Lowering(path)
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
                                       meta_span(path, getattr(failure.obj, "meta", None))),
                                 sources={path: text}) from None
        raise failure.orig_exc from None
    rulebook = assemble(declarations, comments, text, path, lowering.diagnostics)
    lowering.diagnostics.sort(key=_position)
    return rulebook, lowering.diagnostics


_FIRST_WORD = re.compile(r"(?:[ \t\n]|#[^\n]*)*([A-Za-z_][A-Za-z0-9_]*|\S)")
_YAML_KEY = re.compile(r"[ \t]*:(?:[ \t]|$)", re.MULTILINE)
_DECLARATION_WORDS = frozenset(("rulebook", "version", "purpose", "const", "settings",
                                "obstacles", "command", "index", "chance", "prescreen",
                                "verdict", "combine", "rank"))


def _foreign_file(text: str, path: str) -> list[Diagnostic]:
    """One diagnostic, quoting at most the first word, for a file whose very first word starts
    no declaration (another kind of file, named by mistake): none of its lines is shown."""
    first = _FIRST_WORD.match(text)
    if first is not None and (first.group(1) == "rulebook"
                              or first.group(1) not in _DECLARATION_WORDS) \
            and _YAML_KEY.match(text, first.end()):
        # `rulebook: ../x.rules`: a case file or a campaign, which names a rulebook
        return [error(NOT_A_RULEBOOK, f"{path} is not a rulebook: it begins with the YAML key "
                      f"'{first.group(1)[:20]}:', as a case file or a campaign does",
                      Span(path), hint="check the .rules file it names; `idefix-verify test` "
                      "runs a case file")]
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
    span = meta_span(path, getattr(best, "meta", None))
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
