"""Completion in context: what may be written at the cursor of a rulebook being edited.

The text being edited rarely parses, so the context is read from the text itself: the
declaration the cursor is in is the nearest line above that starts with a declaration keyword,
and the last words before the cursor tell the rest. Offered, by context:

* after a number: units (``5 c|`` → ``cm``);
* after ``over``: the domains (``time``, ``wheels``, ``parts``, ``levels``);
* inside ``[…]``: the labels of the axes the selected signal has (``wheel.slip[`` → ``FL`` …);
* inside ``chance(`` / ``mean(`` of a verdict: the chances / the indices;
* in an expression: the names visible there (signals in indices and chances, command
  quantities in command rules, path statistics in verdicts, indices and chances in
  prescreens, constants everywhere), reducers and functions;
* at the start of a line: declaration keywords, or the items of the block the cursor is in;
* in an ``obstacles`` item: what its grammar puts next (``area rim `` → ``keep_out``,
  ``steep``, ``unknown``; ``level `` → ``L1`` … ``L3``; ``level L1 `` → ``below``, ``buffer``).

>>> labels = [item.label for item in completions("const a = 5 c", Position(0, 13))]
>>> "cm" in labels and "delta_heading" not in labels
True
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Literal, get_args

from idefix_rules import signals
from idefix_rules.lsp.positions import LineIndex, Position, Range
from idefix_rules.rulebook.model import DOMAIN_AXES, PARAMETRIC_REDUCERS, Reducer
from idefix_rules.rulebook.syntax_errors import TOP_LEVEL_KEYWORDS
from idefix_rules.rulebook.types import COMMAND_NAMES, ELEMENTWISE_FUNCTIONS, PATH_NAMES, SETTINGS
from idefix_rules.units import UNIT_SYMBOLS, describe, parse_unit

Kind = Literal["constant", "signal", "variable", "reducer", "function", "unit", "keyword",
               "index", "chance", "label", "setting"]

REDUCERS: tuple[str, ...] = get_args(Reducer)  # the rule model's, so none is missed
INDEX_ITEMS = ("value", "nominal", "limit", "weight", "map", "because")
COMBINE_ITEMS = ("run", "path", "confidence", "indifference", "verdict_indifference")
OBSTACLE_ITEMS = {"level": "level L1|L2|L3 below SIZE buffer SIZE",
                  "area": "area NAME keep_out|unknown|steep above ANGLE level L1|L2|L3 "
                          "buffer SIZE"}
AREA_KINDS = {"keep_out": "area kind: a zone kept out of (polygons from the campaign)",
              "unknown": "area kind: surface not seen (polygons from the campaign)",
              "steep": "area kind: terrain inclined above ANGLE (found in the campaign's terrain)"}
_NUMBER = r"(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_WORD = re.compile(r"[A-Za-z_][\w.]*$")
# a number, not the digits that end a name (`L1 `, `x2 `)
_UNIT_TAIL = re.compile(rf"(?<![\w.]){_NUMBER}[ \t]*([A-Za-z%°][A-Za-z%°·*/^\d-]*)?$")
_SELECT = re.compile(r"([A-Za-z_][\w.]*)?[ \t]*\[([\w\s,]*)$")
_OPEN_EXPRESSION = ("below", "buffer", "above")


@dataclass(frozen=True)
class Completion:
    label: str
    kind: Kind
    detail: str
    range: Range  # what the completion replaces (the word typed so far)


def _declared(text: str, keyword: str) -> list[str]:
    """Names declared with ``keyword`` anywhere in the text (parses or not)."""
    return list(dict.fromkeys(re.findall(rf"(?m)^[ \t]*{keyword}[ \t]+([A-Za-z_]\w*)", text)))


def _context(lines: LineIndex, position: Position) -> tuple[str, str]:
    """(declaration keyword the cursor is in or "", the line's text before the cursor)."""
    before = lines.line_text(position.line)[:position.character]
    for number in range(position.line, -1, -1):
        text = lines.line_text(number) if number != position.line else before
        words = text.split(None, 1)
        if words and words[0] in TOP_LEVEL_KEYWORDS and not (
                number == position.line and len(words) == 1 and not text.endswith(" ")):
            return words[0], before
    return "", before


def _unit_items(word_range: Range) -> list[Completion]:
    """Every unit atom, with its dimension and its size in SI: ``a length: 1 cm = 0.01 m``."""
    items = []
    for symbol in UNIT_SYMBOLS:
        if not symbol[0].isalpha() and symbol[0] not in "%°":
            continue  # `1` is the unit of plain ratios in the signal contract; a rulebook omits it
        unit = parse_unit(symbol)
        si_unit = "" if unit.dimension.is_dimensionless else f" {unit.dimension}"
        detail = f"{describe(unit.dimension)}: 1 {symbol} = {unit.scale:.6g}{si_unit}"
        items.append(Completion(symbol, "unit", detail, word_range))
    return items


def _signal_items(word_range: Range) -> list[Completion]:
    names = [*signals.SIGNALS, *(signals.REF_PREFIX + name for name in signals.FMU_SIGNALS)]
    items = []
    for name in names:
        spec = signals.lookup(name)
        assert spec is not None
        axes = f" [{', '.join(spec.axes)}]" if spec.axes else ""
        items.append(Completion(name, "signal", f"{spec.unit}{axes} — {spec.description}",
                                word_range))
    return items


def _expression_items(kind: str, text: str, word_range: Range) -> list[Completion]:
    items = [Completion(name, "constant", "constant", word_range)
             for name in _declared(text, "const")]
    if kind in ("index", "chance", "map"):
        items += _signal_items(word_range)
        for area in _declared(text, "area"):
            for part in signals.AREA_SIGNAL_PARTS:
                spec = signals.lookup(f"{signals.AREA_PREFIX}{area}.{part}")
                assert spec is not None
                items.append(Completion(spec.name, "signal", f"1 [time] — {spec.description}",
                                        word_range))
    elif kind == "command":
        items += [Completion(name, "variable", f"command quantity, {describe(t.dimension)}",
                             word_range) for name, t in COMMAND_NAMES.items()]
    elif kind == "prescreen":
        items += [Completion(name, "index", "index (on the reference run)", word_range)
                  for name in _declared(text, "index")]
        items += [Completion(name, "chance", "chance (on the reference run)", word_range)
                  for name in _declared(text, "chance")]
        items.append(Completion("risk", "variable", "I_max of the reference run", word_range))
    elif kind in ("verdict", "rank"):
        items += [Completion(name, "variable", f"path statistic, {describe(t.dimension)}",
                             word_range) for name, t in PATH_NAMES.items()]
        items += [Completion(name, "function", "path statistic of runs", word_range)
                  for name in ("chance", "mean", "max")]
    if kind in ("index", "chance", "map", "command", "prescreen", "const"):
        items += [Completion(name, "function", "element-wise function", word_range)
                  for name in sorted(ELEMENTWISE_FUNCTIONS)]
    if kind in ("index", "chance", "map"):
        items += [Completion(name, "reducer",
                             "rate over time (…): rate of change per second, keeps the time axis"
                             if name == "rate" else
                             f"{name} {'PARAMETER ' if name in PARAMETRIC_REDUCERS else ''}"
                             "over DOMAIN (…)", word_range) for name in REDUCERS]
    return items


def completions(text: str, position: Position) -> list[Completion]:
    """What may be written at ``position`` (0-based line and character) of ``text``."""
    lines = LineIndex(text)
    kind, before = _context(lines, position)
    if _in_string_or_comment(before):
        return []
    word = _WORD.search(before)
    typed = word.group() if word else ""
    word_range = Range(Position(position.line, position.character - len(typed)), position)
    unit_tail = _UNIT_TAIL.search(before)
    if unit_tail is not None and (unit_tail.group(1) or before[-1:] in (" ", "\t")):
        start = position.character - len(unit_tail.group(1) or "")
        after_number = Range(Position(position.line, start), position)
        # a keyword may follow a number too: `percentile 95 over`, `x > 0 and`
        words: tuple[str, ...] = ("over",) if re.search(
            r"\b(percentile|time_above)[ \t]+\S+[ \t]*\S*$", before) else ("and", "or", "because")
        if kind == "verdict" and "because" in words:
            words += ("indifference",)  # a verdict's margin follows its condition
        if kind == "obstacles":  # a size or an angle: the item's next keyword follows
            written = _obstacle_item(lines, position, before[:start])
            words = tuple(c.label for c in _obstacle_items(written, text, after_number)
                          if c.kind == "keyword")
        return [*_unit_items(after_number),
                *(Completion(w, "keyword", "keyword", after_number) for w in words)]
    if re.search(r"\bover[ \t]+\w*$", before):
        return [Completion(domain, "keyword", f"reduce over the {axis} axis", word_range)
                for domain, axis in DOMAIN_AXES.items()]
    select = _SELECT.search(before)
    if select is not None:
        return [Completion(label, "label", f"{axis} label", word_range)
                for axis, labels in _selectable(select.group(1), select.group(2)).items()
                for label in labels]
    function = re.search(r"\b(chance|mean|max)\([ \t]*\w*$", before)
    if function is not None and kind in ("verdict", "rank"):
        what: Kind = "chance" if function.group(1) == "chance" else "index"
        return [Completion(name, what, what, word_range) for name in _declared(text, what)]
    at_line_start = not before[:len(before) - len(typed)].strip()
    if at_line_start:
        if kind == "index" and not re.match(r"\s*index\b", before):
            return [Completion(item, "keyword", "index item", word_range) for item in INDEX_ITEMS]
        if kind == "settings" and not re.match(r"\s*settings\b", before):
            return [Completion(name, "setting", f"setting, {describe(dimension)}", word_range)
                    for name, (dimension, _) in SETTINGS.items()]
        if kind == "obstacles" and not re.match(r"\s*obstacles\b", before):
            return [Completion(item, "keyword", syntax, word_range)
                    for item, syntax in OBSTACLE_ITEMS.items()]
        if kind == "combine" and not re.match(r"\s*combine\b", before):
            return [Completion(item, "keyword", "combine item", word_range)
                    for item in COMBINE_ITEMS]
        return [Completion(keyword, "keyword", "declaration", word_range)
                for keyword in sorted(TOP_LEVEL_KEYWORDS)]
    if kind == "index":
        item = re.match(r"\s*(?:index\b.*\{)?\s*(value|nominal|limit|weight|map)\s*=", before)
        kind = {"value": "index", "map": "map"}.get(item.group(1), "const") if item else "index"
    elif kind == "obstacles":
        written = _obstacle_item(lines, position, before[:len(before) - len(typed)])
        return _obstacle_items(written, text, word_range)
    elif kind in ("settings", "combine"):
        kind = "const"
    return _expression_items(kind, text, word_range)


def _selectable(operand: str | None, written: str) -> dict[str, tuple[str, ...]]:
    """The labels that may follow ``operand[written`` by axis: those of the signal's axes
    that no label already written selects (every label when the operand is not a signal)."""
    spec = signals.lookup(operand) if operand else None
    axes = [axis for axis in spec.axes if axis in signals.AXIS_LABELS] if spec else \
        list(signals.AXIS_LABELS)
    for label in re.findall(r"\w+", written.rpartition(",")[0]):  # not the one being typed
        axes = [axis for axis in axes if label not in signals.AXIS_LABELS[axis]]
    return {axis: signals.AXIS_LABELS[axis] for axis in axes}


def _obstacle_item(lines: LineIndex, position: Position, before: str) -> list[str]:
    """The words of the obstacles item the cursor is in (``area rim steep above``), from the
    line its keyword starts (``before``: the cursor's line up to the word being typed)."""
    pieces = [before]
    for number in range(position.line - 1, -1, -1):
        if re.match(r"\s*(level|area|obstacles)\b", pieces[0]):
            break
        pieces.insert(0, lines.line_text(number))
    words = " ".join(re.sub(r"#.*", "", piece) for piece in pieces).replace("{", " { ").split()
    if "{" in words:  # the block starts on this line: `obstacles { level …`
        words = words[words.index("{") + 1:]
    return words


def _obstacle_items(item: list[str], text: str, word_range: Range) -> list[Completion]:
    """What the grammar puts after the words ``item`` of an obstacles item:
    ``level LABEL [below SIZE] buffer SIZE`` and
    ``area NAME (keep_out | unknown | steep above ANGLE) level LABEL buffer SIZE [because …]``."""
    def keywords(*words: str) -> list[Completion]:
        return [Completion(word, "keyword", "keyword", word_range) for word in words]

    def labels() -> list[Completion]:
        return [Completion(label, "label", "obstacle level", word_range)
                for label in signals.AXIS_LABELS["level"]]

    if not item:
        return [Completion(word, "keyword", syntax, word_range)
                for word, syntax in OBSTACLE_ITEMS.items()]
    if item[-1] in _OPEN_EXPRESSION or item[-1][-1] in "+-*/^(,<>=":
        return _expression_items("const", text, word_range)  # a size, an angle
    head, rest = item[0], item[1:]
    if head == "area":
        if len(rest) < 2:  # the area's name is new: nothing to offer
            return [] if not rest else [Completion(kind, "keyword", detail, word_range)
                                        for kind, detail in AREA_KINDS.items()]
        rest = rest[2:] if rest[1] == "steep" else rest[1:]
        if rest and rest[0] != "level":
            rest = rest[rest.index("level"):] if "level" in rest else []
        if not rest:  # after the kind, or a steep area's angle
            return keywords("above") if item[-1] == "steep" else keywords("level")
        rest = rest[1:]
    elif head != "level":
        return []
    if not rest:
        return labels()
    if "buffer" in rest:  # the buffer's size is written
        return keywords("because") if head == "area" else []
    return keywords("buffer") if head == "area" or "below" in rest else \
        keywords("below", "buffer")


def _in_string_or_comment(before: str) -> bool:
    """Whether the end of ``before`` (a line up to the cursor) is inside a string or comment."""
    stripped = re.sub(r'"(?:[^"\\]|\\.)*"', "", before)
    return '"' in stripped or "#" in stripped
