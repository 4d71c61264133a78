"""A small Language Server Protocol client for the tests: it starts ``idefix-verify lsp`` as
an editor does (a subprocess speaking JSON-RPC with Content-Length framing on stdin/stdout) and
keeps every message the server sends, so a test can wait for a notification and check what
came before it."""

from __future__ import annotations

import json
import os
import queue
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

Message = dict[str, Any]


class LspClient:
    def __init__(self, initialization_options: dict[str, Any] | None = None,
                 position_encodings: tuple[str, ...] = ("utf-16",)) -> None:
        self.process = subprocess.Popen(
            [sys.executable, "-m", "idefix_rules", "lsp"], stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env={**os.environ, "NO_COLOR": "1"})
        self._next_id = 0
        self._responses: dict[int, queue.Queue[Message]] = {}
        self._lock = threading.Lock()
        self.notifications: list[Message] = []
        self._arrived = threading.Condition()
        self.stderr: list[bytes] = []
        self._threads = [threading.Thread(target=self._read, daemon=True),
                         threading.Thread(target=self._drain_stderr, daemon=True)]
        for thread in self._threads:
            thread.start()
        self.initialize_result = self.request("initialize", {
            "processId": os.getpid(), "rootUri": None,
            "capabilities": {
                "general": {"positionEncodings": list(position_encodings)},
                "textDocument": {
                    "hover": {"contentFormat": ["markdown", "plaintext"]},
                    "publishDiagnostics": {"versionSupport": True},
                    "completion": {"completionItem": {"snippetSupport": False}},
                    "codeAction": {"codeActionLiteralSupport": {"codeActionKind": {
                        "valueSet": ["quickfix"]}}},
                }},
            "initializationOptions": initialization_options or {},
        })
        self.notify("initialized", {})

    # ---- transport

    def _send(self, message: Message) -> None:
        body = json.dumps(message).encode("utf-8")
        assert self.process.stdin is not None
        self.process.stdin.write(b"Content-Length: %d\r\n\r\n" % len(body) + body)
        self.process.stdin.flush()

    def _read(self) -> None:
        stream = self.process.stdout
        assert stream is not None
        while True:
            length = None
            while True:
                line = stream.readline()
                if not line:
                    return
                if line in (b"\r\n", b"\n"):
                    break
                name, _, value = line.decode("ascii").partition(":")
                if name.lower() == "content-length":
                    length = int(value)
            assert length is not None
            message = json.loads(stream.read(length))
            if "id" in message and "method" not in message:
                with self._lock:
                    self._responses.setdefault(message["id"], queue.Queue()).put(message)
            elif "id" in message:  # a request of the server (registrations …): accept it
                self._send({"jsonrpc": "2.0", "id": message["id"], "result": None})
            else:
                with self._arrived:
                    self.notifications.append(message)
                    self._arrived.notify_all()

    def _drain_stderr(self) -> None:
        assert self.process.stderr is not None
        for line in self.process.stderr:
            self.stderr.append(line)

    # ---- requests and notifications

    def request(self, method: str, params: Any, timeout: float = 60) -> Any:
        with self._lock:
            self._next_id += 1
            number = self._next_id
            answers = self._responses.setdefault(number, queue.Queue())
        self._send({"jsonrpc": "2.0", "id": number, "method": method, "params": params})
        answer = answers.get(timeout=timeout)
        if "error" in answer:
            raise AssertionError(f"{method} failed: {answer['error']}")
        return answer["result"]

    def notify(self, method: str, params: Any) -> None:
        self._send({"jsonrpc": "2.0", "method": method, "params": params})

    def wait_for(self, method: str, where: Callable[[Message], bool] = lambda m: True,
                 timeout: float = 60) -> Message:
        """The first notification ``method`` (already received or still to come) that
        satisfies ``where``."""
        deadline = time.monotonic() + timeout
        with self._arrived:
            while True:
                for message in self.notifications:
                    if message["method"] == method and where(message["params"]):
                        return message["params"]  # type: ignore[no-any-return]
                left = deadline - time.monotonic()
                if left <= 0 or self.process.poll() is not None:
                    raise AssertionError(f"no {method} arrived; server stderr:\n"
                                         + b"".join(self.stderr).decode(errors="replace"))
                self._arrived.wait(left)

    def received(self, method: str) -> list[Message]:
        with self._arrived:
            return [m["params"] for m in self.notifications if m["method"] == method]

    # ---- documents

    def open(self, path: Path, text: str, version: int = 1) -> str:
        uri = path.resolve().as_uri()
        self.notify("textDocument/didOpen", {"textDocument": {
            "uri": uri, "languageId": "idefix-rules", "version": version, "text": text}})
        return uri

    def change(self, uri: str, version: int, text: str) -> None:
        """Replace the whole text (an editor may also send ranges: see ``change_range``)."""
        self.notify("textDocument/didChange", {"textDocument": {"uri": uri, "version": version},
                                               "contentChanges": [{"text": text}]})

    def change_range(self, uri: str, version: int, edit_range: Message, text: str) -> None:
        self.notify("textDocument/didChange", {
            "textDocument": {"uri": uri, "version": version},
            "contentChanges": [{"range": edit_range, "text": text}]})

    def diagnostics(self, uri: str, version: int) -> list[Message]:
        params = self.wait_for("textDocument/publishDiagnostics",
                               lambda p: p["uri"] == uri and p.get("version") == version)
        return params["diagnostics"]  # type: ignore[no-any-return]

    def close(self) -> int:
        """Shut the server down as an editor does; its exit code (0 after shutdown)."""
        try:
            self.request("shutdown", None, timeout=30)
            self.notify("exit", None)
            return self.process.wait(timeout=30)
        finally:
            if self.process.poll() is None:
                self.process.kill()
                self.process.wait()
            for thread in self._threads:  # they stop at the end of the server's output
                thread.join(timeout=30)
            for stream in (self.process.stdin, self.process.stdout, self.process.stderr):
                if stream is not None:
                    stream.close()


def utf16_column(line: str, characters: int) -> int:
    """The UTF-16 column of the character at ``characters`` in ``line`` (LSP's default)."""
    return len(line[:characters].encode("utf-16-le")) // 2


def apply_edits(text: str, edits: list[Message]) -> str:
    """The text after LSP text edits (UTF-16 positions), applied from the last to the first."""
    lines = text.split("\n")

    def offset(position: Message) -> int:
        line = position["line"]
        if line >= len(lines):
            return len(text)
        before = sum(len(lines[n]) + 1 for n in range(line))
        units, characters = 0, 0
        for char in lines[line]:
            if units >= position["character"]:
                break
            units += len(char.encode("utf-16-le")) // 2
            characters += 1
        return before + characters

    ordered = sorted(edits, key=lambda e: (e["range"]["start"]["line"],
                                           e["range"]["start"]["character"]), reverse=True)
    for edit in ordered:
        start, end = offset(edit["range"]["start"]), offset(edit["range"]["end"])
        text = text[:start] + edit["newText"] + text[end:]
    return text
