"""An FMU's ``modelDescription.xml`` as text, checked before fmpy reads it.

fmpy's own errors for a broken description name the wrong file or none: lxml reports the member
as a file of the current folder (``Error reading file '/home/me/modelDescription.xml': Invalid
bytes in character encoding``), and a variable without ``valueReference`` comes out as Python's
``int() argument must be a string … not 'NoneType'``, and of two variables of one name the last
silently stands for both. :func:`description_problem` says what is wrong in the description
instead, with its line; the caller names the FMU.

>>> description_problem_in(b'<?xml version="1.0" encoding="UTF-8"?>\\n<a>caf\\xe9</a>')
'its modelDescription.xml is not UTF-8 text, as the FMI standard requires: byte 0xe9 on line 2'
"""

from __future__ import annotations

import re
import zipfile
from pathlib import Path

DESCRIPTION_FILE = "modelDescription.xml"
_DECLARED_ENCODING = re.compile(rb"""^\s*<\?xml[^>]*encoding\s*=\s*["']([^"']+)["']""")
_WHOLE_NUMBER = re.compile(r"\d+")


def description_problem(path: Path) -> str | None:
    """What makes the model description of the FMU (or extracted FMU folder) at ``path``
    unreadable, said; None when it reads, or when it cannot be had at all (no such member:
    fmpy says so)."""
    try:
        if path.is_dir():
            data = (path / DESCRIPTION_FILE).read_bytes()
        else:
            with zipfile.ZipFile(path) as archive:
                data = archive.read(DESCRIPTION_FILE)
    except (OSError, KeyError, zipfile.BadZipFile, EOFError, ValueError):
        return None
    return description_problem_in(data)


def description_problem_in(data: bytes) -> str | None:
    """:func:`description_problem` of a model description's bytes."""
    from lxml import etree

    declared = _DECLARED_ENCODING.match(data)
    encoding = declared.group(1).decode("ascii", "replace").lower() if declared else "utf-8"
    if encoding in ("utf-8", "utf8"):
        try:
            data.decode("utf-8")
        except UnicodeDecodeError as failure:
            line = data.count(b"\n", 0, failure.start) + 1
            return (f"its {DESCRIPTION_FILE} is not UTF-8 text, as the FMI standard requires: "
                    f"byte 0x{data[failure.start]:02x} on line {line}")
    try:
        root = etree.fromstring(data, etree.XMLParser(resolve_entities=False, no_network=True))
    except etree.XMLSyntaxError as failure:
        return f"its {DESCRIPTION_FILE} is not well-formed XML: {failure.msg}"
    variables = root.find("ModelVariables")
    lines: dict[str, int | None] = {}  # name → the line declaring it
    for variable in () if variables is None else variables:
        if not isinstance(variable.tag, str):  # a comment or processing instruction
            continue
        name = variable.get("name", "?")
        reference = variable.get("valueReference")
        where = f"its {DESCRIPTION_FILE}, line {variable.sourceline}: variable {name!r}"
        if reference is None:
            return f"{where} has no valueReference"
        if _WHOLE_NUMBER.fullmatch(reference.strip()) is None:
            return f"{where} has valueReference {reference!r}, not a whole number"
        if name in lines:  # one of the two would silently stand for both
            return f"{where} is declared twice (first on line {lines[name]})"
        lines[name] = variable.sourceline
    return None
