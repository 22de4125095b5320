"""The viewer's server (aos.view / aos-render view) over real HTTP and WebSockets on 127.0.0.1:
the token, the asset whitelist against path traversal, parameter validation (400, and the
server goes on), body limits, picking against the geometry, latest-request-wins, the CLI hand-over
and Ctrl-C, and a short load test (20 clients; tools/bench_viewer.py --load runs the 60 s one).
Every request goes to 127.0.0.1 only; counts and durations are bounded."""

from __future__ import annotations

import asyncio
import http.client
import json
import logging
import math
import shlex
import os
import shutil
import signal
import struct
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any, Iterator, Optional

import numpy as np
import pytest

import aos

aiohttp = pytest.importorskip("aiohttp", reason="the viewer needs aiohttp (pip install aiohttp)")

from conftest import build_lightfield  # noqa: E402

from aos.viewer import Viewer  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
EXE = shutil.which("aos-render")
ALTITUDE = 10.0


def textured_lightfield() -> aos.LightField:
    """3 x 3 nadir views at 10 m over a 2 m grid, 32 x 24 pixels, a gradient image each."""
    light_field = aos.LightField()
    camera = aos.PinholeCamera.from_fov(32, 24, 60.0)
    gradient = (np.arange(32 * 24, dtype=np.float64).reshape(24, 32) % 251).astype(np.uint8)
    for j in range(3):
        for i in range(3):
            pose = aos.look_at((2.0 * i - 2.0, 2.0 * j - 2.0, ALTITUDE),
                               (2.0 * i - 2.0, 2.0 * j - 2.0, 0.0), up=(0.0, 1.0, 0.0))
            light_field.add_view(gradient, camera, pose, name=f"v{j * 3 + i}")
    return light_field


@pytest.fixture(scope="module")
def viewer() -> Iterator[Viewer]:
    handle = aos.view(textured_lightfield(), focal_surface=0.0, pose_view=4, open_browser=False,
                      num_threads=1)
    yield handle
    handle.stop()


def base(viewer: Viewer) -> str:
    return f"http://127.0.0.1:{viewer.port}"


def get(url: str, headers: Optional[dict[str, str]] = None,
        data: Optional[bytes] = None) -> tuple[int, bytes]:
    request = urllib.request.Request(url, headers=headers or {}, data=data)
    try:
        with urllib.request.urlopen(request, timeout=30) as response:
            return response.status, response.read()
    except urllib.error.HTTPError as error:
        return error.code, error.read()


def raw_get(viewer: Viewer, path: str) -> tuple[int, bytes]:
    """A GET of exactly `path` (no client-side normalisation of dots or escapes)."""
    connection = http.client.HTTPConnection("127.0.0.1", viewer.port, timeout=30)
    try:
        connection.putrequest("GET", path, skip_accept_encoding=True)
        connection.endheaders()
        response = connection.getresponse()
        return response.status, response.read()
    finally:
        connection.close()


def decode_frame(body: bytes) -> tuple[dict[str, Any], np.ndarray]:
    length = struct.unpack("<I", body[:4])[0]
    header = json.loads(body[4:4 + length])
    pixels = np.frombuffer(body[4 + length:], dtype=np.uint8)
    assert pixels.size == header["width"] * header["height"] * 4, "frame size"
    return header, pixels.reshape(header["height"], header["width"], 4)


def test_binds_loopback_with_a_random_token(viewer: Viewer) -> None:
    assert viewer.bound_address == "127.0.0.1"
    assert viewer.url.startswith(f"http://127.0.0.1:{viewer.port}/?token=")
    assert len(viewer.token) >= 32
    other = aos.view(textured_lightfield(), open_browser=False)
    try:
        assert other.token != viewer.token
    finally:
        other.stop()
    assert not other.running


def test_another_address_only_explicitly_and_with_a_warning() -> None:
    with pytest.warns(UserWarning, match="not only on this machine"):
        handle = aos.view(textured_lightfield(), host="0.0.0.0", open_browser=False)
    handle.stop()


@pytest.mark.parametrize("path", ["/", "/api/info", "/api/render", "/static/viewer.js",
                                  "/api/pick?u=1&v=1", "/api/export", "/api/command", "/nothing",
                                  "/ws"])
def test_every_request_needs_the_token(viewer: Viewer, path: str) -> None:
    separator = "&" if "?" in path else "?"
    for url in (base(viewer) + path, base(viewer) + path + separator + "token=wrong",
                base(viewer) + path + separator + "token=" + viewer.token[:-1]):
        status, body = get(url)
        assert status == 403, url
        assert b"token" in body
    status, _ = get(base(viewer) + path, headers={"X-AOS-Token": "nope"})
    assert status == 403


def test_the_page_and_its_assets_carry_the_token(viewer: Viewer) -> None:
    status, page = get(viewer.url)
    assert status == 200 and b"<canvas" in page
    assert f"static/viewer.js?token={viewer.token}".encode() in page
    for name in ("viewer.js", "viewer.css"):
        status, body = get(f"{base(viewer)}/static/{name}?token={viewer.token}")
        assert status == 200 and len(body) > 100, name
    # The header works as well as the query.
    status, _ = get(base(viewer) + "/api/info", headers={"X-AOS-Token": viewer.token})
    assert status == 200
    # Nothing is fetched from elsewhere: no absolute URLs in the page or its assets.
    for name in ("index.html", "viewer.js", "viewer.css"):
        text = (Path(aos.viewer.__file__).parent / "static" / name).read_text()
        assert "http://" not in text and "https://" not in text and "//cdn" not in text, name


TRAVERSALS = [
    "/static/../../etc/passwd",
    "/static/..%2f..%2f..%2fetc%2fpasswd",
    "/static/%2e%2e/%2e%2e/%2e%2e/etc/passwd",
    "/static/%2e%2e%2f%2e%2e%2f%2e%2e%2fetc%2fpasswd",
    "/static/%252e%252e%252fetc%252fpasswd",
    "/static/..%5c..%5c..%5cetc%5cpasswd",
    "/static/....//....//etc/passwd",
    "/static/viewer.js/../../../../etc/passwd",
    "/static//etc/passwd",
    "/static/%2fetc%2fpasswd",
    "//etc/passwd",
    "/../../../../etc/passwd",
    "/static/__init__.py",
    "/static/session.py",
    "/static/../session.py",
    "/static/..%2fsession.py",
    "/static/index.html%00.js",
    "/static/.",
    "/static/..",
]


@pytest.mark.parametrize("path", TRAVERSALS)
def test_path_traversal_finds_nothing(viewer: Viewer, path: str) -> None:
    separator = "&" if "?" in path else "?"
    status, body = raw_get(viewer, path + separator + "token=" + viewer.token)
    assert status in (400, 403, 404), (path, status)
    assert b"root:" not in body and b"import" not in body, path


BAD = [
    ({"focal_height": "abc"}, "focal_height: expected a number"),
    # The ranges are aos::ViewParams' table's (cpp/aos/viewer/viewer_options.h).
    ({"focal_height": "nan"}, "focal_height: must be in [-10000000, 10000000], got nan"),
    ({"focal_height": "inf"}, "focal_height: must be in [-10000000, 10000000], got inf"),
    ({"aperture_radius": "-1"}, "aperture_radius: must be >= 0"),
    ({"view_first": "5", "view_last": "2"}, "view_first, view_last"),
    ({"view_last": "10"}, "view_first, view_last"),
    ({"pose_view": "9"}, "pose_view: no view 9"),
    ({"pose_view": "1.5"}, "pose_view: expected a whole number"),
    ({"width": "99999"}, "width: must be in [8, 2048] or 0, got 99999"),
    ({"width": "1e12"},
     "width: must be in [8, 2048] or 0 (a 32-bit whole number), got 1000000000000"),
    ({"fov_deg": "180"}, "fov_deg: must be in [0, 179], got 180"),
    ({"tilt_x_deg": "89"}, "tilt_x_deg: must be in [-80, 80], got 89"),
    ({"gain": "0"}, "gain: must be in [0.01, 100], got 0"),
    ({"mode": "panorama"}, "mode: must be one of"),
    ({"colormap": "rainbow"}, "colormap: must be one of"),
    ({"surface": "true"}, "surface: this viewer was started without a focal surface"),
    ({"preview": "maybe"}, "preview: expected true or false"),
    ({"zoom": "2"}, "zoom: unknown parameter"),
    # A valid-looking request the renderer refuses: a focal plane through the camera centre.
    ({"focal_height": "10"}, "focal"),
]


def test_the_page_parameters_are_the_view_params_table() -> None:
    # One definition (aos::ViewParams, cpp/aos/viewer/viewer_options.h): the session validates
    # by its table, and the page's controls send exactly its fields, its selects offering
    # exactly the table's choices.
    from aos.viewer import session
    rows = {row["name"]: row for row in aos.ViewParams._field_table}
    assert session.Params is aos.ViewParams
    static = Path(aos.viewer.__file__).parent / "static"
    script = (static / "viewer.js").read_text()
    page = (static / "index.html").read_text()
    import re
    controls = set()
    for name in ("SLIDERS", "SELECTS"):
        listed = re.search(rf"const {name} = \[(.*?)\];", script, re.S)
        assert listed is not None, name
        controls |= set(re.findall(r'"(\w+)"', listed.group(1)))
    body = script[script.index("function currentParams()"):]
    body = body[:body.index("return params;")]
    controls |= set(re.findall(r"params\.(\w+) =", body))
    assert controls == set(rows) - {"preview"}, controls ^ set(rows)
    for name in ("mode", "range", "colormap"):
        select = re.search(rf'<select id="{name}">(.*?)</select>', page, re.S)
        assert select is not None, name
        offered = [value or text for value, text in
                   re.findall(r'<option(?: value="([^"]+)")?>([^<]*)</option>', select.group(1))]
        choices = rows[name]["range"].removeprefix("one of ").replace(" or ", ", ").split(", ")
        assert offered == choices, name
    assert list(session.COLORMAPS) == rows["colormap"]["range"].removeprefix(
        "one of ").replace(" or ", ", ").split(", ")


def test_the_session_checks_every_field_against_its_table_range() -> None:
    from aos.viewer.session import BadParameter, Session
    session = Session(textured_lightfield())
    rows = aos.ViewParams._field_table
    numbers = [row for row in rows if row["type"] in ("int", "float") and row["range"].startswith(
        "in [")]
    assert len(numbers) >= 12
    for row in numbers:
        low, high = (float(part) for part in
                     row["range"].split("[", 1)[1].split("]", 1)[0].split(", "))
        with pytest.raises(BadParameter, match=rf"^{row['name']}: must be in \["):
            session.parse({row["name"]: high + (1 if row["type"] == "int" else high * 1e-6 + 1)})
        # The bound itself is accepted where the view count allows it.
        if row["name"] not in ("view_first", "view_last", "pose_view"):
            session.parse({row["name"]: high})


@pytest.mark.parametrize("params, message", BAD)
def test_bad_parameters_answer_400_and_the_server_goes_on(viewer: Viewer, params: dict[str, str],
                                                          message: str) -> None:
    query = urllib.parse.urlencode({**params, "token": viewer.token})
    status, body = get(f"{base(viewer)}/api/render?{query}")
    assert status == 400, body
    assert message in json.loads(body)["error"]
    status, body = get(f"{base(viewer)}/api/render?token={viewer.token}&focal_height=1")
    assert status == 200
    header, image = decode_frame(body)
    assert (header["width"], header["height"]) == (32, 24) and image[:, :, 3].min() == 255


def test_bodies_are_size_limited(viewer: Viewer) -> None:
    url = f"{base(viewer)}/api/render?token={viewer.token}"
    status, body = get(url, headers={"Content-Type": "application/json"},
                       data=json.dumps({"focal_height": 1.0}).encode())
    assert status == 200 and decode_frame(body)[0]["width"] == 32
    status, body = get(url, headers={"Content-Type": "application/json"},
                       data=b"{" + b" " * (1 << 20) + b"}")
    assert status == 413
    status, body = get(url, headers={"Content-Type": "application/json"}, data=b"[1, 2]")
    assert status == 400 and b"JSON object" in body
    status, _ = get(f"{base(viewer)}/api/info?token={viewer.token}")
    assert status == 200


def test_preview_keeps_the_full_size_and_takes_every_kth_view_to_fit_the_budget(
        viewer: Viewer, monkeypatch: pytest.MonkeyPatch) -> None:
    """A preview (a control being dragged) is never downscaled: it is the full-size image of a
    spread subset of the views (every k-th along the flight), as many as the frame budget
    holds at the cost renders have shown, never fewer than MIN_PREVIEW_VIEWS; the image at
    rest integrates every view and equals the exact render."""
    from aos.viewer import session as session_module

    session = viewer.session
    session.preview_view_count = 1 << 30  # what renders before this test taught it: forgotten
    status, body = get(f"{base(viewer)}/api/render?token={viewer.token}&preview=true")
    header, _ = decode_frame(body)
    assert status == 200 and (header["width"], header["height"]) == (32, 24)
    assert header["preview"] is True and header["views_used"] == 9 and header["view_stride"] == 1
    # Every k-th of the selected views, the middle one of each run of k.
    monkeypatch.setattr(session_module, "MIN_PREVIEW_VIEWS", 1)
    for count, first, last, expected in ((1, 0, 9, [4]), (4, 0, 9, [1, 4, 7]),
                                         (4, 2, 9, [3, 5, 7]), (9, 0, 9, [])):
        session.preview_view_count = count
        params = session.parse({"preview": True, "view_first": first, "view_last": last})
        views, stride = session.preview_views(params)
        assert views == expected, (count, first, last)
        assert stride == (math.ceil((last - first) / count) if expected else 1)
        frame = session.render(params)
        assert (frame.width, frame.height) == (32, 24) and frame.info["view_stride"] == stride
        assert frame.info["views_used"] == (len(expected) or 9)
    # A subset that misses what the request sees (the camera over view 0, an aperture holding
    # only it; the subset is view 4): the preview takes every selected view.
    session.preview_view_count = 1
    frame = session.render(session.parse({"preview": True, "pan_x": -2.0, "pan_y": -2.0,
                                          "aperture_radius": 0.5}))
    assert frame.info["view_stride"] == 1 and frame.info["views_used"] == 1
    # A budget nothing meets: the fewest views, MIN_PREVIEW_VIEWS.
    monkeypatch.setattr(session_module, "MIN_PREVIEW_VIEWS", 3)
    monkeypatch.setattr(session_module, "FRAME_BUDGET_MS", -1.0)
    session.render(session.parse({"preview": True}))
    assert session.preview_view_count == 3
    frame = session.render(session.parse({"preview": True}))
    assert frame.info["views_used"] == 3 and frame.info["view_stride"] == 3
    # A generous one: every view.
    monkeypatch.setattr(session_module, "FRAME_BUDGET_MS", 1e9)
    session.render(session.parse({"preview": True}))
    assert session.preview_views(session.parse({"preview": True})) == ([], 1)
    # The cost model: a fixed part and a part per view, from a preview and a full render.
    session._render_costs.clear()
    monkeypatch.setattr(session_module, "FRAME_BUDGET_MS", 20.0)
    session._learn_render_cost(True, 10, 14.0, 2.0)   # 4 ms + 1 ms a view
    session._learn_render_cost(False, 100, 104.0, 2.0)
    assert session.preview_view_count == 14  # (20 - 2 - 4) / 1
    # At rest: every view, the exact render of the page's options.
    session.preview_view_count = 1
    rest = session.parse({})
    full = session.render(rest)
    assert (full.width, full.height) == (32, 24) and full.info["views_used"] == 9
    exact = aos._core.render_integral(session.light_field, session.integral_options(rest))
    raw = session.render_raw(rest)
    np.testing.assert_array_equal(raw.image, exact.image)
    np.testing.assert_array_equal(raw.count, exact.count)
    assert full.rgba == session.display(exact.image, exact.count, rest).tobytes()
    session.preview_view_count = 1 << 30


def expected_world(u: float, v: float, height: float) -> tuple[np.ndarray, float]:
    """The point where the ray through pixel (u, v) of view 4 (at (0, 0, 10), looking down)
    meets the plane z = height, and its depth."""
    camera = aos.PinholeCamera.from_fov(32, 24, 60.0)
    pose = aos.look_at((0.0, 0.0, ALTITUDE), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0))
    direction = pose.rotation.T @ np.asarray(camera.unproject((u, v)))
    depth = (ALTITUDE - height) / 1.0  # the camera looks straight down: z_cam = altitude - z
    return np.array([0.0, 0.0, ALTITUDE]) + direction * depth, depth


@pytest.mark.parametrize("u, v, height", [(16.0, 12.0, 0.0), (3.25, 20.5, 2.0),
                                          (30.0, 1.0, -3.0)])
def test_pick_gives_the_world_point_on_the_focal_plane(viewer: Viewer, u: float, v: float,
                                                       height: float) -> None:
    status, body = get(f"{base(viewer)}/api/pick?token={viewer.token}&u={u}&v={v}"
                       f"&focal_height={height}")
    assert status == 200, body
    answer = json.loads(body)
    world, depth = expected_world(u, v, height)
    np.testing.assert_allclose(answer["world"], world, atol=1e-9)
    assert answer["depth"] == pytest.approx(depth, abs=1e-9)
    assert answer["world"][2] == pytest.approx(height, abs=1e-9)
    # The count is the render's: every view sees the centre of a low plane.
    result = aos.render_integral(viewer.session.light_field, pose_view=4, focal_surface=height,
                                 num_threads=1)
    assert answer["count"] == int(result.count[int(v), int(u)])
    status, body = get(f"{base(viewer)}/api/pick?token={viewer.token}&u=40&v=1")
    assert status == 400 and b"outside" in body


def test_a_geo_referenced_light_field_reports_world_and_crs() -> None:
    light_field = textured_lightfield()
    light_field.origin = (500000.0, 5400000.0, 300.0)
    light_field.crs = "EPSG:32633"
    handle = aos.view(light_field, pose_view=4, open_browser=False, num_threads=1)
    try:
        status, body = get(f"{base(handle)}/api/pick?token={handle.token}&u=16&v=12")
        answer = json.loads(body)
        assert status == 200 and answer["crs"] == "EPSG:32633"
        np.testing.assert_allclose(answer["world"], [500000.0, 5400000.0, 300.0], atol=1e-6)
        if answer.get("lonlat") is not None:  # needs rasterio or pyproj
            # UTM 33N, easting 500000 is the central meridian, 15 degrees east.
            assert answer["lonlat"][0] == pytest.approx(15.0, abs=1e-6)
            assert 48.0 < answer["lonlat"][1] < 49.0
    finally:
        handle.stop()


def test_a_radiometric_light_field_shows_degrees_celsius() -> None:
    """Temperature frames (centikelvin): the pick reads degrees Celsius and the frame header
    gives the display range in degrees (the percentiles, not the 16-bit type's 0..655 K)."""
    light_field = aos.LightField()
    camera = aos.PinholeCamera.from_fov(32, 24, 60.0)
    kelvin = 273.15 + 10.0 + np.arange(32 * 24, dtype=np.float64).reshape(24, 32) / 32.0
    frame = np.rint(kelvin / 0.01).astype(np.uint16)
    for j in range(3):
        for i in range(3):
            pose = aos.look_at((2.0 * i - 2.0, 2.0 * j - 2.0, ALTITUDE),
                               (2.0 * i - 2.0, 2.0 * j - 2.0, 0.0), up=(0.0, 1.0, 0.0))
            light_field.add_view(frame, camera, pose, name=f"v{j * 3 + i}")
    light_field.radiometry = aos.Radiometry(0.01, 0.0)
    handle = aos.view(light_field, focal_surface=0.0, pose_view=4, open_browser=False,
                      num_threads=1)
    try:
        status, body = get(f"{base(handle)}/api/pick?token={handle.token}&u=16.5&v=12.5")
        answer = json.loads(body)
        assert status == 200 and answer["count"] > 0
        assert answer["celsius"] == pytest.approx([0.01 * answer["value"][0] - 273.15], abs=1e-9)
        assert 10.0 < answer["celsius"][0] < 35.0
        status, body = get(f"{base(handle)}/api/render?token={handle.token}")
        header, _ = decode_frame(body)
        low, high = header["display_range_c"]
        assert header["display_range"] == pytest.approx([(low + 273.15) / 0.01,
                                                         (high + 273.15) / 0.01])
        assert 10.0 <= low < high <= 34.0
    finally:
        handle.stop()


def test_map_mode_export_and_command(viewer: Viewer, tmp_path: Path) -> None:
    status, body = get(f"{base(viewer)}/api/render?token={viewer.token}&mode=map&width=40")
    header, image = decode_frame(body)
    assert status == 200 and header["width"] == 40 and len(header["geotransform"]) == 6
    for kind, magic in (("png", b"\x89PNG"), ("tiff", b"II*\x00"), ("exr", b"\x76\x2f\x31\x01"),
                        ("geotiff", b"II")):
        query = f"token={viewer.token}&format={kind}" + ("&mode=map" if kind == "geotiff" else "")
        status, body = get(f"{base(viewer)}/api/export?{query}")
        assert status == 200 and body.startswith(magic), kind
    status, body = get(f"{base(viewer)}/api/export?token={viewer.token}&format=geotiff")
    assert status == 400 and b"map view" in body
    status, body = get(f"{base(viewer)}/api/command?token={viewer.token}&focal_height=1.5"
                       "&aperture_radius=3")
    command = json.loads(body)
    assert status == 200 and command["cli"].startswith("aos-render integral ")
    # Spelled from the options the render uses, each field under its own flag (its table row).
    assert "--focal-surface 1.5" in command["cli"] and "--aperture-radius 3" in command["cli"]
    assert "--threads" not in command["cli"] and "num_threads" not in command["python"]
    # The command renders what the viewer shows: run the Python snippet.
    snippet = command["python"]
    namespace = {"aos": aos, "lf": viewer.session.light_field}
    exec(snippet, namespace)
    status, body = get(f"{base(viewer)}/api/render?token={viewer.token}&focal_height=1.5"
                       "&aperture_radius=3")
    _, shown = decode_frame(body)
    expected = np.clip(namespace["result"].image + 0.5, 0, 255).astype(np.uint8)
    np.testing.assert_array_equal(shown[:, :, 0], expected)
    # The map view's command too: the same map as the options the viewer renders it with.
    query = "mode=map&width=40&focal_height=0.5&aperture_radius=4&view_first=1&view_last=7"
    status, body = get(f"{base(viewer)}/api/command?token={viewer.token}&{query}")
    command = json.loads(body)
    assert command["cli"].startswith("aos-render map ") and "--view-indices 1:7" in command["cli"]
    namespace = {"aos": aos, "lf": viewer.session.light_field}
    exec(command["python"], namespace)
    params = viewer.session.parse(dict(part.split("=") for part in query.split("&")))
    direct = aos._core._render_map(viewer.session.light_field, viewer.session.map_options(params),
                                   "", False, True, None)
    np.testing.assert_array_equal(namespace["result"].image, direct.image)


async def _ws_session(viewer: Viewer, messages: list[dict[str, Any]], expect: int,
                      timeout: float = 30.0) -> list[Any]:
    received: list[Any] = []
    async with aiohttp.ClientSession() as client:
        async with client.ws_connect(f"{base(viewer)}/ws?token={viewer.token}") as socket:
            for message in messages:
                await socket.send_str(json.dumps(message))
            deadline = time.monotonic() + timeout
            while len(received) < expect and time.monotonic() < deadline:
                message = await socket.receive(timeout=deadline - time.monotonic())
                if message.type == aiohttp.WSMsgType.BINARY:
                    received.append(decode_frame(message.data)[0])
                elif message.type == aiohttp.WSMsgType.TEXT:
                    received.append(json.loads(message.data))
                else:
                    break
    return received


def test_websocket_needs_the_token_and_this_origin(viewer: Viewer) -> None:
    async def attempt(url: str, headers: dict[str, str]) -> int:
        async with aiohttp.ClientSession() as client:
            try:
                async with client.ws_connect(url, headers=headers):
                    return 101
            except aiohttp.WSServerHandshakeError as error:
                return error.status

    assert asyncio.run(attempt(f"{base(viewer)}/ws", {})) == 403
    assert asyncio.run(attempt(f"{base(viewer)}/ws?token=x", {})) == 403
    assert asyncio.run(attempt(f"{base(viewer)}/ws?token={viewer.token}",
                               {"Origin": "http://evil.example"})) == 403
    assert asyncio.run(attempt(f"{base(viewer)}/ws?token={viewer.token}",
                               {"Origin": base(viewer)})) == 101


def test_websocket_errors_then_frames_and_the_newest_request_wins(viewer: Viewer) -> None:
    messages = [{"type": "render", "id": 1, "params": {"focal_height": "x"}},
                {"type": "what", "id": 2}]
    messages += [{"type": "render", "id": 10 + k, "params": {"focal_height": 0.1 * k}}
                 for k in range(12)]
    received = asyncio.run(_ws_session(viewer, messages, expect=3))
    errors = [m for m in received if m.get("type") == "error"]
    assert [e["id"] for e in errors[:2]] == [1, 2]
    assert "focal_height" in errors[0]["message"]
    # Let the burst settle, then ask once more: frames come in order, the last one is the newest.
    received = asyncio.run(_ws_session(viewer, messages[2:], expect=1))
    frames = [m for m in received if m.get("type") == "frame"]
    assert frames and frames[0]["id"] >= 10
    ids = [f["id"] for f in frames]
    assert ids == sorted(ids)


def test_newer_requests_supersede_pending_ones() -> None:
    """A burst of 30 requests on one socket renders far fewer than 30 frames, ending with the
    newest (on a 384 x 384 render the single worker is busy while the burst arrives)."""
    handle = aos.view(textured_lightfield(), pose_view=4, width=384, height=288,
                      open_browser=False, num_threads=1)
    try:
        async def burst() -> list[dict[str, Any]]:
            frames: list[dict[str, Any]] = []
            async with aiohttp.ClientSession() as client:
                async with client.ws_connect(f"{base(handle)}/ws?token={handle.token}") as ws:
                    for k in range(30):
                        await ws.send_str(json.dumps({"type": "render", "id": k,
                                                      "params": {"focal_height": 0.01 * k}}))
                    while not frames or frames[-1]["id"] != 29:
                        message = await ws.receive(timeout=60)
                        assert message.type == aiohttp.WSMsgType.BINARY, message
                        frames.append(decode_frame(message.data)[0])
            return frames

        frames = asyncio.run(burst())
        assert frames[-1]["id"] == 29
        assert len(frames) < 30
        stats = handle.server.stats
        assert stats["dropped"] + stats["superseded"] >= 30 - len(frames)
    finally:
        handle.stop()


def rss_bytes() -> int:
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    return 0


async def load(viewer: Viewer, clients: int, seconds: float) -> dict[str, Any]:
    """`clients` pages, each sending a render over its WebSocket and waiting for the frame, plus
    one-shot HTTP renders, for `seconds`. Returns counts of frames, errors and bad responses, and
    the frames' RGBA bytes (`frame_bytes`)."""
    counts = {"frames": 0, "http": 0, "errors": 0, "malformed": 0, "frame_bytes": 0}
    deadline = time.monotonic() + seconds
    defaults = viewer.session.defaults
    width, height = defaults.width or 32, defaults.height or 24

    async def page(index: int) -> None:
        async with aiohttp.ClientSession() as client:
            async with client.ws_connect(f"{base(viewer)}/ws?token={viewer.token}",
                                         max_msg_size=16 << 20) as socket:
                k = 0
                while time.monotonic() < deadline:
                    k += 1
                    params = {"focal_height": (index + k) % 7 * 0.5, "preview": k % 2 == 0,
                              "aperture_radius": 1 + k % 3}
                    await socket.send_str(json.dumps({"type": "render", "id": k,
                                                      "params": params}))
                    message = await socket.receive(timeout=60)
                    if message.type != aiohttp.WSMsgType.BINARY:
                        counts["errors"] += 1
                        continue
                    try:
                        header, image = decode_frame(message.data)
                        # Previews too: the full size (of a subset of the views).
                        if header["id"] != k or (header["width"], header["height"]) != (
                                width, height):
                            raise ValueError(header)
                        counts["frames"] += 1
                        counts["frame_bytes"] += image.nbytes
                    except (ValueError, AssertionError, KeyError):
                        counts["malformed"] += 1
                    if k % 5 == 0:
                        async with client.get(f"{base(viewer)}/api/render",
                                              params={"token": viewer.token,
                                                      "focal_height": str(k % 3)}) as response:
                            body = await response.read()
                            if response.status != 200:
                                counts["errors"] += 1
                            else:
                                counts["frame_bytes"] += decode_frame(body)[1].nbytes
                                counts["http"] += 1

    await asyncio.gather(*(page(index) for index in range(clients)))
    return counts


def test_load_20_clients_no_errors_memory_flat() -> None:
    """20 pages (plus HTTP renders) for 5 s on 256 x 192 frames: no error, every frame
    well-formed, and the server's memory flat to within a quarter of the frames' RGBA bytes.

    The leak this catches: keeping one RGBA frame (or the float image of the same size) per
    update. Every frame sent is counted (a full 256 x 192 frame is 192 KiB, a preview 48 or
    12 KiB); a leak of one frame per update would grow the process by all of them, at least
    the 32 MiB the test demands were sent (about 170 full frames; a loaded 2-core machine
    sends a few hundred in 5 s), and the bound is a quarter of that."""
    handle = aos.view(textured_lightfield(), focal_surface=0.0, pose_view=4, width=512,
                      height=384, open_browser=False, num_threads=1)
    try:
        asyncio.run(load(handle, 20, 1.5))  # warm up: allocator pools, caches
        before = rss_bytes()
        counts = asyncio.run(load(handle, 20, 5.0))
        after = rss_bytes()
    finally:
        handle.stop()
    print(f"RSS {before / 2**20:.1f} -> {after / 2**20:.1f} MiB over {counts}")
    assert counts["errors"] == 0 and counts["malformed"] == 0, counts
    assert counts["frames"] >= 20 and counts["http"] >= 1, counts
    assert counts["frame_bytes"] >= 32 * 2**20, counts  # else the bound would not catch a leak
    assert after - before < counts["frame_bytes"] / 4, (before, after, counts)


# ---- the CLI ----

def cli_env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(Path(aos.__file__).parent.parent),
                                         env.get("PYTHONPATH", "")])
    return env


@pytest.fixture(scope="module")
def lightfield_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("viewer_lf")
    aos.write_lightfield(str(folder / "lf.json"), textured_lightfield())
    return folder / "lf.json"


@pytest.mark.skipif(EXE is None, reason="aos-render is not on PATH")
def test_cli_refuses_bad_command_lines(lightfield_file: Path) -> None:
    run = lambda *args, **kw: subprocess.run([EXE, "view", *args], capture_output=True,  # noqa
                                             text=True, timeout=60, env=kw.get("env", cli_env()))
    result = run("missing.json")
    assert result.returncode == 1 and "missing.json: no such light-field file" in result.stderr
    result = run(str(lightfield_file), "--port", "70000")
    assert result.returncode == 2 and "--port" in result.stderr
    result = run(str(lightfield_file), "--fov-deg", "200")
    assert result.returncode == 2 and "--fov-deg" in result.stderr
    result = run(str(lightfield_file), "--focal-surface", "nothing.obj")
    assert result.returncode == 2 and "nothing.obj" in result.stderr
    env = cli_env()
    env["AOS_PYTHON"] = "/nonexistent/python3"
    result = run(str(lightfield_file), env=env)
    assert result.returncode == 1 and "no Python interpreter with the aos package" in result.stderr
    assert "AOS_PYTHON" in result.stderr
    # Bad values the Python side finds (after loading): one line, exit 1, no server left.
    result = run(str(lightfield_file), "--pose-view", "42", "--no-browser")
    assert result.returncode == 1 and "--pose-view: no view 42" in result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.skipif(EXE is None, reason="aos-render is not on PATH")
def test_cli_serves_until_ctrl_c(lightfield_file: Path) -> None:
    process = subprocess.Popen([EXE, "view", str(lightfield_file), "--no-browser", "--json",
                                "--pose-view", "4", "--focal-height", "1.5"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               env=cli_env())
    try:
        line = process.stdout.readline()
        report = json.loads(line)
        assert report["url"].startswith("http://127.0.0.1:") and report["views"] == 9
        status, body = get(report["url"].replace("/?token=", "/api/info?token="))
        info = json.loads(body)
        assert status == 200 and info["view_count"] == 9
        assert info["defaults"]["pose_view"] == 4 and info["defaults"]["focal_height"] == 1.5
        status, body = get(report["url"].replace("/?token=", "/api/render?token=")
                           + "&orbit_deg=20&aperture_radius=2.5")
        assert status == 200 and decode_frame(body)[0]["width"] == 32
        shown = decode_frame(body)[1]
        # The copied command renders what the page shows.
        status, body = get(report["url"].replace("/?token=", "/api/command?token=")
                           + "&orbit_deg=20&aperture_radius=2.5")
        command = json.loads(body)["cli"]
        assert command.startswith(f"aos-render integral {lightfield_file} ")
        output = lightfield_file.parent / "from_command.png"
        arguments = shlex.split(command)[1:]
        arguments[arguments.index("-o") + 1] = str(output)
        subprocess.run([EXE, *arguments, "-q", "--force"], check=True, timeout=60, env=cli_env())
        written = aos.read_image(str(output))
        assert np.abs(written.astype(int) - shown[:, :, 0].astype(int)).max() <= 1
        # The map view's command line and Python snippet render the same map.
        status, body = get(report["url"].replace("/?token=", "/api/command?token=")
                           + "&mode=map&width=40&aperture_radius=4&view_first=1&view_last=8")
        command = json.loads(body)
        arguments = shlex.split(command["cli"])[1:]
        map_file = lightfield_file.parent / "from_command.tif"
        arguments[arguments.index("-o") + 1] = str(map_file)
        subprocess.run([EXE, *arguments, "-q", "--force"], check=True, timeout=60, env=cli_env())
        namespace: dict[str, Any] = {"aos": aos}
        exec(command["python"], namespace)
        rasterio = pytest.importorskip("rasterio")
        with rasterio.open(map_file) as source:
            cli_map = source.read(1)
        python_map = namespace["result"].image
        python_map = python_map[:, :, 0] if python_map.ndim == 3 else python_map
        covered = namespace["result"].count > 0  # the GeoTIFF's nodata (NaN) elsewhere
        assert covered.any() and np.array_equal(np.isfinite(cli_map), covered)
        np.testing.assert_allclose(cli_map[covered], python_map[covered], atol=1e-4)
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=30) == 0
        assert "Traceback" not in process.stderr.read()
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


def test_missing_aiohttp_says_how_to_install(tmp_path: Path) -> None:
    code = ("import sys; sys.modules['aiohttp'] = None\n"
            "import aos\n"
            "try:\n"
            "    aos.view(aos.LightField())\n"
            "except ImportError as error:\n"
            "    print(error)\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=60, env=cli_env())
    assert "pip install 'aiohttp>=3.9'" in result.stdout, result.stderr


# ---- the virtual camera, tilted planes, maps and surfaces, against geometry ----

def pick(handle: Viewer, **params: Any) -> dict[str, Any]:
    query = urllib.parse.urlencode({**params, "token": handle.token})
    status, body = get(f"{base(handle)}/api/pick?{query}")
    assert status == 200, body
    return json.loads(body)


@pytest.mark.parametrize("orbit, tilt", [(90.0, 0.0), (0.0, 30.0), (-135.0, 20.0)])
def test_orbit_and_tilt_turn_about_the_point_under_the_camera(viewer: Viewer, orbit: float,
                                                              tilt: float) -> None:
    """The pivot is where the base camera's axis meets z = H: it stays at the image centre, at
    the same distance, whatever the orbit and tilt."""
    answer = pick(viewer, u=16.0, v=12.0, focal_height=1.0, orbit_deg=orbit, tilt_deg=tilt)
    np.testing.assert_allclose(answer["world"], [0.0, 0.0, 1.0], atol=1e-9)
    camera, cam_from_world = viewer.session.camera(viewer.session.parse(
        {"focal_height": 1.0, "orbit_deg": orbit, "tilt_deg": tilt}))
    centre = np.asarray(cam_from_world.center)
    assert np.linalg.norm(centre - [0.0, 0.0, 1.0]) == pytest.approx(ALTITUDE - 1.0, abs=1e-9)
    # Tilt leans the camera off the vertical by exactly that angle.
    axis = np.asarray(cam_from_world.rotation).T @ [0.0, 0.0, 1.0]
    assert math.degrees(math.acos(-axis[2])) == pytest.approx(abs(tilt), abs=1e-9)


def test_pan_moves_the_camera_and_a_tilted_plane_passes_under_it(viewer: Viewer) -> None:
    answer = pick(viewer, u=16.0, v=12.0, focal_height=0.5, pan_x=1.5, pan_y=-0.5)
    np.testing.assert_allclose(answer["world"], [1.5, -0.5, 0.5], atol=1e-9)
    # A plane tilted 30 degrees about y through (0, 0, 0.5): z = 0.5 - tan(30) x.
    answer = pick(viewer, u=24.5, v=12.0, focal_height=0.5, tilt_x_deg=30.0)
    x, y, z = answer["world"]
    assert z == pytest.approx(0.5 - math.tan(math.radians(30.0)) * x, abs=1e-9)
    assert x > 0.5 and y == pytest.approx(0.0, abs=1e-9)


def test_map_mode_picks_through_the_geotransform(viewer: Viewer) -> None:
    status, body = get(f"{base(viewer)}/api/render?token={viewer.token}&mode=map&width=40"
                       "&focal_height=0.5")
    header, _ = decode_frame(body)
    x0, p, _, y0, _, _ = header["geotransform"]
    answer = pick(viewer, mode="map", width=40, focal_height=0.5, u=10.5, v=3.5)
    np.testing.assert_allclose(answer["world"], [x0 + 10.5 * p, y0 - 3.5 * p, 0.5], atol=1e-9)


def test_focus_on_a_surface_with_an_offset() -> None:
    """A flat terrain at z = -1 (a mesh given as the focal surface): 'surface' with offset 1.5
    focuses at z = 0.5, and renders the same as the plane z = 0.5. (A plane given as
    focal_surface is where the page's plane starts: see test_a_plane_focal_surface_starts_the_page.)"""
    flat = aos.Mesh([[-100, -100, -1], [100, -100, -1], [100, 100, -1], [-100, 100, -1]],
                    [[0, 1, 2], [0, 2, 3]])
    handle = aos.view(textured_lightfield(), pose_view=4, focal_surface=flat,
                      surface_offset=1.5, open_browser=False, num_threads=1)
    try:
        assert json.loads(get(f"{base(handle)}/api/info?token={handle.token}")[1])[
            "surface"] == "mesh"
        answer = pick(handle, u=20.5, v=7.5, surface="true", surface_offset=1.5)
        world, depth = expected_world(20.5, 7.5, 0.5)
        np.testing.assert_allclose(answer["world"], world, atol=1e-6)
        assert answer["depth"] == pytest.approx(depth, abs=1e-6)
        _, on_surface = decode_frame(get(f"{base(handle)}/api/render?token={handle.token}"
                                         "&surface=true&surface_offset=1.5")[1])
        _, on_plane = decode_frame(get(f"{base(handle)}/api/render?token={handle.token}"
                                       "&surface=false&focal_height=0.5")[1])
        assert np.abs(on_surface.astype(int) - on_plane.astype(int)).max() <= 1
    finally:
        handle.stop()


def test_a_plane_focal_surface_starts_the_page() -> None:
    """aos.view takes focal_surface as IntegralOptions does: a number or a horizontal Plane is
    the plane the page starts on (no surface to switch to); focal_height= is its deprecated
    spelling; a tilted plane is refused (the page tilts its plane itself)."""
    for given in (0.75, aos.Plane.at_height(0.75), aos.FocalSurface(0.75)):
        handle = aos.view(textured_lightfield(), pose_view=4, focal_surface=given,
                          open_browser=False, num_threads=1)
        try:
            assert handle.session.defaults.focal_height == 0.75
            assert handle.session.focal_surface is None
        finally:
            handle.stop()
    with pytest.warns(DeprecationWarning, match="focal_height= is deprecated"):
        handle = aos.view(textured_lightfield(), pose_view=4, focal_height=0.5,
                          open_browser=False, num_threads=1)
    try:
        assert handle.session.defaults.focal_height == 0.5
    finally:
        handle.stop()
    with pytest.raises(ValueError, match="the viewer starts on a horizontal plane"):
        aos.view(textured_lightfield(), focal_surface=aos.Plane((0, 0, 0), (0.1, 0, 1)),
                 open_browser=False)


def test_display_range_gain_and_colour_maps(viewer: Viewer) -> None:
    session = viewer.session
    image = np.array([[0.0, 127.0], [200.0, 255.0]], dtype=np.float32)
    count = np.ones((2, 2), dtype=np.uint32)
    grey = session.display(image, count, session.parse({}))
    np.testing.assert_array_equal(grey[:, :, 0], [[0, 127], [200, 255]])
    assert (grey[:, :, 0] == grey[:, :, 2]).all() and (grey[:, :, 3] == 255).all()
    brighter = session.display(image, count, session.parse({"gain": 2.0, "offset": 0.1}))
    np.testing.assert_array_equal(brighter[:, :, 0], [[26, 255], [255, 255]])
    auto = session.display(image, count, session.parse({"range": "auto"}))
    assert auto[0, 0, 0] == 0 and auto[1, 1, 0] == 255  # 1st..99th percentile stretched
    iron = session.display(image, count, session.parse({"colormap": "iron"}))
    turbo = session.display(image, count, session.parse({"colormap": "turbo"}))
    assert not (iron[:, :, 0] == iron[:, :, 2]).all() and not np.array_equal(iron, turbo)
    assert tuple(iron[0, 0, :3]) == (0, 0, 0) and tuple(iron[1, 1, :3]) == (255, 255, 255)


def test_all_in_focus_with_progress_and_cancel() -> None:
    handle = aos.view(textured_lightfield(), pose_view=4, open_browser=False, num_threads=1)
    try:
        message = {"type": "allinfocus", "id": 7, "params": {}, "first_height": -2.0,
                   "last_height": 2.0, "slices": 4}

        async def run(cancel: bool) -> list[Any]:
            received: list[Any] = []
            async with aiohttp.ClientSession() as client:
                async with client.ws_connect(f"{base(handle)}/ws?token={handle.token}") as ws:
                    await ws.send_str(json.dumps(message))
                    if cancel:
                        await ws.send_str(json.dumps({"type": "cancel"}))
                    while True:
                        reply = await ws.receive(timeout=60)
                        if reply.type == aiohttp.WSMsgType.BINARY:
                            received.append(decode_frame(reply.data)[0])
                            return received
                        received.append(json.loads(reply.data))
                        if received[-1]["type"] in ("cancelled", "error"):
                            return received

        done = asyncio.run(run(cancel=False))
        assert done[-1]["allinfocus"] is True and done[-1]["id"] == 7
        assert done[-1]["width"] == 32
        assert any(m.get("type") == "progress" for m in done[:-1])
        # A long one (200 slices of 384 x 288, seconds) is cancelled at its next progress
        # check, while the socket goes on reading messages.
        message = {**message, "slices": 200, "params": {"width": 384, "height": 288}}
        cancelled = asyncio.run(run(cancel=True))
        assert cancelled[-1].get("type") == "cancelled", cancelled[-1]
        bad = {**message, "slices": 1}
        message = bad
        refused = asyncio.run(run(cancel=False))
        assert refused[-1]["type"] == "error" and "slices" in refused[-1]["message"]
    finally:
        handle.stop()


def test_bad_job_messages_are_answered_with_an_error() -> None:
    """Malformed all-in-focus/stack messages (params not an object, a slice count that is no
    integer, a stack too large for memory) get an error reply: the page never waits forever,
    and the socket keeps working."""
    handle = aos.view(textured_lightfield(), pose_view=4, open_browser=False, num_threads=1)
    try:
        async def run() -> list[Any]:
            answers = []
            async with aiohttp.ClientSession() as client:
                async with client.ws_connect(f"{base(handle)}/ws?token={handle.token}") as ws:
                    common = {"id": 1, "first_height": -1.0, "last_height": 1.0}
                    for message in ({"type": "stack", "params": [], "slices": 4, **common},
                                    {"type": "allinfocus", "params": {}, "slices": 1e999, **common},
                                    {"type": "allinfocus", "params": {}, "slices": 4.5, **common},
                                    {"type": "stack", "params": {"width": 2048, "height": 2048},
                                     "slices": 200, **common}):
                        await ws.send_str(json.dumps(message))
                        answers.append(json.loads((await ws.receive(timeout=30)).data))
                    await ws.send_str(json.dumps({"type": "allinfocus", "params": {}, "slices": 3,
                                                  **common}))
                    while True:  # progress messages, then the frame
                        reply = await ws.receive(timeout=60)
                        if reply.type == aiohttp.WSMsgType.BINARY:
                            answers.append(decode_frame(reply.data)[0])
                            return answers
        answers = asyncio.run(run())
        assert [a["type"] for a in answers[:4]] == ["error"] * 4, answers
        # 1e999 (json.dumps writes Infinity) is refused while the message is parsed.
        assert "params" in answers[0]["message"] and "Infinity" in answers[1]["message"]
        assert "slices" in answers[2]["message"] and "MiB" in answers[3]["message"]
        assert answers[4]["allinfocus"] is True
    finally:
        handle.stop()
    from aos.viewer import Session, Viewer
    with pytest.raises(ValueError, match="token: at least 16"):
        Viewer(Session(textured_lightfield()), token="short")


def test_all_in_focus_on_the_surface_is_terrain_following() -> None:
    """With focus on the surface, first/last are offsets: a flat terrain at z = -1 and offsets
    0.5 .. 2.5 give the all-in-focus image of the planes z = -0.5 .. 1.5."""
    light_field = textured_lightfield()
    flat = aos.Mesh([[-100, -100, -1], [100, -100, -1], [100, 100, -1], [-100, 100, -1]],
                    [[0, 1, 2], [0, 2, 3]])
    handle = aos.view(light_field, pose_view=4, focal_surface=flat, open_browser=False,
                      num_threads=1)
    try:
        async def run(message: dict[str, Any]) -> Any:
            async with aiohttp.ClientSession() as client:
                async with client.ws_connect(f"{base(handle)}/ws?token={handle.token}") as ws:
                    await ws.send_str(json.dumps(message))
                    while True:
                        reply = await ws.receive(timeout=60)
                        if reply.type == aiohttp.WSMsgType.BINARY:
                            return decode_frame(reply.data)
                        if json.loads(reply.data)["type"] in ("cancelled", "error"):
                            raise AssertionError(reply.data)

        common = {"type": "allinfocus", "id": 3, "first_height": 0.5, "last_height": 2.5, "slices": 5}
        _, on_surface = asyncio.run(run({**common, "params": {"surface": "true"}}))
        planes = {"surface": "false"}  # the session starts on its surface
        _, on_planes = asyncio.run(run({**common, "params": planes, "first_height": -0.5,
                                        "last_height": 1.5}))
        _, wrong = asyncio.run(run({**common, "params": planes}))  # planes 0.5 .. 2.5: elsewhere
        assert np.abs(on_surface.astype(int) - on_planes.astype(int)).max() <= 1
        assert np.abs(on_surface.astype(int) - wrong.astype(int)).max() > 1
    finally:
        handle.stop()


@pytest.mark.skipif(EXE is None, reason="aos-render is not on PATH")
def test_cli_view_takes_the_mask(lightfield_file: Path) -> None:
    """view --mask loads the light field masked (integral's flag, same meaning), the page renders
    the masked mean, and the copied command carries --mask."""
    valid = np.ones((24, 32), np.uint8) * 255
    valid[:, :8] = 0  # a letterbox on the left of every frame
    mask = lightfield_file.parent / "mask.png"
    aos.write_image(str(mask), valid)
    process = subprocess.Popen([EXE, "view", str(lightfield_file), "--no-browser", "--json",
                                "--pose-view", "4", "--mask", str(mask)],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               env=cli_env())
    try:
        report = json.loads(process.stdout.readline())
        info = json.loads(get(report["url"].replace("/?token=", "/api/info?token="))[1])
        assert info["masked"] is True and info["channels"] == 1
        command = json.loads(get(report["url"].replace("/?token=", "/api/command?token="))[1])
        assert f"--mask {mask}" in command["cli"] and "mask=" in command["python"]
        header, shown = decode_frame(get(report["url"].replace("/?token=", "/api/render?token="))[1])
        masked = aos.load_lightfield(str(lightfield_file), mask=str(mask)).light_field
        options = dict(pose_view=4, focal_surface=0.0)
        expected = aos.render_integral(masked, **options)
        plain = aos.render_integral(aos.load_lightfield(str(lightfield_file)).light_field, **options)
        assert np.abs(expected.image - plain.image).max() > 5  # the mask matters here
        assert np.array_equal(header["views_used"], expected.views_used)
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=30) == 0
    finally:
        if process.poll() is None:
            process.kill()


JKU_FIRST30 = ROOT.parent / "shared" / "data" / "jku-f0" / "poses" / "poses_first30.json"


@pytest.mark.skipif(EXE is None or not JKU_FIRST30.exists(),
                    reason="aos-render or the F0 data (../shared/data/jku-f0) is missing")
def test_cli_views_jku_poses() -> None:
    process = subprocess.Popen([EXE, "view", str(JKU_FIRST30), "--frames-fov-deg",
                                "50.815436217896945", "--no-browser", "--json", "--width", "64",
                                "--height", "64", "--focal-height", "21"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               env=cli_env())
    try:
        report = json.loads(process.stdout.readline())
        assert report["views"] == 30
        status, body = get(report["url"].replace("/?token=", "/api/render?token="))
        header, image = decode_frame(body)
        assert status == 200 and (header["width"], header["height"]) == (64, 64)
        assert header["views_used"] > 0 and image[:, :, 0].std() > 0
        process.send_signal(signal.SIGTERM)
        assert process.wait(timeout=30) == 0
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


def test_a_port_in_use_is_a_clear_error(viewer: Viewer) -> None:
    with pytest.raises(OSError, match=f"cannot listen on 127.0.0.1:{viewer.port}"):
        aos.view(textured_lightfield(), port=viewer.port, open_browser=False)
    with pytest.raises(ValueError, match="port: must be"):
        aos.view(textured_lightfield(), port=70000, open_browser=False)


def test_a_fixed_view_subset_and_the_time_window_combine() -> None:
    handle = aos.view(textured_lightfield(), pose_view=4, view_indices=[0, 1, 2, 6],
                      open_browser=False, num_threads=1)
    try:
        for query, selected in (("", 4), ("&view_first=1&view_last=7", 3),
                                ("&view_first=2&view_last=3", 1)):
            status, body = get(f"{base(handle)}/api/render?token={handle.token}{query}")
            assert status == 200 and decode_frame(body)[0]["views_selected"] == selected, query
        status, body = get(f"{base(handle)}/api/render?token={handle.token}"
                           "&view_first=3&view_last=6")
        assert status == 400 and b"no view of --view-indices in that range" in body
        status, body = get(f"{base(handle)}/api/command?token={handle.token}&view_last=7")
        assert "--view-indices 0:3,6" in json.loads(body)["cli"]
    finally:
        handle.stop()


def test_a_focal_stack_is_offered_as_a_zip(viewer: Viewer) -> None:
    import io
    import zipfile

    async def run() -> dict[str, Any]:
        async with aiohttp.ClientSession() as client:
            async with client.ws_connect(f"{base(viewer)}/ws?token={viewer.token}") as ws:
                await ws.send_str(json.dumps({"type": "stack", "id": 3, "params": {},
                                              "first_height": -1.0, "last_height": 1.0,
                                              "slices": 3}))
                while True:
                    reply = json.loads((await ws.receive(timeout=60)).data)
                    if reply["type"] != "progress":
                        return reply

    reply = asyncio.run(run())
    assert reply["type"] == "download" and reply["url"].startswith("/api/download/"), reply
    status, _ = get(base(viewer) + reply["url"])
    assert status == 403  # the token, as everywhere
    status, body = get(f"{base(viewer)}{reply['url']}?token={viewer.token}")
    assert status == 200 and len(body) == reply["bytes"]
    names = zipfile.ZipFile(io.BytesIO(body)).namelist()
    assert "stack/stack.json" in names and len([n for n in names if "slice_" in n]) == 3
    status, _ = get(f"{base(viewer)}/api/download/nothing?token={viewer.token}")
    assert status == 404


# ---- defence in depth beside the token (issue 31) ----

def raw_request(port: int, path: str, host: Optional[str], method: str = "GET",
                body: Optional[bytes] = None,
                headers: Optional[dict[str, str]] = None) -> tuple[int, bytes]:
    """One request to 127.0.0.1:port with exactly this Host header (None: none at all)."""
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
    try:
        connection.putrequest(method, path, skip_host=True, skip_accept_encoding=True)
        if host is not None:
            connection.putheader("Host", host)
        for name, value in (headers or {}).items():
            connection.putheader(name, value)
        if body is not None:
            connection.putheader("Content-Type", "application/json")
            connection.putheader("Content-Length", str(len(body)))
        connection.endheaders(body)
        response = connection.getresponse()
        return response.status, response.read()
    finally:
        connection.close()


def test_deeply_nested_json_is_refused_with_a_400_not_a_traceback(viewer: Viewer) -> None:
    """A 60 KB "[[[[..." body answered 500 with a traceback (Python's recursion limit reached
    by the JSON decoder); JSON nested deeper than the flat parameters need is now a 400 with one
    line, over HTTP and over the WebSocket, and the server goes on."""
    from aos.viewer import server

    url = f"{base(viewer)}/api/render?token={viewer.token}"
    nested_object = b'{"focal_height": ' + b"[" * 900 + b"]" * 900 + b"}"  # within the limit
    for body in (b"[" * 60_000, b"[" * 30_000 + b"]" * 30_000, nested_object):
        status, answer = get(url, headers={"Content-Type": "application/json"}, data=body)
        assert status == 400, (status, answer[:300])
        message = json.loads(answer)["error"]
        assert f"nested more than {server.MAX_JSON_DEPTH} deep" in message, message
        assert b"Traceback" not in answer and len(answer) < 300
    status, _ = get(url, headers={"Content-Type": "application/json"},
                    data=b'{"focal_height": 1.0}')
    assert status == 200
    received = asyncio.run(_ws_session(viewer, [{"type": "render", "id": 1}], expect=1))
    assert received[0]["type"] == "frame"

    async def nested_message() -> list[Any]:
        async with aiohttp.ClientSession() as client:
            async with client.ws_connect(f"{base(viewer)}/ws?token={viewer.token}") as socket:
                await socket.send_str("[" * 60_000)
                error = json.loads((await socket.receive(timeout=30)).data)
                await socket.send_str(json.dumps({"type": "render", "id": 2}))
                frame = await socket.receive(timeout=30)
                return [error, decode_frame(frame.data)[0]]

    error, frame = asyncio.run(nested_message())
    assert error["type"] == "error" and "nested more than" in error["message"], error
    assert frame["id"] == 2


def test_numbers_no_float_holds_are_refused_not_echoed(viewer: Viewer) -> None:
    """A WebSocket message with "id": -1e999 was echoed back as -Infinity, which is not JSON
    (found by tools/fuzz.py); 1e999, NaN and Infinity are now refused like any bad parameter."""
    from aos.viewer import server
    from aos.viewer.session import BadParameter

    for text in ('{"id": -1e999}', '{"id": NaN}', '[Infinity]', '{"a": [1e400]}'):
        with pytest.raises(BadParameter, match="not finite|not a JSON number"):
            server.parse_json(text, "message")
    assert server.parse_json('{"id": 1e300, "n": 12}', "message") == {"id": 1e300, "n": 12}

    async def message() -> Any:
        async with aiohttp.ClientSession() as client:
            async with client.ws_connect(f"{base(viewer)}/ws?token={viewer.token}") as socket:
                await socket.send_str('{"type": "render", "id": -1e999}')
                return json.loads((await socket.receive(timeout=30)).data)

    answer = asyncio.run(message())   # json.loads here refuses nothing: check the value
    assert answer["type"] == "error" and "not finite" in answer["message"], answer


def test_a_malformed_request_is_one_log_line_without_a_traceback(
        viewer: Viewer, caplog: pytest.LogCaptureFixture) -> None:
    """A request line over 8190 bytes was answered 400 by aiohttp, which logged "Error handling
    request" with a LineTooLong traceback (found by tools/fuzz.py): now one warning line."""
    with caplog.at_level(logging.DEBUG, logger="aiohttp.server"):
        status, _ = raw_request(viewer.port, "/api/info?q=" + "a" * 200_000,
                                f"127.0.0.1:{viewer.port}")
        deadline = time.monotonic() + 10
        while not any(r.name == "aiohttp.server" for r in caplog.records):
            assert time.monotonic() < deadline, "aiohttp logged nothing"
            time.sleep(0.05)
    assert status == 400
    records = [r for r in caplog.records if r.name == "aiohttp.server"]
    assert all(r.exc_info is None and r.levelno == logging.WARNING for r in records), records
    assert "refused a malformed request" in records[0].getMessage()
    assert "Traceback" not in caplog.text


def test_requests_must_name_this_server_in_their_host_header(viewer: Viewer) -> None:
    """A DNS-rebinding page (evil.example resolved to 127.0.0.1) sends Host: evil.example; it was
    served (only the token stopped it). Now only the addresses of this server are accepted."""
    port = viewer.port
    path = f"/api/info?token={viewer.token}"
    for host in (f"127.0.0.1:{port}", f"localhost:{port}", f"LOCALHOST:{port}",
                 f"[::1]:{port}"):
        assert raw_request(port, path, host)[0] == 200, host
    for host in ("evil.example", f"evil.example:{port}", f"127.0.0.1:{port + 1}", "127.0.0.1",
                 f"127.0.0.1.evil.example:{port}", f"127.0.0.1:{port}@evil", f"[::1]x:{port}",
                 f"127.0.0.2:{port}", ""):
        status, body = raw_request(port, path, host)
        assert status == 403 and b"Host" in body, (host, status, body)
    assert raw_request(port, path, None)[0] == 400  # no Host at all: aiohttp refuses it
    # The page, the API, a POST and the WebSocket alike.
    for request_path in (f"/?token={viewer.token}", f"/static/viewer.js?token={viewer.token}",
                         f"/api/render?token={viewer.token}"):
        assert raw_request(port, request_path, f"evil.example:{port}")[0] == 403
    assert raw_request(port, f"/api/render?token={viewer.token}", f"evil.example:{port}", "POST",
                       b"{}")[0] == 403

    def handshake(host: str, origin: str) -> int:
        key = "dGhlIHNhbXBsZSBub25jZQ=="
        status, _ = raw_request(port, f"/ws?token={viewer.token}", host, headers={
            "Origin": origin, "Upgrade": "websocket", "Connection": "Upgrade",
            "Sec-WebSocket-Key": key, "Sec-WebSocket-Version": "13"})
        return status

    # The finding: Host and Origin both evil.example, the token given: the handshake succeeded.
    assert handshake(f"evil.example:{port}", f"http://evil.example:{port}") == 403
    assert handshake(f"127.0.0.1:{port}", f"http://evil.example:{port}") == 403
    assert handshake(f"127.0.0.1:{port}", f"http://127.0.0.1:{port}") == 101
    assert handshake(f"localhost:{port}", f"http://localhost:{port}") == 101


def test_the_accepted_host_names_follow_the_listening_address() -> None:
    """Which Host names each kind of address accepts (docs/viewer.md), without listening."""
    from aos.viewer import server

    handle = server.Viewer(aos.viewer.Session(textured_lightfield()), "t" * 32)
    try:
        handle.listening_at("127.0.0.1", "127.0.0.1", 8123)
        assert handle.host_allowed("127.0.0.1:8123") and handle.host_allowed("localhost:8123")
        assert not handle.host_allowed("192.168.1.5:8123")
        handle.listening_at("192.168.1.5", "192.168.1.5", 8123)  # a LAN address only
        assert handle.host_allowed("192.168.1.5:8123")
        assert not handle.host_allowed("localhost:8123") and not handle.host_allowed(
            "evil.example:8123")
        handle.listening_at("0.0.0.0", "0.0.0.0", 80)  # every address: any IP literal
        assert handle.host_allowed("10.1.2.3") and handle.host_allowed("[fe80::1]:80")
        assert handle.host_allowed("localhost:80") and not handle.host_allowed("evil.example")
        assert not handle.host_allowed("10.1.2.3:81")
    finally:
        handle.close()


def test_picks_and_exports_count_in_the_request_bound(viewer: Viewer,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """MAX_QUEUED_HTTP bounded only one-shot renders; a flood of picks or exports (each a
    full-size render) queued without bound. With the bound reached, all three answer 503."""
    from aos.viewer import server

    monkeypatch.setattr(server, "MAX_QUEUED_HTTP", 0)  # the bound reached
    for path in ("/api/render?", "/api/pick?u=1&v=1&", "/api/export?format=png&"):
        status, body = get(f"{base(viewer)}{path}token={viewer.token}")
        assert status == 503 and b"busy" in body, (path, status, body[:200])
    monkeypatch.setattr(server, "MAX_QUEUED_HTTP", 64)
    for path in ("/api/render?", "/api/pick?u=1&v=1&", "/api/export?format=png&"):
        assert get(f"{base(viewer)}{path}token={viewer.token}")[0] == 200, path
    assert viewer.server.queued_http == 0


def test_open_pages_are_bounded() -> None:
    """At most max_pages WebSockets (default MAX_PAGES); the next one is told why and closed
    with 1013 (try again later); once one closes, a new page is served."""
    from aos.viewer import server

    assert server.MAX_PAGES == aos.viewer.MAX_PAGES >= 20  # the load test's 20 pages fit
    # The range is the C++ table's (aos.ViewerOptions), as the CLI's --max-pages.
    with pytest.raises(ValueError, match=r"max_pages: must be in \[1, 4096\], got 0"):
        aos.view(textured_lightfield(), max_pages=0, open_browser=False)
    with pytest.raises(ValueError, match=r"port: must be in \[0, 65535\], got 70000"):
        aos.view(textured_lightfield(), port=70000, open_browser=False)
    assert aos.viewer.MAX_PAGES == aos.ViewerOptions().max_pages == 32
    handle = aos.view(textured_lightfield(), pose_view=4, max_pages=2, open_browser=False,
                      num_threads=1)
    try:
        async def run() -> None:
            url = f"{base(handle)}/ws?token={handle.token}"
            async with aiohttp.ClientSession() as client:
                first = await client.ws_connect(url)
                second = await client.ws_connect(url)
                for k, socket in enumerate((first, second)):
                    await socket.send_str(json.dumps({"type": "render", "id": k}))
                    assert decode_frame((await socket.receive(timeout=30)).data)[0]["id"] == k
                third = await client.ws_connect(url)
                refusal = json.loads((await third.receive(timeout=30)).data)
                assert refusal["type"] == "error", refusal
                assert "at most 2 open pages (max_pages)" in refusal["message"], refusal
                closing = await third.receive(timeout=30)
                assert closing.type == aiohttp.WSMsgType.CLOSE and closing.data == 1013
                assert "max_pages" in closing.extra
                await first.close()
                for _ in range(50):  # the server notices the close
                    if len(handle.server.sockets) < 2:
                        break
                    await asyncio.sleep(0.05)
                fourth = await client.ws_connect(url)
                await fourth.send_str(json.dumps({"type": "render", "id": 4}))
                assert decode_frame((await fourth.receive(timeout=30)).data)[0]["id"] == 4
                await second.close()
                await fourth.close()

        asyncio.run(run())
        assert handle.server.stats["refused_pages"] == 1
    finally:
        handle.stop()


@pytest.mark.skipif(EXE is None, reason="aos-render is not on PATH")
def test_cli_max_pages_bounds_the_open_pages(lightfield_file: Path) -> None:
    """`aos-render view --max-pages N` (it was a Python-only option): the second page of N = 1
    is refused with the reason; 0 is a usage error."""
    bad = subprocess.run([EXE, "view", str(lightfield_file), "--no-browser", "--max-pages", "0"],
                         capture_output=True, text=True, timeout=60, env=cli_env())
    assert bad.returncode == 2 and "--max-pages" in bad.stderr, bad.stderr
    assert "max_pages: must be in [1, 4096], got 0 [option --max-pages]" in bad.stderr
    process = subprocess.Popen([EXE, "view", str(lightfield_file), "--no-browser", "--json",
                                "--pose-view", "4", "--max-pages", "1"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               env=cli_env())
    try:
        report = json.loads(process.stdout.readline())
        url = report["url"].replace("http://", "ws://").replace("/?token=", "/ws?token=")

        async def run() -> None:
            async with aiohttp.ClientSession() as client:
                first = await client.ws_connect(url)
                await first.send_str(json.dumps({"type": "render", "id": 1}))
                assert decode_frame((await first.receive(timeout=30)).data)[0]["id"] == 1
                second = await client.ws_connect(url)
                refusal = json.loads((await second.receive(timeout=30)).data)
                assert "at most 1 open pages (max_pages)" in refusal["message"], refusal
                await first.close()

        asyncio.run(run())
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=30) == 0
    finally:
        if process.poll() is None:
            process.kill()


def test_the_browser_is_never_given_the_token(monkeypatch: pytest.MonkeyPatch) -> None:
    """The browser was opened with the tokenised URL, on its command line, where `ps` shows it
    to every local user. It now gets a file of this user's that redirects to the URL."""
    import webbrowser

    opened: list[str] = []
    monkeypatch.setattr(webbrowser, "open", lambda url, *a, **k: opened.append(url) or True)
    handle = aos.view(textured_lightfield(), open_browser=True)
    try:
        assert len(opened) == 1 and handle.token not in opened[0], opened
        assert opened[0].startswith("file://")
        path = Path(urllib.parse.unquote(urllib.parse.urlparse(opened[0]).path))
        assert path.stat().st_mode & 0o777 == 0o600
        assert path.parent.stat().st_mode & 0o777 == 0o700
        page = path.read_text()
        assert f'content="0;url={handle.url}"' in page and f'href="{handle.url}"' in page
    finally:
        handle.stop()
    assert not path.exists()


@pytest.mark.skipif(EXE is None, reason="aos-render is not on PATH")
def test_cli_browser_is_never_given_the_token(lightfield_file: Path, tmp_path: Path) -> None:
    """`aos-render view --browser`: the browser command (here $BROWSER, a script that records
    its arguments: what `ps` would show) gets the redirect file, never the token."""
    record = tmp_path / "argv.json"
    browser = tmp_path / "browser.py"
    browser.write_text("import json, sys\n"
                       f"open({str(record)!r}, 'w').write(json.dumps(sys.argv[1:]))\n")
    env = {**cli_env(), "BROWSER": f"{sys.executable} {browser} %s"}
    process = subprocess.Popen([EXE, "view", str(lightfield_file), "--browser", "--json"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        report = json.loads(process.stdout.readline())
        for _ in range(100):
            if record.exists() and record.read_text():
                break
            time.sleep(0.1)
        arguments = json.loads(record.read_text())
        token = urllib.parse.parse_qs(urllib.parse.urlparse(report["url"]).query)["token"][0]
        assert arguments and not any(token in argument for argument in arguments), arguments
        path = Path(urllib.parse.unquote(urllib.parse.urlparse(arguments[0]).path))
        assert report["url"] in path.read_text()
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=30) == 0
        assert not path.exists()
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


def test_connections_that_never_present_the_token_are_closed(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """An idle connection was kept for aiohttp's keep-alive time (an hour), whether or not it
    ever presented the token: one page could hold any number. Now a connection that has not
    presented the token UNAUTHENTICATED_TIMEOUT_S after it opened is closed; one that has is
    kept."""
    import socket

    from aos.viewer import server

    timeout = 1.0  # long enough for the authenticated request to be served first
    monkeypatch.setattr(server, "UNAUTHENTICATED_TIMEOUT_S", timeout, raising=False)
    handle = aos.view(textured_lightfield(), pose_view=4, open_browser=False, num_threads=1)
    host = f"127.0.0.1:{handle.port}"

    def request(path: str) -> bytes:
        return f"GET {path} HTTP/1.1\r\nHost: {host}\r\n\r\n".encode()

    def closed(connection: socket.socket, within: float) -> bool:
        connection.settimeout(within)
        try:
            while connection.recv(65536):  # a refusal's response comes first
                pass
            return True
        except ConnectionResetError:
            return True
        except socket.timeout:
            return False

    connections = [socket.create_connection(("127.0.0.1", handle.port)) for _ in range(4)]
    try:
        silent, trickle, refused, authenticated = connections
        trickle.sendall(f"GET / HTTP/1.1\r\nHost: {host}\r\n".encode())  # never finished
        refused.sendall(request("/api/info?token=wrong"))
        authenticated.sendall(request(f"/api/info?token={handle.token}"))
        assert authenticated.recv(65536).startswith(b"HTTP/1.1 200")
        start = time.monotonic()
        for connection in (silent, trickle, refused):
            assert closed(connection, timeout + 3.0 - (time.monotonic() - start)), connection
        assert handle.server.stats["closed_unauthenticated"] == 3
        # The authenticated one is still served after the timeout.
        authenticated.sendall(request(f"/api/info?token={handle.token}"))
        authenticated.settimeout(10)
        assert authenticated.recv(65536).startswith(b"HTTP/1.1 200")
    finally:
        for connection in connections:
            connection.close()
        handle.stop()


def stack_job(handle: Viewer, width: int, height: int, slices: int) -> dict[str, Any]:
    async def run() -> dict[str, Any]:
        async with aiohttp.ClientSession() as client:
            async with client.ws_connect(f"{base(handle)}/ws?token={handle.token}") as socket:
                await socket.send_str(json.dumps({
                    "type": "stack", "id": 1, "params": {"width": width, "height": height},
                    "first_height": -1.0, "last_height": 1.0, "slices": slices}))
                while True:
                    reply = json.loads((await socket.receive(timeout=120)).data)
                    if reply["type"] != "progress":
                        return reply

    return asyncio.run(run())


def test_finished_stack_jobs_give_their_memory_back() -> None:
    """Three focal-stack jobs left 1.9 GB resident: the zips were kept in memory and the freed
    slices stayed in glibc's arenas. Now the zips are files (the newest two) and the freed heap
    is handed back (malloc_trim) after each job: resident memory returns to where it was.

    Each job holds 16 slices of 768 x 576 (float32 image + uint32 count: 3.4 MiB each, 54 MiB
    in all) while it runs, then writes and zips them. Measured over three such jobs: the old
    code stayed 99-123 MiB above the level before them (growing job after job); with the
    memory handed back, 0-29 MiB (what writing the slices' TIFFs keeps, which does not grow
    from job to job). The bound, 40 MiB, is under one job's slices."""
    handle = aos.view(textured_lightfield(), pose_view=4, open_browser=False, num_threads=1)
    try:
        job_bytes = 16 * 768 * 576 * 8
        stack_job(handle, 96, 72, 2)  # warm-up: the code paths, the allocator's first arenas
        before = rss_bytes()
        sizes = []
        for _ in range(3):
            reply = stack_job(handle, 768, 576, 16)
            assert reply["type"] == "download", reply
            sizes.append(reply["bytes"])
        after = rss_bytes()
        print(f"RSS before {before / 2**20:.1f} MiB, after 3 jobs {after / 2**20:.1f} MiB "
              f"(one job's slices {job_bytes / 2**20:.0f} MiB, zips {sizes})")
        assert after - before < 40 * 2**20 < job_bytes, (before, after)
        # The two newest stacks are kept as files of the server's, never as bytes in memory.
        downloads = handle.server.downloads
        assert len(downloads) == 2
        assert all(isinstance(path, str) and os.path.getsize(path) in sizes
                   for path in downloads.values())
        folder = handle.server.download_folder
    finally:
        handle.stop()
    assert not os.path.exists(folder)
