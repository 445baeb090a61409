"""A minimal LSP client for the tests: `isaac lsp` started as a subprocess, spoken to in Content-Length framed
JSON-RPC over its stdin and stdout (the way an editor speaks to it), nothing of pygls used on this side."""
from __future__ import annotations

import json
import os
import queue
import subprocess
import sys
import threading
import time
from pathlib import Path

TIMEOUT = 20.0  # s: the longest a test waits for one message (a loaded machine is slow; a hang still fails)


def file_uri(path: Path) -> str:
    return path.resolve().as_uri()


class Client:
    def __init__(self, command=None):
        command = command or [sys.executable, "-c", "from isaac.cli import entry; entry()", "lsp"]
        self.process = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                        stderr=subprocess.PIPE, env={**os.environ, "PYTHONUNBUFFERED": "1"})
        self.messages: queue.Queue = queue.Queue()
        self.next_id = 0
        self.notifications: list = []  # (method, params) received so far, in order
        threading.Thread(target=self._read, daemon=True).start()

    # -- framing ------------------------------------------------------------------------------------------

    def send(self, message: dict) -> None:
        body = json.dumps({"jsonrpc": "2.0", **message}).encode("utf-8")
        self.process.stdin.write(b"Content-Length: %d\r\n\r\n" % len(body) + body)
        self.process.stdin.flush()

    def _read(self) -> None:
        stream = self.process.stdout
        while True:
            length = None
            while True:
                line = stream.readline()
                if not line:
                    return  # the server closed its output
                line = line.strip()
                if not line:
                    break
                name, _, value = line.decode("ascii").partition(":")
                if name.lower() == "content-length":
                    length = int(value)
            self.messages.put(json.loads(stream.read(length)))

    def _next(self, deadline: float) -> dict:
        message = self.messages.get(timeout=max(0.0, deadline - time.monotonic()))
        if "method" in message and "id" not in message:
            self.notifications.append((message["method"], message.get("params")))
        return message

    # -- requests and notifications -----------------------------------------------------------------------

    def request(self, method: str, params) -> object:
        """Send a request; its result (an error response fails the test)."""
        self.next_id += 1
        ident = self.next_id
        self.send({"id": ident, "method": method, "params": params})
        deadline = time.monotonic() + TIMEOUT
        while True:
            message = self._next(deadline)
            if message.get("id") == ident and "method" not in message:
                assert "error" not in message, message["error"]
                return message.get("result")
            if "id" in message and "method" in message:  # a request of the server's (e.g. registration)
                self.send({"id": message["id"], "result": None})

    def notify(self, method: str, params) -> None:
        self.send({"method": method, "params": params})

    def diagnostics(self, uri: str, version: int | None = None) -> list:
        """The next diagnostics published for `uri` (of that version of the document, when given)."""
        for method, params in self.notifications:
            if method == "textDocument/publishDiagnostics" and self._wanted(params, uri, version):
                self.notifications.remove((method, params))
                return params["diagnostics"]
        deadline = time.monotonic() + TIMEOUT
        while True:
            message = self._next(deadline)
            if message.get("method") == "textDocument/publishDiagnostics" and \
                    self._wanted(message["params"], uri, version):
                self.notifications.remove((message["method"], message["params"]))
                return message["params"]["diagnostics"]

    @staticmethod
    def _wanted(params: dict, uri: str, version) -> bool:
        return params["uri"] == uri and (version is None or params.get("version") == version)

    # -- the conversation ---------------------------------------------------------------------------------

    def initialize(self, root: Path) -> dict:
        result = self.request("initialize", {"processId": os.getpid(), "rootUri": file_uri(root),
                                             "capabilities": {}})
        self.notify("initialized", {})
        return result

    def open(self, path: Path, text: str, version: int = 1) -> str:
        uri = file_uri(path)
        self.notify("textDocument/didOpen", {"textDocument": {"uri": uri, "languageId": "isaac", "version": version,
                                                              "text": text}})
        return uri

    def change(self, uri: str, text: str, version: int) -> None:
        self.notify("textDocument/didChange", {"textDocument": {"uri": uri, "version": version},
                                               "contentChanges": [{"text": text}]})

    def at(self, method: str, uri: str, line: int, character: int, **extra):
        return self.request(method, {"textDocument": {"uri": uri},
                                     "position": {"line": line, "character": character}, **extra})

    def close(self) -> int:
        """shutdown, exit; the process's exit code."""
        self.request("shutdown", None)
        self.notify("exit", None)
        try:
            return self.process.wait(timeout=TIMEOUT)
        finally:
            self.kill()

    def kill(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()
        for stream in (self.process.stdin, self.process.stdout, self.process.stderr):
            stream.close()
