"""``python -m aos.viewer --spec JSON``: what ``aos-render view`` runs once it has checked its
command line (the native CLI parses the flags; this takes the values as one JSON object, so the
flags are declared once, in C++). Prints the URL, serves until Ctrl-C (or SIGTERM), then stops
cleanly and exits 0. Errors: one line on stderr, exit 1 (bad input) or 2 (bad spec).

Spec keys: light_field (path); load and options: aos::LoadOptions and aos::IntegralOptions in
their JSON form (cpp/aos/lightfield/options_json.h; read here by IntegralOptions.from_json, so no
field is listed twice); pose_view (index or name, "" = none), cam_from_world (12 numbers or
null), views ("" = all), focal_surface (path, "" = none): what is resolved once the light field is
loaded; viewer: aos::ViewerOptions (host, port, max_pages, render_workers, open_browser) in its
JSON form; quiet, json.
"""

from __future__ import annotations

import json
import math
import signal
import sys
import threading
from typing import Any


def _fail(message: str, code: int = 1) -> int:
    sys.stderr.write(f"aos-render view: error: {message}\n")
    return code


def _main(argv: list[str]) -> int:
    if len(argv) != 2 or argv[0] != "--spec":
        return _fail("usage: python -m aos.viewer --spec JSON (run `aos-render view`)", 2)
    try:
        spec: dict[str, Any] = json.loads(argv[1])
    except ValueError as error:
        return _fail(f"--spec: not JSON ({error})", 2)
    try:
        import aiohttp  # noqa: F401
    except ImportError:
        from . import MISSING_AIOHTTP

        return _fail(MISSING_AIOHTTP)
    import aos

    from . import Session, Viewer, can_open_browser, remote_warning
    from .session import BadParameter, parse_view_list

    quiet = bool(spec.get("quiet")) or bool(spec.get("json"))
    if spec.get("live_dir"):
        return serve_live(spec, quiet)
    try:
        options = aos.IntegralOptions.from_json(json.dumps(spec["options"]))
        load = {key: value for key, value in spec["load"].items()
                if key not in ("load_images", "num_threads")}
        loaded = aos.load_lightfield(spec["light_field"], **load,
                                     num_threads=options.num_threads)
        for note in loaded.notes:
            sys.stderr.write(f"note: {note}\n")
        light_field = loaded.light_field
        surface = None
        if spec.get("focal_surface"):
            surface = aos.FocalSurface.read(spec["focal_surface"])
            if light_field.crs:
                surface = surface.in_crs(light_field.crs)
            if not quiet:
                sys.stderr.write(f"focal surface: {surface!r}\n")
        defaults: dict[str, Any] = {
            "surface": surface is not None,
            "surface_offset": options.surface_offset,
            "focal_height": float(options.focal_surface.plane.point[2]),
            "fov_deg": options.fov_deg,
            "width": options.width, "height": options.height,
            "aperture_radius": "inf" if math.isinf(options.aperture_radius)
            else options.aperture_radius,
        }
        pose_view = str(spec.get("pose_view", ""))
        if pose_view:
            count = len(light_field)
            if pose_view.isdigit() and int(pose_view) < count:
                defaults["pose_view"] = int(pose_view)
            else:
                try:
                    defaults["pose_view"] = aos.find_view(light_field, pose_view)
                except ValueError as error:
                    raise ValueError(f"--pose-view: no view {pose_view} (the light field has "
                                     f"{count} views); by name: {error}") from None
        cam_from_world = None
        if spec.get("cam_from_world"):
            cam_from_world = aos.Rigid3d.from_matrix3x4(spec["cam_from_world"])
        views = None
        if spec.get("views"):
            views = parse_view_list(spec["views"], len(light_field))
        session = Session(light_field, source=spec["light_field"], focal_surface=surface,
                          load_options=load,
                          surface_path=spec.get("focal_surface", ""),
                          defaults=defaults, cam_from_world=cam_from_world, view_indices=views,
                          render_options=options)
        served = aos.ViewerOptions.from_json(json.dumps(spec["viewer"]))
        served.check()
        warning = remote_warning(served.host)
        if warning:
            sys.stderr.write(f"warning: {warning}\n")
        viewer = Viewer(session, host=served.host, port=served.port,
                        render_workers=served.render_workers, max_pages=served.max_pages)
    except BadParameter as error:
        return _fail(str(error))
    except (ValueError, OSError) as error:
        return _fail(str(error).splitlines()[0] if str(error) else type(error).__name__)
    except KeyError as error:
        return _fail(f"--spec: missing {error}", 2)

    # From here on a signal stops the server cleanly (exit 0), also while the browser opens.
    stop = threading.Event()

    def on_signal(_signum: int, _frame: Any) -> None:
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    if hasattr(signal, "SIGHUP"):
        signal.signal(signal.SIGHUP, on_signal)
    if spec.get("json"):
        print(json.dumps({"url": viewer.url, "host": viewer.host, "port": viewer.port,
                          "views": session.view_count}), flush=True)
    else:
        print(f"aos viewer: {session.view_count} views of {spec['light_field']} at\n"
              f"  {viewer.url}\n(Ctrl-C stops it)", flush=True)
    open_browser = served.open_browser
    if open_browser is None:
        open_browser = can_open_browser()
    if open_browser:
        viewer.open_browser()  # a redirect file: the token stays off the browser's command line

    while not stop.wait(0.5):
        if not viewer.running:
            viewer.stop()  # removes the browser's redirect file
            return _fail("the server stopped unexpectedly")
    viewer.stop()
    if not quiet:
        sys.stderr.write("aos viewer: stopped\n")
    return 0


def serve_live(spec: dict[str, Any], quiet: bool) -> int:
    """`aos-render live --view`: the live page on the state folder that command writes (spec
    keys live_dir, viewer, quiet); serves until SIGTERM or SIGINT (exit 0)."""
    import aos

    from . import Viewer, can_open_browser, remote_warning
    from .live import FolderFeed

    try:
        served = aos.ViewerOptions.from_json(json.dumps(spec["viewer"]))
        served.check()
        warning = remote_warning(served.host)
        if warning:
            sys.stderr.write(f"warning: {warning}\n")
        viewer = Viewer(None, host=served.host, port=served.port, max_pages=served.max_pages,
                        live=FolderFeed(spec["live_dir"]))
    except (ValueError, OSError) as error:
        return _fail(str(error).splitlines()[0] if str(error) else type(error).__name__)
    except KeyError as error:
        return _fail(f"--spec: missing {error}", 2)
    stop = threading.Event()
    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, lambda _signum, _frame: stop.set())
    out = sys.stderr if spec.get("url_to_stderr") else sys.stdout
    print(f"aos live page at\n  {viewer.url}", file=out, flush=True)
    open_browser = served.open_browser
    if open_browser is None:
        open_browser = can_open_browser()
    if open_browser:
        viewer.open_browser()
    while not stop.wait(0.5):
        if not viewer.running:
            viewer.stop()
            return _fail("the server stopped unexpectedly")
    viewer.stop()
    if not quiet:
        sys.stderr.write("aos live page: stopped\n")
    return 0


def main(argv: list[str]) -> int:
    """_main(), with Ctrl-C while loading answered like the other commands (exit 130)."""
    try:
        return _main(argv)
    except KeyboardInterrupt:
        sys.stderr.write("aos-render view: interrupted\n")
        return 130


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
