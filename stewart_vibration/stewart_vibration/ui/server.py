"""HTTP + WebSocket server of the planning UI (asyncio + ``websockets``; no rclpy).

One listening socket serves the page and its live WebSocket:

- ``GET /?token=T``: the page (sets an HttpOnly, SameSite=Strict cookie with the token, so the page's
  assets and WebSocket need not carry it); ``GET /static/<file>``: its assets;
  ``GET /files/<kind>/<name>``: files the backend offers (the last run's report plots);
  ``GET /ws``: the WebSocket (live frames out, commands in). All of them need the token (query
  ``token``, the cookie, or ``Authorization: Bearer T``): 401 without it for HTTP, 403 for the WebSocket,
  which also refuses a cross-site ``Origin``.
- Commands are JSON ``{"id": n, "cmd": name, "args": {...}}``; every one gets a reply
  ``{"type": "reply", "id": n, "ok": bool, "message": ..., ...}``. They are rate-limited (one bucket for
  the whole server, whatever the number of pages): ``COMMANDS`` at ``command_rate`` per second,
  ``CHECKS`` (pure computations) at ``check_rate``; ``stop`` and ``estop`` are never limited.
- ``broadcast`` (thread-safe) sends a frame to every page; a page whose previous frame is still being
  sent skips this one (a slow browser cannot back up the node).

The backend (the node) provides ``hello() -> dict`` (sent to each new page), ``command(cmd, args, reply)``
(``reply(dict)`` may be called from any thread) and ``file(kind, name) -> Path | None``.
"""

from __future__ import annotations

import asyncio
import errno
import hmac
import json
import logging
import socket
import threading
import time
from http import HTTPStatus
from http.cookies import SimpleCookie
from pathlib import Path
from typing import cast
from urllib.parse import parse_qs, urlsplit

from websockets.asyncio.server import serve
from websockets.datastructures import Headers
from websockets.http11 import Response

from ..rate_limit import RateLimiter
from . import STATIC_DIR

TOKEN_COOKIE = "stewart_ui_token"
COMMANDS = ("plan_path", "move", "start", "reset")
CHECKS = ("check_pose", "preview_vibration")
UNLIMITED = ("stop", "estop")
CONTENT_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
                 ".css": "text/css; charset=utf-8", ".png": "image/png", ".json": "application/json",
                 ".md": "text/plain; charset=utf-8", ".svg": "image/svg+xml"}
MAX_MESSAGE = 64 * 1024  # a command is small


class PortInUseError(OSError):
    """The UI's port is taken (one clear line, exit code 2)."""


def bind(host: str, port: int) -> socket.socket:
    """A listening TCP socket on host:port (port 0: any free port); PortInUseError if taken."""
    try:
        return socket.create_server((host, port), family=socket.AF_INET6 if ":" in host else socket.AF_INET)
    except OSError as exc:
        if exc.errno == errno.EADDRINUSE:
            raise PortInUseError(f"port {port} on {host} is already in use (another planning_ui?); choose another "
                                 "with -p port:=N, or -p port:=0 for any free port") from None
        raise


def request_token(path: str, headers) -> str | None:
    """The token a request carries: ``?token=``, the cookie or ``Authorization: Bearer``."""
    query = parse_qs(urlsplit(path).query)
    if query.get("token"):
        return query["token"][0]
    auth = headers.get("Authorization", "")
    if auth.lower().startswith("bearer "):
        return auth[7:].strip()
    cookie = SimpleCookie()
    try:
        cookie.load(headers.get("Cookie", ""))
    except Exception:  # noqa: BLE001 - a malformed cookie is no token
        return None
    return cookie[TOKEN_COOKIE].value if TOKEN_COOKIE in cookie else None


def token_ok(given: str | None, token: str) -> bool:
    """True when ``given`` is the access ``token`` (constant-time comparison); False for None."""
    return given is not None and hmac.compare_digest(given.encode(), token.encode())


class UiServer:
    """The page and WebSocket on ``sock`` (from ``bind``), run in a thread of its own."""

    def __init__(self, sock: socket.socket, token: str, backend, static_dir: Path = STATIC_DIR,
                 command_rate: float = 5.0, check_rate: float = 20.0, log=print):
        self.sock, self.token, self.backend, self.static_dir, self.log = sock, token, backend, static_dir, log
        self.host, self.port = sock.getsockname()[:2]
        self.limits = {"command": RateLimiter(command_rate, 2 * command_rate),
                       "check": RateLimiter(check_rate, check_rate)}
        self.clients: dict = {}  # connection -> task sending its last frame (or None)
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self._run, name="planning_ui_server", daemon=True)
        self._ready = threading.Event()
        self._stop: asyncio.Event | None = None
        self.frames_sent = self.frames_skipped = 0

    @property
    def url(self) -> str:
        """The page's address, with the access token."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/?token={self.token}"

    # -- life cycle ---------------------------------------------------------------------
    def start(self) -> None:
        """Start the server thread; returns once it serves (at most 10 s)."""
        self.thread.start()
        self._ready.wait(10.0)

    def stop(self) -> None:
        """Stop the server and join its thread (at most 5 s)."""
        if self._stop is not None and self.thread.is_alive():
            self.loop.call_soon_threadsafe(self._stop.set)
            self.thread.join(5.0)

    def _run(self) -> None:
        asyncio.set_event_loop(self.loop)
        self.loop.run_until_complete(self._main())

    async def _main(self) -> None:
        self._stop = asyncio.Event()
        async with serve(self._handler, sock=self.sock, process_request=self._process_request,
                         max_size=MAX_MESSAGE, compression=None, server_header="stewart_vibration planning_ui",
                         ping_interval=20, ping_timeout=20, logger=cast(logging.Logger, _QuietLogger())):
            self._ready.set()
            await self._stop.wait()

    # -- HTTP ---------------------------------------------------------------------------
    def _response(self, status: int, body: bytes | str, content_type: str = "text/plain; charset=utf-8",
                  **extra) -> Response:
        body = body.encode() if isinstance(body, str) else body
        headers = Headers({"Content-Type": content_type, "Content-Length": str(len(body)),
                           "Cache-Control": "no-store", "X-Content-Type-Options": "nosniff",
                           "Referrer-Policy": "no-referrer", "X-Frame-Options": "DENY", "Connection": "close"})
        if content_type.startswith("text/html"):
            headers["Content-Security-Policy"] = ("default-src 'self'; img-src 'self' data:; "
                                                  "connect-src 'self' ws: wss:; frame-ancestors 'none'")
        for key, value in extra.items():
            headers[key.replace("_", "-")] = value
        return Response(status, HTTPStatus(status).phrase, headers, body)

    def _process_request(self, connection, request):
        path = urlsplit(request.path).path
        if request.method != "GET":
            return self._response(405, "planning_ui: only GET; commands go over the WebSocket\n", Allow="GET")
        if path == "/favicon.ico":
            return self._response(204, b"")
        given = request_token(request.path, request.headers)
        authorized = token_ok(given, self.token)
        if path == "/ws":
            origin = request.headers.get("Origin")
            if not authorized:
                return self._response(403, "planning_ui: WebSocket refused: missing or wrong access token\n")
            if origin is not None and urlsplit(origin).netloc != request.headers.get("Host"):
                return self._response(403, f"planning_ui: WebSocket refused: cross-site origin {origin}\n")
            return None  # go on with the WebSocket handshake
        if not authorized:
            return self._response(401, "planning_ui: access token required: open the URL with ?token=... that "
                                       "the planning_ui node printed in its log\n",
                                  WWW_Authenticate='Bearer realm="planning_ui"')
        cookie = {}
        if urlsplit(request.path).query and given == self.token:
            cookie = {"Set_Cookie": f"{TOKEN_COOKIE}={self.token}; HttpOnly; SameSite=Strict; Path=/"}
        if path in ("/", "/index.html"):
            return self._file(self.static_dir / "index.html", **cookie)
        if path.startswith("/static/"):
            return self._file(self._inside(self.static_dir, path[len("/static/"):]))
        if path.startswith("/files/"):
            parts = path.split("/")
            found = self.backend.file(parts[2], parts[3]) if len(parts) == 4 else None
            return self._file(found)
        return self._response(404, "not found\n")

    @staticmethod
    def _inside(folder: Path, name: str) -> Path | None:
        """``folder/name`` if it is a file directly in ``folder`` (no traversal)."""
        if not name or "/" in name or name.startswith("."):
            return None
        candidate = folder / name
        return candidate if candidate.is_file() else None

    def _file(self, path: Path | None, **extra) -> Response:
        if path is None or not path.is_file():
            return self._response(404, "not found\n")
        kind = CONTENT_TYPES.get(path.suffix, "application/octet-stream")
        return self._response(200, path.read_bytes(), kind, **extra)

    # -- WebSocket ----------------------------------------------------------------------
    async def _handler(self, connection) -> None:
        self.clients[connection] = None
        try:
            await connection.send(json.dumps({"type": "hello", **self.backend.hello()}))
            async for raw in connection:
                await self._on_message(connection, raw)
        except Exception as exc:  # noqa: BLE001 - one page failing must not stop the server
            if type(exc).__name__ not in ("ConnectionClosedOK", "ConnectionClosedError"):
                self.log(f"page connection ended: {type(exc).__name__}: {exc}")
        finally:
            self.clients.pop(connection, None)

    async def _on_message(self, connection, raw) -> None:
        try:
            msg = json.loads(raw)
            ident, cmd, args = msg.get("id"), msg.get("cmd"), msg.get("args", {})
            if not isinstance(cmd, str) or not isinstance(args, dict):
                raise ValueError("expected {id, cmd, args}")
        except (ValueError, AttributeError) as exc:
            await connection.send(json.dumps({"type": "reply", "id": None, "ok": False,
                                              "message": f"malformed command: {exc}"}))
            return
        reply = self._replier(connection, ident, cmd)
        if cmd not in COMMANDS + CHECKS + UNLIMITED:
            reply({"ok": False, "message": f"unknown command {cmd!r}"})
            return
        bucket = "check" if cmd in CHECKS else "command" if cmd in COMMANDS else None
        if bucket and not self.limits[bucket].allow(time.monotonic()):
            limiter = self.limits[bucket]
            reply({"ok": False, "refused_by": "planning_ui", "message": f"rate limit: at most {limiter.rate:g} "
                   f"{'checks' if bucket == 'check' else 'commands'}/s (burst {limiter.burst:g}); try again"})
            return
        self.backend.command(cmd, args, reply)

    def _replier(self, connection, ident, cmd):
        def reply(result: dict) -> None:
            text = json.dumps({"type": "reply", "id": ident, "cmd": cmd, **result})
            self.loop.call_soon_threadsafe(self._send, connection, text)
        return reply

    def _send(self, connection, text: str) -> None:
        if connection in self.clients:
            self.loop.create_task(_quiet_send(connection, text))

    def broadcast(self, frame: dict | str) -> None:
        """Send ``frame`` to every page (from any thread); slow pages skip it."""
        text = frame if isinstance(frame, str) else json.dumps(frame)
        if self.clients:
            self.loop.call_soon_threadsafe(self._broadcast, text)

    def _broadcast(self, text: str) -> None:
        for connection, task in list(self.clients.items()):
            if task is not None and not task.done():
                self.frames_skipped += 1
                continue
            self.clients[connection] = self.loop.create_task(_quiet_send(connection, text))
            self.frames_sent += 1


async def _quiet_send(connection, text: str) -> None:
    try:
        await connection.send(text)
    except Exception:  # noqa: BLE001 - a closed page is dropped by its handler
        pass


class _QuietLogger:
    """websockets' logger: handshake failures (e.g. a refused token) are expected, not errors."""

    def __getattr__(self, name):
        return lambda *args, **kwargs: None

    def isEnabledFor(self, level):  # noqa: N802 - logging API
        return False
