"""Where a side of a diff comes from: a rulebook file, or a file at a git revision.

``rulebooks/idefix-ops.rules`` reads the file; ``rulebooks/idefix-ops.rules@HEAD~1`` reads the
text the file had at ``HEAD~1`` (``git show REV:./NAME`` run in the file's folder, no shell).
A spec that names an existing file is always a file, even if it contains ``@``.

>>> split_spec("rulebooks/idefix-ops.rules@HEAD~1")
('rulebooks/idefix-ops.rules', 'HEAD~1')
>>> split_spec("rulebooks/idefix-ops.rules")
('rulebooks/idefix-ops.rules', None)
"""

from __future__ import annotations

import subprocess
from dataclasses import dataclass
from pathlib import Path

from idefix_rules.errors import Span, UserInputError, error
from idefix_rules.rulebook import check_text, load_checked
from idefix_rules.rulebook.check import CheckedRulebook

GIT_TIMEOUT_S = 30.0
NO_FILE = "D005"  # PATH@REV with no file before the '@'


@dataclass(frozen=True)
class RulebookSource:
    """One checked rulebook and the label it is shown under (``path`` or ``path@rev``)."""

    label: str
    path: Path
    revision: str | None
    checked: CheckedRulebook


def split_spec(spec: str) -> tuple[str, str | None]:
    """``(path, revision)`` of ``PATH@REV``; ``(path, None)`` for a plain file."""
    if Path(spec).is_file() or "@" not in spec:
        return spec, None
    path, _, revision = spec.partition("@")
    return path, revision


def git_text(path: Path, revision: str) -> str:
    """The text of ``path`` at git ``revision`` (:class:`UserInputError` when git cannot)."""
    label = f"{path}@{revision}"
    where = Span(str(path))  # the file named, not "<input>"
    if not revision or revision.startswith("-") or any(c.isspace() for c in revision):
        raise UserInputError(error("D001", f"{label}: {revision!r} is not a git revision",
                                   where,
                                   hint="write PATH@REV, e.g. rulebooks/idefix-ops.rules@HEAD~1"))
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise UserInputError(error("D002", f"{label}: folder {folder} not found", where,
                                   hint="the folder of PATH must exist in the working tree"))
    try:
        done = subprocess.run(["git", "-C", str(folder), "show", f"{revision}:./{path.name}"],
                              capture_output=True, timeout=GIT_TIMEOUT_S, check=False)
    except FileNotFoundError:
        raise UserInputError(error("D003", f"{label}: git is not installed", where)) from None
    except subprocess.TimeoutExpired:
        raise UserInputError(error("D003", f"{label}: git show took more than "
                                           f"{GIT_TIMEOUT_S:g} s", where)) from None
    if done.returncode != 0:
        message = done.stderr.decode("utf-8", errors="replace").strip().splitlines()
        reason = message[-1] if message else f"git exited with {done.returncode}"
        if not _is_revision(folder, revision):
            raise UserInputError(error("D001", f"{label}: {revision!r} is not a git revision "
                                               f"({reason})", where,
                                       hint=f"git log --oneline -- {path} lists the "
                                            "revisions that have the file"))
        raise UserInputError(error("D004", f"{label}: cannot read the file at revision "
                                           f"{revision!r}: {reason}", where,
                                   hint=f"check the revision (git log -- {path}) and that "
                                        f"{path} is inside a git repository"))
    try:
        return done.stdout.decode("utf-8")
    except UnicodeDecodeError as failure:
        raise UserInputError(error("E002", f"{label}: not UTF-8 text ({failure.reason} at "
                                           f"byte {failure.start})", where)) from None



def _is_revision(folder: Path, revision: str) -> bool:
    """Whether git, run in ``folder``, knows ``revision`` as a commit (True outside a
    repository or when git cannot say: the read's own message then stands)."""
    try:
        known = subprocess.run(["git", "-C", str(folder), "rev-parse", "--verify", "--quiet",
                                f"{revision}^{{commit}}"], capture_output=True,
                               timeout=GIT_TIMEOUT_S, check=False)
        inside = subprocess.run(["git", "-C", str(folder), "rev-parse", "--git-dir"],
                                capture_output=True, timeout=GIT_TIMEOUT_S, check=False)
    except (OSError, subprocess.TimeoutExpired):
        return True
    return known.returncode == 0 or inside.returncode != 0

def load_source(spec: str) -> RulebookSource:
    """Read and check the rulebook a spec names; every mistake is a :class:`UserInputError`."""
    path_text, revision = split_spec(spec)
    path = Path(path_text)
    if revision is not None and (not path_text or path_text.endswith("/") or path.is_dir()):
        # git would show the folder's listing ("tree …"), not a rulebook
        named = f"names the folder {path_text}" if path_text else "is empty"
        raise UserInputError(error(
            NO_FILE, f"the path before '@' {named}: PATH@REV reads the file PATH at "
                     f"revision {revision}", Span(spec),
            hint=f"name the rulebook file, e.g. rulebooks/idefix-ops.rules@{revision}"))
    if revision is None:
        return RulebookSource(str(path), path, None, load_checked(path))
    return load_revision(path, revision)


def load_revision(path: Path, revision: str) -> RulebookSource:
    """Read and check the text ``path`` had at git ``revision`` (a :class:`UserInputError`
    names what went wrong: the revision, git, or the rulebook's own errors)."""
    label = f"{path}@{revision}"
    text = git_text(path, revision)
    result = check_text(text, label)
    if result.checked is None:
        raise UserInputError(result.errors or [error("E000", f"{label}: invalid rulebook",
                                                     Span(label))], {label: text})
    return RulebookSource(label, path, revision, result.checked)
