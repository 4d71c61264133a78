"""Every option a command's ``--help`` lists is described in docs/ or the README: an option
only ``--help`` knows of is one a reader of the docs never learns about."""

from __future__ import annotations

import argparse
import importlib
import re
from pathlib import Path

from idefix_rules.cli import COMMAND_MODULES

ROOT = Path(__file__).resolve().parents[2]
LONG_OPTION = re.compile(r"(?<![\w-])--[a-z][\w-]*")


def _documented() -> str:
    pages = [*sorted((ROOT / "docs").glob("*.md")), ROOT / "README.md"]
    return "\n".join(page.read_text(encoding="utf-8") for page in pages)


def _options() -> list[tuple[str, str]]:
    """``(command, --option)`` for every long option a command's ``--help`` lists."""
    found = []
    for module_name in COMMAND_MODULES:
        module = importlib.import_module(f"idefix_rules.cli.{module_name}")
        parser = argparse.ArgumentParser(prog=f"idefix-verify {module.NAME}")
        module.add_arguments(parser)
        listed = parser.format_help().partition("\noptions:")[2]
        found += [(module.NAME, option) for option in dict.fromkeys(LONG_OPTION.findall(listed))
                  if option != "--help"]
    return found


def test_every_option_of_every_command_is_documented() -> None:
    options = _options()
    assert ("build-fmu", "--cached") in options and ("test", "--verbose") in options
    docs = _documented()
    missing = [f"{command} {option}" for command, option in options
               if not re.search(rf"(?<![\w-]){re.escape(option)}(?![\w-])", docs)]
    assert missing == []
