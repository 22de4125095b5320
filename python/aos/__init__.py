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
from typing import Any, Callable, Optional, TypeVar

from . import _core
from ._core import (
    GroundTruth,
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
)

__all__ = [
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

_Options = TypeVar("_Options", IntegralOptions, SimulateOptions, QualityOptions)


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

