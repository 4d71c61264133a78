"""Fixtures of the language-server tests: one server per test module, driven through the
protocol by :class:`lsp_client.LspClient`."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

from lsp_client import LspClient

REPOSITORY = Path(__file__).resolve().parents[2]
DEFAULT_RULEBOOK = REPOSITORY / "rulebooks" / "idefix-ops.rules"


@pytest.fixture(scope="module")
def client() -> Iterator[LspClient]:
    # a short debounce keeps the tests quick; the debounce itself has a test of its own
    server = LspClient({"debounce": 0.02})
    yield server
    assert server.close() == 0


@pytest.fixture
def default_text() -> str:
    return DEFAULT_RULEBOOK.read_text(encoding="utf-8")
