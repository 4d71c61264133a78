"""Standard streams whose encoding lacks characters the output uses (``PYTHONIOENCODING=ascii``,
a Latin-1 or C locale): such a character is written as an ASCII equivalent (``–`` as ``-``,
``…`` as ``...``, ``✗`` as ``x``), or ``?`` where there is none, so a command that has done its
work still says its answer and ends with its own exit code rather than a
``UnicodeEncodeError``. A character the encoding has is written as it is. JSON is written with
``\\u`` escapes on such a stream instead, which lose nothing.
"""

from __future__ import annotations

import codecs
import json
import sys
import unicodedata
from typing import Any

# The name the streams' ``errors`` are set to (a codecs error handler, registered below).
ERRORS = "idefix-ascii"

ASCII = {
    "–": "-", "—": "-", "−": "-", "‐": "-", "‑": "-",
    "…": "...", "·": "|", "•": "*", "●": "*",
    "✗": "x", "✕": "x", "✓": "ok",
    "→": "->", "←": "<-", "↔": "<->", "⇒": "=>", "⇔": "<=>",
    "≈": "~", "≥": ">=", "≤": "<=", "≠": "!=", "±": "+/-", "∓": "-/+", "×": "x", "÷": "/",
    "°": " deg", "µ": "u", "½": "1/2", "∞": "inf", "√": "sqrt",
    "‘": "'", "’": "'", "‚": "'", "“": '"', "”": '"', "„": '"', "«": '"', "»": '"',
}


def ascii_text(char: str) -> str:
    """An ASCII stand-in for one character.

    >>> [ascii_text(c) for c in "–…✗α²⁻é─滑"]
    ['-', '...', 'x', 'alpha', '2', '-', 'e', '-', '?']
    """
    if char in ASCII:
        return ASCII[char]
    name = unicodedata.name(char, "")
    for prefix, case in (("GREEK SMALL LETTER ", str.lower), ("GREEK CAPITAL LETTER ",
                                                               str.capitalize)):
        if name.startswith(prefix) and " " not in name.removeprefix(prefix):
            return case(name.removeprefix(prefix))
    if name.startswith("BOX DRAWINGS "):  # a line, or a corner or crossing of lines
        words = set(name.split())
        if "AND" in words or len(words & {"HORIZONTAL", "VERTICAL"}) != 1:
            return "+"
        return "-" if "HORIZONTAL" in words else "|"
    decomposed = "".join(ASCII.get(c, c) for c in unicodedata.normalize("NFKD", char)
                         if not unicodedata.combining(c))
    return decomposed if decomposed and decomposed.isascii() else "?"


def _replace(problem: UnicodeError) -> tuple[str, int]:
    if not isinstance(problem, UnicodeEncodeError):
        raise problem
    lacking = problem.object[problem.start:problem.end]
    return "".join(ascii_text(char) for char in lacking), problem.end


codecs.register_error(ERRORS, _replace)


def tolerate_encodings() -> None:
    """Standard output and error write what their encoding lacks as ASCII (the module
    docstring); Python's own default would raise (stdout) or write ``\\u2013`` (stderr)."""
    for stream in (sys.stdout, sys.stderr):
        reconfigure = getattr(stream, "reconfigure", None)
        if reconfigure is not None and not stream.closed:
            reconfigure(errors=ERRORS)


def writes_unicode(stream: object) -> bool:
    """Whether ``stream``'s encoding holds every character (a UTF encoding)."""
    encoding = getattr(stream, "encoding", None) or "utf-8"
    try:
        return codecs.lookup(encoding).name.startswith("utf")
    except LookupError:
        return False


def json_text(data: Any, **options: Any) -> str:
    """``json.dumps`` for standard output: characters as they are on a UTF stream, ``\\u``
    escapes on one that lacks them (JSON readers decode both alike)."""
    return json.dumps(data, ensure_ascii=not writes_unicode(sys.stdout), **options)
