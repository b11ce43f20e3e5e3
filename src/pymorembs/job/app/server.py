"""The local web server of ``pymorembs app``: the page, its files and a small JSON API.

Standard library only (:mod:`http.server`, one thread per request), bound to 127.0.0.1. The
framework was chosen by measurement (``docs/app.md``). Long work never runs on a request
thread: a job runs in a child process (:mod:`~pymorembs.job.app.runner`), the eigenfrequencies
of the opened model in a background thread.

:class:`Handler` answers each request with the handler of its route in the table
:data:`~pymorembs.job.app.routes.ROUTES` (JSON in and out; errors are ``{"error": "one line"}``
with status 400, 404 for no such route or file, 500 for a bug of the server). Only requests
addressed to 127.0.0.1 or localhost are answered, and POST bodies must be JSON objects: another
web site open in the same browser cannot drive the app.
"""

from __future__ import annotations

import json
import mimetypes
import traceback
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, unquote, urlparse

from pymorembs.errors import PymorembsError, UserError
from pymorembs.job.app.application import App
from pymorembs.job.app.routes import (
    BytesReply,
    FileReply,
    NotFound,
    Request,
    Route,
    find_route,
)


def _not_json(constant: str) -> None:
    raise ValueError(f"{constant} is not a number in JSON")


def _line(exc: Exception) -> str:
    return " ".join(str(exc).split())


class Handler(BaseHTTPRequestHandler):
    """Requests of the page; ``self.server.app`` is the :class:`App`."""

    server_version = "pymorembs-app"

    def log_message(self, format: str, *args: Any) -> None:  # quiet: the page polls
        pass

    @property
    def app(self) -> App:
        return self.server.app  # type: ignore[attr-defined]

    def _send(self, status: int, body: bytes, kind: str) -> None:
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        try:
            self.wfile.write(body)
        except (BrokenPipeError, ConnectionResetError):  # the page went away meanwhile
            pass

    def _json(self, data: Any, status: int = 200) -> None:
        body = json.dumps(data, allow_nan=False, separators=(",", ":")).encode()
        self._send(status, body, "application/json")

    def _handle(self, route: Route, request: Request) -> None:
        """Answer with what the route's handler returns, or the error in one line."""
        try:
            reply = route.handler(self.app, request)
            if isinstance(reply, FileReply):
                self._file(reply.path, reply.download)
            elif isinstance(reply, BytesReply):
                self._send(200, reply.data, reply.kind)
            else:
                self._json(reply)
        except NotFound as exc:
            self._json({"error": str(exc)}, HTTPStatus.NOT_FOUND)
        except PymorembsError as exc:
            self._json({"error": _line(exc)}, HTTPStatus.BAD_REQUEST)
        except (KeyError, TypeError, ValueError) as exc:
            self._json({"error": f"bad request: {exc}"}, HTTPStatus.BAD_REQUEST)
        except Exception as exc:  # a bug, not the user's mistake: an answer, the traceback here
            traceback.print_exc()
            self._json({"error": f"internal error: {_line(exc)}"}, HTTPStatus.INTERNAL_SERVER_ERROR)

    def _request(self) -> dict[str, Any]:
        """The POST body: a JSON object (an empty body is ``{}``).

        Raises
        ------
        UserError
            A body that is not a JSON object: invalid JSON or UTF-8, ``NaN`` or ``Infinity``
            (not JSON; the state could not be sent back), an array, a string, a number.
        """
        try:
            length = int(self.headers.get("Content-Length") or 0)
        except ValueError:
            raise UserError("bad request: Content-Length is not a number") from None
        data = self.rfile.read(length) if length > 0 else b""
        try:
            request = json.loads(data or b"{}", parse_constant=_not_json)
        except ValueError as exc:  # JSONDecodeError, UnicodeDecodeError, NaN
            raise UserError(f"bad JSON: {_line(exc)}") from None
        if not isinstance(request, dict):
            raise UserError(f"bad JSON: expected an object, got {type(request).__name__}")
        return request

    def _refused(self, post: bool) -> bool:
        """Refuse requests another web site could make through the user's browser: a foreign
        ``Host`` (DNS rebinding), and for POST any body but JSON (a cross-site form or a
        simple request; JSON needs a CORS preflight, which this server never grants)."""
        port = self.server.server_address[1]
        if self.headers.get("Host") not in (f"127.0.0.1:{port}", f"localhost:{port}"):
            self._json({"error": "requests only from this machine's page"}, HTTPStatus.FORBIDDEN)
            return True
        kind = (self.headers.get("Content-Type") or "").split(";")[0].strip()
        if post and kind != "application/json":
            self._json({"error": "send JSON"}, HTTPStatus.UNSUPPORTED_MEDIA_TYPE)
            return True
        return False

    def do_GET(self) -> None:
        if self._refused(post=False):
            return
        url = urlparse(self.path)
        query = {k: v[-1] for k, v in parse_qs(url.query).items()}
        found = find_route("GET", url.path)
        if found is None:
            return self._json({"error": f"no such page {url.path}"}, HTTPStatus.NOT_FOUND)
        route, name = found
        self._handle(route, Request(query=query, name=unquote(name)))

    def do_POST(self) -> None:
        if self._refused(post=True):
            return
        try:
            body = self._request()
        except UserError as exc:
            return self._json({"error": str(exc)}, HTTPStatus.BAD_REQUEST)
        path = urlparse(self.path).path
        found = find_route("POST", path)
        if found is None:
            return self._json({"error": f"no such action {path}"}, HTTPStatus.NOT_FOUND)
        route, name = found
        self._handle(route, Request(body=body, name=unquote(name)))

    def _file(self, path: Path, download: bool = False) -> None:
        if not path.is_file():
            return self._json({"error": f"no file {path.name}"}, HTTPStatus.NOT_FOUND)
        kind = mimetypes.guess_type(path.name)[0] or "application/octet-stream"
        if path.suffix == ".js":
            kind = "text/javascript"
        self.send_response(200)
        data = path.read_bytes()
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(data)))
        self.send_header("Cache-Control", "no-store")
        if download:
            self.send_header("Content-Disposition", f'attachment; filename="{path.name}"')
        self.end_headers()
        self.wfile.write(data)


def make_server(app: App, port: int) -> ThreadingHTTPServer:
    """The server of ``app`` on 127.0.0.1:``port`` (0: a free port), not yet serving.

    Raises
    ------
    UserError
        The port is in use or cannot be bound.
    """
    try:
        server = ThreadingHTTPServer(("127.0.0.1", int(port)), Handler)
    except OSError as exc:
        if exc.errno in (98, 48, 10048):  # EADDRINUSE on Linux, macOS, Windows
            raise UserError(
                f"port {port} is in use (another pymorembs app?); choose another with --port"
            ) from None
        raise UserError(f"cannot listen on 127.0.0.1:{port}: {exc.strerror}") from None
    server.daemon_threads = True
    server.app = app  # type: ignore[attr-defined]
    return server
