"""aos: Airborne Optical Sectioning -- drone light fields and integral rendering.

The algorithms live in the C++ core (``aos._core``); this package re-exports it and adds the
keyword-argument conveniences. Every option is declared once, in the C++ ``XxxOptions`` structs,
which Python exposes with exactly their fields and the C++ defaults. Each function takes an
Options object and/or keywords; one mechanism (``_Router``) sends every keyword to the field of
that name, nested structs included (``all_in_focus(num_threads=3)`` sets the rendering's and the
merge's), refusing unknown or ambiguous names with TypeError. The keywords are typed for type
checkers (``aos._keywords``). A number is a horizontal plane wherever a plane is taken
(``focal_surface=21.0`` is the plane ``Plane.at_height(21.0)``); enums are also taken by name
(``method="robust"``). Simulated scenes are JSON documents (docs/scenes.md) parsed by the C++ core.

Objects: every class has a repr; results that are images have ``.image``. Light fields, views,
cameras, poses, planes and every Options struct compare with ``==`` (exact), pickle (process
pools, Dask) and copy/deepcopy; a light field pickles with its pixels.

Frames and units: metres and radians inside, degrees only where named ``*_deg``; poses are named
by what they map (``cam_from_world``), cameras use OpenCV axes (x right, y down, z forward), and
pixel centres sit at +0.5 in continuous pixel coordinates.

numpy copy rules:

* Images passed in (``LightField.add_view``, ``write_image``) are always COPIED; accepted dtypes
  are uint8, uint16 and float32 (float64 is converted to float32; ``write_image`` also takes
  uint32), shape (H, W) or (H, W, C). Other dtypes raise ValueError.
* Result images (``read_image``, ``IntegralResult.image`` / ``.count``, ``MergeResult.image``,
  ...) share memory with the C++ result, which the array keeps alive. ``View.image`` returns a
  copy; ``FocalStack.images`` / ``.counts`` / ``.variances`` stack the slices into a new
  (N, H, W[, C]) array, a copy on every access.
* Vectors and matrices are float64 arrays converted by value both ways.

Errors: bad input raises ValueError naming the field; a progress callback that raises stops the
work and its exception propagates; Ctrl-C during long calls raises KeyboardInterrupt.
"""

from __future__ import annotations

import copy
import warnings
import json
import os
from typing import TYPE_CHECKING, Any, Callable, Optional, Sequence, TypeVar

try:
    from . import _core
except ImportError as _error:
    # Ctrl-C while the core initialises: pybind11 reports it as ImportError("initialization
    # failed") caused by the KeyboardInterrupt. It is an interrupt, not a broken install.
    if isinstance(_error.__cause__, KeyboardInterrupt):
        raise KeyboardInterrupt from None
    raise
from ._keywords import (
    AllInFocusKeywords,
    CalibrateKeywords,
    DemoKeywords,
    FocalStackKeywords,
    IntegralKeywords,
    MapKeywords,
    MergeKeywords,
    PosesKeywords,
    GroundKeywords,
    QualityKeywords,
    RectifyKeywords,
    ResolutionKeywords,
    FlightPlanKeywords,
    SimulateKeywords,
    SurfaceIntegralKeywords,
    TelemetryKeywords,
    VideoKeywords,
    DetectKeywords,
    DetectMapKeywords,
)

if TYPE_CHECKING:
    from typing_extensions import Unpack
from ._core import (
    AltitudeOutlier,
    TelemetryOptions,
    TelemetryResult,
    VideoFramesOptions,
    VideoFramesResult,
    VideoImportResult,
    OdmGeoEntry,
    OdmGeoFile,
    read_odm_geo,
    write_odm_geo,
    OdmGcp,
    OdmGcpFile,
    read_odm_gcp,
    write_odm_gcp,
    GcpResidual,
    GcpCheckResult,
    check_gcps,
    PosesOptions,
    GroundOptions,
    GroundResult,
    PosesResult,
    PoseSource,
    Radiometry,
    DetectOptions,
    LiveIntegrator,
    LiveOptions,
    LiveTrack,
    Detection,
    DetectResult,
    anomaly_scores,
    read_positions,
    CalibrateOptions,
    CalibrationResult,
    read_camera_file,
    Rectifier,
    RectifyLightFieldResult,
    RectifyOptions,
    make_rectifier,
    LensCamera,
    LensModel,
    ResolutionOptions,
    ResolutionResult,
    FlightPlanOptions,
    FlightPlanResult,
    Waypoint,
    flight_plan_csv,
    flight_plan_geojson,
    flight_plan_kml,
    flight_plan_map,
    PlanPreviewResult,
    DemoOptions,
    DemoRender,
    DemoResult,
    TargetVisibility,
    write_demo,
    AllInFocusOptions,
    FocalStack,
    FocalSurface,
    Heightfield,
    FocalStackOptions,
    GroundTruth,
    MergeMethod,
    MergeOptions,
    MergeResult,
    SurfaceIntegralOptions,
    SurfaceIntegralResult,
    MapOptions,
    MapResult,
    DistributedOptions,
    ViewerOptions,
    ViewParams,
    QualityOptions,
    QualityResult,
    ApertureOptions,
    IntegralOptions,
    IntegralResult,
    LightField,
    LoadResult,
    Mesh,
    PinholeCamera,
    Plane,
    Rigid3d,
    Scene,
    SimulateOptions,
    SimulationResult,
    View,
    __version__,
    default_scene,
    find_view,
    load_lightfield,
    load_scene,
    look_at,
    parse_scene,
    read_image,
    virtual_camera,
    write_image,
    write_lightfield,
    write_simulation,
    ground_heightfield,
    interpolate_plane,
    plane_depth,
    read_focal_stack,
    stack_planes,
    write_focal_stack,
)

__all__ = [
    "DemoOptions",
    "DemoRender",
    "DemoResult",
    "TargetVisibility",
    "run_demo",
    "write_demo",
    "PosesOptions",
    "GroundOptions",
    "GroundResult",
    "estimate_ground",
    "PosesResult",
    "PoseSource",
    "Radiometry",
    "DetectOptions",
    "LiveIntegrator",
    "LiveOptions",
    "LiveTrack",
    "Detection",
    "DetectResult",
    "anomaly_scores",
    "detect",
    "detect_map",
    "estimate_poses",
    "import_colmap",
    "read_positions",
    "AltitudeOutlier",
    "TelemetryOptions",
    "TelemetryResult",
    "import_telemetry",
    "import_video",
    "VideoFramesOptions",
    "VideoFramesResult",
    "VideoImportResult",
    "OdmGeoEntry",
    "OdmGeoFile",
    "read_odm_geo",
    "write_odm_geo",
    "OdmGcp",
    "OdmGcpFile",
    "read_odm_gcp",
    "write_odm_gcp",
    "GcpResidual",
    "GcpCheckResult",
    "check_gcps",
    "CalibrateOptions",
    "CalibrationResult",
    "calibrate",
    "read_camera_file",
    "write_camera_file",
    "Rectifier",
    "RectifyLightFieldResult",
    "RectifyOptions",
    "make_rectifier",
    "LensCamera",
    "LensModel",
    "ResolutionOptions",
    "ResolutionResult",
    "sampling_resolution",
    "FlightPlanOptions",
    "FlightPlanResult",
    "Waypoint",
    "plan_flight",
    "flight_plan_csv",
    "flight_plan_geojson",
    "flight_plan_kml",
    "flight_plan_map",
    "PlanPreviewResult",
    "preview_flight_plan",
    "AllInFocusOptions",
    "FocalStack",
    "FocalSurface",
    "Heightfield",
    "FocalStackOptions",
    "MergeMethod",
    "MergeOptions",
    "MergeResult",
    "SurfaceIntegralOptions",
    "SurfaceIntegralResult",
    "MapOptions",
    "MapResult",
    "DistributedOptions",
    "ViewerOptions",
    "ViewParams",
    "render_map",
    "all_in_focus",
    "interpolate_plane",
    "merge_focal_stack",
    "plane_depth",
    "read_focal_stack",
    "render_focal_stack",
    "render_integral_on_depth",
    "stack_planes",
    "write_focal_stack",
    "GroundTruth",
    "QualityOptions",
    "QualityResult",
    "compare_images",
    "ApertureOptions",
    "IntegralOptions",
    "IntegralResult",
    "LightField",
    "LoadResult",
    "Mesh",
    "PinholeCamera",
    "Plane",
    "Rigid3d",
    "Scene",
    "SimulateOptions",
    "SimulationResult",
    "View",
    "__version__",
    "default_scene",
    "find_view",
    "load_lightfield",
    "load_scene",
    "look_at",
    "parse_scene",
    "read_image",
    "rectify_light_field",
    "render_integral",
    "simulate",
    "virtual_camera",
    "write_image",
    "write_lightfield",
    "write_simulation",
    "view",
    "ground_heightfield",
]

# Keyword routing: every wrapper below takes its options as an Options object and/or as keywords,
# and one mechanism sorts the keywords into the (possibly nested) Options structs by field name.

# Fields that name one setting for every stage that has it, set everywhere at once (as the CLI's
# --threads sets the rendering and the merge of `allinfocus`).
_SHARED_FIELDS = frozenset({"num_threads"})


def _is_options(value: Any) -> bool:
    return hasattr(type(value), "_fields")


def _words(class_name: str) -> str:
    """MergeMethod -> 'merge method'."""
    return "".join(" " + c.lower() if c.isupper() else c for c in class_name).strip()


class _Router:
    """Routes keyword arguments to the fields of one or more Options structs by field name.

    A keyword goes to the field of that name wherever it lies in the structs, nested Options
    included (FocalStackOptions.render, AllInFocusOptions.merge.robust, ...): a struct-valued
    field takes an Options object of its type, otherwise the keyword names a plain field. A name
    at several plain fields is refused as ambiguous, unless it is one of _SHARED_FIELDS, which is
    set at all of them. Unknown names raise TypeError listing the valid ones; ``exclude`` lists
    fields the function ignores (a stack's render.surface_offset), which are refused likewise.
    A deprecated spelling of a field (the class's ``_deprecated``: ``focal_plane`` for
    ``focal_surface``) warns with DeprecationWarning and sets the field.
    Values: an enum field takes its member's name (``method="robust"``, ValueError for an unknown
    one), a plane field a number (its height; converted by aos._core).
    """

    def __init__(self, function: str, *root_types: type, keywords: str = "",
                 exclude: Sequence[Sequence[str]] = (), also: Optional[dict[str, str]] = None):
        self.function = function
        self.root_types = root_types
        # The TypedDict of these keywords in aos._keywords (generated by tools/options.py from
        # the routed fields; `also`: types a keyword takes beyond its field's, by name).
        self.keywords = keywords
        self.also = dict(also or {})
        excluded = {tuple(path) for path in exclude}
        # Paths (root index, field, nested field, ...) by the field name they end with.
        self.paths: dict[str, list[tuple[Any, ...]]] = {}
        # Deprecated spellings (old name -> field name) of the structs' fields: a keyword so
        # spelled warns (DeprecationWarning) and goes to the field.
        self.deprecated: dict[str, str] = {}

        def walk(options: Any, prefix: tuple[Any, ...]) -> None:
            self.deprecated.update(getattr(type(options), "_deprecated", {}))
            for name in type(options)._fields:
                path = prefix + (name,)
                if path[1:] in excluded:
                    continue
                self.paths.setdefault(name, []).append(path)
                value = getattr(options, name)
                if _is_options(value):
                    walk(value, path)

        for index, root_type in enumerate(root_types):
            walk(root_type(), (index,))

    def names(self) -> set[str]:
        """Every keyword this router accepts."""
        return set(self.paths)

    def apply(self, roots: Sequence[Any], kwargs: dict[str, Any]) -> None:
        """Sets each keyword on its field(s) of ``roots`` (Options objects of root_types), in
        place. Outer fields first: ``stack=FocalStackOptions(...)`` is set before ``slices=``."""
        renamed: dict[str, Any] = {}
        for key, value in kwargs.items():
            if key in self.deprecated and key not in self.paths:
                new = self.deprecated[key]
                warnings.warn(f"{self.function}(): {key}= is deprecated; use {new}=",
                              DeprecationWarning, stacklevel=3)
                if new in kwargs:
                    raise TypeError(f"{self.function}(): give {new}= or {key}=, not both")
                key = new
            renamed[key] = value
        assignments = [(path, value) for key, value in renamed.items()
                       for path in self._targets(roots, key, value)]
        for path, value in sorted(assignments, key=lambda assignment: len(assignment[0])):
            self._set(roots, path, value)

    def _targets(self, roots: Sequence[Any], key: str, value: Any) -> list[tuple[Any, ...]]:
        if key not in self.paths:
            raise TypeError(
                f"{self.function}() got an unexpected keyword argument {key!r} "
                f"(options: {', '.join(sorted(self.paths))})"
            )
        struct = [path for path in self.paths[key] if _is_options(self._get(roots, path))]
        plain = [path for path in self.paths[key] if path not in struct]
        if struct and (not plain or isinstance(value, type(self._get(roots, struct[0])))):
            targets = struct
        else:
            targets = plain
        if len(targets) > 1 and key not in _SHARED_FIELDS:
            where = ", ".join(".".join(path[1:]) for path in targets)
            raise TypeError(
                f"{self.function}(): keyword argument {key!r} is ambiguous ({where}); "
                "set it on an options object instead"
            )
        return targets

    @staticmethod
    def _get(roots: Sequence[Any], path: tuple[Any, ...]) -> Any:
        value = roots[path[0]]
        for name in path[1:]:
            value = getattr(value, name)
        return value

    def _set(self, roots: Sequence[Any], path: tuple[Any, ...], value: Any) -> None:
        chain = [roots[path[0]]]
        for name in path[1:-1]:
            chain.append(getattr(chain[-1], name))
        name = path[-1]
        current = getattr(chain[-1], name)
        members = getattr(type(current), "__members__", None)
        if isinstance(value, str) and members is not None:
            if value not in members:
                names = list(members)
                raise ValueError(
                    f"{name}: unknown {_words(type(current).__name__)} {value!r} "
                    f"({', '.join(names[:-1])} or {names[-1]})"
                )
            value = members[value]
        try:
            setattr(chain[-1], name, value)
        except TypeError:
            expected = type(current).__name__
            if isinstance(current, Plane):
                expected = "Plane or a number (the height of a horizontal plane)"
            elif isinstance(current, _core.FocalSurface):
                expected = ("a FocalSurface, Mesh, Heightfield, Plane or a number (the height of "
                            "a horizontal plane)")
            raise TypeError(
                f"{self.function}(): {name}: expected {expected}, got {type(value).__name__} "
                f"{value!r}"
            ) from None
        # Write the nested structs back up (pybind11 hands out references to nested fields, but
        # this does not rely on it).
        for index in range(len(chain) - 1, 0, -1):
            setattr(chain[index - 1], path[index], chain[index])


_Options = TypeVar("_Options")


def _copy_options(function: str, cls: type[_Options], options: Optional[_Options]) -> _Options:
    """A copy of ``options`` (the caller's object is never changed), or the defaults."""
    if options is None:
        return cls()
    if not isinstance(options, cls):
        raise TypeError(
            f"{function}(): options must be {cls.__name__} or None, not {type(options).__name__}"
        )
    return copy.copy(options)


def _require_pose(function: str, render: IntegralOptions, kwargs: dict[str, Any]) -> None:
    """Refuses a virtual camera without a pose: neither pose_view nor cam_from_world given (an
    identity cam_from_world counts as not given unless passed as a keyword)."""
    if render.pose_view >= 0 or "cam_from_world" in kwargs:
        return
    if render.cam_from_world == Rigid3d():
        raise ValueError(
            f"{function}(): no virtual camera pose: give pose_view or cam_from_world (a view's "
            "index, or a pose such as aos.look_at(eye, target))"
        )


_RENDER_INTEGRAL = _Router("render_integral", IntegralOptions, keywords="IntegralKeywords")
# A stack's slices replace its surface's offset; a terrain-following stack takes focal_surface (a
# mesh, DEM or depth map) and first_offset/last_offset.
_RENDER_FOCAL_STACK = _Router(
    "render_focal_stack",
    FocalStackOptions,
    keywords="FocalStackKeywords",
    exclude=[("render", "surface_offset")],
)
_MERGE_FOCAL_STACK = _Router("merge_focal_stack", MergeOptions, keywords="MergeKeywords")
_ALL_IN_FOCUS = _Router(
    "all_in_focus",
    AllInFocusOptions,
    keywords="AllInFocusKeywords",
    exclude=[("stack", "render", "surface_offset")],
)
_RENDER_INTEGRAL_ON_DEPTH = _Router(
    "render_integral_on_depth",
    IntegralOptions,
    SurfaceIntegralOptions,
    keywords="SurfaceIntegralKeywords",
    exclude=[("surface_offset",)],  # the depth gives the focal points
)
_RENDER_MAP = _Router("render_map", MapOptions, keywords="MapKeywords")
_SIMULATE = _Router("simulate", SimulateOptions, keywords="SimulateKeywords")
_RUN_DEMO = _Router("run_demo", DemoOptions, keywords="DemoKeywords")
_COMPARE_IMAGES = _Router("compare_images", QualityOptions, keywords="QualityKeywords")
_SAMPLING_RESOLUTION = _Router("sampling_resolution", ResolutionOptions,
                               keywords="ResolutionKeywords")
_PLAN_FLIGHT = _Router("plan_flight", FlightPlanOptions, keywords="FlightPlanKeywords")
_CALIBRATE = _Router("calibrate", CalibrateOptions, keywords="CalibrateKeywords")
_RECTIFY_LIGHT_FIELD = _Router("rectify_light_field", RectifyOptions, keywords="RectifyKeywords")
_ESTIMATE_POSES = _Router("estimate_poses", PosesOptions, keywords="PosesKeywords")
_IMPORT_COLMAP = _Router("import_colmap", PosesOptions, keywords="PosesKeywords")
_ESTIMATE_GROUND = _Router("estimate_ground", GroundOptions, keywords="GroundKeywords")


_IMPORT_TELEMETRY = _Router("import_telemetry", TelemetryOptions, keywords="TelemetryKeywords")
# The video import writes its own telemetry CSV: the log's fields are not keywords.
_IMPORT_VIDEO = _Router(
    "import_video",
    VideoFramesOptions,
    TelemetryOptions,
    keywords="VideoKeywords",
    exclude=[("telemetry_file",), ("frame_interval_s",), ("time_offset_s",), ("altitude",),
             ("radiometric",), ("kelvin_per_count",), ("kelvin_offset",),
             ("temperature_frames_dir",)],
)
# Detection renders the integral image of IntegralOptions and scores it with DetectOptions.
_DETECT = _Router("detect", IntegralOptions, DetectOptions, keywords="DetectKeywords")
_DETECT_MAP = _Router("detect_map", MapOptions, DetectOptions, keywords="DetectMapKeywords")


def render_integral(
    light_field: LightField,
    options: Optional[IntegralOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Unpack[IntegralKeywords],
) -> IntegralResult:
    """Integral rendering of ``light_field`` (Eq. 1 of the AOS paper).

    ``kwargs`` are fields of :class:`IntegralOptions` overriding those of a copy of ``options``
    (or of the defaults); unknown names raise TypeError. ``focal_surface`` may be a number: the
    horizontal plane at that height; or a Plane, Mesh, Heightfield or FocalSurface. The virtual camera needs a pose: ``pose_view`` or
    ``cam_from_world`` (ValueError otherwise). ``progress(stage, done, total)`` is called from
    this thread at most every 0.1 s (and once when done == total); if it raises, rendering stops
    and the exception propagates. The GIL is released while rendering.

    Example::

        result = aos.render_integral(lf, focal_surface=0.0, pose_view=60)
        image, count = result.image, result.count   # float32 and uint32, no copies
    """
    merged = _copy_options("render_integral", IntegralOptions, options)
    keywords: dict = dict(kwargs)
    _RENDER_INTEGRAL.apply([merged], keywords)
    _require_pose("render_integral", merged, keywords)
    return _core.render_integral(light_field, merged, progress)


def detect(
    light_field: LightField,
    options: Optional[IntegralOptions] = None,
    detect_options: Optional[DetectOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Unpack[DetectKeywords],
) -> DetectResult:
    """Finds anomalies (a person, an animal) in the integral image of ``light_field``, as
    ``aos-render detect`` does: the image of :func:`render_integral` (``kwargs`` of
    :class:`IntegralOptions`: the virtual camera, the focal surface, the views) scored by
    :class:`DetectOptions` (``detector`` 'rx', 'rx-local', 'anomaly-imaging' or 'temperature',
    ``channels``, ``one_sided`` (warm spots only, one feature), the threshold: ``quantile``,
    ``false_alarm_rate``, ``min_score``, ``robust_sigmas`` or ``min_temperature_c``; the blobs:
    ``min_area_px``, ``max_detections``). Each detection is located on the focal surface
    (``world``; ``lon_lat`` in WGS84 when the light field has a CRS) with the views that saw it.
    ``result.write("found.geojson")`` writes GeoJSON, KML or CSV; ``result.overlay()`` draws
    them. The result pickles. Raises ValueError naming the field (docs/detection.md).

    Example::

        found = aos.detect(lf, pose_view=191, focal_surface=aos.FocalSurface.read("dem.obj"))
        for d in found.detections:
            print(d.lon_lat, d.peak_score, len(d.views))
    """
    merged = _copy_options("detect", IntegralOptions, options)
    scoring = _copy_options("detect", DetectOptions, detect_options)
    keywords: dict = dict(kwargs)
    _DETECT.apply([merged, scoring], keywords)
    _require_pose("detect", merged, keywords)
    return _core._detect(light_field, merged, scoring, progress)


def detect_map(
    light_field: LightField,
    options: Optional[MapOptions] = None,
    detect_options: Optional[DetectOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Unpack[DetectMapKeywords],
) -> DetectResult:
    """:func:`detect` on the orthographic map (``aos-render map --detect``): ``kwargs`` are fields
    of :class:`MapOptions` (pixel_size or width, extent, focal_surface, ...) or
    :class:`DetectOptions`. rx-local's windows follow the map's pixel size; a detection's point
    is its pixels' vertical lines on the focal surface; ``result.geotransform`` is the map's.

    Example::

        found = aos.detect_map(lf, pixel_size=0.1, focal_surface=aos.FocalSurface.read("dem.tif"))
        found.write("found.geojson")
    """
    merged = _copy_options("detect_map", MapOptions, options)
    scoring = _copy_options("detect_map", DetectOptions, detect_options)
    _DETECT_MAP.apply([merged, scoring], dict(kwargs))
    return _core._detect_map(light_field, merged, scoring, progress)


def simulate(
    scene: "Scene | dict[str, Any] | str | os.PathLike[str]",
    output_dir: "Optional[str | os.PathLike[str]]" = None,
    options: Optional[SimulateOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Unpack[SimulateKeywords],
) -> SimulationResult:
    """Simulates a scene (docs/scenes.md): its views, recorded poses and ground truth.

    ``scene`` is a :class:`Scene`, a dict in the scene-file schema (image paths relative to the
    current folder), or the path of a scene file. ``kwargs`` are fields of
    :class:`SimulateOptions`. With ``output_dir`` the result is also written there (a new or
    empty folder; see ``aos-render simulate``). The GIL is released while simulating;
    ``progress(stage, done, total)`` works as in :func:`render_integral`.

    Example::

        result = aos.simulate({"occluders": {"voxels": {"density": 0.5}}, "sampling": {"grid": 9}})
        integral = aos.render_integral(result.light_field, cam_from_world=result.truth.cam_from_world)
    """
    if isinstance(scene, Scene):
        parsed = scene
    elif isinstance(scene, dict):
        parsed = parse_scene(json.dumps(scene), "<dict>", os.getcwd())
    elif isinstance(scene, (str, os.PathLike)):
        parsed = load_scene(os.fspath(scene))
    else:
        raise TypeError(
            f"simulate(): scene must be a Scene, a dict or a path, not {type(scene).__name__}"
        )
    merged = _copy_options("simulate", SimulateOptions, options)
    _SIMULATE.apply([merged], dict(kwargs))
    result = _core._simulate(parsed, merged, progress)
    if output_dir is not None:
        write_simulation(result, parsed, os.fspath(output_dir))
    return result


def _scene_of(function: str, scene: Any) -> Scene:
    """A Scene from a Scene, a dict in the scene-file schema, or the path of a scene file."""
    if isinstance(scene, Scene):
        return scene
    if isinstance(scene, dict):
        return parse_scene(json.dumps(scene), "<dict>", os.getcwd())
    if isinstance(scene, (str, os.PathLike)):
        return load_scene(os.fspath(scene))
    raise TypeError(
        f"{function}(): scene must be a Scene, a dict or a path, not {type(scene).__name__}"
    )


def run_demo(
    scene: "Optional[Scene | dict[str, Any] | str | os.PathLike[str]]" = None,
    output_dir: "Optional[str | os.PathLike[str]]" = None,
    options: Optional[DemoOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Unpack[DemoKeywords],
) -> DemoResult:
    """What ``aos-render demo`` does: simulate a scene (None: the built-in default, a red target
    under forest canopy), render a single view, integral images and an all-in-focus image from
    its truth camera, and score each against the ground truth and by how clearly the target
    shows (``DemoRender.visibility``).

    ``scene`` is a :class:`Scene`, a dict in the scene-file schema or a path, as for
    :func:`simulate`. ``kwargs`` are fields of :class:`DemoOptions`. With ``output_dir`` the
    result is also written there with :func:`write_demo` (a new or empty folder, refused before
    any work otherwise): the simulation, the PNGs, demo.json and an index.html to open in a
    browser. The GIL is released while working; ``progress(stage, done, total)`` works as in
    :func:`render_integral`.

    Example::

        result = aos.run_demo(output_dir="aos-demo")   # then open aos-demo/index.html
        print(result.render("integral_ground").visibility.standout_fraction)
    """
    parsed = default_scene() if scene is None else _scene_of("run_demo", scene)
    merged = _copy_options("run_demo", DemoOptions, options)
    _RUN_DEMO.apply([merged], dict(kwargs))
    merged.check()
    if output_dir is not None:
        _core._check_demo_folder(os.fspath(output_dir))  # before any work
    result = _core._run_demo(parsed, merged, progress)
    if output_dir is not None:
        write_demo(result, os.fspath(output_dir))
    return result


def compare_images(
    test: Any,
    reference: Any,
    mask: Any = None,
    options: Optional[QualityOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Unpack[QualityKeywords],
) -> QualityResult:
    """PSNR, SSIM and colour (quaternion) SSIM of ``test`` against ``reference``.

    Arrays (H, W) or (H, W, C) of uint8, uint16, uint32 or float32 (float64 converted), copied.
    ``mask`` (e.g. a count map): non-zero pixels are compared (SSIM: pixels whose whole window is
    valid). ``kwargs`` are fields of :class:`QualityOptions`. Definitions: docs/metrics.md.
    The working memory is checked against the budget first (ValueError); the GIL is released
    and ``progress(stage, done, total)`` works as in :func:`render_integral` (Ctrl-C stops it).
    """
    merged = _copy_options("compare_images", QualityOptions, options)
    _COMPARE_IMAGES.apply([merged], dict(kwargs))
    return _core._compare_images(test, reference, mask, merged, progress)


def render_focal_stack(
    light_field: LightField,
    options: Optional[FocalStackOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Unpack[FocalStackKeywords],
) -> FocalStack:
    """Renders a focal stack: N slices between ``first_plane`` and ``last_plane``.

    ``kwargs`` are fields of :class:`FocalStackOptions` (first_plane, last_plane, slices; a
    number is the horizontal plane at that height) or of :class:`IntegralOptions` (applied to
    ``options.render``: pose_view, fov_deg, width, aperture_radius, variance, ...).
    ``focal_surface`` (a Mesh, Heightfield or FocalSurface that is not a plane) makes a
    terrain-following stack at first_offset .. last_offset; another plane there is refused
    (the slices' planes replace it). All slices stay in memory; :func:`all_in_focus` streams.

    Example::

        stack = aos.render_focal_stack(lf, pose_view=60, first_plane=0.0, last_plane=20.0,
                                       slices=100)
        images = stack.images   # float32 (100, H, W[, C]), a copy
    """
    merged = _copy_options("render_focal_stack", FocalStackOptions, options)
    _RENDER_FOCAL_STACK.apply([merged], dict(kwargs))
    _require_pose("render_focal_stack", merged.render, dict(kwargs))
    return _core._render_focal_stack(light_field, merged, progress)


def merge_focal_stack(
    stack: FocalStack,
    options: Optional[MergeOptions] = None,
    *,
    light_field: Optional[LightField] = None,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Unpack[MergeKeywords],
) -> MergeResult:
    """All-in-focus image, depth and confidence of a stack (``method`` sobel/improved/robust).

    ``kwargs`` are fields of :class:`MergeOptions` (``method`` may be a string) or of
    :class:`SurfaceIntegralOptions` (agreement, min_inlier_fraction). The robust method
    needs a stack rendered with ``variance=True`` and the ``light_field`` it came from.
    """
    merged = _copy_options("merge_focal_stack", MergeOptions, options)
    _MERGE_FOCAL_STACK.apply([merged], dict(kwargs))
    return _core._merge_focal_stack(stack, merged, light_field, progress)


def all_in_focus(
    light_field: LightField,
    options: Optional[AllInFocusOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Unpack[AllInFocusKeywords],
) -> MergeResult:
    """The one-call pipeline: slices rendered one at a time and merged (memory flat in N).

    ``kwargs`` are fields of :class:`AllInFocusOptions`, nested ones included: of
    :class:`MergeOptions` (method as a string or MergeMethod, ...), :class:`FocalStackOptions`
    (first_plane, last_plane, slices; a number is the horizontal plane at that height),
    :class:`IntegralOptions` (pose_view, fov_deg, width, height, aperture_radius, ...) or
    :class:`SurfaceIntegralOptions` (agreement, min_inlier_fraction: the robust mean).
    ``num_threads`` limits the rendering and the merge alike, as ``aos-render allinfocus
    --threads`` does.

    Example::

        result = aos.all_in_focus(lf, pose_view=60, first_plane=0.0, last_plane=20.0, slices=100)
        image, depth = result.image, result.depth
    """
    merged = _copy_options("all_in_focus", AllInFocusOptions, options)
    _ALL_IN_FOCUS.apply([merged], dict(kwargs))
    _require_pose("all_in_focus", merged.stack.render, dict(kwargs))
    return _core._all_in_focus(light_field, merged, progress)


def render_integral_on_depth(
    light_field: LightField,
    depth: Any,
    options: Optional[IntegralOptions] = None,
    surface: Optional[SurfaceIntegralOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Unpack[SurfaceIntegralKeywords],
) -> SurfaceIntegralResult:
    """Integral on a per-pixel depth surface (``depth``: camera z in metres, (H, W), copied).

    ``kwargs`` are fields of :class:`IntegralOptions` or :class:`SurfaceIntegralOptions`
    (robust, agreement, min_inlier_fraction). The depth gives the focal points; focal_surface
    gives only the normal of the grazing test (a plane's, else the up axis). Used for the
    "oracle" image on a true depth map and for re-integrating a merged depth map.
    """
    render = _copy_options("render_integral_on_depth", IntegralOptions, options)
    surf = _copy_options("render_integral_on_depth", SurfaceIntegralOptions, surface)
    _RENDER_INTEGRAL_ON_DEPTH.apply([render, surf], dict(kwargs))
    _require_pose("render_integral_on_depth", render, dict(kwargs))
    return _core._render_integral_on_depth(light_field, render, depth, surf, progress)


def render_map(
    light_field: LightField,
    options: Optional[MapOptions] = None,
    *,
    path: "Optional[str | os.PathLike[str]]" = None,
    force: bool = False,
    arrays: Optional[bool] = None,
    progress: Optional[Callable[[str, int, int], object]] = None,
    client: Any = None,
    load: Optional[dict[str, Any]] = None,
    **kwargs: Unpack[MapKeywords],
) -> MapResult:
    """An orthographic map of ``light_field``: a virtual camera looking straight down onto
    ``focal_surface`` (default the horizontal plane z = 0, local frame; a number is the plane at
    that height; a Mesh or DEM Heightfield a terrain), rendered in tiles
    (docs/terrain-and-maps.md).

    ``kwargs`` are fields of :class:`MapOptions` (pixel_size or width, extent, focal_surface,
    surface_offset, aperture_radius, view_indices, min_view_angle_deg, lens_tolerance_px,
    tile_size, num_threads, max_pixels). Returns a :class:`MapResult`: ``geotransform`` (GDAL's, world coordinates =
    origin + local), ``crs`` (the light field's), the summary (``views_used``, ``samples``,
    ``uncovered_pixels``, ...) and, when held in memory, ``image`` (float32, row 0 = largest y)
    and ``count`` (uint32; 0 = no view sees the pixel).

    Without ``path`` the map is held in memory (about 4 (C + 1) bytes per pixel). With ``path``
    it is written as a Cloud-Optimised GeoTIFF (bands: the image with NaN = nodata where count
    is 0, then the count; an existing file is refused unless ``force``) and, by default, streamed
    tile by tile as the CLI does, so memory does not grow with the map: the result then has no
    arrays (``has_arrays`` is False; ``image`` raises). ``arrays=True`` keeps them as well.
    Raises ValueError naming the field or the file.

    Example::

        m = aos.render_map(lf, pixel_size=0.05, focal_surface=0.0, path="map.tif")   # streamed
        x0, p, _, y0, _, _ = m.geotransform   # pixel (col, row) centre: x0 + (col + 0.5) p
        m = aos.render_map(lf, pixel_size=0.05)                          # in memory: m.image

    With ``client`` (a ``dask.distributed.Client``) the map's tiles are rendered as Dask tasks
    that read only the frames they need from their files (``load``: grey, mask, mask_dir as
    load_lightfield), bit for bit the same map (aos.distributed, docs/distributed.md); the
    result is then an ``aos.distributed.DistributedMapResult`` with the same attributes.
    """
    merged = _copy_options("render_map", MapOptions, options)
    _RENDER_MAP.apply([merged], dict(kwargs))
    target = "" if path is None else os.fspath(path)
    if path is not None and not target:
        raise ValueError("render_map(): path: empty; give a file name or None")
    if arrays is None:
        arrays = path is None
    if not arrays and path is None:
        raise ValueError("render_map(): arrays=False without a path keeps nothing; give a path")
    if client is not None:
        from . import distributed

        return distributed.render_map(light_field, merged, path=target or None, client=client,
                                      load=load, force=force, arrays=bool(arrays),
                                      progress=progress)  # type: ignore[return-value]
    if load is not None:
        raise ValueError("render_map(): load: only with client (the light field holds its frames)")
    return _core._render_map(light_field, merged, target, force, bool(arrays), progress)


def sampling_resolution(
    camera: "LensCamera | PinholeCamera",
    options: Optional[ResolutionOptions] = None,
    **kwargs: Unpack[ResolutionKeywords],
) -> ResolutionResult:
    """Sampling resolution of a nadir camera over a focal plane: Eq. 2 and the Appendix A
    back-projection of the AOS paper, and the effective value p' = p + 2e under a pose error.

    ``kwargs`` are fields of :class:`ResolutionOptions` (distance_m, pose_error_px, pose_error_m).

    Example::

        cam = aos.LensCamera.from_pinhole(aos.PinholeCamera.from_fov(1871, 1871, 80.0))
        r = aos.sampling_resolution(cam, distance_m=35.0)   # r.eq2_samples_per_m2 ~ 1014
    """
    if isinstance(camera, PinholeCamera):
        camera = LensCamera.from_pinhole(camera)
    merged = _copy_options("sampling_resolution", ResolutionOptions, options)
    _SAMPLING_RESOLUTION.apply([merged], dict(kwargs))
    return _core._sampling_resolution(camera, merged)


def plan_flight(
    options: Optional[FlightPlanOptions] = None,
    *,
    csv: "Optional[str | os.PathLike[str]]" = None,
    geojson: "Optional[str | os.PathLike[str]]" = None,
    kml: "Optional[str | os.PathLike[str]]" = None,
    png: "Optional[str | os.PathLike[str]]" = None,
    png_size: int = 800,
    force: bool = False,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Unpack[FlightPlanKeywords],
) -> FlightPlanResult:
    """Plans a flight over a synthetic aperture: the waypoints, the number of images, the flight's
    length and time, frames per minute and the Eq. 2 sampling resolution (docs/flight-planning.md;
    ``aos-render plan`` is its twin).

    ``kwargs`` are fields of :class:`FlightPlanOptions` (shape, center, radius_m, pattern,
    spacing_m, along_spacing_m, outer_scale, altitude_m, dem, ...). ``csv``, ``geojson``, ``kml``
    and ``png`` name files to write, each refused if it exists unless ``force``; they are written
    only when the plan is accepted (a bad option or a plan over the battery writes nothing).
    A plan over ``max_waypoints`` (10**6), the battery or the memory budget is refused before it
    is generated; Ctrl-C (or ``progress`` raising) stops the planning and the exports and writes
    nothing.

    Example (the paper's experiment 1: 231 images)::

        plan = aos.plan_flight(shape="circle", radius_m=15.0, spacing_m=3.0, along_spacing_m=1.0,
                               altitude_m=20.0)
    """
    merged = _copy_options("plan_flight", FlightPlanOptions, options)
    _PLAN_FLIGHT.apply([merged], dict(kwargs))
    outputs = {"csv": csv, "geojson": geojson, "kml": kml, "png": png}
    for name, path in outputs.items():
        if path is None:
            continue
        if os.path.isdir(path):
            raise ValueError(f"{os.fspath(path)}: {name} is a folder; give a file name")
        if os.path.lexists(path) and not force:
            raise ValueError(f"{os.fspath(path)}: {name} exists; give force=True to replace it (nothing was written)")
    result = _core._plan_flight(merged, progress)
    texts = {}
    if csv is not None:
        texts[csv] = flight_plan_csv(result)
    if geojson is not None:
        texts[geojson] = flight_plan_geojson(result)
    if kml is not None:
        texts[kml] = flight_plan_kml(result)
    image = flight_plan_map(merged, result, png_size) if png is not None else None
    for path, text in texts.items():
        temporary = os.fspath(path) + ".partial"
        try:
            with open(temporary, "w", encoding="utf-8") as stream:
                stream.write(text)
            os.replace(temporary, path)
        except BaseException:  # Ctrl-C or a full disk: no partial file is left behind
            if os.path.lexists(temporary):
                os.remove(temporary)
            raise
    if png is not None and image is not None:
        write_image(os.fspath(png), image)
    return result


def preview_flight_plan(
    plan: FlightPlanResult,
    scene: "Scene | dict[str, Any] | str | os.PathLike[str]",
    *,
    num_threads: int = -1,
    progress: Optional[Callable[[str, int, int], object]] = None,
) -> PlanPreviewResult:
    """Flies ``plan`` in the simulator over ``scene`` (a Scene, a dict in the scene-file schema or
    a path; docs/scenes.md) and reports what it reveals: the share of rays that reach the ground,
    PSNR/SSIM of the integral image on the ground against the occluder-free truth
    (``aos-render plan --simulate``; cpp/aos/plan/preview.h)."""
    return _core._preview_flight_plan(plan, _scene_of("preview_flight_plan", scene), num_threads, progress)


def rectify_light_field(
    light_field: LightField,
    options: Optional[RectifyOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Unpack[RectifyKeywords],
) -> RectifyLightFieldResult:
    """Rectifies every lens view of ``light_field`` into a perspective view, as ``aos-render
    rectify --lightfield`` does: its pixels are resampled (``make_rectifier``, one per distinct
    lens), its camera becomes the rectified pinhole camera and its pose turns with it; pinhole
    views are kept. ``kwargs`` are fields of :class:`RectifyOptions` (fov_deg, width, height,
    yaw_deg, pitch_deg, roll_deg). Raises ValueError naming the field and the view when a lens
    does not cover the requested view. The GIL is released.

    Example::

        pinhole = aos.rectify_light_field(raw_lf, fov_deg=80).light_field
        image = aos.render_integral(pinhole, pose_view=10, focal_surface=0.0).image
    """
    merged = _copy_options("rectify_light_field", RectifyOptions, options)
    _RECTIFY_LIGHT_FIELD.apply([merged], dict(kwargs))
    return _core._rectify_light_field(light_field, merged, progress)


def calibrate(
    frames: "Sequence[Any]",
    names: "Optional[Sequence[str]]" = None,
    options: Optional[CalibrateOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Unpack[CalibrateKeywords],
) -> CalibrationResult:
    """Calibrates a lens from checkerboard frames (OpenCV), as ``aos-render calibrate`` does.

    ``frames`` are numpy arrays ((H, W) or (H, W, C) of uint8, uint16 or float32; float64 is
    converted to float32; COPIED) or image file paths (str or os.PathLike, read by the core's
    image reader), all of the same size. ``names`` label them in the result and in errors
    (default: the path, or ``frame_0000``, ``frame_0001``, ... for arrays). ``kwargs`` are fields
    of :class:`CalibrateOptions`: ``model`` (a LensModel or "pinhole", "radtan", "fisheye",
    "omnidir"), ``pattern_columns`` and ``pattern_rows`` (inner corners), ``square_size_m``.
    Frames where the board is not found are listed in ``frames_rejected``; at least 3 must be
    used. The GIL is released while reading and fitting; ``progress(stage, done, total)`` works
    as in :func:`render_integral`. Raises ValueError naming the option or the frame.

    Example::

        options = aos.CalibrateOptions(model=aos.LensModel.fisheye, square_size_m=0.03)
        result = aos.calibrate(sorted(glob.glob("board/*.png")), options=options)
        aos.write_camera_file("camera.json", result.camera, result, options)  # as the CLI writes
    """
    frames = list(frames)
    if names is None:
        names = [
            os.fsdecode(frame) if isinstance(frame, (str, bytes, os.PathLike)) else f"frame_{i:04d}"
            for i, frame in enumerate(frames)
        ]
    merged = _copy_options("calibrate", CalibrateOptions, options)
    _CALIBRATE.apply([merged], dict(kwargs))
    return _core._calibrate(frames, list(names), merged, progress)


def write_camera_file(
    path: "str | os.PathLike[str]",
    camera: LensCamera,
    calibration: "CalibrationResult | dict[str, Any] | None" = None,
    options: Optional[CalibrateOptions] = None,
) -> None:
    """Writes ``camera`` as a camera file (JSON, read by :func:`read_camera_file` and by
    ``aos-render rectify --camera``), atomically.

    ``calibration`` is stored as the file's free-form "calibration" record: a dict (any JSON
    object), or a :class:`CalibrationResult`, recorded as ``aos-render calibrate`` records it
    (rms_px, frames_used, frames_rejected, and with ``options`` the pattern "COLUMNSxROWS" and
    square_size_m). Raises ValueError naming the file and the field for an invalid camera.
    """
    if isinstance(calibration, CalibrationResult):
        _core._write_camera_file(os.fspath(path), camera,
                                 _core._calibration_record(calibration, options))
        return
    if calibration is None or isinstance(calibration, dict):
        if options is not None:
            raise TypeError("write_camera_file(): options is for a CalibrationResult calibration")
        record = calibration if calibration is not None else {}
    else:
        raise TypeError(
            "write_camera_file(): calibration must be a CalibrationResult, a dict or None, not "
            f"{type(calibration).__name__}"
        )
    text = json.dumps(record, allow_nan=False) if record else ""  # ValueError for NaN, inf
    _core._write_camera_file(os.fspath(path), camera, text)


def estimate_poses(
    frames_dir: str | os.PathLike[str],
    options: Optional[PosesOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Unpack[PosesKeywords],
) -> PosesResult:
    """Estimates the poses of a folder of frames with COLMAP (CPU, headless), as
    ``aos-render poses`` does; the frames are never modified.

    ``kwargs`` are fields of :class:`PosesOptions` (matcher, sequential_overlap, camera_file,
    camera_model, fov_deg, positions_file, workspace, preset, ...); ``preset="quick"`` trades
    some accuracy for speed (smaller frames, fewer features, fewer pairs; docs/poses.md).
    Progress stages: features,
    matching, mapping, import. Raises ValueError for bad options, COLMAP missing or failing, or
    too few frames registered; unregistered frames are listed in ``result.unregistered``.
    Implausible results (a self-calibrated focal length off the ``fov_deg`` prior, a median
    depth off ``flight_height_m``) raise too, or with ``allow_implausible=True`` come back
    with an "IMPLAUSIBLE" warning and ``result.implausible`` set (docs/poses.md).

    Example::

        result = aos.estimate_poses("flight/", positions_file="gps.csv", fov_deg=60)
        aos.write_lightfield("flight.json", result.light_field)
    """
    merged = _copy_options("estimate_poses", PosesOptions, options)
    _ESTIMATE_POSES.apply([merged], dict(kwargs))
    return _core._estimate_poses(os.fspath(frames_dir), merged, progress)


def estimate_ground(
    light_field: LightField,
    points: Any,
    options: Optional[GroundOptions] = None,
    **kwargs: Unpack[GroundKeywords],
) -> GroundResult:
    """Where the ground is, from reconstructed points in the light field's LOCAL frame (e.g.
    ``estimate_poses(...).point_positions``), as ``aos-render ground`` does: a robust plane and
    a coarse elevation model by a lower-envelope fit (docs/terrain-and-maps.md). Up is the side
    the light field's cameras fly on. ``kwargs`` are fields of :class:`GroundOptions`
    (cell_size_m, quantile, ...). ``result.heightfield(light_field.origin, light_field.crs)`` is
    the model as a DEM (``.write(path)``), usable as a focal surface.
    """
    merged = _copy_options("estimate_ground", GroundOptions, options)
    _ESTIMATE_GROUND.apply([merged], dict(kwargs))
    return _core._estimate_ground(points, _core._ground_up_sign(points, light_field), merged)


def import_colmap(
    model_dir: str | os.PathLike[str],
    images_dir: str | os.PathLike[str],
    options: Optional[PosesOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Unpack[PosesKeywords],
) -> PosesResult:
    """Imports an existing COLMAP sparse model (a ``sparse/N`` folder, text or binary) with the
    frames COLMAP was given, as ``aos-render import-colmap`` does: registered frames become
    views (images not loaded), the others are listed as unregistered, and ``positions_file`` or
    ``exif_positions`` (fields of :class:`PosesOptions`, like ``min_registered_fraction``)
    geo-reference it; ``flight_height_m`` checks the geo-referenced scale, as for
    :func:`estimate_poses`. Raises ValueError naming the file and the field; ``progress`` as for
    :func:`estimate_poses` (Ctrl-C raises KeyboardInterrupt while the model is read).
    """
    merged = _copy_options("import_colmap", PosesOptions, options)
    _IMPORT_COLMAP.apply([merged], dict(kwargs))
    return _core._import_colmap(os.fspath(model_dir), os.fspath(images_dir), merged, progress)


def import_telemetry(
    frames_dir: str | os.PathLike[str],
    options: Optional[TelemetryOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Unpack[TelemetryKeywords],
) -> TelemetryResult:
    """Poses a folder of frames from GPS and gimbal telemetry, without COLMAP, as
    ``aos-render import-telemetry`` does: a CSV log (``telemetry_file``: columns frame or time,
    lat, lon, alt, yaw, pitch, roll; yaw = compass heading clockwise from true north, pitch -90 =
    nadir, roll positive = the image's right side down) or the frames' EXIF GPS and DJI XMP
    gimbal tags, plus a camera (``camera_file`` or ``fov_deg``). The light field is
    geo-referenced: ``crs`` the flight's UTM zone (EPSG:326zz / 327zz), origin a round point
    near the mean position. Altitude outliers are replaced by a running median and listed in
    ``result.altitude_outliers`` (docs/terrain-and-maps.md). Raises ValueError naming the file,
    line and field. Nothing is written (but, with ``radiometric="flir"``, the temperature
    frames in ``temperature_frames_dir``): pass ``result.light_field`` to
    :func:`write_lightfield`. ``progress`` as for :func:`estimate_poses` (a unit per frame
    header; Ctrl-C raises KeyboardInterrupt).

    Example::

        result = aos.import_telemetry("flight/", telemetry_file="log.csv", fov_deg=50)
        aos.write_lightfield("flight.json", result.light_field)
    """
    merged = _copy_options("import_telemetry", TelemetryOptions, options)
    _IMPORT_TELEMETRY.apply([merged], dict(kwargs))
    return _core._import_telemetry(os.fspath(frames_dir), merged, progress)


def import_video(
    video: "str | os.PathLike[str]",
    output_dir: "str | os.PathLike[str]",
    options: Optional[VideoFramesOptions] = None,
    telemetry: Optional[TelemetryOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Unpack[VideoKeywords],
) -> VideoImportResult:
    """A drone video and its DJI subtitle telemetry (``srt_file``) as a posed light field, in the
    new folder ``output_dir`` (frames/, telemetry.csv, lightfield.json; nothing is left on an
    error). ``kwargs`` are fields of :class:`VideoFramesOptions` (srt_file, frame_every_s,
    frame_every_m, srt_altitude, fixed_pitch_deg, srt_offset_s) or of :class:`TelemetryOptions`
    (the camera, references and outlier rule, as :func:`import_telemetry` takes them). Frames are
    decoded with OpenCV. The result's ``telemetry`` states every assumption (order, references,
    altitude outliers) and ``frames`` what was taken and how it was oriented.

    Example::

        result = aos.import_video("DJI_0001.MP4", "flight", srt_file="DJI_0001.SRT",
                                  frame_every_m=2.0, fov_deg=70, altitude_reference="takeoff",
                                  dem="dem.tif")
        lf = aos.load_lightfield(result.light_field_path).light_field
    """
    merged = _copy_options("import_video", VideoFramesOptions, options)
    posing = _copy_options("import_video", TelemetryOptions, telemetry)
    _IMPORT_VIDEO.apply([merged, posing], dict(kwargs))
    return _core._import_video(os.fspath(video), os.fspath(output_dir), merged, posing, progress)


def view(light_field: "LightField | str | os.PathLike[str] | None" = None, **kwargs: Any) -> Any:
    """Starts the interactive browser viewer on ``light_field`` (a LightField or a path) and
    returns its handle at once: ``.url`` (with the session token), ``.stop()``. Works in a
    notebook (the server runs in a background thread). Keywords: the starting focus and camera
    with IntegralOptions' names (focal_surface, surface_offset, aperture_radius,
    pose_view, cam_from_world, fov_deg, width, height, view_indices, min_view_angle_deg,
    num_threads) and host, port, open_browser; see :func:`aos.viewer.view` and docs/viewer.md.
    ``live=`` an aos.LiveIntegrator instead of a light field: the live page (docs/live.md).
    Needs aiohttp (a dependency of aos; ``pip install aiohttp`` if it was removed).

    Example::

        viewer = aos.view(lf, focal_surface=21.0)
        print(viewer.url)
        viewer.stop()
    """
    from .viewer import view as _view

    return _view(light_field, **kwargs)
