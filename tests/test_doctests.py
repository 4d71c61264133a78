"""The examples in the package's docstrings run as written: each module's doctests, so an
example that a change broke (or an edit damaged) fails here instead of misleading a reader."""

from __future__ import annotations

import doctest
import importlib
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "idefix_rules"


def _modules() -> list[str]:
    names = []
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        if parts[-1] == "__main__":
            continue  # running it would start the command line
        names.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return names


def _with_examples(name: str) -> bool:
    source = (PACKAGE.parent / Path(*name.split("."))).with_suffix(".py")
    if not source.exists():
        source = PACKAGE.parent / Path(*name.split(".")) / "__init__.py"
    return ">>>" in source.read_text(encoding="utf-8")


@pytest.mark.parametrize("name", [name for name in _modules() if _with_examples(name)])
def test_the_docstring_examples_of_a_module_run_as_written(name: str) -> None:
    module = importlib.import_module(name)
    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    tests = finder.find(module, name)
    for test in tests:
        runner.run(test)
    failed, attempted = runner.summarize(verbose=False)
    assert failed == 0, f"{failed} of {attempted} examples of {name} failed (output above)"
