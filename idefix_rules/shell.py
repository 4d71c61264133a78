"""Commands the tool prints for a person to paste into a shell: every word quoted where the
shell would split or expand it (a folder with a space, a ``$`` in a name).

>>> from pathlib import Path
>>> command_line("idefix-verify", Path("my camp.yaml"), "--resume", "--runs", 8)
"idefix-verify 'my camp.yaml' --resume --runs 8"
"""

from __future__ import annotations

import shlex


def command_line(*words: object) -> str:
    """``words`` as one shell command line, each quoted as the shell needs it (``shlex``)."""
    return " ".join(shlex.quote(str(word)) for word in words)
