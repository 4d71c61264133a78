"""Versions of two rulebooks: a changed rule needs a new version, and versions only go up.

>>> from idefix_rules.rulebook.model import Header, Rulebook
>>> old = Rulebook(Header("ops", "1.0.0", "p"))
>>> version_warnings(old, Rulebook(Header("ops", "1.0.0", "p")), changed=True)
['the rules changed but the version did not (still 1.0.0): raise it before uplink']
"""

from __future__ import annotations

import re

from idefix_rules.rulebook.model import Rulebook

_SEMVER = re.compile(r"^(\d+)\.(\d+)\.(\d+)(?:-([0-9A-Za-z.-]+))?")


PreRelease = tuple[tuple[int, int | str], ...]


def version_key(version: str) -> tuple[int, int, int, int, PreRelease] | None:
    """Sortable key of a semantic version, in SemVer 2.0.0's precedence (its section 11): a
    pre-release sorts before its release; its dot-separated identifiers compare in turn,
    numeric ones as numbers and below alphanumeric ones, and more identifiers sort later when
    the ones before are equal.

    >>> sorted(["1.3.0", "1.3.0-rc.10", "1.3.0-rc.2", "1.3.0-alpha", "1.3.0-alpha.1",
    ...         "1.3.0-beta", "1.3.0-1"], key=version_key)
    ['1.3.0-1', '1.3.0-alpha', '1.3.0-alpha.1', '1.3.0-beta', '1.3.0-rc.2', '1.3.0-rc.10', '1.3.0']
    """
    match = _SEMVER.match(version)
    if match is None:
        return None
    major, minor, patch, pre = match.groups()
    identifiers: PreRelease = tuple(
        (0, int(part)) if part.isdigit() else (1, part) for part in (pre or "").split(".")
        if part)
    return int(major), int(minor), int(patch), 0 if pre else 1, identifiers


def version_warnings(old: Rulebook, new: Rulebook, changed: bool) -> list[str]:
    """Warnings about the header versions of a diff whose rules ``changed`` (or not)."""
    before, after = old.header.version, new.header.version
    old_key, new_key = version_key(before), version_key(after)
    if old_key is None or new_key is None or old.header.name != new.header.name:
        return []
    if changed and before == after:
        return [f"the rules changed but the version did not (still {after}): raise it before "
                "uplink"]
    if new_key < old_key:
        return [f"the version went backwards: {before} → {after}"]
    return []
