"""The canonical printer of rulebooks, which is also the formatter (``idefix-verify fmt``).

Sections come in one fixed order (header, constants, settings, obstacles, command rules,
indices, chances, combine, prescreens, verdicts, ranking), columns are aligned within a section,
expressions get the fewest parentheses their precedence allows, numbers print in the shortest
form that reads back as the same float (``repr``, without a trailing ``.0``) with their unit as
written, and comments come back where the parser found them (see
:mod:`~idefix_rules.rulebook.parser` for how comments are kept). Two properties hold:
``parse(format(m)) == m`` and formatting is idempotent.

>>> from idefix_rules.rulebook import model
>>> format_expr(model.Binary("*", model.Binary("+", model.Name("a"), model.Number(2.0)),
...                          model.Number(5.0, "cm")))
'(a + 2) * 5 cm'
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

from idefix_rules.errors import InfrastructureError, Span, UserInputError, error
from idefix_rules.limits import check_rulebook_text
from idefix_rules.rulebook import model
from idefix_rules.rulebook.parser import parse_rulebook

LINE_WIDTH = 100
INDENT = "  "
# Values longer than this are not padded to align the `because` column after them.
_ALIGN_LIMIT = 30
# Comments at the end of lines line up at one column when that column is not too far right.
_COMMENT_COLUMN_LIMIT = 60

# ----------------------------------------------------------------------------- expressions

_BINARY_PRECEDENCE = {
    "or": 1, "and": 2,
    "<": 4, "<=": 4, ">": 4, ">=": 4, "==": 4, "!=": 4,
    "+": 5, "-": 5, "*": 6, "/": 6, "^": 8,
}
_COMPARISON = 4
_UNARY_PRECEDENCE = {"not": 3, "-": 7}
_ATOM = 9


def precedence(expr: model.Expr) -> int:
    """Binding strength of an expression's outermost construct (higher binds tighter)."""
    if isinstance(expr, model.Binary):
        return _BINARY_PRECEDENCE[expr.op]
    if isinstance(expr, model.Unary):
        return _UNARY_PRECEDENCE[expr.op]
    return _ATOM


def format_number(value: float) -> str:
    """Shortest text that reads back as the same float: ``70``, ``0.2``, ``1e-05``."""
    if value == 0:
        return "0"
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def format_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _wrapped(expr: model.Expr, minimum: int) -> str:
    text = format_expr(expr)
    return f"({text})" if precedence(expr) < minimum else text


def _simple(expr: model.Expr) -> str:
    """Reducer parameters and window values: a number or name as is, anything else in ()."""
    text = format_expr(expr)
    return text if isinstance(expr, model.Number | model.Name) else f"({text})"


def format_expr(expr: model.Expr) -> str:
    """An expression in canonical form, with minimal parentheses."""
    if isinstance(expr, model.Number):
        number = format_number(expr.value)
        return f"{number} {expr.unit}" if expr.unit else number
    if isinstance(expr, model.Name):
        return expr.name
    if isinstance(expr, model.Select):
        return f"{_wrapped(expr.operand, _ATOM)}[{', '.join(expr.labels)}]"
    if isinstance(expr, model.Table):
        entries = ", ".join(f"{label}: {format_expr(value)}" for label, value in expr.entries)
        return "{" + entries + "}"
    if isinstance(expr, model.Unary):
        strength = _UNARY_PRECEDENCE[expr.op]
        operand = _wrapped(expr.operand, strength)
        return f"not {operand}" if expr.op == "not" else f"-{operand}"
    if isinstance(expr, model.Binary):
        strength = _BINARY_PRECEDENCE[expr.op]
        if expr.op == "^":  # right-associative; the base is a postfix expression
            left, right = _wrapped(expr.left, _ATOM), _wrapped(expr.right, _UNARY_PRECEDENCE["-"])
        elif strength == _COMPARISON:  # comparisons do not chain
            left, right = _wrapped(expr.left, strength + 1), _wrapped(expr.right, strength + 1)
        else:  # left-associative
            left, right = _wrapped(expr.left, strength), _wrapped(expr.right, strength + 1)
        return f"{left} {expr.op} {right}"
    if isinstance(expr, model.Call):
        return f"{expr.function}({', '.join(format_expr(arg) for arg in expr.args)})"
    if isinstance(expr, model.Reduce):
        parts: list[str] = [expr.reducer]
        if expr.parameter is not None:
            parts.append(_simple(expr.parameter))
        parts += ["over", expr.domain]
        if expr.window is not None:
            parts.append(format_window(expr.window))
        parts.append(f"({format_expr(expr.operand)})")
        return " ".join(parts)
    if isinstance(expr, model.Invalid):  # in a message only: such a rulebook is never printed
        return "…"
    raise TypeError(f"not an expression: {expr!r}")


def format_window(window: model.Window) -> str:
    prefix = "during command" if window.kind == "command" else window.kind
    return f"{prefix} {_simple(window.value)}"


# ----------------------------------------------------------------------------- comments

@dataclass
class _Comments:
    """A node's comments sorted by where they go (see the parser's docstring)."""

    leading: list[str] = field(default_factory=list)
    before: dict[str, list[str]] = field(default_factory=dict)
    inline: dict[str, list[str]] = field(default_factory=dict)

    @classmethod
    def of(cls, node: object) -> _Comments:
        sorted_comments = cls()
        for comment in getattr(node, "comments", ()):
            if not comment.startswith("@"):
                sorted_comments.leading.append(comment)
                continue
            anchor, _, body = comment[1:].partition(" ")
            if anchor.endswith("^"):
                sorted_comments.before.setdefault(anchor[:-1], []).append(body)
            else:
                sorted_comments.inline.setdefault(anchor, []).append(body)
        return sorted_comments

    def take_inline(self, anchor: str) -> str:
        return "  ".join(self.inline.pop(anchor, []))

    def rest_inline(self) -> str:
        rest = [text for texts in self.inline.values() for text in texts]
        self.inline.clear()
        return "  ".join(rest)


@dataclass
class _Line:
    text: str
    comment: str = ""


def _render(lines: Sequence[_Line], align: bool = True) -> list[str]:
    """Lines with their end-of-line comments, lined up in one column where sensible."""
    widths = [len(line.text) for line in lines if line.comment]
    column = max(widths, default=0) + 2
    out = []
    for line in lines:
        if not line.comment:
            out.append(line.text)
        elif align and column <= _COMMENT_COLUMN_LIMIT:
            out.append(f"{line.text.ljust(column)}{line.comment}")
        else:
            out.append(f"{line.text}  {line.comment}")
    return out


def _leading(comments: _Comments, indent: str = "") -> list[_Line]:
    return [_Line(indent + text) for text in comments.leading]


# ----------------------------------------------------------------------------- declarations

def _with_rationale(text: str, rationale: str | None, pad_to: int,
                    split: bool) -> list[str]:
    """``text because "…"`` on one line, or (``split``) the rationale on a continuation line."""
    if rationale is None:
        return [text]
    because = f"because {format_string(rationale)}"
    if split:
        return [text, INDENT + because]
    return [f"{text.ljust(pad_to)} {because}"]


def _fits(text: str, rationale: str | None, pad_to: int) -> bool:
    if rationale is None:
        return True
    return len(text.ljust(pad_to)) + len(format_string(rationale)) + 9 <= LINE_WIDTH


def _value_column(values: Iterable[str]) -> int:
    return max((len(value) for value in values if len(value) <= _ALIGN_LIMIT), default=0)


def _header(header: model.Header) -> list[str]:
    comments = _Comments.of(header)
    lines = _leading(comments)
    lines += [_Line(f"{text}") for text in comments.before.pop("rulebook", [])]
    lines.append(_Line(f"rulebook {format_string(header.name)} version "
                       f"{format_string(header.version)}", comments.take_inline("rulebook")))
    lines += [_Line(text) for text in comments.before.pop("purpose", [])]
    purpose = _Line(f"purpose {format_string(header.purpose)}", comments.take_inline("purpose"))
    extra = comments.rest_inline()
    purpose.comment = "  ".join(filter(None, [purpose.comment, extra]))
    lines.append(purpose)
    return _render(lines, align=False)


def _simple_section(entries: Sequence[tuple[object, str, str | None]],
                    indent: str = "") -> list[str]:
    """One declaration a line (or two): ``(node, text, rationale)``; leading comments above,
    a blank line before a commented declaration that is not the first."""
    column = len(indent) + _value_column(text for _, text, _ in entries)
    # One layout per section: when one rationale does not fit on its line, all go below.
    split = not all(_fits(indent + text, rationale, column) for _, text, rationale in entries)
    lines: list[_Line] = []
    for position, (node, text, rationale) in enumerate(entries):
        comments = _Comments.of(node)
        comments.inline.pop("block$", None)  # a block's closing comments: printed by _block
        if comments.leading and position > 0:
            lines.append(_Line(""))
        lines += [_Line(indent + text_) for text_ in comments.leading]
        printed = _with_rationale(indent + text, rationale, column, split)
        for number, line_text in enumerate(printed):
            last = number == len(printed) - 1
            lines.append(_Line(line_text, comments.rest_inline() if last else ""))
    return _render(lines)


def _constants(constants: Sequence[model.Constant]) -> list[str]:
    width = max(len(constant.name) for constant in constants)
    return _simple_section([(c, f"const {c.name.ljust(width)} = {format_expr(c.value)}",
                             c.rationale) for c in constants])


def _block(keyword: str, entries: Sequence[object], texts: Sequence[str]) -> list[str]:
    first = _Comments.of(entries[0])
    block_comments = first.before.pop("block", [])
    body = _simple_section([(entry, text, None) for entry, text in zip(entries, texts,
                                                                         strict=True)],
                           INDENT)
    closing = [INDENT + text for text in _Comments.of(entries[-1]).inline.get("block$", [])]
    return [*block_comments, f"{keyword} {{", *body, *closing, "}"]


def _settings(settings: Sequence[model.Setting]) -> list[str]:
    width = max(len(setting.name) for setting in settings)
    return _block("settings", settings,
                  [f"{s.name.ljust(width)} = {format_expr(s.value)}" for s in settings])


def _obstacles(levels: Sequence[model.ObstacleLevel],
               areas: Sequence[model.Area] = ()) -> list[str]:
    texts = []
    if levels:
        width = max(len(level.level) for level in levels)
        belows = [f"below {format_expr(level.below)} " if level.below is not None else ""
                  for level in levels]
        below_width = max(len(below) for below in belows)
        texts = [f"level {level.level.ljust(width)} {below.ljust(below_width)}"
                 f"buffer {format_expr(level.buffer)}" for level, below in zip(levels, belows,
                                                                             strict=True)]
    for area in areas:
        kind = (f"steep above {format_expr(area.above)}"
                if area.kind == "steep" and area.above is not None else area.kind)
        text = f"area {area.name} {kind} level {area.level} buffer {format_expr(area.buffer)}"
        if area.rationale is not None:
            text += f" because {format_string(area.rationale)}"
        texts.append(text)
    return _block("obstacles", [*levels, *areas], texts)


def _rules(keyword: str, rules: Sequence[model.CommandRule | model.Prescreen
                                         | model.VerdictRule]) -> list[str]:
    return _simple_section([(rule, f"{keyword} {rule.name}: require "
                             f"{format_expr(rule.condition)}{_margin(rule)}", rule.rationale)
                            for rule in rules])


def _margin(rule: model.ConditionRule) -> str:
    """`` indifference 2 %`` of a verdict that gives one."""
    margin = getattr(rule, "indifference", None)
    return "" if margin is None else f" indifference {format_expr(margin)}"


def _chances(chances: Sequence[model.Chance]) -> list[str]:
    return _simple_section([(chance, f"chance {chance.name} = {format_expr(chance.condition)}",
                             chance.rationale) for chance in chances])


def _item_block(node: object, opening: str, keyword: str,
                items: Sequence[tuple[str, str]]) -> list[str]:
    """``keyword … {`` with one item a line, aligned ``=``; comments by item anchor."""
    comments = _Comments.of(node)
    lines = _leading(comments)
    lines += [_Line(text) for text in comments.before.pop(keyword, [])]
    lines.append(_Line(opening, comments.take_inline(keyword)))
    width = max((len(key) for key, _ in items if key != "because"), default=0)
    for key, value in items:
        lines += [_Line(INDENT + text) for text in comments.before.pop(key, [])]
        text = f"because {value}" if key == "because" else f"{key.ljust(width)} = {value}"
        lines.append(_Line(INDENT + text, comments.take_inline(key)))
    stray_before = [text for texts in comments.before.values() for text in texts]
    lines += [_Line(INDENT + text) for text in stray_before]
    closing = _Line("}", comments.take_inline("}"))
    extra = comments.rest_inline()
    closing.comment = "  ".join(filter(None, [closing.comment, extra]))
    lines.append(closing)
    return _render(lines)


def _index(index: model.Index) -> list[str]:
    title = f" {format_string(index.title)}" if index.title is not None else ""
    items = [("value", format_expr(index.value))]
    if index.nominal is not None:
        items.append(("nominal", format_expr(index.nominal)))
    items += [("limit", format_expr(index.limit)), ("weight", format_expr(index.weight))]
    if index.map is not None:
        items.append(("map", format_expr(index.map)))
    if index.rationale is not None:
        items.append(("because", format_string(index.rationale)))
    return _item_block(index, f"index {index.name}{title} {{", "index", items)


def _combine(combine: model.Combine) -> list[str]:
    items = [("run", str(combine.run)), ("path", str(combine.path))]
    if combine.confidence is not None:
        items.append(("confidence", format_expr(combine.confidence)))
    if combine.indifference is not None:
        items.append(("indifference", format_expr(combine.indifference)))
    if combine.verdict_indifference is not None:
        items.append(("verdict_indifference", format_expr(combine.verdict_indifference)))
    return _item_block(combine, "combine {", "combine", items)


def _ranking(ranking: model.Ranking) -> list[str]:
    keys = ", ".join(format_expr(key.expr) + (" desc" if key.descending else "")
                     for key in ranking.keys)
    comments = _Comments.of(ranking)
    return _render([*_leading(comments), _Line(f"rank by {keys}", comments.rest_inline())])


def _is_written(node: model.Combine | model.Ranking, default: object) -> bool:
    return node != default or node.span.line > 0 or bool(node.comments)


def format_rulebook(rulebook: model.Rulebook) -> str:
    """The rulebook as canonical text, ending with one newline."""
    sections: list[list[str]] = [_header(rulebook.header)]
    if rulebook.constants:
        sections.append(_constants(rulebook.constants))
    if rulebook.settings:
        sections.append(_settings(rulebook.settings))
    if rulebook.obstacle_levels or rulebook.areas:
        sections.append(_obstacles(rulebook.obstacle_levels, rulebook.areas))
    if rulebook.command_rules:
        sections.append(_rules("command", rulebook.command_rules))
    sections += [_index(index) for index in rulebook.indices]
    if rulebook.chances:
        sections.append(_chances(rulebook.chances))
    if _is_written(rulebook.combine, model.Combine()):
        sections.append(_combine(rulebook.combine))
    if rulebook.prescreens:
        sections.append(_rules("prescreen", rulebook.prescreens))
    if rulebook.verdicts:
        sections.append(_rules("verdict", rulebook.verdicts))
    if _is_written(rulebook.ranking, model.DEFAULT_RANKING) and rulebook.ranking.keys:
        sections.append(_ranking(rulebook.ranking))
    if rulebook.trailing_comments:
        sections.append(list(rulebook.trailing_comments))
    return "\n\n".join("\n".join(section) for section in sections) + "\n"


def formatted_text(source: str, path: str) -> str:
    """The canonical text of a rulebook; raises ``UserInputError`` on syntax errors."""
    rulebook = parse_rulebook(source, path)
    text = format_rulebook(rulebook)
    try:
        check_rulebook_text(text, path)
    except UserInputError as failure:  # the file itself was within the limits
        problem = failure.diagnostics[0]
        raise UserInputError(error(
            problem.code, f"formatted, {path} would be over a rulebook's limits "
                          f"({problem.message}); the file is left as it is", Span(path),
            hint="split long expressions into named constants, or the rulebook into two"),
            failure.sources) from None
    if parse_rulebook(text, path) != rulebook:  # never write a file that means something else
        raise InfrastructureError(f"{path}: the formatter changed the rule model; "
                                  "file left untouched (please report)")
    return text


def with_line_endings(text: str, original: str | bytes) -> str:
    """``text`` (formatted: lines end with LF) with the line endings of the ``original`` it
    was formatted from: CRLF when the original has one (a file saved on Windows stays so),
    else LF. What ``fmt`` writes and the language server's formatting gives.

    >>> with_line_endings("a\\nb\\n", b"x\\r\\ny\\r\\n")
    'a\\r\\nb\\r\\n'
    """
    crlf = "\r\n" in original if isinstance(original, str) else b"\r\n" in original
    return text.replace("\n", "\r\n") if crlf else text
