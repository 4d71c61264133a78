"""Fixtures of the language-server tests: one server per test module, driven through the
protocol by :class:`lsp_client.LspClient`."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

from lsp_client import LspClient

# The frozen operations rulebook 1.1.0: the tests find positions, names and hover texts in it
FROZEN_RULEBOOK = Path(__file__).resolve().parents[1] / "fixtures" / "rulebooks" / \
    "idefix-ops-1.1.0.rules"


@pytest.fixture(scope="module")
def client() -> Iterator[LspClient]:
    # a short debounce keeps the tests quick; the debounce itself has a test of its own
    server = LspClient({"debounce": 0.02})
    yield server
    assert server.close() == 0


@pytest.fixture
def default_text() -> str:
    return FROZEN_RULEBOOK.read_text(encoding="utf-8")
