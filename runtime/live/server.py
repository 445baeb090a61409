"""Live stage, the page's server: loopback only, the standard library only (http.server, one thread a request).

    GET  /              the live page (runtime/viewer: live.html, draw.js, live.js, the scene inside it)
    GET  /events        server-sent events: `frame` (poses, breath, wind, lag), `audio` (blocks as rendered),
                        `scene` (new drawing data after a re-plan), `notice`, `end`
    GET  /status.json   the run's state now: frame, time, clients, frames dropped
    POST /drag          {"body": NAME, "point": [x, y, z] (its frame), "target": [x, y, z] (world)}, or
                        {"release": true}: the mouse pulls that point of the body toward the target
    POST /parameter     {"name": NAME, "value": "45 g"}: re-plan with that parameter (a `let`)

Why server-sent events over http.server rather than a WebSocket library: the stream is one way (poses to the
page) and the page's few messages back are small POSTs; EventSource is built into every browser and
reconnects by itself; http.server's ThreadingHTTPServer holds one thread per open page, which is what a loopback
tool needs; no dependency. The server binds 127.0.0.1 and answers only requests addressed to a loopback name
(no DNS rebinding); a POST must be JSON (a form on another site cannot send it without a preflight, which is
never answered) from this server's own origin when the browser says one.

The stream keeps the newest BUFFER messages; a page that falls further behind misses the oldest (counted as
frames dropped) and goes on from the oldest it can still have.
"""
from __future__ import annotations

import json
import threading
from collections import deque
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

from isaac_ir.diagnostics import Diagnostic, SceneError

LOOPBACK = "127.0.0.1"
DEFAULT_PORT = 8766
# messages kept for a page that is behind (about two seconds of frames at 50 Hz)
BUFFER = 100
# s: a comment line on an idle stream this often (a closed page is noticed at the next write)
KEEPALIVE = 2.0
# bytes: the largest POST body taken
MAX_BODY = 1 << 16


class LiveError(SceneError):
    """A live run that cannot start (the port is taken): exit 2, with what to do."""

    def __init__(self, message: str, hint: str | None = None):
        super().__init__([Diagnostic(message, None, hint)])


class Hub:
    """The stream's messages, numbered; every page's handler waits on it for the ones it has not sent."""

    def __init__(self):
        self._cond = threading.Condition()
        self._messages: deque = deque(maxlen=BUFFER)  # (seq, kind, text, frames published up to it)
        self._seq = 0
        self._frames = 0
        self._scene = None  # (version, text) of the newest `scene` message
        self.closed = False
        self.dropped = 0  # frames that some page missed
        self.clients = 0
        self.pages = 0  # pages that ever connected

    def publish(self, kind: str, data: dict) -> None:
        text = json.dumps(data, separators=(",", ":"), allow_nan=False)
        with self._cond:
            self._seq += 1
            self._frames += kind == "frame"
            self._messages.append((self._seq, kind, text, self._frames))
            if kind == "scene":
                self._scene = (data["version"], text)
            self._cond.notify_all()

    def close(self) -> None:
        with self._cond:
            self.closed = True
            self._cond.notify_all()

    def newest(self) -> tuple:
        """(the newest message's number, frames published up to it)."""
        with self._cond:
            return self._seq, self._frames

    def scene_after(self, version: int):
        """The newest `scene` message when it is newer than the page's version, else None."""
        with self._cond:
            return self._scene[1] if self._scene is not None and self._scene[0] > version else None

    def wait(self, after: int, frames_after: int, timeout: float) -> tuple:
        """([(seq, kind, text, frames)] newer than `after`, frames missed since) once there are some, or on close
        or timeout."""
        with self._cond:
            if not self.closed and (not self._messages or self._messages[-1][0] <= after):
                self._cond.wait(timeout)
            fresh = [m for m in self._messages if m[0] > after]
            missed = 0
            if fresh and fresh[0][0] > after + 1:  # fallen out of the buffer
                missed = fresh[0][3] - (fresh[0][1] == "frame") - frames_after
                self.dropped += missed
            return fresh, missed


class Commands:
    """What the page asked for, for the run to take between two frames: the drag (the newest only) and the
    parameters to change (in order)."""

    def __init__(self):
        self._lock = threading.Lock()
        self._drag = None
        self._drag_changed = False
        self._parameters: list = []

    def drag(self, command: dict) -> None:
        with self._lock:
            self._drag = None if command.get("release") else command
            self._drag_changed = True

    def parameter(self, name: str, value: str) -> None:
        with self._lock:
            self._parameters.append((name, value))

    def take(self) -> tuple:
        """(drag changed, the drag or None, [(name, value)])."""
        with self._lock:
            out = (self._drag_changed, self._drag, self._parameters)
            self._drag_changed, self._parameters = False, []
            return out


class LiveServer:
    """The page, the stream and the commands, served from daemon threads (module docstring)."""

    def __init__(self, page: bytes, port: int | None = None, status=None):
        self.hub, self.commands = Hub(), Commands()
        self._page = page
        self._lock = threading.Lock()
        self.status = status or (lambda: {})
        handler = type("Handler", (_Handler,), {"live": self})
        try:
            self._httpd = ThreadingHTTPServer((LOOPBACK, DEFAULT_PORT if port is None else port), handler)
        except OSError as error:
            if port is not None:
                raise LiveError(f"--port {port}: cannot serve on {LOOPBACK}:{port} ({error.strerror or error})",
                                "another program (another isaac live?) has it: choose another port, or --port 0 "
                                "for any free one") from None
            self._httpd = ThreadingHTTPServer((LOOPBACK, 0), handler)  # the default is taken: any free one
        self._httpd.daemon_threads = True
        self.port = self._httpd.server_address[1]
        self.url = f"http://{LOOPBACK}:{self.port}/"
        # (a short poll: close() waits for the serving loop to notice, half a poll on average, and the run's end
        # should not; a hundred wake-ups a second cost the loop nothing it can measure)
        self._thread = threading.Thread(target=self._httpd.serve_forever, kwargs={"poll_interval": 0.01},
                                        name="isaac-live-server", daemon=True)
        self._thread.start()

    def set_page(self, page: bytes) -> None:
        with self._lock:
            self._page = page

    def page(self) -> bytes:
        with self._lock:
            return self._page

    def close(self) -> None:
        self.hub.close()
        self._httpd.shutdown()
        self._httpd.server_close()


class _Handler(BaseHTTPRequestHandler):
    live: LiveServer = None
    server_version = "isaac-live"

    def _loopback(self) -> bool:
        host = (self.headers.get("Host") or "").rsplit(":", 1)[0].strip("[]")
        if host in (LOOPBACK, "localhost", "::1"):
            return True
        self.send_error(HTTPStatus.FORBIDDEN, "the live page answers loopback addresses only")
        return False

    def do_GET(self):  # noqa: N802 (the http.server name)
        if not self._loopback():
            return
        route, _, query = self.path.partition("?")
        if route in ("/", "/index.html"):
            self._send(HTTPStatus.OK, "text/html; charset=utf-8", self.live.page())
        elif route == "/status.json":
            self._send(HTTPStatus.OK, "application/json", json.dumps(self.live.status()).encode())
        elif route == "/events":
            self._events(_query_int(query, "scene", 0))
        else:
            self.send_error(HTTPStatus.NOT_FOUND)

    def do_POST(self):  # noqa: N802
        if not self._loopback():
            return
        origin = self.headers.get("Origin")
        port = self.live.port
        if origin is not None and origin not in (f"http://{LOOPBACK}:{port}", f"http://localhost:{port}"):
            self.send_error(HTTPStatus.FORBIDDEN, "not from the live page")
            return
        if (self.headers.get("Content-Type") or "").split(";")[0].strip() != "application/json":
            self.send_error(HTTPStatus.UNSUPPORTED_MEDIA_TYPE, "JSON only")
            return
        length = int(self.headers.get("Content-Length") or 0)
        if not 0 < length <= MAX_BODY:
            self.send_error(HTTPStatus.BAD_REQUEST, "a JSON body, up to 64 KiB")
            return
        try:
            body = json.loads(self.rfile.read(length))
            if self.path == "/drag":
                self.live.commands.drag(_drag_command(body))
            elif self.path == "/parameter":
                self.live.commands.parameter(str(body["name"]), str(body["value"]))
            else:
                self.send_error(HTTPStatus.NOT_FOUND)
                return
        except (ValueError, KeyError, TypeError) as error:
            self.send_error(HTTPStatus.BAD_REQUEST, f"cannot take that: {error}")
            return
        self._send(HTTPStatus.OK, "application/json", b'{"ok":true}')

    def _send(self, status, kind: str, body: bytes) -> None:
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(body)

    def _events(self, version: int) -> None:
        hub = self.live.hub
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", "text/event-stream")
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        with hub._cond:
            hub.clients += 1
            hub.pages += 1
        try:
            after, frames = hub.newest()
            scene = hub.scene_after(version)
            if scene is not None:
                self._write("scene", scene)
            while True:
                fresh, _ = hub.wait(after, frames, KEEPALIVE)
                if not fresh:
                    if hub.closed:
                        break
                    self.wfile.write(b": idle\n\n")
                for seq, kind, text, count in fresh:
                    self._write(kind, text)
                    after, frames = seq, count
        except (BrokenPipeError, ConnectionResetError, TimeoutError, OSError):
            pass  # the page went away
        finally:
            with hub._cond:
                hub.clients -= 1

    def _write(self, kind: str, text: str) -> None:
        self.wfile.write(f"event: {kind}\ndata: {text}\n\n".encode())

    def log_message(self, format, *args):  # noqa: A002 (the http.server signature); requests are not news
        pass


def _drag_command(body: dict) -> dict:
    if body.get("release"):
        return {"release": True}
    point, target = [float(v) for v in body["point"]], [float(v) for v in body["target"]]
    if len(point) != 3 or len(target) != 3:
        raise ValueError("point and target are 3 numbers each")
    return {"body": str(body["body"]), "point": point, "target": target}


def _query_int(query: str, name: str, default: int) -> int:
    for item in query.split("&"):
        key, _, value = item.partition("=")
        if key == name and value.lstrip("-").isdigit():
            return int(value)
    return default
