"""An FMU archive: unzipped into a folder, and the signal map it ships."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

from idefix_rules.errors import Span, UserInputError, error
from idefix_rules.fmu.description import FmuDescription
from idefix_rules.fmu.mapping import DONE_SIGNAL
from idefix_rules.signals import FMU_SIGNALS

SIGNAL_MAP_FILE = "signal_map.json"


def extract_fmu(fmu_path: str | Path, folder: str | Path | None = None) -> Path:
    """Unzip an FMU into ``folder`` (None: a new temporary folder); returns the folder.

    A campaign extracts once and hands the folder to every worker's runner (``unzipped``).
    """
    from fmpy import extract

    path = Path(fmu_path)
    if not path.is_file():
        found = "is not a file" if path.exists() else "not found"
        raise UserInputError(error("F101", f"FMU file {found}", Span(str(path))))
    try:
        return Path(extract(str(path), unzipdir=None if folder is None else str(folder)))
    except Exception as exc:  # fmpy and zipfile raise plain exceptions for unreadable archives
        raise UserInputError(error("F102", f"not a readable FMU: {exc}", Span(str(path)))) \
            from None


def default_signal_map(description: FmuDescription, source: Path) -> dict[str, str]:
    """The map used when a campaign gives none: the FMU's shipped ``signal_map.json``, else
    every variable named like a contract signal."""
    text = None
    try:
        if source.is_dir():
            shipped = source / SIGNAL_MAP_FILE
            text = shipped.read_text(encoding="utf-8") if shipped.is_file() else None
        else:
            with zipfile.ZipFile(source) as archive:
                if SIGNAL_MAP_FILE in archive.namelist():
                    text = archive.read(SIGNAL_MAP_FILE).decode("utf-8")
        shipped_map = None if text is None else json.loads(text)
    except (OSError, UnicodeDecodeError, ValueError, zipfile.BadZipFile) as failure:
        raise UserInputError(error("F102", f"not a readable FMU: its {SIGNAL_MAP_FILE} cannot "
                                   f"be read ({failure})", Span(str(source)))) from None
    if shipped_map is None:
        return {name: name for name in FMU_SIGNALS
                if name in description.variables and name != DONE_SIGNAL}
    if not (isinstance(shipped_map, dict) and all(
            isinstance(key, str) and isinstance(value, str)
            for key, value in shipped_map.items())):
        raise UserInputError(error(
            "F102", f"not a readable FMU: its {SIGNAL_MAP_FILE} must be a JSON object of FMU "
                    "variable names to signal names (strings), e.g. {\"px\": \"x\"}",
            Span(str(source))))
    return dict(shipped_map)
