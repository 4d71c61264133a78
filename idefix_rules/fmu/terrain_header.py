"""The text header of a terrain file (``IDEFIX-TERRAIN 1``, docs/terrain-format.md), read
as the rover model's C reader reads it (``fmu/idefix_rover/sources/terrain.c``), so that the
terrain checked here is the one the FMU simulates on.

The C reader takes the last of two ``cell`` lines, stops at a value's first character that is
not a number (``1_000`` is 1) and ignores values after the ones it wants; rock lines must follow
their ``rocks N`` line directly, one to a line. Where the two readers could differ, or a
mistake would pass unseen, the header is refused at the line and column that say it.

>>> header = read_header(b"IDEFIX-TERRAIN 1\\nnx 2\\nny 3\\norigin 0 -1\\ncell 0.5\\n"
...                      b"rocks 1\\nrock 0.5 0 0.02 0.1 0.1 0.05 L2\\nheights\\n", "site.dem")
>>> header.nx, header.ny, header.origin, header.cell, header.rocks[0].level
(2, 3, (0.0, -1.0), 0.5, 'L2')
"""

from __future__ import annotations

import math
import re
import unicodedata
from dataclasses import dataclass

from idefix_rules.errors import Span, UserInputError, error
from idefix_rules.limits import (
    MAX_ROCK_SEMI_AXIS,
    MAX_TERRAIN_EXTENT,
    MAX_TERRAIN_HEIGHT,
    MAX_TERRAIN_ROCKS,
    MIN_ROCK_SEMI_AXIS,
)
from idefix_rules.units import PLAIN_WHOLE_NUMBER, UnitError, plain_number

MAGIC = "IDEFIX-TERRAIN 1"
MAX_NODES = 16_000_000  # nx*ny, as the FMU reads it
# The C reader reads a line into 512 bytes (fgets): 510 characters, the newline and the NUL.
# A longer line is read as two, the second taken for a line of its own.
MAX_LINE = 510
ITEMS = {"nx": "nx N", "ny": "ny N", "origin": "origin X Y", "cell": "cell C", "rocks": "rocks N"}
NEEDED = "header needs 'nx N', 'ny N', 'origin X Y', 'cell C'"
ROCK_USAGE = "expected 'rock x y z a b c [level]'"
LEVELS = ("L1", "L2", "L3")
# Bytes of header text: printable ASCII and the tab (a line's CR is its CRLF ending).
_TEXT = re.compile(rb"[\t\x20-\x7e]*")


@dataclass(frozen=True)
class RockLine:
    """A ``rock x y z a b c [level]`` line: centre (m, z above the datum), semi-axes (m)."""

    x: float
    y: float
    z: float
    a: float
    b: float
    c: float
    level: str | None
    line: int


@dataclass(frozen=True)
class TerrainHeader:
    """A terrain file's header, checked: the grid of ``nx`` × ``ny`` nodes ``cell`` apart from
    ``origin``, its rocks, the line of each item (``lines``), the ``heights`` line
    (``end_line``) and where the grid's bytes start (``grid_offset``); ``text``: the header as
    read, which messages may quote (never the grid's bytes)."""

    nx: int
    ny: int
    origin: tuple[float, float]
    cell: float
    rocks: tuple[RockLine, ...]
    lines: dict[str, int]
    end_line: int
    grid_offset: int
    text: str

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) of the grid."""
        x0, y0 = self.origin
        return x0, x0 + (self.nx - 1) * self.cell, y0, y0 + (self.ny - 1) * self.cell


class _Reader:
    """The header's lines one by one, and its errors at their line and column (quoting only
    the lines read as text)."""

    def __init__(self, data: bytes, path: str) -> None:
        self.data, self.path = data, path
        self.offset, self.line = 0, 0
        self.shown: list[str] = []

    def fail(self, message: str, line: int | None = None, column: int = 1,
             code: str = "F204", hint: str | None = None) -> UserInputError:
        return UserInputError(error(code, message, Span(self.path, line or self.line, column),
                                    hint=hint), sources={self.path: "\n".join(self.shown)})

    def next_line(self) -> str | None:
        """The next line as text (its CRLF's CR dropped); None at the end of the file."""
        if self.offset >= len(self.data):
            return None
        end = self.data.find(b"\n", self.offset)
        whole = self.data[self.offset:len(self.data) if end < 0 else end]
        self.offset = len(self.data) if end < 0 else end + 1
        self.line += 1
        raw = whole.removesuffix(b"\r")
        text = _TEXT.match(raw)
        if text is not None and text.end() < len(raw):
            self.binary(raw, text.end())
        if len(whole) > MAX_LINE:
            raise self.fail(f"header line of {len(whole)} characters: at most {MAX_LINE} (the "
                            "rover model reads a longer line as two)", column=MAX_LINE + 1)
        self.shown.append(raw.decode("ascii"))
        return self.shown[-1]

    def first_line(self) -> str:
        """The first line, undecoded bytes replaced (it is compared, never quoted)."""
        end = self.data.find(b"\n")
        whole = self.data[:len(self.data) if end < 0 else end]
        self.offset = len(self.data) if end < 0 else end + 1
        self.line = 1
        self.shown.append("")
        return whole.decode("ascii", "replace").strip()

    def binary(self, raw: bytes, at: int) -> None:
        """A line that is no ASCII text: the grid's bytes where a header line was due (its
        ``heights`` line missing), or text with a character outside ASCII. Never quoted."""
        column = at + 1
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError:
            text = ""
        if text and not any((ord(char) < 0x20 and char != "\t") or char == "\x7f"
                            for char in text):
            char = text[at]  # the bytes before it are ASCII: one character each
            raise self.fail(f"header line is not ASCII text: '{char}' "
                            f"({unicodedata.name(char, f'U+{ord(char):04X}')})", column=column,
                            hint="the header is ASCII text: the words and plain numbers of "
                                 "docs/terrain-format.md")
        raise self.fail(f"missing 'heights' line: line {self.line} holds binary data (byte "
                        f"0x{raw[at]:02x}), not header text", column=column,
                        hint="the header ends with a line 'heights'; the binary height grid "
                             "follows it")


def _words(text: str) -> list[tuple[str, int]]:
    """The words of a line with their columns (from 1)."""
    return [(found.group(), found.start() + 1) for found in re.finditer(r"\S+", text)]


def read_header(data: bytes, path: str) -> TerrainHeader:
    """Read and check the header of the terrain file ``data`` (from ``path``, for messages)."""
    reader = _Reader(data, path)
    if reader.first_line() != MAGIC:  # another kind of file: quote none of it
        raise UserInputError(error(
            "F204", f"expected '{MAGIC}' as the first line", Span(path, 1, 1),
            hint="a DEM of bare heights ends in .npy or .csv"), sources={path: ""})
    values: dict[str, list[tuple[str, int]]] = {}
    lines: dict[str, int] = {}
    rocks: list[RockLine] = []
    while True:
        text = reader.next_line()
        if text is None:
            raise reader.fail("missing 'heights' line", reader.line + 1,
                              hint="the header ends with a line 'heights'; the binary height "
                                   "grid follows it")
        words = _words(text)
        if not words:
            continue
        key = words[0][0]
        if key == "heights":
            _no_more(reader, "heights", words, 0)
            break
        if key == "rock":
            raise reader.fail("a 'rock' line outside the rock lines: they follow their "
                              "'rocks N' line directly, N of them", hint=_ROCKS_HINT)
        if key not in ITEMS:
            raise reader.fail(f"unknown header line '{key}'")
        if key in lines:
            raise reader.fail(f"'{key}' given again: line {lines[key]} gives it already",
                              hint="give each header item once")
        lines[key], values[key] = reader.line, words[1:]
        _no_more(reader, key, words, 2 if key == "origin" else 1)
        if key == "rocks":
            rocks = _rock_lines(reader, _rock_count(reader, words))
    return _checked(reader, values, lines, rocks)


def _no_more(reader: _Reader, key: str, words: list[tuple[str, int]], wanted: int) -> None:
    """Refuse the words after the ``wanted`` values of ``key`` (the FMU ignores them)."""
    if len(words) > wanted + 1:
        extra, column = words[wanted + 1]
        takes = {0: "no value", 1: "one value", 2: "two values"}[wanted]
        raise reader.fail(f"'{key}' takes {takes}: '{_shown(extra)}' is one too many",
                          column=column)


def _shown(word: str) -> str:
    return word if len(word) <= 20 else word[:20] + "…"


def _number(reader: _Reader, key: str, word: tuple[str, int] | None, whole: bool,
            line: int | None = None) -> float:
    """The value ``word`` of item ``key`` as a plain decimal number (a whole one for counts)."""
    if word is None:
        raise reader.fail(f"{NEEDED}: '{key}' has no value", line)
    text, column = word
    if whole:
        if PLAIN_WHOLE_NUMBER.fullmatch(text) is None:
            raise reader.fail(f"{NEEDED}: '{_shown(text)}' is not a whole number", line, column)
        return int(text)
    try:
        value = plain_number(text)
    except UnitError as failure:
        raise reader.fail(f"'{key}': {failure}", line, column) from None
    if not math.isfinite(value):
        raise reader.fail(f"'{key}': {_shown(text)} is beyond a double", line, column)
    return value


_ROCKS_HINT = "write 'rocks N', then its N 'rock x y z a b c [level]' lines, then 'heights'"


def _rock_count(reader: _Reader, words: list[tuple[str, int]]) -> int:
    count = int(_number(reader, "rocks", words[1] if len(words) > 1 else None, whole=True))
    column = words[1][1]
    if count < 0:
        raise reader.fail(f"'rocks {count}': a count of rocks is 0 or more", column=column)
    if count > MAX_TERRAIN_ROCKS:
        raise reader.fail(f"{count} rocks; at most {MAX_TERRAIN_ROCKS} (the rover model holds "
                          f"{MAX_TERRAIN_ROCKS})", column=column, code="F202",
                          hint="keep the rocks near the paths")
    return count


def _rock_lines(reader: _Reader, count: int) -> list[RockLine]:
    """The ``count`` rock lines that follow a ``rocks`` line, one to a line (no blank lines:
    the rover model reads the next ``count`` lines as rocks)."""
    at = reader.line
    rocks = []
    for index in range(count):
        text = reader.next_line()
        words = _words(text or "")
        if text is None:
            raise reader.fail(f"'rocks {count}' but the file ends after {index} rock lines", at,
                              hint=_ROCKS_HINT)
        if not words or words[0][0] != "rock":
            raise reader.fail(f"'rocks {count}' (line {at}) says {count} rock lines follow it "
                              f"directly; line {reader.line} is no rock line", hint=_ROCKS_HINT)
        rocks.append(_rock(reader, words))
    return rocks


def _rock(reader: _Reader, words: list[tuple[str, int]]) -> RockLine:
    if len(words) < 7:
        raise reader.fail(f"{ROCK_USAGE}: {len(words) - 1} values")
    if len(words) > 8:
        extra, column = words[8]
        raise reader.fail(f"{ROCK_USAGE}: '{_shown(extra)}' is one too many", column=column)
    x, y, z, a, b, c = (_number(reader, f"rock {name}", word, whole=False)
                        for name, word in zip("xyzabc", words[1:7], strict=True))
    for size, (_, column) in zip((a, b, c), words[4:7], strict=True):
        if not size > 0:
            raise reader.fail(f"rock semi-axis {size:.12g} m: a semi-axis is above 0",
                              column=column)
        if size < MIN_ROCK_SEMI_AXIS:
            raise reader.fail(f"rock semi-axis {size:.12g} m: at least {MIN_ROCK_SEMI_AXIS:g} m "
                              "(a smaller grain is part of the regolith, which the soil model "
                              "represents)", column=column)
        if size > MAX_ROCK_SEMI_AXIS:
            raise reader.fail(f"rock semi-axis {size:.12g} m: at most {MAX_ROCK_SEMI_AXIS:g} m "
                              "(a larger rock is a hill or a crater: give it in the heights)",
                              column=column)
    most = MAX_TERRAIN_HEIGHT + MAX_ROCK_SEMI_AXIS  # a rock on the highest ground
    if abs(z) > most:
        raise reader.fail(f"rock centre height {z:.12g} m: at most {most:g} m from the datum "
                          f"either way (heights lie within {MAX_TERRAIN_HEIGHT:g} m of it)",
                          column=words[3][1])
    level = words[7][0] if len(words) == 8 else None
    if level is not None and level not in LEVELS:
        raise reader.fail(f"rock level '{_shown(level)}': expected L1, L2 or L3",
                          column=words[7][1])
    return RockLine(x, y, z, a, b, c, level, reader.line)


def _checked(reader: _Reader, values: dict[str, list[tuple[str, int]]],
             lines: dict[str, int], rocks: list[RockLine]) -> TerrainHeader:
    """The header's items, each within what the rover model reads."""
    for key in ("nx", "ny", "origin", "cell"):
        if key not in values:
            raise reader.fail(f"{NEEDED}: '{key}' is missing")

    def value(key: str, index: int = 0, whole: bool = False) -> float:
        given = values[key]
        if index >= len(given) > 0:
            raise reader.fail(f"{NEEDED}: '{key}' has one value, needs two", lines[key])
        return _number(reader, key, given[index] if given else None, whole, lines[key])

    nx, ny = int(value("nx", whole=True)), int(value("ny", whole=True))
    x0, y0 = value("origin"), value("origin", 1)
    cell = value("cell")
    for key, count in (("nx", nx), ("ny", ny)):
        if count < 2:
            raise reader.fail(f"need nx >= 2, ny >= 2 and nx*ny <= {MAX_NODES}", lines[key],
                              values[key][0][1])
    if nx * ny > MAX_NODES:
        raise reader.fail(f"need nx >= 2, ny >= 2 and nx*ny <= {MAX_NODES}", lines["nx"],
                          values["nx"][0][1])
    if not cell > 0:
        raise reader.fail("need a finite cell > 0", lines["cell"], values["cell"][0][1])
    widest = (max(nx, ny) - 1) * cell
    if widest > MAX_TERRAIN_EXTENT:
        raise reader.fail(
            f"cell {cell:.12g} m with {'nx' if nx >= ny else 'ny'} {max(nx, ny)} makes the grid "
            f"{widest:.12g} m wide; at most {MAX_TERRAIN_EXTENT / 1000:g} km",
            lines["cell"], values["cell"][0][1],
            hint="the rover model starts within 1000 km of the terrain's origin; is the cell "
                 "in metres?")
    header = TerrainHeader(nx, ny, (x0, y0), cell, tuple(rocks), lines, reader.line,
                           reader.offset, "\n".join(reader.shown))
    x_min, x_max, y_min, y_max = header.extent
    for rock in rocks:
        if not (x_min <= rock.x <= x_max and y_min <= rock.y <= y_max):  # as C206 says it
            raise reader.fail(
                f"rock at ({rock.x:g} m, {rock.y:g} m) lies outside the grid (x {x_min:g} … "
                f"{x_max:g} m, y {y_min:g} … {y_max:g} m)", rock.line,
                hint="rock positions are world coordinates, in the grid's frame")
    return header
