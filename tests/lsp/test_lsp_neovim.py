"""The Neovim set-up of docs/editor.md, as written there, in a headless Neovim: a ``*.rules``
file gets the ``idefix-rules`` file type (not Snort's ``hog``, which Neovim 0.7 gives it
otherwise), the language server attaches, and a broken rulebook's diagnostics arrive at their
line and column. Skipped where ``nvim`` is not installed (CI installs it, .ci/run)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPOSITORY = Path(__file__).resolve().parents[2]
EDITOR_DOCS = REPOSITORY / "docs" / "editor.md"
NVIM = shutil.which("nvim")

pytestmark = pytest.mark.skipif(NVIM is None, reason="nvim is not installed (apt-get install "
                                                     "neovim); the Neovim set-up is not run")

DOCUMENTED_COMMAND = '{ "idefix-verify", "lsp" }'

# Runs after the file is read: waits for diagnostics, writes what the buffer got, quits.
PROBE = """\
local buf = vim.api.nvim_get_current_buf()
local function attached()
  if vim.lsp.get_clients then return #vim.lsp.get_clients({ bufnr = buf }) end
  return #vim.tbl_keys(vim.lsp.buf_get_clients(buf))
end
vim.wait(60000, function() return #vim.diagnostic.get(buf) > 0 end, 50)
local lines = { "filetype " .. vim.bo[buf].filetype, "clients " .. attached() }
for _, d in ipairs(vim.diagnostic.get(buf)) do
  table.insert(lines, string.format("diagnostic %d:%d %s", d.lnum + 1, d.col + 1, d.message))
end
vim.fn.writefile(lines, os.getenv("PROBE_OUT"))
vim.cmd("qa!")
"""

BROKEN = """\
rulebook "broken" version "1.0.0"
purpose "A verdict reading a constant nobody declared"

index I_s "slip" {
  value  = max over time (max over wheels (abs(wheel.slip)))
  limit  = 70 %
  weight = 1
}

verdict acceptable_risk: require risk <= critical_risk
"""


def documented_config() -> str:
    """The first Lua block of the Neovim section of docs/editor.md."""
    section = EDITOR_DOCS.read_text(encoding="utf-8").split("## Neovim\n", 1)[1]
    match = re.search(r"```lua\n(.*?)```", section, re.DOTALL)
    assert match is not None, "docs/editor.md has no Lua block under '## Neovim'"
    return match.group(1)


def lua_list(words: list[str]) -> str:
    return "{ " + ", ".join('"' + w.replace("\\", "\\\\").replace('"', '\\"') + '"'
                            for w in words) + " }"


def test_the_documented_neovim_config_detects_rulebooks_and_attaches_the_server(
        tmp_path: Path) -> None:
    assert NVIM is not None
    config = documented_config()
    assert config.count(DOCUMENTED_COMMAND) == 1
    # the server of this checkout, not whatever idefix-verify is on PATH
    config = config.replace(DOCUMENTED_COMMAND,
                            lua_list([sys.executable, "-m", "idefix_rules", "lsp"]))
    (tmp_path / "init.lua").write_text(config, encoding="utf-8")
    (tmp_path / "probe.lua").write_text(PROBE, encoding="utf-8")
    (tmp_path / "broken.rules").write_text(BROKEN, encoding="utf-8")
    out = tmp_path / "probe.out"
    environment = {**os.environ, "PYTHONPATH": str(REPOSITORY), "PROBE_OUT": str(out),
                   "XDG_CONFIG_HOME": str(tmp_path / "config"),
                   "XDG_DATA_HOME": str(tmp_path / "data"),
                   "XDG_STATE_HOME": str(tmp_path / "state")}
    finished = subprocess.run([NVIM, "--headless", "-u", "init.lua", "-i", "NONE",
                               "-c", "luafile probe.lua", "broken.rules"],
                              cwd=tmp_path, env=environment, capture_output=True, text=True,
                              timeout=120, check=False)
    assert finished.returncode == 0, finished.stdout + finished.stderr
    lines = out.read_text(encoding="utf-8").splitlines()
    assert lines[:2] == ["filetype idefix-rules", "clients 1"], lines
    assert lines[2:] == ["diagnostic 10:42 unknown name 'critical_risk' in a verdict or rank key"]
