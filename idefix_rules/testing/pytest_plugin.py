"""pytest plugin (entry point ``idefix_rules``): case files as test items, rulebook fixtures.

Installed with the package, so ``pytest rulebooks/tests`` runs every case of every case file
(a YAML file with top-level ``rulebook:`` and ``cases:`` keys) as one test item, reported with
the same expected-vs-actual text as ``idefix-verify test``. A broken case file is a collection
error naming its line and column.

Fixtures for Python tests of a rulebook (the default rulebook is the ini option
``idefix_rulebook``, ``rulebooks/idefix-ops.rules`` under the rootdir when not set)::

    def test_slip_limit(compiled_rulebook):                 # CompiledRulebook, once a session
        assert compiled_rulebook.checked.limits["I_s"] == 0.7

    def test_other(load_rulebook):                          # factory: path → CheckedRulebook
        checked = load_rulebook("rulebooks/history/idefix-ops-0.9.0.rules")
        before = load_rulebook("rulebooks/idefix-ops.rules@HEAD~1")  # at a git revision

``PATH@REV`` reads the file as it was at a git revision, exactly as ``idefix-verify diff`` does
(:mod:`idefix_rules.diff.source`); the ini option takes that form too.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from idefix_rules.diff.source import load_revision, split_spec
from idefix_rules.errors import UserInputError, render_diagnostics
from idefix_rules.rulebook import load_checked
from idefix_rules.rulebook.check import CheckedRulebook
from idefix_rules.rulebook.compile import CompiledRulebook, compile_rulebook
from idefix_rules.testing.case_model import Case, CaseFile
from idefix_rules.testing.casefile import load_case_file
from idefix_rules.testing.runner import run_case

_CASE_FILE = re.compile(r"^rulebook\s*:", re.MULTILINE)
_CASES = re.compile(r"^cases\s*:", re.MULTILINE)
DEFAULT_RULEBOOK = "rulebooks/idefix-ops.rules"


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addini("idefix_rulebook", "rulebook the rulebook fixtures load (relative to the "
                  "rootdir)", default=DEFAULT_RULEBOOK)


def is_case_file(path: Path) -> bool:
    """A ``.yaml``/``.yml`` file with top-level ``rulebook:`` and ``cases:`` keys."""
    if path.suffix not in (".yaml", ".yml"):
        return False
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return False
    return bool(_CASE_FILE.search(text) and _CASES.search(text))


def pytest_collect_file(file_path: Path, parent: pytest.Collector) -> pytest.Collector | None:
    if is_case_file(file_path):
        collector: CaseFileCollector = CaseFileCollector.from_parent(parent, path=file_path)
        return collector
    return None


class CaseFileError(Exception):
    """A broken case file (rendered diagnostics)."""


class CaseFileCollector(pytest.File):
    """One case file: its cases are the items."""

    def collect(self) -> Iterator[CaseItem]:
        try:
            case_file = load_case_file(self.path)
        except UserInputError as failure:
            raise CaseFileError(render_diagnostics(failure.diagnostics, failure.sources)) \
                from None
        compiled = compile_rulebook(case_file.checked)
        for case in case_file.cases:
            yield CaseItem.from_parent(self, name=case.name, case=case, case_file=case_file,
                                       compiled=compiled)

    def repr_failure(self, excinfo: pytest.ExceptionInfo[BaseException],
                     style: Any = None) -> str:
        if isinstance(excinfo.value, CaseFileError):
            return str(excinfo.value)
        return str(super().repr_failure(excinfo))


class CaseMismatch(Exception):
    """Expectations of a case that did not hold."""


class CaseItem(pytest.Item):
    def __init__(self, *, case: Case, case_file: CaseFile, compiled: CompiledRulebook,
                 **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.case = case
        self.case_file = case_file
        self.compiled = compiled

    def runtest(self) -> None:
        outcome = run_case(self.compiled, self.case)
        if not outcome.passed:
            lines = [f"case {self.case.name} ({self.case.span})"]
            if self.case.description:
                lines.append(f"  {self.case.description}")
            lines += ["  " + m.render().replace("\n", "\n  ") for m in outcome.mismatches]
            raise CaseMismatch("\n".join(lines))

    def repr_failure(self, excinfo: pytest.ExceptionInfo[BaseException],
                     style: Any = None) -> str:
        if isinstance(excinfo.value, CaseMismatch):
            return str(excinfo.value)
        return str(super().repr_failure(excinfo))

    def reportinfo(self) -> tuple[Path, int, str]:
        return self.path, max(self.case.span.line - 1, 0), f"case: {self.case.name}"


# ----------------------------------------------------------------------------- fixtures

@pytest.fixture(scope="session")
def load_rulebook(pytestconfig: pytest.Config) -> Callable[[str | Path], CheckedRulebook]:
    """Factory: read, parse and check a rulebook (relative paths from the rootdir), or the
    text a rulebook had at a git revision (``PATH@REV``, as in ``idefix-verify diff``); a
    broken rulebook or an unknown revision fails the test with its diagnostics."""
    root = Path(str(pytestconfig.rootpath))

    def load(path: str | Path) -> CheckedRulebook:
        name, revision = split_spec(str(path))
        located = Path(name) if Path(name).is_absolute() else root / name
        try:
            if revision is not None:
                return load_revision(located, revision).checked
            return load_checked(located)
        except UserInputError as failure:
            pytest.fail(render_diagnostics(failure.diagnostics, failure.sources),
                        pytrace=False)

    return load


@pytest.fixture(scope="session")
def rulebook(pytestconfig: pytest.Config,
             load_rulebook: Callable[[str | Path], CheckedRulebook]) -> CheckedRulebook:
    """The checked rulebook of the ini option ``idefix_rulebook``."""
    return load_rulebook(str(pytestconfig.getini("idefix_rulebook")))


@pytest.fixture(scope="session")
def compiled_rulebook(rulebook: CheckedRulebook) -> CompiledRulebook:
    """The compiled evaluator of :func:`rulebook`."""
    return compile_rulebook(rulebook)
