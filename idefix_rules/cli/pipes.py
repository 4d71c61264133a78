"""Standard output whose reader went away: every command ends the same quiet way.

Rich handles a broken pipe on its own (``SystemExit(1)``);
:class:`~idefix_rules.cli.console.StdoutConsole` hands it back as :class:`BrokenPipeError`
instead, so ``idefix_rules.cli.main`` ends plain ``print`` output and rich output alike with
exit 141 and no traceback.
"""

from __future__ import annotations

import os
import sys

# 128 + SIGPIPE: what a shell reports for the writer of `yes | head -1`.
BROKEN_PIPE_EXIT = 141


def quiet_broken_pipe() -> int:
    """Standard output's reader is gone: point stdout at devnull so the interpreter's final
    flush cannot fail again, and return the shell's code for SIGPIPE."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)
    return BROKEN_PIPE_EXIT
