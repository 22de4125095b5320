"""aos.viewer: an interactive integral-image viewer in the browser (``aos-render view``,
``aos.view``).

A local aiohttp server holds one light field in memory (frames loaded once) and renders it with
the C++ renderer (GIL released) as the page's sliders move: focus (plane height and tilt, or the
offset above a terrain), aperture, the views in use, the virtual camera (a recorded view, orbit,
pan, zoom, or the orthographic map) and the display (gain, offset, colour map). See
docs/viewer.md for the page, the security model and measured speeds.

Needs aiohttp, a dependency of the aos package (installed with it).

Example (also in a notebook; the server runs in a background thread)::

    viewer = aos.view(light_field, focal_height=21.0)
    print(viewer.url)      # http://127.0.0.1:PORT/?token=...
    viewer.stop()
"""

from __future__ import annotations

import asyncio
import html
import ipaddress
import os
import secrets
import shutil
import sys
import tempfile
import threading
import warnings
import webbrowser
from pathlib import Path
from typing import Any, Optional

import aos as _aos

from .session import MAX_PAGES, BadParameter, Params, Session

# The server's defaults: aos::ViewerOptions (cpp/aos/viewer/viewer_options.h), one definition for
# aos.view, the Viewer class and aos-render view.
_SERVED = _aos.ViewerOptions()

__all__ = ["Viewer", "view", "BadParameter", "Params", "Session", "MISSING_AIOHTTP"]

MISSING_AIOHTTP = (
    "the viewer needs aiohttp, a dependency of aos that is missing here: pip install "
    "'aiohttp>=3.9' (into the Python that aos is installed in)")


def _require_aiohttp() -> None:
    try:
        import aiohttp  # noqa: F401
    except ImportError:
        raise ImportError(MISSING_AIOHTTP) from None


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def remote_warning(host: str) -> Optional[str]:
    if is_loopback(host):
        return None
    return (f"the viewer listens on {host}, not only on this machine: anyone who can reach it "
            "and has the URL (its token) can see the light field")


def can_open_browser() -> bool:
    """Whether a browser can be shown: a desktop session (X11/Wayland), macOS or Windows."""
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


class Viewer:
    """A running viewer: ``url`` (with its token), ``stop()``; a context manager.

    The server runs its own event loop in a background thread, so the caller (a script or a
    notebook) is not blocked. In a notebook the handle shows as a link. ``max_pages``: how many
    pages (WebSockets) may be open at once; the next one is told so and closed.
    """

    def __init__(self, session: Optional[Session], *, host: str = "127.0.0.1", port: int = 0,
                 token: Optional[str] = None, render_workers: int = 1,
                 max_pages: int = MAX_PAGES, live: Any = None) -> None:
        _require_aiohttp()
        from aiohttp import web

        from .server import Viewer as _Server

        if not 0 <= port <= 65535:
            raise ValueError(f"port: must be 0 (any free port) .. 65535, got {port}")
        self.session = session
        self.host = host
        if token and (len(token) < 16 or
                      not all(c.isascii() and (c.isalnum() or c in "-_") for c in token)):
            raise ValueError("token: at least 16 URL-safe characters (A-Z, a-z, 0-9, -, _); "
                             "leave it out for a random one")
        self.token = token or secrets.token_urlsafe(24)
        self.server = _Server(session, self.token, render_workers, max_pages, live=live)
        self._loop = asyncio.new_event_loop()
        self._ready = threading.Event()
        self._stopped = threading.Event()
        self._error: Optional[BaseException] = None
        self._runner: Optional[web.AppRunner] = None
        self.port = port
        self.bound_address = ""  # the address the socket listens on, once started
        self._browser_folder = ""  # open_browser's redirect file, removed by stop()
        self._watcher: Optional["asyncio.Task[None]"] = None
        self._thread = threading.Thread(target=self._serve, name="aos-viewer", daemon=True)
        self._thread.start()
        self._ready.wait()
        if self._error is not None:
            raise self._error

    def _serve(self) -> None:
        from aiohttp import web

        asyncio.set_event_loop(self._loop)

        async def start() -> None:
            self._runner = web.AppRunner(self.server.app(), handle_signals=False,
                                         access_log=None, shutdown_timeout=1.0)
            await self._runner.setup()
            site = web.TCPSite(self._runner, self.host, self.port)
            await site.start()
            sockets = site._server.sockets if site._server else []  # type: ignore[union-attr,attr-defined]
            if sockets:
                self.bound_address = sockets[0].getsockname()[0]
                self.port = sockets[0].getsockname()[1]
            self.server.listening_at(self.host, self.bound_address, self.port)
            runner = self._runner
            self._watcher = asyncio.ensure_future(self.server.watch_connections(
                lambda: runner.server.connections if runner.server is not None else []))

        try:
            self._loop.run_until_complete(start())
        except BaseException as error:  # noqa: BLE001 - handed to the constructor
            self._error = OSError(f"view(): cannot listen on {self.host}:{self.port}: {error}")
            if self._runner is not None:
                self._loop.run_until_complete(self._runner.cleanup())
            self.server.close()
            self._loop.close()
            self._ready.set()
            return
        self._ready.set()
        self._loop.run_forever()
        try:
            if self._watcher is not None:
                self._watcher.cancel()
            if self._runner is not None:
                self._loop.run_until_complete(self._runner.cleanup())
        finally:
            self.server.close()
            self._loop.close()
            self._stopped.set()

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        if self.host in ("0.0.0.0", "::"):
            host = "127.0.0.1"
        return f"http://{host}:{self.port}/?token={self.token}"

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def stop(self, timeout: float = 10.0) -> None:
        """Stops the server (open pages lose their connection) and waits for it."""
        if self._thread.is_alive():
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(timeout)
        if self._browser_folder:
            shutil.rmtree(self._browser_folder, ignore_errors=True)
            self._browser_folder = ""

    def open_browser(self) -> str:
        """Opens the page in the desktop's browser without putting the token on any command
        line (where `ps` shows it to every local user): the browser is given a local file,
        readable by this user only (mode 0600 in a 0700 folder), that redirects to ``url``.
        Returns the file's URI; stop() removes it."""
        if not self._browser_folder:
            self._browser_folder = tempfile.mkdtemp(prefix="aos-viewer-open-")
        path = Path(self._browser_folder) / "open.html"
        url = html.escape(self.url, quote=True)
        descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(descriptor, "w", encoding="utf-8") as file:
            file.write(f'<!DOCTYPE html>\n<meta charset="utf-8">\n'
                       f'<meta http-equiv="refresh" content="0;url={url}">\n'
                       f'<title>aos viewer</title>\n<p><a href="{url}">Open the aos viewer</a>'
                       "</p>\n")
        uri = path.as_uri()
        webbrowser.open(uri)
        return uri

    def wait(self) -> None:
        """Blocks until the server stops (Ctrl-C stops it)."""
        try:
            while self._thread.is_alive():
                self._thread.join(0.5)
        except KeyboardInterrupt:
            self.stop()

    def __enter__(self) -> "Viewer":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.stop()

    def __repr__(self) -> str:
        state = "running" if self.running else "stopped"
        return f"<aos.Viewer {state} at {self.url}>"

    def _repr_html_(self) -> str:
        what = "live" if self.session is None else f"{self.session.view_count} views"
        return (f'<a href="{self.url}" target="_blank">aos viewer</a> '
                f"({'running' if self.running else 'stopped'}; {what})")


def _caller_level() -> int:
    """The stacklevel of warnings.warn that names the first frame outside the aos package (the
    user's call, through aos.view or aos.viewer.view)."""
    package = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    frame, level = sys._getframe(1), 1
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(package):
        frame, level = frame.f_back, level + 1
    return level


def view(light_field: Any = None, *, live: Any = None, focal_surface: Any = None, surface_offset: float = 0.0,
         aperture_radius: float = float("inf"), pose_view: Optional[int] = None,
         cam_from_world: Any = None, fov_deg: float = 0.0, width: int = 0, height: int = 0,
         view_indices: Optional[list[int]] = None, min_view_angle_deg: Optional[float] = None,
         num_threads: Optional[int] = None, host: str = _SERVED.host, port: int = _SERVED.port,
         open_browser: Optional[bool] = None, render_workers: int = _SERVED.render_workers,
         max_pages: int = MAX_PAGES, source: str = "",
         focal_height: Optional[float] = None, options: Any = None) -> Viewer:
    """Starts the viewer on ``light_field`` (an aos.LightField, or a path that
    aos.load_lightfield reads) and returns its handle at once (``.url``, ``.stop()``).

    ``live``: an aos.LiveIntegrator (or a viewer.live.LiveFeed) instead of a light field: the
    live page shows its newest update as frames are added (from any thread), the detections as
    markers, the tracks in a list and the flight path on a mini-map (docs/live.md); the
    render keywords do not apply then.

    The keywords are the starting values of the page's controls, with the names and meaning of
    :class:`aos.IntegralOptions`' fields: ``focal_surface`` (a number H: the plane z = H, or a
    horizontal Plane; or a path, Mesh, Heightfield or FocalSurface: the page then starts on it,
    ``surface_offset`` metres above it, and can switch to the plane z = 0), ``aperture_radius``, ``pose_view`` (default: the middle view), ``cam_from_world``
    (a fixed pose instead of the views'), ``fov_deg``, ``width``, ``height``, ``view_indices``,
    ``min_view_angle_deg``, ``num_threads``. ``host`` other than a loopback address makes it
    reachable from other machines (a warning says so). ``open_browser``: None = where a desktop
    session exists (the browser gets a local file that redirects to the URL, so the token is
    never on its command line). ``max_pages``: pages open at once (the next is refused).
    ``focal_height`` is the deprecated spelling of a number as ``focal_surface`` (it warns).
    ``options``: an aos.IntegralOptions every render starts from: the fields the page does not
    control (``lens_tolerance_px``, ``min_view_count``, ...) are taken from it as they are;
    ``min_view_angle_deg`` and ``num_threads`` given here replace its own (None: its own, or
    IntegralOptions' defaults, 1 degree and all cores).
    """
    import aos

    _require_aiohttp()
    # The server's settings first (before any frame is loaded), checked by their C++ table
    # (aos.ViewerOptions: ranges named).
    served = aos.ViewerOptions(host=host, port=port, render_workers=render_workers,
                               max_pages=max_pages, open_browser=open_browser)
    served.check()
    if live is not None:
        from .live import IntegratorFeed, LiveFeed

        if light_field is not None:
            raise TypeError("view(): give a light field or live=, not both")
        feed = live if isinstance(live, LiveFeed) else IntegratorFeed(live)
        warning = remote_warning(host)
        if warning:
            warnings.warn(warning, stacklevel=2)
        viewer = Viewer(None, host=host, port=port, render_workers=render_workers,
                        max_pages=max_pages, live=feed)
        if open_browser is None:
            open_browser = can_open_browser()
        if open_browser:
            viewer.open_browser()
        return viewer
    if isinstance(light_field, (str, os.PathLike)):
        source = source or os.fspath(light_field)
        light_field = aos.load_lightfield(os.fspath(light_field)).light_field
    if not isinstance(light_field, aos.LightField):
        raise TypeError(f"view(): light_field must be an aos.LightField or a path, not "
                        f"{type(light_field).__name__}")
    start_height = 0.0  # of the page's plane
    if focal_height is not None:
        warnings.warn("view(): focal_height= is deprecated; use focal_surface=", DeprecationWarning,
                      stacklevel=_caller_level())
        start_height = float(focal_height)
    surface = None
    surface_path = ""
    if focal_surface is not None:
        if isinstance(focal_surface, (str, os.PathLike)):
            surface_path = os.fspath(focal_surface)
            surface = aos.FocalSurface.read(surface_path)
        else:
            surface = aos.FocalSurface(focal_surface)
        if surface.kind == "plane":  # the starting plane, not a surface to switch to
            plane = surface.plane
            if plane.normal[0] != 0.0 or plane.normal[1] != 0.0:
                raise ValueError("view(): focal_surface: the viewer starts on a horizontal "
                                 "plane (a number or Plane.at_height(H)); it tilts it on the page")
            start_height, surface = float(plane.point[2]), None
        else:
            surface = surface.in_crs(light_field.crs) if light_field.crs else surface
    defaults: dict[str, Any] = {"focal_height": start_height, "surface_offset": surface_offset,
                                "aperture_radius": aperture_radius, "fov_deg": fov_deg,
                                "width": width, "height": height,
                                "surface": surface is not None}
    if pose_view is not None:
        defaults["pose_view"] = pose_view
    if options is not None and not isinstance(options, aos.IntegralOptions):
        raise TypeError(f"view(): options must be an aos.IntegralOptions, not "
                        f"{type(options).__name__}")
    if cam_from_world is not None and not isinstance(cam_from_world, aos.Rigid3d):
        raise TypeError("view(): cam_from_world must be an aos.Rigid3d")
    session = Session(light_field, source=source, surface_path=surface_path,
                      focal_surface=surface, defaults=defaults,
                      cam_from_world=cam_from_world, view_indices=view_indices,
                      min_view_angle_deg=min_view_angle_deg, num_threads=num_threads,
                      render_options=options)
    warning = remote_warning(host)
    if warning:
        warnings.warn(warning, stacklevel=2)
    viewer = Viewer(session, host=host, port=port, render_workers=render_workers,
                    max_pages=max_pages)
    if open_browser is None:
        open_browser = can_open_browser()
    if open_browser:
        viewer.open_browser()
    return viewer
