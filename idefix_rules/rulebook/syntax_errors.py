"""Syntax errors of a rulebook as diagnostics, and recovery to find more than one per file.

Lark's LALR parser stops at the first error. To report the others in the same run, the parser
blanks out the top-level declaration that holds the error (spaces keep every line and column
where it was) and parses again; :func:`blank_failed_declaration` does that blanking. Each
diagnostic names what was found and what was expected, in words.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterable
from typing import get_args

import lark

from idefix_rules.errors import Diagnostic, Span, error
from idefix_rules.rulebook.grammar import terminal_words
from idefix_rules.rulebook.infer import did_you_mean
from idefix_rules.rulebook.model import Reducer
from idefix_rules.units import ascii_digits, foreign_digit, foreign_digit_message

SYNTAX_ERROR = "E001"  # an unexpected token or character
REDUCERS_IN_ORDER: tuple[str, ...] = get_args(Reducer)
REDUCER_WORDS = frozenset(REDUCERS_IN_ORDER)
FOREIGN_DIGIT = "E011"  # a digit of another script than 0-9 (`７0 %`)

# Words that start a top-level declaration; a line starting with one starts a new chunk.
TOP_LEVEL_KEYWORDS = frozenset({
    "rulebook", "const", "settings", "obstacles", "command", "index", "chance", "combine",
    "prescreen", "verdict", "rank",
})

_EXPRESSION_START = frozenset({
    "NAME", "QUANTITY", "LPAR", "LBRACE", "MINUS", "NOT", "MAX", "MIN", "MEAN", "FINAL",
    "INITIAL", "RMS", "SUM", "INTEGRAL", "ANY", "ALL", "COUNT", "PERCENTILE", "TIME_ABOVE",
    "CHANCE",
})
_OPERATORS = frozenset({"PLUS", "MINUS", "STAR", "SLASH", "CARET", "COMPARE", "AND", "OR"})


_DECLARATION_START = frozenset({
    "RULEBOOK", "CONST", "SETTINGS", "OBSTACLES", "COMMAND", "INDEX", "CHANCE", "COMBINE",
    "PRESCREEN", "VERDICT", "RANK",
})


def describe_expected(expected: Iterable[str]) -> str:
    """``'=' or a name``; expression starts fold into "an expression", operators and the
    words that start a declaration likewise."""
    names = set(expected)
    words: list[str] = []
    if len(names & _DECLARATION_START) >= 4:
        names -= _DECLARATION_START
        words.append("a new declaration")
    if {"NAME", "QUANTITY", "LPAR"} <= names:
        names -= _EXPRESSION_START
        words.append("an expression")
    if len(names & _OPERATORS) >= 4:
        names -= _OPERATORS
        words.append("an operator")
    vocabulary = terminal_words()
    end = "$END" in names
    names.discard("$END")
    words.extend(sorted(vocabulary.get(name, name) for name in names))
    if end:
        words.append("the end of the file")
    if not words:
        return "nothing more"
    if len(words) == 1:
        return words[0]
    return ", ".join(words[:-1]) + " or " + words[-1]


def _describe_token(token: lark.Token) -> str:
    if token.type == "$END":
        return "end of file"
    if token.type == "NAME":
        return f"name '{token}'"
    if token.type == "QUANTITY":
        return f"number '{token}'"
    if token.type == "STRING":
        return "a string"
    return f"'{token}'"


def syntax_diagnostic(failure: lark.exceptions.UnexpectedInput, text: str,
                      path: str) -> Diagnostic:
    """One diagnostic for a lark syntax error, at the offending token or character."""
    if isinstance(failure, lark.exceptions.UnexpectedCharacters):
        position = failure.pos_in_stream or 0
        char = text[position] if position < len(text) else ""
        span = Span(path, failure.line, failure.column, failure.line, failure.column + 1)
        if foreign_digit(char) is not None:
            return _foreign_digit(text, position, span)
        hint = None
        if char == '"':
            hint = 'a string ends with " on the same line it starts'
        elif char and char in "!=&|" and failure.allowed:
            hint = "comparisons are <, <=, >, >=, ==, !=; logic is and, or, not"
        shown = repr(char)[1:-1] if char.isprintable() else f"\\u{ord(char or ' '):04x}"
        message = f"unexpected character '{shown}'"
        if failure.allowed:
            allowed = acceptable(getattr(failure, "state", None), set(failure.allowed))
            message += f"; expected {describe_expected(allowed)}"
        return error(SYNTAX_ERROR, message, span, hint)
    if isinstance(failure, lark.exceptions.UnexpectedToken):
        token = failure.token
        reduction = _reduction_mistake(token, text, path)
        if reduction is not None:
            return reduction
        expected = acceptable(failure.state, set(failure.expected or ()))
        if token.type == "$END":
            line, column = _end_position(text)
            span = Span(path, line, column, line, column + 1)
        else:
            span = Span(path, token.line or 1, token.column or 1,
                        token.end_line or token.line or 1,
                        token.end_column or (token.column or 1) + 1)
        message = f"unexpected {_describe_token(token)}; expected {describe_expected(expected)}"
        end = token.end_pos if isinstance(token.end_pos, int) else None
        following = text[end] if end is not None and end < len(text) else ""
        hint = _name_read_as_reduction(token, expected, text) or \
            _name_read_as_negation(token, text) or _hint(token, expected, following)
        return error(SYNTAX_ERROR, message, span, hint)
    line, column = getattr(failure, "line", 1) or 1, getattr(failure, "column", 1) or 1
    return error(SYNTAX_ERROR, "syntax error", Span(path, line, column, line, column + 1))



def _name_read_as_reduction(token: lark.Token, expected: set[str], text: str) -> str | None:
    """A declared constant, index or chance spelt like a reduction word (``const max = …``)
    read where it is used as the start of a reduction: point at its declaration (E103)."""
    if "OVER" not in expected:
        return None
    start = token.start_pos if isinstance(token.start_pos, int) and token.type != "$END" \
        else len(text.rstrip())
    word = re.search(r"([A-Za-z_]\w*)\s*$", text[:start])
    if word is None:
        return None
    declared = re.search(rf"^[ \t]*(const|index|chance)[ \t]+{re.escape(word.group(1))}\b",
                         text, re.MULTILINE)
    if declared is None:
        return None
    line = text.count("\n", 0, declared.start()) + 1
    kind = {"const": "constant"}.get(declared.group(1), declared.group(1))
    return (f"'{word.group(1)}' is read as the reduction '{word.group(1)} over …'; the {kind} "
            f"of that name (line {line}) can never be read: rename it")

def _name_read_as_negation(token: lark.Token, text: str) -> str | None:
    """A constant, index or chance named ``not`` used where an expression starts (``limit =
    not``) is read as a negation of what follows, and the parser fails a little later: point at
    its declaration (E103)."""
    declared = re.search(r"^[ \t]*(const|index|chance)[ \t]+not\b", text, re.MULTILINE)
    if declared is None:
        return None
    start = token.start_pos if isinstance(token.start_pos, int) and token.type != "$END" \
        else len(text)
    before = re.sub(r"#[^\n]*", "", text[:start])
    # the words of the failing declaration up to the token, its own name left out
    starts = list(re.finditer(r"^[ \t]*(?:" + "|".join(sorted(TOP_LEVEL_KEYWORDS))
                              + r")\b(?:[ \t]+not\b)?", before, re.MULTILINE))
    own = before[starts[-1].end():] if starts else before
    if re.search(r"\bnot\b", own) is None:
        return None
    line = text.count("\n", 0, declared.start()) + 1
    kind = {"const": "constant"}.get(declared.group(1), declared.group(1))
    return (f"'not' is read as the negation 'not …' of what follows; the {kind} of that name "
            f"(line {line}) cannot be read there: rename it")


def _reduction_mistake(token: lark.Token, text: str, path: str) -> Diagnostic | None:
    """A reduction written wrong before the token: a parametric reducer without its parameter
    (``percentile over time (x)``: E106), or a word that is no reducer before ``over``
    (``mx over time (x)``: E001 naming the reducers)."""
    start = token.start_pos if isinstance(token.start_pos, int) else None
    if start is None or token.type == "$END":
        return None
    # the token's own line up to it, outside a comment (a comment may say anything)
    line_start = text.rfind("\n", 0, start) + 1
    line = text[line_start:start]
    if "#" in line:
        return None

    def span(match: re.Match[str]) -> Span:
        number = text.count("\n", 0, start) + 1
        return Span(path, number, match.start(1) + 1, number, match.end(1) + 1)

    missing = re.search(r"\b(percentile|time_above)\s+over\s+$", line)
    if missing is not None:
        word = missing.group(1)
        example = "percentile 95" if word == "percentile" else "time_above 30 deg"
        return error("E106", f"'{word}' needs a parameter before 'over'", span(missing),
                     hint=f"write `{example} over time (…)`")
    if str(token) != "over":
        return None
    # a word where an expression starts: after '=', '(', ',', an operator or a keyword of
    # logic (not an axis after 'over', nor a unit after its number)
    found = re.search(r"(?:^|[=(,+\-*/<>!]|\b(?:require|and|or|not))\s*"
                      r"([A-Za-z_][A-Za-z0-9_]*)\s+$", line)
    if found is None or found.group(1) in REDUCER_WORDS:
        return None
    close = difflib.get_close_matches(found.group(1), sorted(REDUCER_WORDS), n=1, cutoff=0.5)
    return error(SYNTAX_ERROR, f"'{found.group(1)}' is not a reducer: a reduction is written "
                               "`REDUCER over AXIS (…)`", span(found),
                 hint=(f"did you mean '{close[0]}'? " if close else "") + "reducers: "
                 + ", ".join(REDUCERS_IN_ORDER))


def _foreign_digit(text: str, position: int, span: Span) -> Diagnostic:
    """``７0 %``: the word around ``position``, written with 0-9, is the hint."""
    start, end = position, position + 1
    while start > 0 and not _word_end(text[start - 1]):
        start -= 1
    while end < len(text) and not _word_end(text[end]):
        end += 1
    return error(FOREIGN_DIGIT, foreign_digit_message(text, position), span,
                 hint=f"write {ascii_digits(text[start:end])}")


def _word_end(char: str) -> bool:
    return char.isspace() or char in "(){}[],=<>!+*/#\""


def acceptable(state: object, candidates: set[str]) -> set[str]:
    """The candidates the parser would really accept next.

    LALR merges states, so lark's ``expected`` holds terminals that only fit elsewhere; feed
    each one to a copy of the parser state, as lark's ``InteractiveParser.accepts`` does.
    """
    copy = getattr(state, "copy", None)
    if copy is None:
        return candidates
    accepted = set()
    for name in candidates:
        trial = copy()
        try:
            trial.feed_token(lark.Token(name, ""), is_end=name == "$END")
        except lark.exceptions.UnexpectedInput:
            continue
        except Exception:
            pass
        accepted.add(name)
    return accepted or candidates


def _hint(token: lark.Token, expected: set[str], following: str = "") -> str | None:
    """``following``: the character right after the token in the text."""
    if token.type == "EQUAL" and "COMPARE" in expected:
        if following and following in "<>":  # `=>`, `=<`: written back to front
            return f"did you mean '{following}='?"
        return "use '==' to compare"
    if token.type in _DECLARATION_START and token.column == 1 \
            and len(expected & _DECLARATION_START) < 4:
        return "the declaration before this line is not finished"
    if str(token) == "-" and "LPAR" in expected and expected <= {"QUANTITY", "NAME", "LPAR"}:
        # a reducer's parameter or a window's value: a number, a name or a parenthesis
        return "a negative value here goes in parentheses: time_above (-5 deg) over …"
    if token.type == "COMPARE" and "COMPARE" not in expected:
        return "comparisons do not chain: write `0 < x and x < 1`"
    if token.type == "REQUIRE" and "COLON" in expected:
        return "a rule is written `command NAME: require CONDITION`"
    if token.type in {"NAME", "QUANTITY"} and expected & _OPERATORS:
        return ("is an operator missing? A unit follows its number on the same line, "
                "without spaces inside it: 5 cm/s")
    if token.type == "NAME" and "EQUAL" not in expected:
        keyword_words = [word.strip("'") for name, word in terminal_words().items()
                         if name in expected and word.startswith("'")]
        return did_you_mean(str(token), keyword_words)
    if token.type == "$END" and "RBRACE" in expected:
        return "a block opened with '{' is not closed"
    return None


def _end_position(text: str) -> tuple[int, int]:
    lines = text.splitlines() or [""]
    # The last line that holds something: an error "at the end" points just after it.
    for number in range(len(lines), 0, -1):
        stripped = lines[number - 1].split("#", 1)[0].rstrip()
        if stripped:
            return number, len(stripped) + 1
    return 1, 1


def error_line(failure: lark.exceptions.UnexpectedInput, text: str) -> tuple[int, int]:
    """Line and column of a syntax error (the end of the text for 'unexpected end')."""
    if isinstance(failure, lark.exceptions.UnexpectedToken) and failure.token.type == "$END":
        return _end_position(text)
    return (getattr(failure, "line", 1) or 1), (getattr(failure, "column", 1) or 1)


def _chunk_starts(lines: list[str]) -> list[int]:
    """0-based numbers of the lines that start a top-level declaration."""
    starts = []
    for number, line in enumerate(lines):
        words = line.split(None, 1)
        if words and words[0] in TOP_LEVEL_KEYWORDS:
            starts.append(number)
    return starts


def blank_failed_declaration(text: str, line: int, column: int) -> str:
    """The text with the declaration around ``line`` replaced by spaces (newlines kept).

    When the error sits on the first word of a declaration, the declaration before it is the
    one left unfinished, so that one is blanked.
    """
    lines = text.split("\n")
    index = min(max(line - 1, 0), len(lines) - 1)
    starts = _chunk_starts(lines)
    before = [start for start in starts if start <= index]
    start = before[-1] if before else 0
    first_word_column = len(lines[start]) - len(lines[start].lstrip()) + 1
    if before and start == index and column <= first_word_column and len(before) > 1:
        start = before[-2]
    after = [s for s in starts if s > start]
    end = after[0] if after else len(lines)
    if start == index and end == start:
        end = start + 1
    for number in range(start, max(end, start + 1)):
        lines[number] = " " * len(lines[number])
    return "\n".join(lines)
