"""Writing output files so that a reader never sees half of one, and keeping the last one.

>>> import tempfile, pathlib
>>> folder = pathlib.Path(tempfile.mkdtemp())
>>> write_atomic(folder / "summary.json", "{}\\n")
>>> set_aside(folder / "summary.json")
[PosixPath('.../summary.previous.json')]
"""

from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path


def cache_root() -> Path:
    """This user's cache folder of the tool: ``$IDEFIX_CACHE``, else ``~/.cache/idefix-rules``
    (the built rover FMU, the rulebook parser's tables)."""
    root = os.environ.get("IDEFIX_CACHE")
    return Path(root) if root else Path.home() / ".cache" / "idefix-rules"


def previous_path(path: Path) -> Path:
    """Where :func:`set_aside` keeps ``path``: ``name.previous.ext`` beside it."""
    return path.with_name(f"{path.stem}.previous{path.suffix}")


def previous_report_path(path: Path) -> Path:
    """Where :func:`set_aside_report` keeps a JUnit report: ``name.xml.previous`` beside it, a
    name no ``*.xml`` glob of a CI server (``reports/*.xml``) takes for a second report."""
    return path.with_name(f"{path.name}.previous")


def set_aside_report(path: Path | None) -> list[Path]:
    """Rename the JUnit report ``path`` to its :func:`previous_report_path` (replacing an
    older copy). A copy an earlier version kept as ``name.previous.xml``, which a CI
    server's ``*.xml`` glob took for a second report on every run, goes too: it becomes the
    kept copy when there is no newer one, else it is removed. Returns the new names."""
    if path is None:
        return []
    path = Path(path)
    target = previous_report_path(path)
    earlier = previous_path(path)
    if earlier != path and earlier.is_file() and is_junit_report(earlier):
        if path.is_file() or target.is_file():
            earlier.unlink()
        else:
            os.replace(earlier, target)
    if not path.is_file():
        return []
    os.replace(path, target)
    return [target]


def is_junit_report(path: Path) -> bool:
    """Whether an existing file may be replaced by a JUnit report: an empty file (``touch``,
    ``mktemp``), or an XML document (UTF-8 or UTF-16 with its byte order mark) whose first
    element is ``testsuites`` or ``testsuite`` (ours or another tool's, after any
    declaration, stylesheet instruction, comment or document type)."""
    try:
        with path.open("rb") as handle:
            head = handle.read(8192)
    except OSError:
        return False
    if not head.strip():
        return True
    encoding = "utf-16" if head[:2] in (b"\xff\xfe", b"\xfe\xff") else "utf-8"
    text = head.decode(encoding, errors="replace").lstrip("\ufeff")
    prolog = re.compile(r"\s*(<\?.*?\?>|<!--.*?-->|<!DOCTYPE[^>]*>)", re.DOTALL)
    while (found := prolog.match(text)) is not None:
        text = text[found.end():]
    return re.match(r"\s*<testsuites?[\s/>]", text) is not None


def write_atomic(path: Path, data: str | bytes) -> None:
    """Write ``data`` to a temporary file beside ``path``, then rename it over ``path``: a
    kill or a full disk leaves the old file or the new one, never a part."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data.encode("utf-8") if isinstance(data, str) else data)
        os.chmod(temporary, 0o666 & ~_umask())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def _umask() -> int:
    current = os.umask(0o022)
    os.umask(current)
    return current


# The report's figures beside its page (report/__init__.py writes them): set aside with the
# page, so that no figure of an earlier report (of another campaign, another evaluation, a run
# without a report) stays beside this one's outputs.
REPORT_FIGURES = ("risk_map_*.png", "box_local_error.png", "box_heading_error.png",
                  "dominant_index.png", "sensitivity.png")


def report_outputs(folder: Path, page: str = "report.html") -> list[Path]:
    """The report's page and every figure of a report in ``folder`` (existing or not, for
    :func:`set_aside`); copies already set aside (``*.previous.*``) are not among them."""
    found = [Path(folder) / page]
    for pattern in REPORT_FIGURES:
        found += sorted(path for path in Path(folder).glob(pattern)
                        if ".previous." not in path.name)
    return found


def set_aside(*paths: Path | None) -> list[Path]:
    """Rename each existing file to its :func:`previous_path` (replacing an older copy), so no
    output of an earlier run stays where this run's will be. Returns the new names."""
    moved = []
    for path in paths:
        if path is not None and Path(path).is_file():
            target = previous_path(Path(path))
            os.replace(path, target)
            moved.append(target)
    return moved
