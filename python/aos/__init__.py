"""aos: Airborne Optical Sectioning -- drone light fields and integral rendering.

The algorithms live in the C++ core (``aos._core``); this package re-exports it and adds the
keyword-argument conveniences. Every option is declared once, in the C++ ``XxxOptions`` structs:
``IntegralOptions``, ``QualityOptions`` and ``SimulateOptions`` expose exactly their fields with the
C++ defaults. Simulated scenes are JSON documents (docs/scenes.md) parsed by the C++ core.

Frames and units: metres and radians inside, degrees only where named ``*_deg``; poses are named
by what they map (``cam_from_world``), cameras use OpenCV axes (x right, y down, z forward), and
pixel centres sit at +0.5 in continuous pixel coordinates.

numpy copy rules:

* Images passed in (``LightField.add_view``, ``write_image``) are always COPIED; accepted dtypes
  are uint8, uint16 and float32 (float64 is converted to float32; ``write_image`` also takes
  uint32), shape (H, W) or (H, W, C). Other dtypes raise ValueError.
* Result images (``read_image``, ``IntegralResult.image`` / ``.count``) share memory with the C++
  result, which the array keeps alive. ``View.image`` returns a copy.
* Vectors and matrices are float64 arrays converted by value both ways.

Errors: bad input raises ValueError naming the field; a progress callback that raises stops the
work and its exception propagates; Ctrl-C during long calls raises KeyboardInterrupt.
"""

from __future__ import annotations

import copy
import json
import os
from typing import Any, Callable, Optional, Sequence, TypeVar

from . import _core
from ._core import (
    PosesOptions,
    PosesResult,
    PoseSource,
    read_positions,
    CalibrateOptions,
    CalibrationResult,
    read_camera_file,
    Rectifier,
    RectifyOptions,
    make_rectifier,
    LensCamera,
    LensModel,
    ResolutionOptions,
    ResolutionResult,
    AllInFocusOptions,
    FocalStack,
    FocalStackOptions,
    GroundTruth,
    MergeMethod,
    MergeOptions,
    MergeResult,
    SurfaceIntegralOptions,
    SurfaceIntegralResult,
    QualityOptions,
    QualityResult,
    IntegralOptions,
    IntegralResult,
    LightField,
    LoadResult,
    PinholeCamera,
    Plane,
    Rigid3d,
    Scene,
    SimulateOptions,
    SimulationResult,
    View,
    __version__,
    default_scene,
    load_lightfield,
    load_scene,
    look_at,
    parse_scene,
    read_image,
    virtual_camera,
    write_image,
    write_lightfield,
    write_simulation,
    interpolate_plane,
    plane_depth,
    read_focal_stack,
    stack_planes,
    write_focal_stack,
)

__all__ = [
    "PosesOptions",
    "PosesResult",
    "PoseSource",
    "estimate_poses",
    "import_colmap",
    "read_positions",
    "CalibrateOptions",
    "CalibrationResult",
    "calibrate",
    "read_camera_file",
    "write_camera_file",
    "Rectifier",
    "RectifyOptions",
    "make_rectifier",
    "LensCamera",
    "LensModel",
    "ResolutionOptions",
    "ResolutionResult",
    "sampling_resolution",
    "AllInFocusOptions",
    "FocalStack",
    "FocalStackOptions",
    "MergeMethod",
    "MergeOptions",
    "MergeResult",
    "SurfaceIntegralOptions",
    "SurfaceIntegralResult",
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
    "IntegralOptions",
    "IntegralResult",
    "LightField",
    "LoadResult",
    "PinholeCamera",
    "Plane",
    "Rigid3d",
    "Scene",
    "SimulateOptions",
    "SimulationResult",
    "View",
    "__version__",
    "default_scene",
    "load_lightfield",
    "load_scene",
    "look_at",
    "parse_scene",
    "read_image",
    "render_integral",
    "simulate",
    "virtual_camera",
    "write_image",
    "write_lightfield",
    "write_simulation",
]

_Options = TypeVar(
    "_Options",
    IntegralOptions,
    SimulateOptions,
    QualityOptions,
    SurfaceIntegralOptions,
    FocalStackOptions,
    MergeOptions,
    ResolutionOptions,
    CalibrateOptions,
)


def _merge_options(
    function: str, cls: type[_Options], options: Optional[_Options], overrides: dict[str, Any]
) -> _Options:
    """A copy of ``options`` (or of the defaults) with ``overrides`` applied by field name."""
    if options is None:
        merged = cls()
    elif isinstance(options, cls):
        merged = copy.copy(options)
    else:
        raise TypeError(
            f"{function}(): options must be {cls.__name__} or None, not {type(options).__name__}"
        )
    for name, value in overrides.items():
        if name not in cls._fields:
            raise TypeError(
                f"{function}() got an unexpected keyword argument {name!r} "
                f"(options: {', '.join(cls._fields)})"
            )
        setattr(merged, name, value)
    return merged


def render_integral(
    light_field: LightField,
    options: Optional[IntegralOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Any,
) -> IntegralResult:
    """Integral rendering of ``light_field`` (Eq. 1 of the AOS paper).

    ``kwargs`` are fields of :class:`IntegralOptions` overriding those of a copy of ``options``
    (or of the defaults); unknown names raise TypeError. ``progress(stage, done, total)`` is
    called from this thread at most every 0.1 s (and once when done == total); if it raises,
    rendering stops and the exception propagates. The GIL is released while rendering.

    Example::

        result = aos.render_integral(lf, focal_plane=aos.Plane.at_height(0.0), pose_view=60)
        image, count = result.image, result.count   # float32 and uint32, no copies
    """
    merged = _merge_options("render_integral", IntegralOptions, options, kwargs)
    return _core.render_integral(light_field, merged, progress)


def simulate(
    scene: "Scene | dict[str, Any] | str | os.PathLike[str]",
    output_dir: "Optional[str | os.PathLike[str]]" = None,
    options: Optional[SimulateOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Any,
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
    merged = _merge_options("simulate", SimulateOptions, options, kwargs)
    result = _core._simulate(parsed, merged, progress)
    if output_dir is not None:
        write_simulation(result, parsed, os.fspath(output_dir))
    return result


def compare_images(
    test: Any, reference: Any, mask: Any = None, options: Optional[QualityOptions] = None,
    **kwargs: Any
) -> QualityResult:
    """PSNR, SSIM and colour (quaternion) SSIM of ``test`` against ``reference``.

    Arrays (H, W) or (H, W, C) of uint8, uint16, uint32 or float32 (float64 converted), copied.
    ``mask`` (e.g. a count map): non-zero pixels are compared (SSIM: pixels whose whole window is
    valid). ``kwargs`` are fields of :class:`QualityOptions`. Definitions: docs/metrics.md.
    """
    merged = _merge_options("compare_images", QualityOptions, options, kwargs)
    return _core._compare_images(test, reference, mask, merged)



def _method(value: Any) -> Any:
    """A merge method given by name ("sobel", "improved", "robust") becomes a MergeMethod."""
    if isinstance(value, str):
        if value not in MergeMethod.__members__:
            raise ValueError(
                f"method: unknown merge method {value!r} (sobel, improved or robust)"
            )
        return MergeMethod.__members__[value]
    return value


def _split_kwargs(
    function: str, kwargs: dict[str, Any], groups: "list[tuple[str, Any]]"
) -> "dict[str, dict[str, Any]]":
    """Sorts keyword arguments into the options classes whose field they name (first wins)."""
    sorted_kwargs: dict[str, dict[str, Any]] = {name: {} for name, _ in groups}
    for key, value in kwargs.items():
        for name, cls in groups:
            if key in cls._fields:
                sorted_kwargs[name][key] = _method(value) if key == "method" else value
                break
        else:
            names = ", ".join(f for _, cls in groups for f in cls._fields)
            raise TypeError(f"{function}() got an unexpected keyword argument {key!r} (options: {names})")
    return sorted_kwargs


def _apply_surface(merge: MergeOptions, fields: dict[str, Any]) -> None:
    """Fields of SurfaceIntegralOptions (agreement, min_inlier_fraction) go to merge.robust."""
    if fields:
        robust = copy.copy(merge.robust)
        for key, value in fields.items():
            setattr(robust, key, value)
        merge.robust = robust


def _stack_options(
    function: str, options: Optional[FocalStackOptions], kwargs: dict[str, Any]
) -> FocalStackOptions:
    groups = _split_kwargs(
        function, kwargs, [("stack", FocalStackOptions), ("render", IntegralOptions)]
    )
    merged = _merge_options(function, FocalStackOptions, options, groups["stack"])
    render = copy.copy(merged.render)
    for key, value in groups["render"].items():
        setattr(render, key, value)
    merged.render = render
    return merged


def render_focal_stack(
    light_field: LightField,
    options: Optional[FocalStackOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Any,
) -> FocalStack:
    """Renders a focal stack: N slices between ``first_plane`` and ``last_plane``.

    ``kwargs`` are fields of :class:`FocalStackOptions` (first_plane, last_plane, slices) or of
    :class:`IntegralOptions` (applied to ``options.render``: pose_view, fov_deg, width,
    aperture_radius, variance, ...). All slices stay in memory; :func:`all_in_focus` streams.

    Example::

        stack = aos.render_focal_stack(lf, pose_view=60, first_plane=aos.Plane.at_height(0),
                                       last_plane=aos.Plane.at_height(20), slices=100)
    """
    merged = _stack_options("render_focal_stack", options, kwargs)
    return _core._render_focal_stack(light_field, merged, progress)


def merge_focal_stack(
    stack: FocalStack,
    options: Optional[MergeOptions] = None,
    *,
    light_field: Optional[LightField] = None,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Any,
) -> MergeResult:
    """All-in-focus image, depth and confidence of a stack (``method`` sobel/improved/robust).

    ``kwargs`` are fields of :class:`MergeOptions` (``method`` may be a string) or of
    :class:`SurfaceIntegralOptions` (agreement, min_inlier_fraction). The robust method
    needs a stack rendered with ``variance=True`` and the ``light_field`` it came from.
    """
    groups = _split_kwargs(
        "merge_focal_stack", kwargs, [("merge", MergeOptions), ("surface", SurfaceIntegralOptions)]
    )
    merged = _merge_options("merge_focal_stack", MergeOptions, options, groups["merge"])
    _apply_surface(merged, groups["surface"])
    return _core._merge_focal_stack(stack, merged, light_field, progress)


def all_in_focus(
    light_field: LightField,
    options: Optional[AllInFocusOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Any,
) -> MergeResult:
    """The one-call pipeline: slices rendered one at a time and merged (memory flat in N).

    ``kwargs`` are fields of :class:`MergeOptions` (method as a string or MergeMethod, ...),
    :class:`FocalStackOptions` (first_plane, last_plane, slices), :class:`IntegralOptions`
    (pose_view, fov_deg, width, height, aperture_radius, ...) or :class:`SurfaceIntegralOptions`
    (agreement, min_inlier_fraction: the robust mean).

    Example::

        result = aos.all_in_focus(lf, pose_view=60, first_plane=aos.Plane.at_height(0),
                                  last_plane=aos.Plane.at_height(20), slices=100)
        image, depth = result.image, result.depth
    """
    groups = _split_kwargs(
        "all_in_focus",
        kwargs,
        [
            ("merge", MergeOptions),
            ("stack", FocalStackOptions),
            ("render", IntegralOptions),
            ("surface", SurfaceIntegralOptions),
        ],
    )
    merged = copy.copy(options) if options is not None else AllInFocusOptions()
    merge = copy.copy(merged.merge)
    for key, value in groups["merge"].items():
        setattr(merge, key, value)
    _apply_surface(merge, groups["surface"])
    stack = copy.copy(merged.stack)
    for key, value in groups["stack"].items():
        setattr(stack, key, value)
    render = copy.copy(stack.render)
    for key, value in groups["render"].items():
        setattr(render, key, value)
    stack.render = render
    merged.merge = merge
    merged.stack = stack
    return _core._all_in_focus(light_field, merged, progress)


def render_integral_on_depth(
    light_field: LightField,
    depth: Any,
    options: Optional[IntegralOptions] = None,
    surface: Optional[SurfaceIntegralOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Any,
) -> SurfaceIntegralResult:
    """Integral on a per-pixel depth surface (``depth``: camera z in metres, (H, W), copied).

    ``kwargs`` are fields of :class:`IntegralOptions` or :class:`SurfaceIntegralOptions`
    (robust, agreement, min_inlier_fraction). Used for the "oracle" image on
    a true depth map and for re-integrating a merged depth map.
    """
    groups = _split_kwargs(
        "render_integral_on_depth",
        kwargs,
        [("render", IntegralOptions), ("surface", SurfaceIntegralOptions)],
    )
    render = _merge_options("render_integral_on_depth", IntegralOptions, options, groups["render"])
    surf = _merge_options(
        "render_integral_on_depth", SurfaceIntegralOptions, surface, groups["surface"]
    )
    return _core._render_integral_on_depth(light_field, render, depth, surf, progress)


def sampling_resolution(
    camera: "LensCamera | PinholeCamera", options: Optional[ResolutionOptions] = None, **kwargs: Any
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
    merged = _merge_options("sampling_resolution", ResolutionOptions, options, kwargs)
    return _core._sampling_resolution(camera, merged)


def _lens_model(value: Any) -> Any:
    """A lens model given by name (pinhole, radtan, fisheye, omnidir) becomes a LensModel."""
    if isinstance(value, str):
        if value not in LensModel.__members__:
            raise ValueError(
                f"model: unknown lens model {value!r} (pinhole, radtan, fisheye or omnidir)"
            )
        return LensModel.__members__[value]
    return value


def calibrate(
    frames: "Sequence[Any]",
    names: "Optional[Sequence[str]]" = None,
    options: Optional[CalibrateOptions] = None,
    *,
    progress: Optional[Callable[[str, int, int], object]] = None,
    **kwargs: Any,
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
    overrides = {
        key: _lens_model(value) if key == "model" else value for key, value in kwargs.items()
    }
    merged = _merge_options("calibrate", CalibrateOptions, options, overrides)
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
    **kwargs: Any,
) -> PosesResult:
    """Estimates the poses of a folder of frames with COLMAP (CPU, headless), as
    ``aos-render poses`` does; the frames are never modified.

    ``kwargs`` are fields of :class:`PosesOptions` (matcher, sequential_overlap, camera_file,
    camera_model, fov_deg, positions_file, workspace, ...). Progress stages: features,
    matching, mapping, import. Raises ValueError for bad options, COLMAP missing or failing, or
    too few frames registered; unregistered frames are listed in ``result.unregistered``.

    Example::

        result = aos.estimate_poses("flight/", positions_file="gps.csv", fov_deg=60)
        aos.write_lightfield("flight.json", result.light_field)
    """
    merged = _merge_options("estimate_poses", PosesOptions, options, kwargs)
    return _core._estimate_poses(os.fspath(frames_dir), merged, progress)


def import_colmap(
    model_dir: str | os.PathLike[str],
    images_dir: str | os.PathLike[str],
    options: Optional[PosesOptions] = None,
    **kwargs: Any,
) -> PosesResult:
    """Imports an existing COLMAP sparse model (a ``sparse/N`` folder, text or binary) with the
    frames COLMAP was given, as ``aos-render import-colmap`` does: registered frames become
    views (images not loaded), the others are listed as unregistered, and ``positions_file`` or
    ``exif_positions`` (fields of :class:`PosesOptions`, like ``min_registered_fraction``)
    geo-reference it. Raises ValueError naming the file and the field.
    """
    merged = _merge_options("import_colmap", PosesOptions, options, kwargs)
    return _core._import_colmap(os.fspath(model_dir), os.fspath(images_dir), merged)
