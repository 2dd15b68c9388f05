"""The judge's web server: the standard library's ``ThreadingHTTPServer`` in a thread.

Every path starts with the run's secret (``/<secret>/``); any other path, or any path before
the run is known, is 404 (counted as ``dropped_wrong_secret``). Under the secret:

* ``GET /<secret>/`` the page, ``GET /<secret>/static/<file>`` its script and style (package
  data, no CDN);
* ``GET /<secret>/api/state`` what the page shows (:meth:`JudgeCore.view`);
* ``GET /<secret>/api/events`` the same state pushed as server-sent events
  (``text/event-stream``): one ``data:`` line of JSON at once and again the moment anything
  changes (a comment every ``KEEPALIVE_S`` otherwise); the browser's ``EventSource``
  reconnects by itself (``retry: 1000``), e.g. to a resumed run on the same port. At most
  ``MAX_STREAMS`` streams at once (503 beyond);
* ``POST /<secret>/api/answer`` an answer (:meth:`JudgeCore.answer`): 200 once recorded,
  400 malformed (field and reason in the JSON body), 409 already answered or not ready;
* ``POST /<secret>/api/undo`` take back the latest answer (:meth:`JudgeCore.undo`);
* ``GET /<secret>/api/rollout/<candidate id>`` a simulated candidate's recorded episode
  (:mod:`localpbo_ros.rollouts`), 404 for an unknown candidate or a task without episodes.

Resources are bounded under hostile input: at most ``max_connections`` requests are handled
at once (further connections are closed at once and counted as ``dropped_http_busy``); a
request line longer than ``MAX_LINE`` (8 KiB) gets 414 and the header block (all lines
together) larger than ``MAX_HEADERS`` (8 KiB) gets 431, both unread beyond the limit; a JSON
body with a repeated key gets 400; bodies are read only up to ``judge.MAX_BODY_BYTES`` (larger
ones are refused unread); a body that stops short of its ``Content-Length`` gets 408 after
``BODY_TIMEOUT_S`` (3 s) and the connection is closed, and a silent client is cut off after
``SOCKET_TIMEOUT_S``. Nothing is logged per request; refusals go to the node's throttled
warnings and counters.
"""

from __future__ import annotations

import functools
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
BODY_TIMEOUT_S = 3.0
"""Seconds a request body may take to arrive in full (then 408)."""
MAX_LINE = 8192
"""Bytes of the request line at most (414 beyond)."""
MAX_HEADERS = 8192
"""Bytes of the header lines together at most (431 beyond)."""
MAX_STREAMS = 8
"""Event streams served at once."""
KEEPALIVE_S = 15.0
"""Seconds between two keep-alive comments of an idle event stream."""
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
        self.streams = threading.BoundedSemaphore(MAX_STREAMS)
        self.closing = False
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
        elif rest == "api/events" and self.command == "GET":
            self._events()
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

    def _events(self) -> None:
        """Stream the page's state (server-sent events) until the client or server leaves."""
        server = self.server
        if not server.streams.acquire(blocking=False):
            self.close_connection = True
            self._refuse(503, "events", "too_many_streams", f"at most {MAX_STREAMS} at once")
            return
        core = server.judge.core
        self.close_connection = True
        try:
            self.send_response(200)
            self.send_header("Content-Type", "text/event-stream; charset=utf-8")
            for key, value in SECURITY_HEADERS.items():
                self.send_header(key, value)
            self.send_header("Connection", "close")
            self.end_headers()
            self.wfile.write(b"retry: 1000\n\n")
            seen = -1
            while not server.closing:
                with core.changed:
                    if core.version == seen:
                        core.changed.wait_for(
                            functools.partial(_moved_on, core, server, seen), timeout=KEEPALIVE_S
                        )
                    if server.closing:
                        break
                    if core.version == seen:
                        chunk = b": keep-alive\n\n"
                    else:
                        seen = core.version
                        state = json.dumps(core.view(), allow_nan=False, separators=(",", ":"))
                        chunk = b"data: " + state.encode() + b"\n\n"
                self.wfile.write(chunk)
                self.wfile.flush()
        except (ConnectionError, TimeoutError, OSError):
            pass  # the page went away; it reconnects by itself
        finally:
            server.streams.release()

    def do_POST(self) -> None:
        judge = self.server.judge
        rest = self._route()
        if rest is None:
            return
        if rest not in ("api/answer", "api/undo"):
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
        self.connection.settimeout(BODY_TIMEOUT_S)
        try:
            body = self.rfile.read(length)
        except TimeoutError:
            body = b""
        finally:
            self.connection.settimeout(SOCKET_TIMEOUT_S)
        if len(body) < length:
            self.close_connection = True
            detail = f"{len(body)} of {length} bytes arrived within {BODY_TIMEOUT_S:g} s"
            self._refuse(408, "body", "body_timeout", detail)
            return
        if rest == "api/undo":
            self._json(judge.core.undo(body))
        else:
            self._json(judge.core.answer(body))

    def handle_one_request(self) -> None:
        """One request, its line read only up to ``MAX_LINE`` bytes (414 beyond)."""
        try:
            self.raw_requestline = self.rfile.readline(MAX_LINE + 1)
            if len(self.raw_requestline) > MAX_LINE:
                self.requestline, self.request_version, self.command = "", "HTTP/1.1", ""
                self.close_connection = True
                self._refuse(414, "request_line", "line_too_long", f"more than {MAX_LINE} bytes")
                return
            if not self.raw_requestline:
                self.close_connection = True
                return
            if not self.parse_request():
                return
            method = getattr(self, "do_" + self.command, None)
            if method is None:
                self.send_error(501, f"Unsupported method ({self.command!r})")
                return
            method()
            self.wfile.flush()
        except TimeoutError:
            self.close_connection = True

    def parse_request(self) -> bool:
        """The standard parse, with the header block limited to ``MAX_HEADERS`` bytes (431
        beyond, read no further)."""
        real = self.rfile
        limited = _LimitedLines(real, MAX_HEADERS + len(self.raw_requestline))
        self.rfile = limited  # type: ignore[assignment]
        try:
            ok = super().parse_request()
        finally:
            self.rfile = real
        if limited.exceeded:
            self.close_connection = True
            if not ok:  # the standard parse already answered (it saw a cut-off header)
                return False
            self._refuse(431, "headers", "headers_too_large", f"more than {MAX_HEADERS} bytes")
            return False
        return ok


class _LimitedLines:
    """``readline`` over a file with a byte budget; past it, the header block ends (an empty
    line) and ``exceeded`` is set."""

    def __init__(self, raw: Any, budget: int) -> None:
        self.raw = raw
        self.budget = budget
        self.exceeded = False

    def readline(self, limit: int = -1) -> bytes:
        if self.budget <= 0:
            self.exceeded = True
            return b"\r\n"
        size = self.budget + 1 if limit < 0 else min(limit, self.budget + 1)
        line = self.raw.readline(size)
        self.budget -= len(line)
        if self.budget < 0:
            self.exceeded = True
            return b"\r\n"
        return line

    def read(self, n: int = -1) -> bytes:
        return bytes(self.raw.read(n))


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
        """Stop serving (event streams end) and release the port."""
        with self.core.changed:
            self._server.closing = True
            self.core.changed.notify_all()
        self._server.shutdown()
        self._server.server_close()
        self._thread.join(timeout=5.0)


def _moved_on(core: Any, server: Any, seen: int) -> bool:
    """The page's state changed since version ``seen``, or the server closes."""
    return bool(core.version != seen or server.closing)
