"""The viewer's model: one light field loaded once, the parameters a page may send (validated),
and what a render request turns into (aos.render_integral / aos.render_map, GIL released).

Nothing here knows about HTTP; server.py maps BadParameter to 400 and the results to bytes.

Parameters (all optional; JSON numbers/strings/booleans, or query-string text): the fields of
``aos.ViewParams``, defined once with their ranges and help in the C++ table (aos::ViewParams,
cpp/aos/viewer/viewer_options.h): ``mode``; focus (``focal_height``, ``tilt_x_deg`` /
``tilt_y_deg``, ``surface``, ``surface_offset``); ``aperture_radius``, ``view_first`` /
``view_last``; the virtual camera (``pose_view``, ``orbit_deg``, ``tilt_deg``, ``pan_x`` /
``pan_y`` / ``pan_z``, ``fov_deg``, ``width`` / ``height``); the display (``range``, ``gain``,
``offset``, ``colormap``: not the render); and ``preview``.

* ``preview`` (while a control is dragged): the full-size image from a spread subset of the
  selected views, every k-th along the flight (never a downscaled image): k = the selected
  views / ``Session.preview_view_count``, the views a preview can take so that its render and
  display fit ``FRAME_BUDGET_MS`` (the server's share of a 33 ms frame) on this host; it is
  learnt after every render from its time, as a fixed part plus a part per view (the last
  preview and the last full render give both), and never below ``MIN_PREVIEW_VIEWS``. At rest
  the page asks for the image of every view.
"""

from __future__ import annotations

import copy
import math
import os
import re
import shlex
import tempfile
from dataclasses import dataclass, field
from typing import Any, Callable, Optional

import numpy as np

import aos
from aos import _command

# Pages (WebSockets) a viewer serves at once by default (Viewer's max_pages): each keeps one
# pending render and may queue one all-in-focus or stack job. The default is the C++ table's
# (aos.ViewerOptions, cpp/aos/viewer/viewer_options.h), as the CLI's is.
MAX_PAGES = aos.ViewerOptions().max_pages
# The server's share of a 33 ms frame (30 updates a second while a control is dragged): a
# preview's render and display mapping should take this long at most. The rest is the page's:
# receiving the 1 MiB frame and drawing it, about 15 ms in headless Chromium on 2 cores
# (tools/bench_viewer.py), where the input-to-display p95 stays under 60 ms.
FRAME_BUDGET_MS = 20.0
# A preview integrates at least this many views (or all the selected ones), whatever the budget:
# fewer would show single frames, occluders and all.
MIN_PREVIEW_VIEWS = 8


class BadParameter(ValueError):
    """A request parameter out of range or malformed (the server answers 400 with the text)."""


class Superseded(Exception):
    """Raised from a render's progress callback when a newer request replaced it."""


# One validated request: the table's fields (aos::ViewParams), typed, ranged and documented there.
Params = aos.ViewParams
_ROWS = {row["name"]: row for row in Params._field_table}
# The choices of the colormap row, from its type: Literal['grey', 'turbo', 'iron'].
COLORMAPS = tuple(re.findall(r"'([^']*)'", _ROWS["colormap"]["type"]))


def _turbo_lut() -> np.ndarray:
    # Google's polynomial approximation of the Turbo colour map (Mikhailov 2019), 256 entries.
    t = np.linspace(0.0, 1.0, 256)
    r = 0.13572138 + t * (4.61539260 + t * (-42.66032258 + t * (132.13108234 + t * (
        -152.94239396 + t * 59.28637943))))
    g = 0.09140261 + t * (2.19418839 + t * (4.84296658 + t * (-14.18503333 + t * (
        4.27729857 + t * 2.82956604))))
    b = 0.10667330 + t * (12.64194608 + t * (-60.58204836 + t * (110.36276771 + t * (
        -89.90310912 + t * 27.34824973))))
    return np.clip(np.stack([r, g, b], axis=1) * 255.0 + 0.5, 0, 255).astype(np.uint8)


def _iron_lut() -> np.ndarray:
    # A thermal "iron" palette: black, blue-violet, red, orange, yellow, white.
    stops = np.array([0.0, 0.2, 0.45, 0.7, 0.9, 1.0])
    colours = np.array([[0, 0, 0], [70, 0, 140], [200, 20, 60], [240, 120, 0], [255, 220, 40],
                        [255, 255, 255]], dtype=float)
    t = np.linspace(0.0, 1.0, 256)
    lut = np.stack([np.interp(t, stops, colours[:, c]) for c in range(3)], axis=1)
    return np.clip(lut + 0.5, 0, 255).astype(np.uint8)


_LUTS = {
    "grey": np.repeat(np.arange(256, dtype=np.uint8)[:, None], 3, axis=1),
    "turbo": _turbo_lut(),
    "iron": _iron_lut(),
}


def _read_fields(options: Any, raw: dict[str, Any]) -> None:
    """Sets the fields of ``options`` (an Options class: ViewParams, DetectOptions) named in
    ``raw`` (JSON values or query text), each read as its field-table row's type: numbers
    (``inf`` too; the ranges refuse NaN), whole numbers within 32 bits, booleans, text (the
    choices are the ranges'), and for an optional field '' or 'none' as unset. Unknown names and
    unreadable values raise BadParameter naming the field; ranges are checked by the caller."""
    rows = {row["name"]: row for row in type(options)._field_table}
    for name, value in raw.items():
        row = rows.get(name)
        if row is None:
            raise BadParameter(f"{str(name)[:40]}: unknown parameter (known: "
                               f"{', '.join(sorted(rows))})")
        kind = row["type"]
        if kind.endswith(" | None"):
            if value is None or str(value).strip().lower() in ("", "none"):
                setattr(options, name, None)
                continue
            kind = kind[:-len(" | None")]
        if kind == "float":
            converted: Any = _as_float(name, value)
        elif kind == "int":
            converted = _as_int(name, value)
            if not -2**31 <= converted < 2**31:
                raise BadParameter(f"{name}: must be {row['range'] or 'a number'} (a 32-bit "
                                   f"whole number), got {converted}")
        elif kind == "bool":
            converted = _as_bool(name, value)
        else:  # text, its choices checked by the range
            converted = str(value)[:100]
        setattr(options, name, converted)


def parse_detect_options(raw: dict[str, Any]) -> aos.DetectOptions:
    """DetectOptions from a page's raw values (its field table: detector, one_sided, the
    threshold rules, ...), checked (BadParameter naming the field)."""
    options = aos.DetectOptions()
    _read_fields(options, raw)
    try:
        options.check()
    except ValueError as error:
        raise BadParameter(str(error)) from None
    return options


def params_dict(params: Params) -> dict[str, Any]:
    """The fields as JSON values (an infinite aperture as "inf")."""
    values = {name: getattr(params, name) for name in Params._fields}
    if math.isinf(values["aperture_radius"]):
        values["aperture_radius"] = "inf"
    return values


def _with(params: Params, **changes: Any) -> Params:
    """A copy of ``params`` with ``changes``."""
    changed = copy.copy(params)
    for name, value in changes.items():
        setattr(changed, name, value)
    return changed


def _as_float(name: str, value: Any) -> float:
    if isinstance(value, bool):
        raise BadParameter(f"{name}: expected a number, got {value!r}")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise BadParameter(f"{name}: expected a number, got {str(value)[:40]!r}") from None
    return number


def _as_int(name: str, value: Any) -> int:
    number = _as_float(name, value)
    if not math.isfinite(number) or number != int(number):
        raise BadParameter(f"{name}: expected a whole number, got {str(value)[:40]!r}")
    return int(number)


def _as_bool(name: str, value: Any) -> bool:
    if isinstance(value, bool):
        return value
    if value in (0, 1):
        return bool(value)
    text = str(value).lower()
    if text in ("true", "1", "yes", "on"):
        return True
    if text in ("false", "0", "no", "off", ""):
        return False
    raise BadParameter(f"{name}: expected true or false, got {str(value)[:40]!r}")


def parse_view_list(text: str, view_count: int) -> list[int]:
    """'0:10,15,20:30' (indices and half-open ranges) -> sorted unique indices in [0, count)."""
    indices: set[int] = set()
    for part in text.split(","):
        part = part.strip()
        try:
            if ":" in part:
                first_text, last_text = part.split(":", 1)
                first, last = int(first_text), int(last_text)
                if not 0 <= first < last <= view_count:
                    raise ValueError
                indices.update(range(first, last))
            else:
                index = int(part)
                if not 0 <= index < view_count:
                    raise ValueError
                indices.add(index)
        except ValueError:
            raise BadParameter(f"views: {part!r} is not an index or range A:B within "
                               f"0..{view_count}") from None
    return sorted(indices)


@dataclass
class Frame:
    """A rendered, display-mapped image and what the page shows beside it."""

    rgba: bytes
    width: int
    height: int
    info: dict[str, Any] = field(default_factory=dict)


def _rotation_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rotation_about(axis: np.ndarray, angle: float) -> np.ndarray:
    axis = axis / np.linalg.norm(axis)
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


class Session:
    """A light field loaded once, with an optional focal surface, rendered on request.

    ``render`` and ``pick`` may be called from any thread; the C++ renderer releases the GIL.
    ``num_threads`` is passed to every render (-1 = all cores).
    """

    def __init__(self, light_field: aos.LightField, *, source: str = "",
                 load_options: Optional[dict[str, Any]] = None, surface_path: str = "",
                 focal_surface: Optional[aos.FocalSurface] = None,
                 defaults: Optional[dict[str, Any]] = None,
                 cam_from_world: Optional[aos.Rigid3d] = None,
                 view_indices: Optional[list[int]] = None,
                 min_view_angle_deg: Optional[float] = None, num_threads: Optional[int] = None,
                 lens_tolerance_px: Optional[float] = None,
                 adaptive_preview: bool = True,
                 render_options: Optional[aos.IntegralOptions] = None) -> None:
        if len(light_field) == 0:
            raise ValueError("view(): the light field has no views")
        self.light_field = light_field
        self.source = source
        # How many views a preview integrates (every k-th of the selected ones), at full size;
        # learnt from every render's time (adaptive_preview), from the last preview's and the
        # last full render's (views, milliseconds) in _render_costs.
        self.preview_view_count = 1 << 30
        self._render_costs: dict[bool, tuple[int, float]] = {}
        self.adaptive_preview = adaptive_preview
        # How `source` was loaded (load_lightfield's fov_deg, images_dir, grey, mask, mask_dir)
        # and the focal surface's file, for the equivalent command.
        self.load_options = {k: v for k, v in (load_options or {}).items() if v}
        self.surface_path = surface_path
        # A DEM in another CRS moved into the light field's once (as the CLI does).
        self.focal_surface = (None if focal_surface is None
                              else focal_surface.in_crs(light_field.crs))
        # Every render starts from these options: the page sets what it controls (camera,
        # focus, aperture, views: integral_options, map_options) and every other field is as
        # given here, so a field added to IntegralOptions reaches the viewer's renders (and its
        # map view, for the fields MapOptions shares) without a line here. The keywords override
        # single fields.
        self.render_options = copy.copy(render_options or aos.IntegralOptions())
        for name, value in (("min_view_angle_deg", min_view_angle_deg),
                            ("num_threads", num_threads),
                            ("lens_tolerance_px", lens_tolerance_px)):
            if value is not None:
                setattr(self.render_options, name, value)
        self.num_threads = self.render_options.num_threads
        self.view_indices = view_indices  # a fixed subset from --view-indices (None = all)
        # A pose given as such (--look-at, --cam-from-world) replaces the views' as the base.
        self.fixed_cam_from_world = cam_from_world
        views = light_field.views
        self.view_count = len(views)
        self.view_names = [view.name for view in views]
        self.cam_from_world = [view.cam_from_world for view in views]
        self.centres = np.array([pose.center for pose in self.cam_from_world])
        self.cameras = [view.camera.pinhole() for view in views]
        first = views[0].image
        self.channels = 1 if first is None or first.ndim == 2 else int(first.shape[2])
        if light_field.masked:
            self.channels -= 1  # the frames' weight channel (masks) is divided out by renders
        self.dtype = "float32" if first is None else str(first.dtype)
        self.type_range = {"uint8": (0.0, 255.0), "uint16": (0.0, 65535.0)}.get(self.dtype)
        # Radiometric frames (values measure temperature): the page shows degrees Celsius, and
        # the frames' type range (0..655 K for 16-bit centikelvin) gives way to the percentiles.
        self.radiometry = light_field.radiometry
        if self.radiometry is not None:
            self.type_range = None
        # The newest detections (detect()): (number, local point), drawn on every frame.
        self.detections: list[tuple[int, np.ndarray]] = []
        # Mean view centre and the up axis (+z or -z, towards the cameras from the ground).
        self.mean_centre = self.centres.mean(axis=0)
        # Without a pose the viewer starts at the middle view (the CLI's integral needs one).
        self.defaults = Params(view_last=self.view_count, pose_view=self.view_count // 2)
        if defaults:
            self.defaults = self.parse(defaults)
        # The up axis: the cameras lie above the ground. Where the cameras sit at smaller z than
        # the default focal plane (JKU frames, z down), up is -z.
        self.up_z = -1.0 if self.mean_centre[2] < self.defaults.focal_height else 1.0

    # ---- parameters ----

    def parse(self, raw: dict[str, Any], base: Optional[Params] = None) -> Params:
        """Validated Params from a dict of raw values (unknown keys refused): each read as its
        table row's type, then checked against the table's ranges (Params.check)."""
        params = copy.copy(base or self.defaults)
        _read_fields(params, raw)
        try:
            params.check(self.view_count)
        except ValueError as error:
            raise BadParameter(str(error)) from None
        if params.surface and self.focal_surface is None:
            raise BadParameter("surface: this viewer was started without a focal surface "
                               "(--focal-surface)")
        return params

    # ---- the virtual camera ----

    def base_pose(self, params: Params) -> aos.Rigid3d:
        if self.fixed_cam_from_world is not None:
            return self.fixed_cam_from_world
        return self.cam_from_world[params.pose_view]

    def focal_plane(self, params: Params) -> aos.Plane:
        """The focal plane z = H tilted about the point under the base camera."""
        centre = self.base_pose(params).center
        tx, ty = math.radians(params.tilt_x_deg), math.radians(params.tilt_y_deg)
        normal = np.array([math.tan(tx), math.tan(ty), 1.0])
        return aos.Plane((float(centre[0]), float(centre[1]), params.focal_height),
                         tuple(normal / np.linalg.norm(normal)))

    def camera(self, params: Params) -> tuple[aos.PinholeCamera, aos.Rigid3d]:
        """The virtual camera (intrinsics at full or preview size) and its cam_from_world."""
        base = self.base_pose(params)
        rotation = base.rotation  # cam_from_world
        centre = base.center
        if params.orbit_deg or params.tilt_deg:
            # Pivot: where the base camera's axis meets the horizontal plane z = H (or a point
            # 30 m ahead when it runs parallel to it).
            axis = rotation.T @ np.array([0.0, 0.0, 1.0])
            distance = 30.0
            if abs(axis[2]) > 1e-6:
                t = (params.focal_height - centre[2]) / axis[2]
                if t > 0:
                    distance = t
            pivot = centre + distance * axis
            turn = (_rotation_z(math.radians(params.orbit_deg))
                    @ _rotation_about(rotation.T @ np.array([1.0, 0.0, 0.0]),
                                      math.radians(params.tilt_deg)))
            centre = pivot + turn @ (centre - pivot)
            rotation = rotation @ turn.T
        centre = centre + np.array([params.pan_x, params.pan_y, params.pan_z])
        cam_from_world = aos.Rigid3d(rotation, -rotation @ centre)
        pose_camera = self.cameras[params.pose_view]
        width = params.width or pose_camera.width
        height = params.height or pose_camera.height
        fov = params.fov_deg or pose_camera.fov_x_deg()
        return aos.PinholeCamera.from_fov(width, height, fov), cam_from_world

    def views_of(self, params: Params) -> list[int]:
        """The views a request selects ([] = all)."""
        if params.view_first == 0 and params.view_last == self.view_count:
            return list(self.view_indices or [])
        chosen = list(range(params.view_first, params.view_last))
        if self.view_indices is not None:
            allowed = set(self.view_indices)
            chosen = [index for index in chosen if index in allowed]
            if not chosen:
                raise BadParameter("view_first, view_last: no view of --view-indices in that range")
        return chosen

    def preview_views(self, params: Params) -> tuple[list[int], int]:
        """The views a preview integrates and k: every k-th of the selected ones along the
        flight (the middle one of each run of k), k = ceil(selected / preview_view_count);
        ([] = all, 1) when they all fit."""
        chosen = self.views_of(params) or list(range(self.view_count))
        count = max(MIN_PREVIEW_VIEWS, self.preview_view_count)
        stride = max(1, math.ceil(len(chosen) / count))
        if stride == 1:
            return self.views_of(params), 1
        return chosen[stride // 2::stride], stride

    def _learn_render_cost(self, preview: bool, views: int, render_ms: float,
                           display_ms: float) -> None:
        """preview_view_count from this render's time: time = fixed + views x per view, the
        two parts from the last preview and the last full render (their view counts differ),
        or all per view while only one kind was measured."""
        self._render_costs[preview] = (max(1, views), render_ms)
        costs = list(self._render_costs.values())
        if len(costs) == 2 and costs[0][0] != costs[1][0]:
            (n0, t0), (n1, t1) = costs
            per_view = (t1 - t0) / (n1 - n0)
            fixed = max(0.0, t0 - per_view * n0)
        else:
            per_view, fixed = render_ms / max(1, views), 0.0
        if not per_view > 0.0:  # noise made the slope useless: all per view
            per_view, fixed = render_ms / max(1, views), 0.0
        budget = FRAME_BUDGET_MS - display_ms - fixed  # display and the fixed part stay
        self.preview_view_count = max(MIN_PREVIEW_VIEWS, int(budget / per_view)
                                      if per_view > 0.0 else 1 << 30)

    def integral_options(self, params: Params,
                         views: Optional[list[int]] = None) -> aos.IntegralOptions:
        """The render options of a request; `views` (a preview's subset) in place of the
        selected views."""
        camera, cam_from_world = self.camera(params)
        options = copy.copy(self.render_options)
        for name, value in (("pose_view", -1), ("cam_from_world", cam_from_world),
                            ("fov_deg", camera.fov_x_deg()), ("width", camera.width),
                            ("height", camera.height),
                            ("aperture_radius", params.aperture_radius),
                            ("view_indices", self.views_of(params) if views is None else views),
                            ("surface_offset", 0.0), ("variance", False)):
            setattr(options, name, value)
        if params.surface:
            options.focal_surface = self.focal_surface
            options.surface_offset = params.surface_offset
        else:
            options.focal_surface = self.focal_plane(params)
        return options

    def map_options(self, params: Params, views: Optional[list[int]] = None) -> aos.MapOptions:
        width = params.width or self.cameras[params.pose_view].width
        options = aos.MapOptions(width=width, aperture_radius=params.aperture_radius,
                                 view_indices=self.views_of(params) if views is None else views)
        # The fields a map shares with the render options (the aperture block), as given.
        page = {"width", "aperture_radius", "view_indices", "focal_surface", "surface_offset"}
        for row in aos.MapOptions._field_table:
            name = row["name"]
            if name not in page and hasattr(self.render_options, name):
                setattr(options, name, getattr(self.render_options, name))
        if params.surface:
            options.focal_surface = self.focal_surface
            options.surface_offset = params.surface_offset
        else:
            options.focal_surface = params.focal_height
        return options

    # ---- rendering ----

    def render_raw(self, params: Params,
                   progress: Optional[Callable[[str, int, int], object]] = None,
                   views: Optional[list[int]] = None) -> Any:
        """The float image, count and grid/camera of one request (C++, GIL released); `views`
        in place of the selected views (a preview's subset)."""
        try:
            if params.mode == "map":
                return aos._core._render_map(self.light_field, self.map_options(params, views),
                                             "", False, True, progress)
            return aos._core.render_integral(self.light_field,
                                             self.integral_options(params, views),
                                             progress)
        except ValueError as error:
            # An option the C++ Check() refused (e.g. a plane behind the camera): the request's.
            raise BadParameter(str(error)) from None

    def display(self, image: np.ndarray, count: np.ndarray, params: Params,
                ranges: Optional[list[tuple[float, float]]] = None) -> np.ndarray:
        """The image as RGBA uint8 for the page: range, gain, offset, colour map. The display
        range (the values shown black and white at gain 1, offset 0) is appended to
        ``ranges`` when given."""
        data = image if image.ndim == 3 else image[:, :, None]
        covered = count > 0
        if params.range == "views" and self.type_range is not None:
            low, high = self.type_range
        else:
            values = data[covered]
            if values.size:
                low, high = (float(v) for v in np.percentile(values, [1.0, 99.0]))
            else:
                low, high = 0.0, 1.0
            if not high > low:
                high = low + 1.0
        if ranges is not None:
            ranges.append((low, high))
        # level = ((v - low) * gain / (high - low) + offset) * 255 + 0.5, in place, in float32.
        scale = 255.0 * params.gain / (high - low)
        bias = 255.0 * params.offset + 0.5 - low * scale
        used = data[:, :, :3] if data.shape[2] >= 3 else data[:, :, :1]
        scaled = np.multiply(used, np.float32(scale), dtype=np.float32)
        scaled += np.float32(bias)
        np.clip(scaled, 0.0, 255.0, out=scaled)
        levels = scaled.astype(np.uint8)
        height, width = count.shape
        rgba = np.empty((height, width, 4), dtype=np.uint8)
        if levels.shape[2] >= 3:
            rgba[:, :, :3] = levels
        else:
            rgba[:, :, :3] = _LUTS[params.colormap][levels[:, :, 0]]
        rgba[:, :, 3] = 255
        return rgba

    def render(self, params: Params,
               progress: Optional[Callable[[str, int, int], object]] = None) -> Frame:
        import time

        # The views once per request (another page's render may learn meanwhile).
        views, stride = self.preview_views(params) if params.preview else (None, 1)
        integrated = len(views or self.views_of(params)) or self.view_count
        start = time.perf_counter()
        try:
            result = self.render_raw(params, progress, views)
        except BadParameter:
            if stride == 1:
                raise
            # The subset missed what the request sees (a small aperture holding none of its
            # views): the preview takes every selected view.
            views, stride = None, 1
            integrated = len(self.views_of(params)) or self.view_count
            result = self.render_raw(params, progress)
        rendered = time.perf_counter()
        ranges: list[tuple[float, float]] = []
        rgba = self.display(result.image, result.count, params, ranges)
        height, width = rgba.shape[:2]
        if self.adaptive_preview:
            self._learn_render_cost(params.preview, integrated, 1000.0 * (rendered - start),
                                    1000.0 * (time.perf_counter() - rendered))
        info: dict[str, Any] = {
            "width": width, "height": height, "mode": params.mode, "preview": params.preview,
            "view_stride": stride,
            "render_ms": round(1000.0 * (rendered - start), 2),
            "display_ms": round(1000.0 * (time.perf_counter() - rendered), 2),
            "uncovered_pixels": int((result.count == 0).sum()),
            "display_range": [float(ranges[0][0]), float(ranges[0][1])],
        }
        if self.radiometry is not None:
            info["display_range_c"] = [float(self.radiometry.celsius(v)) for v in ranges[0]]
        if params.mode == "map":
            info["geotransform"] = list(result.geotransform)
        else:
            info["views_used"] = result.views_used
            info["views_selected"] = result.views_selected
        info["markers"] = self.markers(params, width, height, info.get("geotransform"))
        return Frame(rgba.tobytes(), width, height, info)

    # ---- detection ----

    def markers(self, params: Params, width: int, height: int,
                geotransform: Optional[list[float]] = None) -> list[list[float]]:
        """[number, u, v] of each detection in this frame (pixel coordinates of the frame):
        projected by its camera, or placed by the map's geotransform."""
        found = self.detections
        markers = []
        if params.mode == "map":
            if geotransform is None:
                return []
            x0, pixel, _, y0, _, _ = geotransform
            origin = np.asarray(self.light_field.origin, dtype=float)
            for number, local in found:
                world = origin + local
                u, v = (world[0] - x0) / pixel, (y0 - world[1]) / pixel
                if 0.0 <= u < width and 0.0 <= v < height:
                    markers.append([number, round(float(u), 2), round(float(v), 2)])
            return markers
        if not found:
            return []
        camera, cam_from_world = self.camera(params)
        rotation = np.asarray(cam_from_world.rotation)
        translation = np.asarray(cam_from_world.translation)
        for number, local in found:
            p = rotation @ local + translation
            if p[2] <= 0.0:
                continue
            u = camera.fx * p[0] / p[2] + camera.cx
            v = camera.fy * p[1] / p[2] + camera.cy
            if 0.0 <= u < width and 0.0 <= v < height:
                markers.append([number, round(float(u), 2), round(float(v), 2)])
        return markers

    def detect(self, params: Params,
               options: Optional[aos.DetectOptions] = None) -> dict[str, Any]:
        """Detections (aos.detect, or aos.detect_map in map mode) in the full-size render of
        ``params`` with ``options`` (DetectOptions: parse_detect_options reads a page's); kept,
        so that every later frame marks them. Each carries the pan and focus that centre the
        perspective view on it."""
        params = _with(params, preview=False)
        options = options or aos.DetectOptions()
        try:
            if params.mode == "map":
                result = aos.detect_map(self.light_field, self.map_options(params), options)
            else:
                result = aos.detect(self.light_field, self.integral_options(params), options)
        except ValueError as error:
            raise BadParameter(str(error)) from None
        camera, cam_from_world = self.camera(params)
        rotation = np.asarray(cam_from_world.rotation)
        centre = np.asarray(cam_from_world.center)
        axis = rotation.T @ np.array([0.0, 0.0, 1.0])
        items: list[dict[str, Any]] = []
        kept: list[tuple[int, np.ndarray]] = []
        for number, d in enumerate(result.detections, start=1):
            local = np.asarray(d.local, dtype=float)
            item: dict[str, Any] = {
                "id": number, "pixel": [float(c) for c in d.pixel], "area_px": d.area_px,
                "peak_score": float(d.peak_score), "views": len(d.views), "world": None,
                "lonlat": None if d.lon_lat is None else [float(c) for c in d.lon_lat],
                "celsius": float(d.peak_celsius) if math.isfinite(d.peak_celsius) else None,
            }
            if np.all(np.isfinite(local)):
                item["world"] = [float(c) for c in d.world]
                kept.append((number, local))
                # Pan so that the camera's axis meets the detection's height at the detection
                # (the perspective view; the map shows its whole extent).
                if params.mode != "map" and abs(axis[2]) > 1e-9:
                    hit = centre + (local[2] - centre[2]) / axis[2] * axis
                    item["centre"] = {
                        "pan_x": params.pan_x + float(local[0] - hit[0]),
                        "pan_y": params.pan_y + float(local[1] - hit[1]),
                        "focal_height": (params.focal_height if params.surface
                                         else float(local[2])),
                    }
            items.append(item)
        self.detections = kept
        return {"detections": items, "threshold": float(result.threshold),
                "threshold_rule": result.threshold_rule, "dropped": result.dropped,
                "flagged_pixels": int(result.flagged_pixels)}

    # ---- picking a pixel ----

    def pick(self, params: Params, u: float, v: float) -> dict[str, Any]:
        """World coordinate, depth and view count at continuous pixel (u, v) of the full-size
        render of ``params`` (pixel centres at +0.5)."""
        params = _with(params, preview=False)
        result = self.render_raw(params)
        height, width = result.count.shape
        if not (0.0 <= u < width and 0.0 <= v < height):
            raise BadParameter(f"u, v: ({u:g}, {v:g}) lies outside the {width}x{height} image")
        column, row = int(u), int(v)
        count = int(result.count[row, column])
        value = np.atleast_1d(result.image[row, column]).astype(float).tolist()
        origin = np.asarray(self.light_field.origin, dtype=float)
        answer: dict[str, Any] = {"u": u, "v": v, "count": count, "value": value}
        if self.radiometry is not None and count > 0:
            answer["celsius"] = [float(self.radiometry.celsius(x)) for x in value]
        if params.mode == "map":
            x0, p, _, y0, _, _ = result.geotransform
            world_xy = np.array([x0 + u * p, y0 - v * p])
            if params.surface:
                assert self.focal_surface is not None  # parse() refuses surface without one
                z = float(self.focal_surface.heights_at(self.light_field, world_xy[None, :],
                                                        params.surface_offset)[0])
            else:
                z = params.focal_height + float(origin[2])
            if not math.isfinite(z):
                answer["world"] = None
                return answer
            point_world = np.array([world_xy[0], world_xy[1], z])
            answer["depth"] = None
        else:
            camera, cam_from_world = self.camera(params)
            direction_cam = np.asarray(camera.unproject((u, v)), dtype=float)
            rotation = cam_from_world.rotation
            centre = cam_from_world.center
            if params.surface:
                assert self.focal_surface is not None  # parse() refuses surface without one
                depth_map = self.focal_surface.depth_for(
                    self.light_field, camera, cam_from_world, params.surface_offset,
                    self.views_of(params))
                depth = float(np.asarray(depth_map)[row, column])
                # The depth map holds the pixel centre's depth; the clicked point's ray uses it.
            else:
                plane = self.focal_plane(params)
                normal = np.asarray(plane.normal, dtype=float)
                along = normal @ (rotation.T @ direction_cam)
                depth = float(normal @ (np.asarray(plane.point) - centre) / along) if abs(
                    along) > 1e-12 else 0.0
            if not depth > 0.0:
                answer["world"] = None
                answer["depth"] = None
                return answer
            point_local = centre + rotation.T @ (direction_cam * depth)
            point_world = origin + point_local
            answer["depth"] = depth
        answer["world"] = [float(c) for c in point_world]
        answer["local"] = [float(c) for c in point_world - origin]
        crs = self.light_field.crs
        if crs:
            answer["crs"] = crs
            answer["lonlat"] = lon_lat(crs, point_world[0], point_world[1])
        return answer

    # ---- export and the equivalent command ----

    def export(self, params: Params, kind: str) -> tuple[bytes, str, str]:
        """The full-size render as a file: (bytes, content type, file name)."""
        params = _with(params, preview=False)
        with tempfile.TemporaryDirectory(prefix="aos-viewer-") as folder:
            if kind == "geotiff":
                if params.mode != "map":
                    raise BadParameter("format: geotiff needs the map view (mode=map)")
                path = os.path.join(folder, "map.tif")
                options = self.map_options(params)
                try:
                    aos._core._render_map(self.light_field, options, path, False, False, None)
                except ValueError as error:
                    raise BadParameter(str(error)) from None
                return open(path, "rb").read(), "image/tiff", "aos-map.tif"
            result = self.render_raw(params)
            if kind == "png":
                path = os.path.join(folder, "render.png")
                aos.write_image(path, self.display(result.image, result.count, params)[:, :, :3])
                return open(path, "rb").read(), "image/png", "aos-render.png"
            if kind in ("tiff", "exr"):
                path = os.path.join(folder, "render." + ("tif" if kind == "tiff" else "exr"))
                aos.write_image(path, result.image, sample_type="float32")
                return (open(path, "rb").read(), "image/tiff" if kind == "tiff" else
                        "image/x-exr", os.path.basename(path).replace("render", "aos-render"))
        raise BadParameter(f"format: must be png, tiff, exr or geotiff, got {kind[:20]!r}")

    def command(self, params: Params) -> dict[str, str]:
        """The equivalent `aos-render` command line and Python snippet (full size), spelled from
        the options the render uses through their field tables (aos/_command.py): each field
        that differs from its default, under its flag and its keyword."""
        params = _with(params, preview=False)
        source = shlex.quote(self.source) if self.source else "LIGHTFIELD"
        load = [(row, self.load_options[row["name"]]) for row in aos._core._load_field_table
                if row["name"] in self.load_options]
        if load:
            source += " " + _command.cli_arguments(load)
        # The Python snippet loads the light field and the surface the same way.
        prelude = ""
        if self.source:
            keywords = _command.python_keywords(load)
            prelude = (f"lf = aos.load_lightfield({self.source!r}"
                       + (f", {keywords}" if keywords else "") + ").light_field\n")
        if params.mode == "map":
            command, function, output = "map", "render_map", "map.tif"
            options: Any = self.map_options(params)
        else:
            command, function, output = "integral", "render_integral", "render.png"
            options = self.integral_options(params)
        skip = ("num_threads",) + (("focal_surface",) if params.surface else ())
        changed = _command.changed_fields(options, skip=skip)
        cli_changed = changed
        if params.surface:
            # The surface as the viewer was given it (a file), not its in-memory CRS copy.
            row = next(r for r in type(options)._field_table if r["name"] == "focal_surface")
            cli_changed = [(row, self.surface_path or "SURFACE")] + changed
            if self.surface_path:
                prelude += f"surface = aos.FocalSurface.read({self.surface_path!r})\n"
        cli = (f"aos-render {command} {source} {_command.cli_arguments(cli_changed)} "
               f"-o {output}")
        keywords = _command.python_keywords(changed)
        if params.surface:
            keywords = "focal_surface=surface" + (f", {keywords}" if keywords else "")
        python = prelude + f"result = aos.{function}(lf" + (f", {keywords}" if keywords else "") + ")"
        return {"cli": cli, "python": python}

    # ---- what the page needs to draw itself ----

    def info(self) -> dict[str, Any]:
        lf = self.light_field
        return {
            "source": self.source,
            "view_count": self.view_count,
            "view_names": self.view_names,
            "view_fov_deg": [camera.fov_x_deg() for camera in self.cameras],
            "centres": [[float(c) for c in centre] for centre in self.centres],
            "origin": [float(c) for c in np.asarray(lf.origin)],
            "crs": lf.crs,
            "masked": lf.masked,
            "radiometric": lf.radiometry is not None,
            "channels": self.channels,
            "dtype": self.dtype,
            "up_z": self.up_z,
            "surface": None if self.focal_surface is None else self.focal_surface.kind,
            "fixed_pose": self.fixed_cam_from_world is not None,
            "defaults": params_dict(self.defaults),
            "colormaps": list(COLORMAPS),
        }


def lon_lat(crs: str, x: float, y: float) -> Optional[list[float]]:
    """Longitude and latitude (WGS 84) of a point in ``crs``, or None when no transformer is
    installed (rasterio or pyproj)."""
    try:
        from pyproj import Transformer  # type: ignore[import-not-found]

        transformer = Transformer.from_crs(crs, "EPSG:4326", always_xy=True)
        lon, lat = transformer.transform(x, y)
        return [float(lon), float(lat)]
    except ImportError:
        pass
    try:
        # rasterio has no type stubs (import-untyped), or is absent (import-not-found).
        from rasterio.warp import transform  # type: ignore

        lons, lats = transform(crs, "EPSG:4326", [x], [y])
        return [float(lons[0]), float(lats[0])]
    except ImportError:
        return None
    except Exception:  # an unknown CRS: no latitude/longitude rather than a failed pick
        return None
