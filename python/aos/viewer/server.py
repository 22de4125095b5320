"""The viewer's HTTP and WebSocket server (aiohttp).

Security model (docs/viewer.md):

* It binds 127.0.0.1 unless another host is given explicitly (the caller warns).
* Every request must name this server in its ``Host`` header (``host_allowed``: the address it
  listens on with its port, and ``localhost`` / ``127.0.0.1`` / ``[::1]`` where it serves
  loopback): 403 otherwise, so a DNS-rebinding page (its own name resolved to 127.0.0.1) cannot
  talk to it even with a leaked token. A WebSocket's ``Origin``, when sent, must be this
  ``Host``.
* Every request, the WebSocket included, must carry the session's random token (``?token=`` or
  the ``X-AOS-Token`` header), compared in constant time: 403 without it. A connection that has
  not presented the token within ``UNAUTHENTICATED_TIMEOUT_S`` of opening (nothing sent, a slow
  header, only requests without the token) is closed.
* It serves only its own page and assets, from a fixed in-package whitelist read into memory
  at start (``ASSETS``): no path from a request ever reaches the file system.
* Parameters are validated (session.Params): a bad one answers 400 with the message, and the
  server goes on. Request bodies are limited to ``MAX_BODY_BYTES`` (413 beyond), WebSocket
  messages to the same; JSON nested deeper than ``MAX_JSON_DEPTH`` is refused (400). Any other
  failure of a handler answers 500 with one line, never a traceback.
* Renders are bounded: one render worker thread (``render_workers``) runs them one at a time;
  each WebSocket keeps only its newest request (a newer one supersedes the pending one, and
  cancels a running full-size render at its next progress check, at most 0.1 s apart; a running
  preview finishes, so that images keep coming while the user drags), at most ``max_pages``
  WebSockets are open (the next one is told so and closed), and at most ``MAX_QUEUED_HTTP``
  HTTP requests that use the render worker (renders, picks, exports) wait or run (503 beyond).
* A finished focal stack is kept as a zip file in the server's private temporary folder (the
  newest ``MAX_DOWNLOADS``), not in memory, and the freed heap is handed back to the system
  (``release_memory``) after every all-in-focus or stack job.

Endpoints: ``/`` (the page), ``/static/<asset>``, ``/api/info``, ``/api/render`` (GET query or
POST JSON: one frame, the WebSocket's binary format), ``/api/pick``, ``/api/detect`` (aos.detect
on the current view, with any DetectOptions field in the query, read by its table: detector,
one_sided, a threshold rule, ...; later frames carry the detections as ``markers``), ``/api/export``,
``/api/command``, ``/api/download/<key>`` (a focal stack the page asked for), ``/ws`` (JSON
requests in, binary frames and JSON messages out).

Binary frame: uint32 little-endian length N of a UTF-8 JSON header (id, width, height, timings,
statistics), the header, then width * height * 4 bytes of RGBA.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import ctypes
import hmac
import ipaddress
import json
import logging
import math
import os
import re
import secrets
import shutil
import socket as socket_module
import struct
import tempfile
import threading
import time
import weakref
import zipfile
from importlib import resources
from typing import Any, Callable, Optional

from aiohttp import WSMsgType, http_exceptions, web

import aos

from . import is_loopback
from .session import (MAX_PAGES, BadParameter, Frame, Params, Session, Superseded,
                      parse_detect_options)

MAX_BODY_BYTES = 64 * 1024
# Nesting of a JSON body or message (the parameters are one flat object): deeper is refused
# before anything walks it (a 60 KB "[[[[..." would otherwise reach Python's recursion limit).
MAX_JSON_DEPTH = 8
# HTTP requests that use the render worker (renders, picks, exports) waiting or running.
MAX_QUEUED_HTTP = 64
# Seconds a connection may stay open without presenting the token (nothing sent, a header
# trickled in, or only refused requests) before the server closes it.
UNAUTHENTICATED_TIMEOUT_S = 10.0
MAX_DOWNLOADS = 2  # focal stacks kept for download (zip files in the server's temporary folder)
MAX_STACK_BYTES = 1 << 30  # one focal-stack request's slices in memory
TOKEN_HEADER = "X-AOS-Token"

log = logging.getLogger("aos.viewer")


class _MalformedRequestsInOneLine(logging.Filter):
    """aiohttp answers a malformed request (a request line over 8190 bytes, a bad header) with a
    400 itself, but logs it as "Error handling request" with a traceback: a client's mistake,
    not the server's. Such records become one warning line without the traceback."""

    def filter(self, record: logging.LogRecord) -> bool:
        error = record.exc_info[1] if record.exc_info else None
        if isinstance(error, http_exceptions.HttpProcessingError):
            message = " ".join(str(error).split())[:200]
            record.msg, record.args = "refused a malformed request: %s", (message,)
            record.exc_info, record.exc_text = None, None
            record.levelno, record.levelname = logging.WARNING, "WARNING"
        return True


logging.getLogger("aiohttp.server").addFilter(_MalformedRequestsInOneLine())

# The whole set of files the server can send: request name -> (package file, content type).
ASSET_FILES = {
    "index.html": ("index.html", "text/html; charset=utf-8"),
    "viewer.js": ("viewer.js", "text/javascript; charset=utf-8"),
    "viewer.css": ("viewer.css", "text/css; charset=utf-8"),
    "live.html": ("live.html", "text/html; charset=utf-8"),
    "live.js": ("live.js", "text/javascript; charset=utf-8"),
}
# How long /api/live waits for an update newer than the page's before answering the current one.
LIVE_WAIT_S = 10.0
# Live requests waiting at once (each holds a thread of the live pool while it waits).
MAX_LIVE_WAITERS = 32


def load_assets() -> dict[str, tuple[bytes, str]]:
    folder = resources.files("aos.viewer") / "static"
    return {name: ((folder / file).read_bytes(), kind)
            for name, (file, kind) in ASSET_FILES.items()}


def encode_frame(frame: Frame, header: dict[str, Any]) -> bytes:
    text = json.dumps({**frame.info, **header}).encode()
    return struct.pack("<I", len(text)) + text + frame.rgba


def _security_headers(response: web.StreamResponse) -> None:
    response.headers["Cache-Control"] = "no-store"
    response.headers["X-Content-Type-Options"] = "nosniff"
    response.headers["Referrer-Policy"] = "no-referrer"
    response.headers["X-Frame-Options"] = "SAMEORIGIN"
    response.headers["Content-Security-Policy"] = (
        "default-src 'self'; img-src 'self' data: blob:; connect-src 'self'; "
        "style-src 'self'; script-src 'self'; frame-ancestors 'self'")


def _bad(message: str, status: int = 400) -> web.Response:
    response = web.json_response({"error": message}, status=status)
    _security_headers(response)
    return response


def parse_json(text: str | bytes, what: str) -> Any:
    """A request body or WebSocket message as JSON; BadParameter (naming ``what``) when it is
    not JSON, holds a number no float can hold (1e999, NaN, Infinity: echoed back they would
    not be JSON) or is nested deeper than MAX_JSON_DEPTH."""
    def finite(literal: str) -> float:
        number = float(literal)
        if not math.isfinite(number):
            raise BadParameter(f"{what}: the number {literal[:40]} is not finite")
        return number

    def constant(literal: str) -> float:
        raise BadParameter(f"{what}: {literal} is not a JSON number")

    try:
        value = json.loads(text, parse_float=finite, parse_int=int, parse_constant=constant)
    except BadParameter:
        raise
    except RecursionError:  # deeper than the interpreter's recursion limit
        raise BadParameter(f"{what}: JSON nested more than {MAX_JSON_DEPTH} deep") from None
    except (ValueError, UnicodeDecodeError):
        raise BadParameter(f"{what}: not JSON") from None
    # Walked without recursion: what later code does with the value (str(), repr) recurses.
    pending = [(value, 1)]
    while pending:
        item, depth = pending.pop()
        if isinstance(item, (list, dict)):
            if depth > MAX_JSON_DEPTH:
                raise BadParameter(f"{what}: JSON nested more than {MAX_JSON_DEPTH} deep")
            children = item.values() if isinstance(item, dict) else item
            pending.extend((child, depth + 1) for child in children)
    return value


_malloc_trim: Optional[Callable[[int], int]] = None


def release_memory() -> None:
    """Hands the freed heap back to the system (glibc's malloc_trim; nothing elsewhere). A
    finished focal stack's slices are freed when the job ends, but glibc keeps freed blocks in
    its arenas for reuse (large ones too, once its mmap threshold has grown past their size),
    so without this the process stays at the job's peak resident size."""
    global _malloc_trim
    if _malloc_trim is None:
        try:
            _malloc_trim = ctypes.CDLL(None).malloc_trim
        except (OSError, AttributeError):  # not glibc
            _malloc_trim = lambda _pad: 0  # noqa: E731
    _malloc_trim(0)


class Viewer:
    """The server's state: the session, the token, the render worker."""

    def __init__(self, session: Optional[Session], token: str, render_workers: int = 1,
                 max_pages: int = MAX_PAGES, live: Any = None) -> None:
        if render_workers < 1:
            raise ValueError(f"render_workers: must be >= 1, got {render_workers}")
        if isinstance(max_pages, bool) or not isinstance(max_pages, int) or max_pages < 1:
            raise ValueError(f"max_pages: must be an integer >= 1, got {max_pages!r}")
        if (session is None) == (live is None):
            raise ValueError("viewer: give a session or a live feed (one of them)")
        self.session = session
        # A live feed (viewer/live.py) serves the live page instead of the session's.
        self.live = live
        self.live_waiters = 0
        self.live_executor = concurrent.futures.ThreadPoolExecutor(
            max_workers=2, thread_name_prefix="aos-live") if live is not None else None
        self.token = token
        self.max_pages = max_pages
        self.assets = load_assets()
        self.executor = concurrent.futures.ThreadPoolExecutor(
            max_workers=render_workers, thread_name_prefix="aos-render")
        self.queued_http = 0
        self.stats = {"renders": 0, "superseded": 0, "dropped": 0, "errors": 0,
                      "refused_pages": 0, "closed_unauthenticated": 0}
        self.sockets: set[web.WebSocketResponse] = set()
        # Where the server listens (listening_at): the Host header values that name it.
        self.port = -1
        self.host_names: frozenset[str] = frozenset()
        self.any_ip_host = False
        # Connections (their transports) that presented the token; the others are closed
        # UNAUTHENTICATED_TIMEOUT_S after they opened.
        self.authenticated: "weakref.WeakSet[Any]" = weakref.WeakSet()
        # Focal stacks waiting to be downloaded: random key -> zip file in download_folder (the
        # newest MAX_DOWNLOADS; the folder is made at the first and removed by close()).
        self.downloads: dict[str, str] = {}
        self.download_folder = ""

    def listening_at(self, host: str, bound_address: str, port: int) -> None:
        """Called once the socket listens on ``bound_address``:``port`` (``host`` as the caller
        gave it). Accepted Host names: that host and address; where it serves loopback (a
        loopback or wildcard address), also localhost, 127.0.0.1 and ::1; on a wildcard address
        (0.0.0.0, ::) also this machine's name and any IP address literal (a DNS-rebinding page
        reaches a server by a name of the attacker's, never by an IP literal)."""
        wildcard = bound_address in ("0.0.0.0", "::", "")
        names = {host.strip("[]").lower(), bound_address.lower()}
        if wildcard or is_loopback(host) or is_loopback(bound_address):
            names |= {"localhost", "127.0.0.1", "::1"}
        if wildcard:
            names.add(socket_module.gethostname().lower())
        self.host_names = frozenset(name for name in names if name)
        self.any_ip_host = wildcard
        self.port = port

    def host_allowed(self, header: Optional[str]) -> bool:
        """Whether a Host header names this server (see listening_at)."""
        text = (header or "").strip().lower()
        if text.startswith("["):  # [IPv6]:port
            name, _, rest = text[1:].partition("]")
        else:
            name, colon, port_text = text.partition(":")
            rest = colon + port_text
        if rest == "":
            port = 80  # a browser leaves out the default port
        elif re.fullmatch(r":[0-9]{1,5}", rest):
            port = int(rest[1:])
        else:
            return False
        if port != self.port or not name:
            return False
        if name in self.host_names:
            return True
        if self.any_ip_host:
            try:
                ipaddress.ip_address(name)
                return True
            except ValueError:
                return False
        return False

    async def watch_connections(self, connections: Callable[[], list[Any]]) -> None:
        """Runs until cancelled: closes every connection (``connections()``: aiohttp's
        handlers, web.Server.connections) that has not presented the token
        UNAUTHENTICATED_TIMEOUT_S after it was first seen (polled at most a quarter of that
        apart). An authenticated one is left to aiohttp's keep-alive timeout, a WebSocket to
        its heartbeat."""
        first_seen: dict[Any, float] = {}
        while True:
            now = time.monotonic()
            still_open = set()
            for handler in connections():
                transport = getattr(handler, "transport", None)
                if transport is None or transport.is_closing():
                    continue
                still_open.add(transport)
                seen = first_seen.setdefault(transport, now)
                if (now - seen >= UNAUTHENTICATED_TIMEOUT_S
                        and transport not in self.authenticated):
                    self.stats["closed_unauthenticated"] += 1
                    transport.abort()
            for transport in [t for t in first_seen if t not in still_open]:
                del first_seen[transport]
            await asyncio.sleep(min(1.0, UNAUTHENTICATED_TIMEOUT_S / 4))

    def offer_download(self, key: str, path: str) -> None:
        self.downloads[key] = path
        while len(self.downloads) > MAX_DOWNLOADS:
            _remove_file(self.downloads.pop(next(iter(self.downloads))))

    def new_download_path(self) -> tuple[str, str]:
        """A fresh key and the path its zip is to be written to (in the private folder)."""
        if not self.download_folder:
            self.download_folder = tempfile.mkdtemp(prefix="aos-viewer-")  # mode 0700
        key = secrets.token_urlsafe(16)
        return key, os.path.join(self.download_folder, f"{key}.zip")

    def authorised(self, request: web.Request) -> bool:
        given = request.query.get("token") or request.headers.get(TOKEN_HEADER) or ""
        return hmac.compare_digest(given.encode(), self.token.encode())

    async def run(self, function: Any, *args: Any) -> Any:
        loop = asyncio.get_running_loop()
        return await loop.run_in_executor(self.executor, function, *args)

    async def run_request(self, function: Any, *args: Any) -> Any:
        """An HTTP request's work on the render worker, counted in MAX_QUEUED_HTTP (renders,
        picks and exports alike): 503 when that many wait or run already."""
        if self.queued_http >= MAX_QUEUED_HTTP:
            raise web.HTTPServiceUnavailable(
                reason=f"busy: {MAX_QUEUED_HTTP} requests are waiting for the render worker; "
                       "try again")
        self.queued_http += 1
        try:
            return await self.run(function, *args)
        finally:
            self.queued_http -= 1

    # ---- the app ----

    def app(self) -> web.Application:
        @web.middleware
        async def guard(request: web.Request, handler: Any) -> web.StreamResponse:
            host = request.headers.get("Host")
            if not self.host_allowed(host):
                return _bad(f"forbidden: the Host header {str(host)[:60]!r} does not name this "
                            f"viewer (127.0.0.1:{self.port}, localhost:{self.port} or the "
                            "address it listens on)", 403)
            if not self.authorised(request):
                return _bad("forbidden: this viewer needs its session token (the URL it "
                            "printed)", 403)
            if request.transport is not None:
                self.authenticated.add(request.transport)
            try:
                response = await handler(request)
            except web.HTTPException as error:
                if error.status >= 400:
                    return _bad(error.reason or "error", error.status)
                raise
            except BadParameter as error:
                return _bad(str(error))
            except Exception as error:  # noqa: BLE001 - one line to the client, never a traceback
                log.exception("viewer: %s %s failed", request.method, request.path)
                return _bad(f"internal error ({type(error).__name__}); the server goes on", 500)
            _security_headers(response)
            return response

        app = web.Application(middlewares=[guard], client_max_size=MAX_BODY_BYTES)
        app.router.add_get("/", self.page)
        app.router.add_get("/static/{name}", self.asset)
        if self.live is not None:
            app.router.add_get("/api/live", self.live_state)
            app.router.add_get("/api/live/image", self.live_image)
            return app
        app.router.add_get("/api/info", self.info)
        app.router.add_route("*", "/api/render", self.render_once)
        app.router.add_get("/api/pick", self.pick)
        app.router.add_get("/api/detect", self.detect)
        app.router.add_get("/api/export", self.export)
        app.router.add_get("/api/command", self.command)
        app.router.add_get("/api/download/{key}", self.download)
        app.router.add_get("/ws", self.websocket)
        app.on_shutdown.append(self._close_sockets)
        return app

    async def _close_sockets(self, _app: web.Application) -> None:
        for socket in list(self.sockets):
            if socket.prepared:
                await socket.close()

    def close(self) -> None:
        self.executor.shutdown(wait=True, cancel_futures=True)
        if self.live_executor is not None:
            self.live_executor.shutdown(wait=False, cancel_futures=True)
            self.live.close()
        self.downloads.clear()
        if self.download_folder:
            shutil.rmtree(self.download_folder, ignore_errors=True)

    # ---- static ----

    async def page(self, request: web.Request) -> web.Response:
        body, kind = self.assets["live.html" if self.live is not None else "index.html"]
        # The assets' URLs carry the token too (it is URL-safe base64: no escaping needed).
        body = body.replace(b"{{TOKEN}}", self.token.encode())
        return web.Response(body=body, content_type=kind.split(";")[0], charset="utf-8")

    async def asset(self, request: web.Request) -> web.Response:
        # A name from the whitelist, never a path: anything else (../, %2e%2e, index.html?x)
        # is simply not a key of the dict.
        found = self.assets.get(request.match_info["name"])
        if found is None or request.match_info["name"] in ("index.html", "live.html"):
            return _bad("not found", 404)
        body, kind = found
        return web.Response(body=body, content_type=kind.split(";")[0], charset="utf-8")

    # ---- live ----

    async def live_state(self, request: web.Request) -> web.Response:
        """The newest update's state (JSON) once it is newer than ``after`` (the page's), or
        after LIVE_WAIT_S the current one; 204 before the first update."""
        after = request.query.get("after", "0")
        if not re.fullmatch(r"[0-9]{1,12}", after):
            raise BadParameter("after: an update number (a whole number >= 0)")
        if self.live_waiters >= MAX_LIVE_WAITERS:
            raise web.HTTPServiceUnavailable(reason=f"busy: {MAX_LIVE_WAITERS} live requests "
                                                    "are waiting; try again")
        self.live_waiters += 1
        try:
            # The wait is the event loop's (no thread held); each look at the feed is a short
            # call on the live pool (it may read a file or encode a PNG).
            loop = asyncio.get_running_loop()
            deadline = loop.time() + LIVE_WAIT_S
            while True:
                snapshot = await loop.run_in_executor(self.live_executor, self.live.snapshot)
                if (snapshot is not None and snapshot[0] > int(after)) or loop.time() >= deadline:
                    break
                await asyncio.sleep(self.live.poll_s)
        finally:
            self.live_waiters -= 1
        if snapshot is None:
            return web.Response(status=204)
        return web.Response(body=snapshot[1], content_type="application/json")

    async def live_image(self, request: web.Request) -> web.Response:
        """The newest update's image (PNG): the integral with its detections boxed."""
        snapshot = self.live.current()  # what /api/live last answered: never waits
        if snapshot is None or not snapshot[2]:
            return _bad("no image yet", 404)
        response = web.Response(body=snapshot[2], content_type="image/png")
        response.headers["X-AOS-Update"] = str(snapshot[0])
        return response

    # ---- requests ----

    async def _params(self, request: web.Request,
                      apart: Optional[dict[str, Any]] = None) -> dict[str, Any]:
        """The request's view parameters (JSON body and query). With ``apart``, the query's
        DetectOptions fields go there instead (/api/detect)."""
        raw: dict[str, Any] = {}
        if request.method == "POST":
            body = parse_json(await request.read(), "body")  # 413 beyond MAX_BODY_BYTES
            if not isinstance(body, dict):
                raise BadParameter("body: expected a JSON object of parameters")
            raw.update(body)
        elif request.method != "GET":
            raise web.HTTPMethodNotAllowed(request.method, ["GET", "POST"])
        for key, value in request.query.items():
            if key in ("token", "u", "v", "format"):
                continue
            if apart is not None and key in aos.DetectOptions._fields:
                apart[key] = value
            else:
                raw[key] = value
        return raw

    async def info(self, request: web.Request) -> web.Response:
        return web.json_response(self.session.info())

    async def render_once(self, request: web.Request) -> web.Response:
        params = self.session.parse(await self._params(request))
        frame = await self.run_request(self.session.render, params)
        self.stats["renders"] += 1
        return web.Response(body=encode_frame(frame, {"id": None}),
                            content_type="application/octet-stream")

    async def pick(self, request: web.Request) -> web.Response:
        params = self.session.parse(await self._params(request))
        u = _finite(request.query.get("u"), "u")
        v = _finite(request.query.get("v"), "v")
        answer = await self.run_request(self.session.pick, params, u, v)
        return web.json_response(answer)

    async def detect(self, request: web.Request) -> web.Response:
        # The detector's fields by DetectOptions' own table (detector, one_sided, a threshold
        # rule, min_temperature_c, ...): every field the CLI and Python take.
        detect: dict[str, Any] = {}
        params = self.session.parse(await self._params(request, detect))
        options = parse_detect_options(detect)
        answer = await self.run_request(self.session.detect, params, options)
        return web.json_response(answer)

    async def export(self, request: web.Request) -> web.Response:
        params = self.session.parse(await self._params(request))
        kind = request.query.get("format", "png")
        body, content_type, name = await self.run_request(self.session.export, params, kind)
        response = web.Response(body=body, content_type=content_type)
        response.headers["Content-Disposition"] = f'attachment; filename="{name}"'
        return response

    async def download(self, request: web.Request) -> web.StreamResponse:
        # A key the server made (a dict lookup, never a path).
        path = self.downloads.get(request.match_info["key"])
        if path is None or not os.path.isfile(path):
            return _bad("not found (a focal stack is kept for the newest few requests)", 404)
        response = web.FileResponse(path, headers={"Content-Type": "application/zip"})
        response.headers["Content-Disposition"] = 'attachment; filename="aos-focal-stack.zip"'
        return response

    async def command(self, request: web.Request) -> web.Response:
        params = self.session.parse(await self._params(request))
        return web.json_response(self.session.command(params))

    # ---- the WebSocket: the image stream ----

    async def websocket(self, request: web.Request) -> web.StreamResponse:
        # The Host header names this server (the guard checked it), so an Origin equal to it is
        # this server's page.
        origin = request.headers.get("Origin")
        host = request.headers.get("Host", "")
        if origin is not None and origin.lower() not in (f"http://{host}".lower(),
                                                         f"https://{host}".lower()):
            return _bad("forbidden: cross-origin WebSocket", 403)
        socket = web.WebSocketResponse(max_msg_size=MAX_BODY_BYTES, heartbeat=30.0)
        if len(self.sockets) >= self.max_pages:
            # Accepted only to say why (a browser sees no status of a refused handshake).
            self.stats["refused_pages"] += 1
            await socket.prepare(request)
            reason = (f"refused: this viewer serves at most {self.max_pages} open pages "
                      "(max_pages); close one and reload")
            await socket.send_str(json.dumps({"type": "error", "id": None, "message": reason}))
            await socket.close(code=1013, message=reason.encode()[:120])  # 1013: try again later
            return socket
        self.sockets.add(socket)  # before prepare: the count holds while it is awaited
        stream = _Stream(self, socket)
        try:
            await socket.prepare(request)
            async for message in socket:
                if message.type != WSMsgType.TEXT:
                    if message.type == WSMsgType.ERROR:
                        break
                    await stream.error(None, "messages must be JSON text")
                    continue
                try:
                    await stream.receive(message.data)
                except Exception as error:  # noqa: BLE001 - one line to the page, never a traceback
                    log.exception("viewer: a WebSocket message failed")
                    await stream.error(None, f"internal error ({type(error).__name__})")
        finally:
            stream.close()
            self.sockets.discard(socket)
        return socket


def _remove_file(path: str) -> None:
    try:
        os.remove(path)
    except OSError:
        pass


def _finite(value: Optional[str], name: str, what: str = "pixel coordinate") -> float:
    try:
        number = float(value) if value is not None else math.nan
    except ValueError:
        number = math.nan
    if not math.isfinite(number):
        raise BadParameter(f"{name}: expected a finite {what}, got {str(value)[:40]!r}")
    return number


class _Stream:
    """One page's WebSocket: only its newest render request is kept (latest wins)."""

    def __init__(self, viewer: Viewer, socket: web.WebSocketResponse) -> None:
        self.viewer = viewer
        self.socket = socket
        self.pending: Optional[tuple[Any, Params]] = None
        self.generation = 0  # bumped by every request; a render checks it to cancel itself
        self.busy = False
        self.job_cancel: Optional[threading.Event] = None
        self.closed = False

    async def send_json(self, message: dict[str, Any]) -> None:
        if not self.socket.closed:
            await self.socket.send_str(json.dumps(message))

    async def error(self, request_id: Any, message: str) -> None:
        self.viewer.stats["errors"] += 1
        await self.send_json({"type": "error", "id": request_id, "message": message})

    async def receive(self, text: str) -> None:
        try:
            message = parse_json(text, "message")
        except BadParameter as error:
            await self.error(None, str(error))
            return
        if not isinstance(message, dict):
            await self.error(None, "expected a JSON object")
            return
        kind = message.get("type", "render")
        request_id = message.get("id")
        if not isinstance(request_id, (int, float, str, type(None))):
            request_id = None
        if kind == "render":
            raw = message.get("params", {})
            try:
                if not isinstance(raw, dict):
                    raise BadParameter("params: expected a JSON object")
                params = self.viewer.session.parse(raw)
            except BadParameter as error:
                await self.error(request_id, str(error))
                return
            if self.pending is not None:
                self.viewer.stats["dropped"] += 1
            self.pending = (request_id, params)
            self.generation += 1
            if not self.busy:
                self.busy = True
                asyncio.ensure_future(self._drain())
        elif kind in ("allinfocus", "stack"):
            # A task: this loop must go on reading (a "cancel" is the next message).
            if self.job_cancel is not None:
                await self.error(request_id, "an all-in-focus is already running; cancel it "
                                 "first")
                return
            self.job_cancel = threading.Event()
            asyncio.ensure_future(self._all_in_focus(request_id, message, self.job_cancel,
                                                     stack=kind == "stack"))
        elif kind == "cancel":
            if self.job_cancel is not None:
                self.job_cancel.set()
        else:
            await self.error(request_id, f"type: unknown message type {str(kind)[:20]!r}")

    async def _drain(self) -> None:
        try:
            while self.pending is not None and not self.closed:
                request_id, params = self.pending
                self.pending = None
                generation = self.generation

                # A newer request replaces the pending one; it cancels a running FULL render
                # (the input moved on), never a running preview: cancelling those on every
                # input event would starve the page of images while the user drags.
                cancellable = not params.preview

                def progress(_stage: str, _done: int, _total: int) -> None:
                    if self.closed or (cancellable and self.generation != generation):
                        raise Superseded()

                try:
                    frame = await self.viewer.run(self.viewer.session.render, params, progress)
                except Superseded:
                    self.viewer.stats["superseded"] += 1
                    continue
                except BadParameter as error:
                    await self.error(request_id, str(error))
                    continue
                except Exception as error:  # noqa: BLE001 - the page waits for an answer
                    if self.closed:  # the executor shut down with the server
                        return
                    # Any other failure is answered: the page holds its next preview until
                    # this one's frame or error comes.
                    log.exception("render failed")
                    await self.error(request_id, f"render failed: {type(error).__name__}: "
                                     f"{str(error)[:200]}")
                    continue
                self.viewer.stats["renders"] += 1
                if self.socket.closed:
                    return
                await self.socket.send_bytes(encode_frame(frame, {
                    "type": "frame", "id": request_id,
                    "stale": self.generation != generation}))
        finally:
            self.busy = False

    async def _all_in_focus(self, request_id: Any, message: dict[str, Any],
                            cancel: threading.Event, stack: bool = False) -> None:
        """A focal stack of the current view merged into an all-in-focus image (a frame), or
        (``stack``) the stack itself as a zip of its folder (write_focal_stack) offered for
        download, with progress messages; a "cancel" message (or closing the page) stops it.
        It runs on the render worker: renders wait for it."""
        try:
            await self._run_all_in_focus(request_id, message, cancel, stack)
        finally:
            self.job_cancel = None

    async def _run_all_in_focus(self, request_id: Any, message: dict[str, Any],
                                cancel: threading.Event, stack: bool) -> None:
        import aos

        session = self.viewer.session
        try:
            raw = message.get("params", {})
            if not isinstance(raw, dict):
                raise BadParameter("params: must be an object of parameters")
            params = session.parse(raw)
            first = float(message.get("first_height", "nan"))
            last = float(message.get("last_height", "nan"))
            slices_value = message.get("slices", 20)
            if not isinstance(slices_value, int) or isinstance(slices_value, bool):
                raise BadParameter(f"slices: must be an integer, got {str(slices_value)[:20]!r}")
            slices = slices_value
            if not (math.isfinite(first) and math.isfinite(last) and first != last):
                raise BadParameter("first_height, last_height: two different finite heights")
            if not 2 <= slices <= 200:
                raise BadParameter(f"slices: must be 2..200, got {slices}")
            if params.mode != "perspective":
                raise BadParameter("mode: all-in-focus needs the perspective view")
            if stack:
                # render_focal_stack keeps every slice (float32 channels + uint32 count), and the
                # zip is built in memory: bound what one request may ask for.
                camera, _ = session.camera(params)
                slice_bytes = camera.width * camera.height * (4 * session.channels + 4)
                if slices * slice_bytes > MAX_STACK_BYTES:
                    raise BadParameter(
                        f"slices: {slices} slices of {camera.width} x {camera.height} need "
                        f"{slices * slice_bytes / 2**20:.0f} MiB, more than the viewer's "
                        f"{MAX_STACK_BYTES // 2**20} MiB for a focal stack; use fewer slices or "
                        "a smaller image, or `aos-render stack`")
        except (BadParameter, TypeError, ValueError, OverflowError) as error:
            await self.error(request_id, str(error))
            return
        loop = asyncio.get_running_loop()
        last_sent = [0.0]

        def progress(stage: str, done: int, total: int) -> None:
            if cancel.is_set() or self.closed:
                raise Superseded()
            now = time.monotonic()
            if now - last_sent[0] > 0.1 or done == total:
                last_sent[0] = now
                asyncio.run_coroutine_threadsafe(self.send_json(
                    {"type": "progress", "id": request_id, "stage": stage, "done": done,
                     "total": total}), loop)

        def stack_keywords() -> dict[str, Any]:
            # The current view's camera and views; the slices span the focus slider's range:
            # heights of planes, or (focus on the surface) offsets of a terrain-following stack.
            # Every other field as the page's renders have it (session.render_options).
            options = session.integral_options(params)
            options.surface_offset = 0.0
            keywords: dict[str, Any] = dict(slices=slices, render=options, progress=progress)
            if params.surface:  # options.focal_surface is the session's surface
                keywords.update(first_offset=first, last_offset=last)
            else:
                options.focal_surface = 0.0  # the slices are the planes
                keywords.update(first_plane=first, last_plane=last)
            return keywords

        def work_stack(path: str) -> int:
            # The slices are written and zipped straight to the download file (never held as a
            # zip in memory); they are freed when this returns.
            focal_stack = aos.render_focal_stack(session.light_field, **stack_keywords())
            try:
                with tempfile.TemporaryDirectory(prefix="aos-viewer-") as folder:
                    target = os.path.join(folder, "stack")
                    aos.write_focal_stack(target, focal_stack)
                    del focal_stack
                    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED,
                                         compresslevel=1) as zip:
                        for name in sorted(os.listdir(target)):
                            zip.write(os.path.join(target, name), f"stack/{name}")
                return os.path.getsize(path)
            except BaseException:
                _remove_file(path)
                raise

        def finished(work: Callable[..., Any], *args: Any) -> Callable[[], Any]:
            # The job, then its freed memory handed back to the system: its locals (the
            # slices) are gone once it returns.
            def job() -> Any:
                try:
                    return work(*args)
                finally:
                    release_memory()
            return job

        async def run_job(work: Any) -> Any:
            # The job on the render worker; None when it was cancelled or failed (the page is
            # told either way: it must never wait for an answer that does not come).
            try:
                return await self.viewer.run(work)
            except Superseded:
                await self.send_json({"type": "cancelled", "id": request_id})
            except (ValueError, BadParameter) as error:
                await self.error(request_id, str(error))
            except Exception as error:  # noqa: BLE001 - a render or the zip failed (disk, memory)
                await self.error(request_id, f"{type(error).__name__}: {error}")
            return None

        if stack:
            key, path = self.viewer.new_download_path()
            size = await run_job(finished(work_stack, path))
            if size is None:
                return
            self.viewer.offer_download(key, path)
            await self.send_json({"type": "download", "id": request_id,
                                  "url": f"/api/download/{key}", "bytes": size})
            return

        def work() -> Frame:
            result = aos.all_in_focus(session.light_field, **stack_keywords())
            count = (result.slice >= 0).astype("uint32")
            rgba = session.display(result.image, count, params)
            return Frame(rgba.tobytes(), rgba.shape[1], rgba.shape[0],
                         {"width": rgba.shape[1], "height": rgba.shape[0], "mode": "allinfocus"})

        frame = await run_job(finished(work))
        if frame is None:
            return
        if not self.socket.closed:
            await self.socket.send_bytes(encode_frame(frame, {"type": "frame", "id": request_id,
                                                              "allinfocus": True}))

    def close(self) -> None:
        self.closed = True
        self.generation += 1
        if self.job_cancel is not None:
            self.job_cancel.set()
