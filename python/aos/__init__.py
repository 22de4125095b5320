"""aos: Airborne Optical Sectioning -- drone light fields and integral rendering.

The algorithms live in the C++ core (``aos._core``); this package re-exports it and adds the
keyword-argument conveniences. Every option is declared once, in the C++ ``XxxOptions`` structs:
``IntegralOptions`` and ``DefaultSceneOptions`` expose exactly their fields with the C++ defaults.

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
from typing import Any, Callable, Optional, TypeVar

from . import _core
from ._core import (
    DefaultSceneOptions,
    QualityOptions,
    QualityResult,
    IntegralOptions,
    IntegralResult,
    LightField,
    LoadResult,
    PinholeCamera,
    Plane,
    Rigid3d,
    View,
    __version__,
    load_lightfield,
    look_at,
    read_image,
    virtual_camera,
    write_image,
    write_lightfield,
)

__all__ = [
    "DefaultSceneOptions",
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
    "View",
    "__version__",
    "load_lightfield",
    "look_at",
    "make_default_lightfield",
    "read_image",
    "render_integral",
    "virtual_camera",
    "write_image",
    "write_lightfield",
]

_Options = TypeVar("_Options", IntegralOptions, DefaultSceneOptions, QualityOptions)


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


def make_default_lightfield(
    options: Optional[DefaultSceneOptions] = None, **kwargs: Any
) -> LightField:
    """The deterministic synthetic light field of ``aos-render demo``.

    ``kwargs`` are fields of :class:`DefaultSceneOptions` overriding those of a copy of
    ``options`` (or of the defaults); unknown names raise TypeError.
    """
    merged = _merge_options("make_default_lightfield", DefaultSceneOptions, options, kwargs)
    return _core.make_default_lightfield(merged)


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

