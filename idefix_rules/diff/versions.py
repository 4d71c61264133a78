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


def version_key(version: str) -> tuple[int, int, int, int, str] | None:
    """Sortable key of a semantic version (a pre-release sorts before its release)."""
    match = _SEMVER.match(version)
    if match is None:
        return None
    major, minor, patch, pre = match.groups()
    return int(major), int(minor), int(patch), 0 if pre else 1, pre or ""


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
