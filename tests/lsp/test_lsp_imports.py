"""The language server sits below the command line: it reads rulebooks through the rulebook
package, never through ``idefix_rules.cli`` (and so never imports rich)."""

from __future__ import annotations

import subprocess
import sys


def test_the_language_server_imports_nothing_of_the_command_line() -> None:
    code = ("import sys, idefix_rules.lsp.server, idefix_rules.lsp.analysis; "
            "print(sorted(m for m in sys.modules "
            "if m.startswith('idefix_rules.cli') or m.split('.')[0] == 'rich'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]"
