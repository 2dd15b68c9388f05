"""The judge's web server: the standard library's ``ThreadingHTTPServer`` in a thread.

Every path starts with the run's secret (``/<secret>/``); any other path, or any path before
the run is known, is 404 (counted as ``dropped_wrong_secret``). Under the secret:

* ``GET /<secret>/`` the page, ``GET /<secret>/static/<file>`` its script and style (package
  data, no CDN);
* ``GET /<secret>/api/state`` what the page shows (:meth:`JudgeCore.view`);
* ``POST /<secret>/api/answer`` an answer (:meth:`JudgeCore.answer`): 200 once recorded,
  400 malformed (field and reason in the JSON body), 409 already answered or not ready;
* ``GET /<secret>/api/rollout/<candidate id>`` a simulated candidate's recorded episode
  (:mod:`localpbo_ros.rollouts`), 404 for an unknown candidate or a task without episodes.

Resources are bounded under hostile input: at most ``max_connections`` requests are handled
at once (further connections are closed at once and counted as ``dropped_http_busy``), a
request line or header may not exceed 8 KiB, bodies are read only up to
``judge.MAX_BODY_BYTES`` (larger ones are refused unread) and a silent client is cut off after
``SOCKET_TIMEOUT_S``. Nothing is logged per request; refusals go to the node's throttled
warnings and counters.
"""

from __future__ import annotations

import hmac
import json
import re
import socket
import sys
import threading
from collections.abc import Callable
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from typing import Any

from localpbo_ros.judge import MAX_BODY_BYTES, JudgeCore, Reply

SOCKET_TIMEOUT_S = 10.0
MAX_LINE = 8192
STATIC_FILES = {
    "judge.js": "text/javascript; charset=utf-8",
    "judge.css": "text/css; charset=utf-8",
}
PAGE = "judge.html"
ROLLOUT = re.compile(r"api/rollout/(0|[1-9][0-9]{0,18})")
SECURITY_HEADERS = {
    "Cache-Control": "no-store",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
    "X-Frame-Options": "DENY",
    "Content-Security-Policy": "default-src 'self'; img-src 'self' data:; frame-ancestors 'none'",
}

RolloutSource = Callable[[int], dict[str, Any] | None]
"""``candidate id -> rollout dict`` (None: unknown candidate or no episodes to show)."""


def web_file(name: str) -> bytes:
    """A file of the page (``localpbo_ros/web/``)."""
    return resources.files("localpbo_ros").joinpath("web", name).read_bytes()


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    request_queue_size = 16

    def __init__(self, address: tuple[str, int], judge: JudgeWeb, max_connections: int) -> None:
        self.judge = judge
        self.slots = threading.BoundedSemaphore(max_connections)
        family = socket.AF_INET6 if ":" in address[0] else socket.AF_INET
        self.address_family = family
        super().__init__(address, _Handler)

    def process_request(self, request: Any, client_address: Any) -> None:
        if not self.slots.acquire(blocking=False):
            self.judge.refused("http_busy", "too many connections at once")
            self.shutdown_request(request)
            return
        try:
            super().process_request(request, client_address)
        except Exception:
            self.slots.release()
            raise

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self.slots.release()

    def handle_error(self, request: Any, client_address: Any) -> None:
        exc = sys.exc_info()[1]
        if isinstance(exc, ConnectionError):  # the browser went away mid-request
            return
        self.judge.refused("http_error", f"a request failed in the server: {exc!r}"[:400])


class _Handler(BaseHTTPRequestHandler):
    server: _Server
    timeout = SOCKET_TIMEOUT_S
    protocol_version = "HTTP/1.1"
    server_version = "localpbo-judge"
    sys_version = ""

    def log_message(self, format: str, *args: Any) -> None:
        pass  # no log line per request; refusals are counted and warned (throttled)

    def _send(self, status: int, body: bytes, content_type: str) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        for key, value in SECURITY_HEADERS.items():
            self.send_header(key, value)
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, reply: Reply) -> None:
        body = json.dumps(reply.body, allow_nan=False).encode()
        self._send(reply.status, body, "application/json")

    def _refuse(self, status: int, field: str, reason: str, detail: str) -> None:
        """Send a refusal and count it (``dropped_http_<reason>``)."""
        self.server.judge.refused(f"http_{reason}", detail)
        self._json(Reply.refuse(status, field, reason, detail))

    def _not_found(self, rest: str) -> None:
        self.server.judge.refused("http_not_found", f"no such path: {rest[:80]!r}")
        self._send(404, b"not found\n", "text/plain; charset=utf-8")

    def _route(self) -> str | None:
        """The path under the secret; None when answered here (404 for a wrong secret,
        counted; a redirect from ``/<secret>`` to ``/<secret>/``)."""
        judge = self.server.judge
        secret = judge.secret()
        path = self.path.split("?", 1)[0]
        head, slash, rest = path.lstrip("/").partition("/")
        if not secret or not hmac.compare_digest(head.encode(), secret.encode()):
            judge.refused("wrong_secret", "request with a wrong or missing secret")
            self._send(404, b"not found\n", "text/plain; charset=utf-8")
            return None
        if not slash:
            self.send_response(301)
            self.send_header("Location", f"/{secret}/")
            self.send_header("Content-Length", "0")
            self.end_headers()
            return None
        return rest

    def do_GET(self) -> None:
        judge = self.server.judge
        rest = self._route()
        if rest is None:
            return
        if rest in ("", "index.html"):
            self._send(200, web_file(PAGE), "text/html; charset=utf-8")
        elif rest.startswith("static/") and rest[7:] in STATIC_FILES:
            self._send(200, web_file(rest[7:]), STATIC_FILES[rest[7:]])
        elif rest == "api/state":
            self._json(Reply(200, judge.core.view()))
        elif (match := ROLLOUT.fullmatch(rest)) is not None:
            rollout = judge.rollout(int(match.group(1)))
            if rollout is None:
                self._refuse(
                    404, "candidate_id", "no_rollout", "unknown candidate or no episode to show"
                )
            else:
                self._json(Reply(200, rollout))
        else:
            self._not_found(rest)

    do_HEAD = do_GET

    def do_POST(self) -> None:
        judge = self.server.judge
        rest = self._route()
        if rest is None:
            return
        if rest != "api/answer":
            self._not_found(rest)
            return
        length_text = self.headers.get("Content-Length", "")
        if not length_text.isdigit() or len(length_text) > 12:
            self.close_connection = True
            self._refuse(400, "body", "no_length", "a Content-Length header is required")
            return
        length = int(length_text)
        if length > MAX_BODY_BYTES:  # refused unread
            self.close_connection = True
            self._refuse(400, "body", "too_large", f"{length} bytes; at most {MAX_BODY_BYTES}")
            return
        self._json(judge.core.answer(self.rfile.read(length)))

    def parse_request(self) -> bool:
        if len(self.raw_requestline) > MAX_LINE:
            self.server.judge.refused("http_too_large", "request line too long")
            self.send_error(414)
            return False
        return super().parse_request()


class JudgeWeb:
    """The page's server for one :class:`JudgeCore` (see module docstring).

    Args:
        core: the judge's state.
        refused: counts and logs a refused request (``reason``, ``detail``).
        rollout: the rollouts of simulated candidates.
        host: bind address.
        port: bind port (0: a free one).
        max_connections: requests handled at once.

    Raises:
        OSError: the address cannot be bound.
    """

    def __init__(
        self,
        core: JudgeCore,
        refused: Callable[[str, str], None],
        rollout: RolloutSource,
        *,
        host: str,
        port: int,
        max_connections: int,
    ) -> None:
        self.core = core
        self.refused = refused
        self.rollout = rollout
        self._server = _Server((host, port), self, max_connections)
        self.host = host
        self.port = int(self._server.server_address[1])
        self._thread = threading.Thread(
            target=self._server.serve_forever, kwargs={"poll_interval": 0.1}, daemon=True
        )
        self._thread.start()

    def secret(self) -> str:
        """The current run's secret ("" before the run is known)."""
        with self.core.lock:
            return self.core.secret

    def url(self) -> str:
        """The page's address ("" before the run is known)."""
        secret = self.secret()
        if not secret:
            return ""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/{secret}/"

    def close(self) -> None:
        """Stop serving and release the port."""
        self._server.shutdown()
        self._server.server_close()
        self._thread.join(timeout=5.0)
