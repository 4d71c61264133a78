"""A campaign given through a pipe (a shell's ``<(…)``, a FIFO) is read once, whole: the look
at whether a campaign path is a zip archive (an FMU given as the campaign) read a pipe's start
away, and the campaign was then empty."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest

from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.errors import UserInputError


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="named pipes need a POSIX system")
def test_a_campaign_from_a_pipe_is_read_whole(tmp_path: Path) -> None:
    fifo = tmp_path / "campaign.yaml"
    os.mkfifo(fifo)
    text = "name: piped\nno_such_key: 1\n"

    def write() -> None:
        with open(fifo, "w", encoding="utf-8") as pipe:
            pipe.write(text)

    writer = threading.Thread(target=write)
    writer.start()
    try:
        with pytest.raises(UserInputError) as raised:
            load_campaign(fifo)
    finally:
        writer.join(timeout=10)
    lines = {d.span.line for d in raised.value.diagnostics
             if d.span is not None and "no_such_key" in d.message}
    assert lines == {2}, raised.value.diagnostics  # the text as written, not an empty file
