"""The live viewer of `isaac watch`: a loopback-only HTTP server that always holds the newest result.

    GET /             the viewer page (write.render_html) with the newest result inside it, in live mode
    GET /status.json  {"result": n, "state": "running|complete|failed|error", "message": ..., "diagnostic": ...}
    GET /data.json    the newest result's viewer data (write.viewer_data), fetched by the page when n changes

The page polls /status.json four times a second and swaps a new result in without a reload, keeping its time,
camera and play state; a bad edit shows its diagnostic over the last good result. The server binds 127.0.0.1
only and answers only requests addressed to a loopback name (no DNS rebinding).
"""
from __future__ import annotations

import json
import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

from .write import render_html

LOOPBACK = "127.0.0.1"


def empty_data(name: str) -> dict:
    """Viewer data with nothing to draw yet (the scene has not loaded once)."""
    return {"scene": name, "start": 0.0, "end": 0.0, "frame_rate": 1.0, "cameras": [], "lights": [], "bodies": [],
            "links": [], "time": "", "position": "", "orientation": "", "frames": 0, "note": "", "audio": None,
            "live": True, "result": 0}


class LiveServer:
    """Holds the newest page, data and status; serves them from a daemon thread."""

    def __init__(self, name: str, port: int = 8765):
        self._lock = threading.Lock()
        self._status = {"result": 0, "state": "starting", "message": "", "diagnostic": None}
        self._data = b""
        self._page = b""
        self.publish(empty_data(name))
        handler = type("Handler", (_Handler,), {"live": self})
        try:
            self._httpd = ThreadingHTTPServer((LOOPBACK, port), handler)
        except OSError:  # the port is taken (another watch?): any free one will do
            self._httpd = ThreadingHTTPServer((LOOPBACK, 0), handler)
        self._httpd.daemon_threads = True
        self.port = self._httpd.server_address[1]
        self.url = f"http://{LOOPBACK}:{self.port}/"
        self._thread = threading.Thread(target=self._httpd.serve_forever, name="isaac-viewer", daemon=True)
        self._thread.start()

    def publish(self, data: dict, **status) -> None:
        """A new result: its viewer data, and the status that goes with it (result number, state, message)."""
        data = dict(data, live=True)
        page = render_html(data).encode("utf-8")
        payload = json.dumps(data, separators=(",", ":"), allow_nan=False).encode("utf-8")
        with self._lock:
            self._page, self._data = page, payload
            self._status.update(status, result=data["result"])

    def set_status(self, **status) -> None:
        """The same result, news about it (a bad edit's diagnostic, a run's progress)."""
        with self._lock:
            self._status.update(status)

    def status(self) -> dict:
        with self._lock:
            return dict(self._status)

    def close(self) -> None:
        self._httpd.shutdown()
        self._httpd.server_close()

    def _get(self, route: str):
        with self._lock:
            if route in ("/", "/index.html"):
                return "text/html; charset=utf-8", self._page
            if route == "/data.json":
                return "application/json", self._data
            if route == "/status.json":
                return "application/json", json.dumps(self._status).encode("utf-8")
        return None, None


class _Handler(BaseHTTPRequestHandler):
    live: LiveServer = None
    server_version = "isaac-watch"

    def do_GET(self):  # noqa: N802 (the http.server name)
        host = (self.headers.get("Host") or "").rsplit(":", 1)[0].strip("[]")
        if host not in (LOOPBACK, "localhost", "::1"):
            self.send_error(HTTPStatus.FORBIDDEN, "the live viewer answers loopback addresses only")
            return
        kind, body = self.live._get(self.path.split("?", 1)[0])
        if body is None:
            self.send_error(HTTPStatus.NOT_FOUND)
            return
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, format, *args):  # noqa: A002 (the http.server signature); requests are not news
        pass
