"""The wheel ships every package of the source tree.

`pyproject.toml` lists its packages by hand (two of them are mapped from top-level folders), so a
new sub-package that is not added there is missing from a non-editable install: the tests pass in
an editable checkout and the installed tool fails on import.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _listed() -> set[str]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    return set(config["tool"]["setuptools"]["packages"])


def _mapped() -> dict[str, str]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    return dict(config["tool"]["setuptools"]["package-dir"])


def test_every_package_of_the_source_tree_is_listed() -> None:
    in_tree = {
        ".".join(init.parent.relative_to(ROOT).parts)
        for init in (ROOT / "idefix_rules").rglob("__init__.py")
    }
    listed = _listed()
    assert in_tree - listed == set(), "packages missing from pyproject.toml"
    stale = {name for name in listed - in_tree if name not in _mapped()}
    assert stale == set(), "pyproject.toml lists packages that no longer exist"


def test_mapped_packages_point_at_existing_folders() -> None:
    for name, folder in _mapped().items():
        assert name in _listed()
        assert (ROOT / folder).is_dir(), f"{name} maps to missing folder {folder}"
