"""Type stubs of aos._core, the pybind11 module built from cpp/python/ (hand-written, but for
the head of every Options class, which tools/options.py writes from the C++ field tables;
checked against the module by tests/python/test_stubs.py and tests/python/test_options.py).

numpy copy rules:

* Vectors and matrices: any array-like of the right shape goes in (converted to float64); a new
  float64 array comes out. Mutating a returned array does not change the object.
* Images going in (LightField.add_view, write_image) are always COPIED (add_view adds the
  1-pixel border views need). dtypes: uint8, uint16, float32 kept; float64 converted to float32;
  uint32 accepted by write_image only. Shape (H, W) or (H, W, C), C in 1..4, any strides.
  Other dtypes raise ValueError naming the dtype.
* Images coming out: (H, W) for one channel, else (H, W, C). Result images (read_image,
  IntegralResult.image / .count, MergeResult.image, ...) SHARE memory with the C++ result, which
  the array keeps alive; View.image is a COPY; FocalStack.images / .counts / .variances are new
  (N, H, W[, C]) arrays (COPIES) on every access.

Values: a number is accepted wherever a Plane is taken (the horizontal plane at that height).
Rigid3d, Plane, PinholeCamera, LensCamera, View, PoseSource, LightField, LoadResult and every
Options class compare with == (exact) and pickle; Options and LightField also define __copy__ and
__deepcopy__ (the others copy through pickling).
"""

import os
from typing import Any, Callable, ClassVar, Literal, Optional, Sequence, Union

import numpy
import numpy.typing

__version__: str

_PathLike = Union[str, bytes, os.PathLike[str], os.PathLike[bytes]]
_Vector = numpy.typing.ArrayLike
_Float64Array = numpy.typing.NDArray[numpy.float64]
_ImageArray = numpy.typing.NDArray[Any]
_Progress = Optional[Callable[[str, int, int], object]]
# A plane, or a number: the horizontal plane at that height.
_PlaneLike = Union[Plane, float]

class Rigid3d:
    """x_b = rotation @ x_a + translation, named b_from_a (cam_from_world: world -> OpenCV camera
    axes, x right, y down, z forward)."""

    def __init__(self, rotation: _Vector = ..., translation: _Vector = ...) -> None:
        """Identity rotation and zero translation by default. Not validated here."""
    @property
    def rotation(self) -> _Float64Array:
        """3x3 rotation matrix (float64 copy)."""
    @rotation.setter
    def rotation(self, value: _Vector) -> None: ...
    @property
    def translation(self) -> _Float64Array:
        """Translation 3-vector (float64 copy)."""
    @translation.setter
    def translation(self, value: _Vector) -> None: ...
    @property
    def center(self) -> _Float64Array:
        """For cam_from_world: the camera centre in world coordinates, -R^T t."""
    @property
    def matrix3x4(self) -> _Float64Array:
        """The 3x4 matrix [R | t] (float64 copy)."""
    def inverse(self) -> Rigid3d: ...
    @staticmethod
    def from_matrix3x4(m: _Vector) -> Rigid3d:
        """From [R | t] as a (3, 4) array-like, or 12 numbers row by row."""
    def __eq__(self, other: object) -> bool: ...
    def __repr__(self) -> str: ...

def look_at(eye: _Vector, target: _Vector, up: _Vector | None = None) -> Rigid3d:
    """cam_from_world of a camera at eye looking at target; up appears up in the image (None:
    (0, 0, 1), or (0, 1, 0) for a camera looking straight along z). ValueError if eye == target
    or up is parallel to the viewing direction."""

class Plane:
    """A plane through point with normal normal (local frame, metres)."""

    def __init__(self, point: _Vector | float = ..., normal: _Vector | None = None) -> None:
        """Defaults: point (0, 0, 0), normal (0, 0, 1). Plane(z) with a number is the horizontal
        plane at height z (Plane.at_height(z))."""
    @property
    def point(self) -> _Float64Array: ...
    @point.setter
    def point(self, value: _Vector) -> None: ...
    @property
    def normal(self) -> _Float64Array: ...
    @normal.setter
    def normal(self, value: _Vector) -> None: ...
    @staticmethod
    def at_height(z: float) -> Plane:
        """The horizontal plane at height z."""
    def __eq__(self, other: object) -> bool:
        """Exact equality of point and normal."""
    def __repr__(self) -> str: ...
    @staticmethod
    def in_front_of(cam_from_world: Rigid3d, distance: float, horizontal: bool = False) -> Plane:
        """The plane `distance` metres in front of a camera along its axis (perpendicular to it,
        or horizontal through that point)."""

class PinholeCamera:
    """Pinhole camera; pixel centres at (i + 0.5, j + 0.5); u = fx x / z + cx, v = fy y / z + cy."""

    def __init__(self, width: int, height: int, fx: float, fy: float, cx: float, cy: float) -> None: ...
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    @staticmethod
    def from_fov(width: int, height: int, fov_deg: float) -> PinholeCamera:
        """Square pixels, centred principal point, horizontal field of view fov_deg in (0, 180)."""
    @property
    def K(self) -> _Float64Array:
        """The 3x3 intrinsic matrix (float64 copy)."""
    def fov_x_deg(self) -> float: ...
    def project(self, point: _Vector) -> _Float64Array:
        """Pixel (u, v) of a point in camera coordinates (z > 0)."""
    def unproject(self, pixel: _Vector) -> _Float64Array:
        """Ray direction (x, y, 1) through continuous pixel coordinates (u, v)."""
    def check(self, where: str = "camera") -> None:
        """ValueError naming `where` if a field is out of range or not finite."""
    def __eq__(self, other: object) -> bool: ...
    def __repr__(self) -> str: ...

class LensModel:
    pinhole: ClassVar[LensModel]
    radtan: ClassVar[LensModel]
    fisheye: ClassVar[LensModel]
    omnidir: ClassVar[LensModel]
    def __init__(self, value: int) -> None: ...
    @property
    def name(self) -> str: ...
    @property
    def value(self) -> int: ...

class LensCamera:
    """A camera with a lens model (pinhole, radtan, fisheye, omnidir); see aos/geometry/lens.h."""

    def __init__(
        self,
        model: LensModel,
        width: int,
        height: int,
        fx: float,
        fy: float,
        cx: float,
        cy: float,
        distortion: Optional[Sequence[float]] = None,
        xi: float = ...,
        skew: float = ...,
    ) -> None:
        """`distortion` of the model's natural length (radtan 5, fisheye 4, omnidir 4, pinhole
        0; None: no distortion); another length raises ValueError naming the model."""
    @staticmethod
    def from_pinhole(camera: PinholeCamera) -> LensCamera: ...
    def pinhole(self) -> PinholeCamera:
        """The pinhole part (size, fx, fy, cx, cy); distortion, skew and xi dropped."""
    model: LensModel
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    skew: float
    xi: float
    @property
    def distortion(self) -> list[float]:
        """A new list of the model's natural length: radtan k1, k2, p1, p2, k3; fisheye k1..k4;
        omnidir k1, k2, p1, p2; pinhole none."""
    @distortion.setter
    def distortion(self, value: Sequence[float]) -> None:
        """ValueError naming the model for another length (set model first)."""
    @property
    def max_radius(self) -> float: ...
    @property
    def theta_max(self) -> float: ...
    def finalize(self, where: str = "camera") -> None: ...
    def project(self, point: _Vector) -> Optional[_Float64Array]:
        """Pixel of a camera-frame point, or None outside the valid field."""
    def unproject(self, pixel: _Vector) -> Optional[_Float64Array]:
        """Unit ray through the pixel, or None."""
    def unproject_pixels(self, pixels: numpy.typing.ArrayLike) -> _Float64Array:
        """Unit rays (N, 3) through pixels (N, 2); NaN rows where there is none."""
    def __eq__(self, other: object) -> bool: ...
    def __repr__(self) -> str: ...

def read_image(path: _PathLike) -> _ImageArray:
    """Reads an image file; uint8/uint16 kept, other types become float32. The returned array
    owns the decoded pixels (no extra copy)."""

def write_image(
    path: _PathLike,
    array: numpy.typing.ArrayLike,
    sample_type: str = "auto",
    range_min: float | None = None,
    range_max: float | None = None,
    description: str = "",
    units: str = "uint8",
    png_compression_level: int = 1,
) -> None:
    """Writes `array` (COPIED first; uint8, uint16, uint32, float32, float64 -> float32) to `path`
    atomically. A float array's values are in the units of `units` ('uint8' 0..255, 'uint16'
    0..65535, 'float32' 0..1); to an integer format they take its depth and map the range
    (default: the units' full range) onto the codes, as aos-render does.
    sample_type: 'auto', 'uint8', 'uint16', 'uint32', 'float32'."""

class View:
    """One view of a light field (read-only)."""

    @property
    def name(self) -> str: ...
    @property
    def image_path(self) -> str: ...
    @property
    def camera(self) -> LensCamera:
        """The view's one camera (model 'pinhole' for pinhole views), the same for views added
        with add_view and views loaded from a file; camera.pinhole() is its PinholeCamera."""
    @property
    def cam_from_world(self) -> Rigid3d: ...
    @property
    def lens(self) -> LensCamera:
        """Deprecated alias of `camera` (emits DeprecationWarning); removed in the next release."""
    @property
    def image(self) -> Optional[_ImageArray]:
        """A COPY of the pixels, native dtype; None if loaded without images."""
    def __eq__(self, other: object) -> bool:
        """Exact equality of every field and of the pixels."""
    def __repr__(self) -> str: ...

class Radiometry:
    """How pixel values measure temperature: kelvin = kelvin_per_unit * value + kelvin_offset."""

    def __init__(self, kelvin_per_unit: float = 0.01, kelvin_offset: float = 0.0) -> None: ...
    @property
    def kelvin_per_unit(self) -> float: ...
    @property
    def kelvin_offset(self) -> float: ...
    def kelvin(self, values: numpy.typing.ArrayLike) -> Any:
        """Temperatures in kelvin of pixel values (float64)."""
    def celsius(self, values: numpy.typing.ArrayLike) -> Any:
        """Temperatures in degrees Celsius of pixel values (float64)."""
    def value_of_celsius(self, celsius: float) -> float: ...
    def __eq__(self, other: object) -> bool: ...

class PoseSource:
    """Where a light field's estimated poses came from and how good they are."""

    @property
    def method(self) -> str: ...
    @property
    def mean_reprojection_error_px(self) -> float: ...
    @property
    def median_depth(self) -> float: ...
    @property
    def pose_error(self) -> float: ...
    @property
    def georeferenced(self) -> bool: ...
    @property
    def georeference_rms_m(self) -> float: ...
    @property
    def world_frame(self) -> str: ...
    @property
    def unregistered(self) -> list[str]: ...
    def __eq__(self, other: object) -> bool: ...
    def __repr__(self) -> str: ...

class LightField:
    """Views (image, pinhole camera, cam_from_world) in a local frame whose zero lies at origin."""

    def __init__(self) -> None: ...
    @property
    def pose_source(self) -> Optional[PoseSource]:
        """PoseSource of estimated poses, or None."""
    @property
    def origin(self) -> _Float64Array:
        """World position of the local frame's zero (float64 copy)."""
    @origin.setter
    def origin(self, value: _Vector) -> None: ...
    @property
    def crs(self) -> str:
        """'EPSG:<code>' of the world coordinates (origin + local), or '' = not geo-referenced."""
    @crs.setter
    def crs(self, value: str) -> None: ...
    @property
    def masked(self) -> bool:
        """True when loaded with a mask: each view's last channel is the mask weight."""
    @property
    def grey(self) -> bool:
        """True when the frames are read as grey whenever the file is loaded."""
    @grey.setter
    def grey(self, value: bool) -> None: ...
    @property
    def radiometry(self) -> Optional[Radiometry]:
        """Radiometry when the values measure temperature, else None."""
    @radiometry.setter
    def radiometry(self, value: Optional[Radiometry]) -> None: ...
    @property
    def views(self) -> list[View]:
        """A new list of the views (pixels not copied)."""
    def __len__(self) -> int: ...
    def image_bytes(self) -> int: ...
    def add_view(
        self,
        image: numpy.typing.ArrayLike,
        camera: Union[PinholeCamera, LensCamera],
        cam_from_world: Rigid3d,
        name: str = "",
    ) -> None:
        """Appends a view; `image` is COPIED (uint8, uint16, float32; float64 -> float32).
        ValueError for another dtype, a bad camera, a size mismatch or an invalid pose."""
    def __eq__(self, other: object) -> bool:
        """Exact equality of origin, crs, pose_source and every view (fields and pixels)."""
    def __copy__(self) -> LightField:
        """A copy sharing the (read-only) pixels."""
    def __deepcopy__(self, memo: dict[int, Any]) -> LightField: ...
    def __repr__(self) -> str: ...

class LoadResult:
    @property
    def light_field(self) -> LightField: ...
    @property
    def format(self) -> str:
        """'aos' or 'jku'."""
    @property
    def notes(self) -> list[str]: ...
    def __eq__(self, other: object) -> bool: ...
    def __repr__(self) -> str: ...

def _load_view_images(
    light_field: LightField,
    indices: Sequence[int],
    grey: bool = False,
    mask: _PathLike = "",
    mask_dir: _PathLike = "",
    num_threads: int = 1,
) -> None: ...
def _drop_view_images(light_field: LightField, indices: Sequence[int]) -> None: ...
def _view_image(light_field: LightField, index: int) -> Optional[numpy.ndarray]: ...
def _set_view_image(light_field: LightField, index: int, image: numpy.ndarray) -> None: ...
def load_lightfield(
    path: _PathLike,
    fov_deg: float = 0.0,
    images_dir: _PathLike = "",
    load_images: bool = True,
    grey: bool = False,
    mask: _PathLike = "",
    mask_dir: _PathLike = "",
    num_threads: int = -1,
    progress: _Progress = None,
) -> LoadResult:
    """Loads an aos JSON light field or a JKU poses.json (fields of aos::LoadOptions)."""

def find_view(light_field: LightField, name: str) -> int:
    """The index of the view named ``name`` (name, file name, or stem), e.g. for pose_view."""

def write_lightfield(
    path: _PathLike,
    light_field: LightField,
    images_subdir: str = "views",
    image_extension: str = ".png",
) -> None:
    """Writes the aos JSON format (fields of aos::WriteLightFieldOptions)."""

class ApertureOptions:
    """The synthetic aperture every render integrates (render/aperture.h): the base of
    IntegralOptions and MapOptions, whose fields these are. Defaults from the C++ struct
    aos::ApertureOptions."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        aperture_radius: float = ...,
        view_indices: Sequence[int] = ...,
        min_view_angle_deg: float = ...,
        lens_tolerance_px: float = ...,
        num_threads: int = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    aperture_radius: float
    """Radius of the synthetic aperture, metres: on the lens plane of a perspective virtual camera,
    around the vertical line through the focal point for a map; 0 = the single nearest view, inf
    = every view. [m, >= 0]"""
    @property
    def view_indices(self) -> list[int]:
        """Views to integrate (indices into the light field); empty means all views. Reading returns
        a new list: assign a list to change it."""
    @view_indices.setter
    def view_indices(self, value: Sequence[int]) -> None: ...
    min_view_angle_deg: float
    """Minimum angle between a view's ray and the focal plane, degrees, [0, 90); smaller (grazing)
    rays are ignored. [deg, in [0, 90)]"""
    lens_tolerance_px: float
    """Views with a lens model: the largest error of a sample position, view pixels, [0, 1], where
    the exact lens projection is replaced by local maps; 0 = project every sample exactly. [px,
    in [0, 1]]"""
    num_threads: int
    """Worker threads; -1 = all cores. [in [1, 1024] or -1]"""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> ApertureOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def __eq__(self, other: object) -> bool: ...
    def __copy__(self) -> ApertureOptions: ...
    def __deepcopy__(self, memo: dict[int, Any]) -> ApertureOptions: ...
    def __repr__(self) -> str: ...

class IntegralOptions(ApertureOptions):
    """Options of render_integral. Defaults come from the C++ struct aos::IntegralOptions;
    IntegralOptions(**fields) overrides them by name (unknown names raise TypeError)."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        cam_from_world: Rigid3d = ...,
        pose_view: int = ...,
        fov_deg: float = ...,
        width: int = ...,
        height: int = ...,
        focal_surface: FocalSurface | Mesh | Heightfield | Plane | float = ...,
        surface_offset: float = ...,
        variance: bool = ...,
        min_view_count: int = ...,
        aperture_radius: float = ...,
        view_indices: Sequence[int] = ...,
        min_view_angle_deg: float = ...,
        lens_tolerance_px: float = ...,
        num_threads: int = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    cam_from_world: Rigid3d
    """Virtual camera pose, local frame -> camera (OpenCV axes). Ignored when pose_view >= 0."""
    pose_view: int
    """If >= 0, the virtual camera takes the pose of this view (index into the light field). [>= -1]"""
    fov_deg: float
    """Horizontal field of view of the virtual camera, degrees, (0, 180); 0 = the pose view's, else
    50. [deg, in (0, 180) or 0]"""
    width: int
    """Output width, pixels (1 .. 65536); 0 = the pose view's, else 512. [px, in [1, 65536] or 0]"""
    height: int
    """Output height, pixels (1 .. 65536); 0 = the pose view's, else 512. [px, in [1, 65536] or 0]"""
    @property
    def focal_surface(self) -> FocalSurface:
        """Where the rays are focused: a plane (a number is the horizontal plane z = that height,
        local frame), a Mesh, a Heightfield (DEM) or a FocalSurface; default the plane z = 0."""
    @focal_surface.setter
    def focal_surface(self, value: FocalSurface | Mesh | Heightfield | Plane | float) -> None: ...
    surface_offset: float
    """Offset of focal_surface along up (towards the views), metres. [m, finite]"""
    variance: bool
    """Also return the per-pixel variance of the view samples (the samples then go through the
    scalar kernel, which also sums their squares: a few times slower)."""
    min_view_count: int
    """Pixels averaged over fewer views than this are left uncovered (image and count 0): the rim of
    the aperture, where few views see a point and its occluders stay; 0 = keep every pixel a view
    sees. [>= 0]"""
    @property
    def focal_plane(self) -> Plane | None:
        """Deprecated: use focal_surface."""
    @focal_plane.setter
    def focal_plane(self, value: FocalSurface | Mesh | Heightfield | Plane | float) -> None: ...
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> IntegralOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self, view_count: int) -> None:
        """ValueError naming the offending field."""
    def __eq__(self, other: object) -> bool: ...
    def __copy__(self) -> IntegralOptions: ...
    def __deepcopy__(self, memo: dict[int, Any]) -> IntegralOptions: ...
    def __repr__(self) -> str: ...

class Mesh:
    """A triangle mesh in world coordinates (light field origin + local); arrays are copies."""

    def __init__(self, vertices: _Vector, triangles: _Vector) -> None:
        """(N, 3) vertices and (M, 3) 0-based indices; degenerate triangles are dropped."""
    @staticmethod
    def read(path: str) -> Mesh:
        """Reads an OBJ or PLY (ascii / binary_little_endian) mesh."""
    @property
    def vertices(self) -> _Float64Array: ...
    @property
    def triangles(self) -> numpy.typing.NDArray[numpy.int32]: ...
    @property
    def dropped_triangles(self) -> int:
        """Degenerate triangles dropped on reading."""
    def __eq__(self, other: object) -> bool: ...
    def __repr__(self) -> str: ...

class Heightfield:
    """A DEM raster: heights at pixel centres placed by a north-up GDAL geotransform; NaN = nodata."""

    def __init__(self, heights: _Vector, geotransform: Sequence[float], crs: str = "") -> None: ...
    @staticmethod
    def read(path: str) -> Heightfield:
        """Reads band 1 of a GDAL raster (nodata -> NaN)."""
    def write(self, path: str, overwrite: bool = False) -> None:
        """Writes a float32 GeoTIFF atomically; refuses an existing file unless overwrite, and a
        path not ending in .tif or .tiff."""
    def to_mesh(self) -> Mesh: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def heights(self) -> numpy.typing.NDArray[numpy.float32]:
        """float32 (H, W), metres, NaN = nodata (a copy)."""
    @property
    def geotransform(self) -> tuple[float, float, float, float, float, float]: ...
    @property
    def crs(self) -> str:
        """WKT, or '' when the raster has no CRS."""
    @property
    def source(self) -> str:
        """The file it was read from, or '' when built from arrays."""
    def __eq__(self, other: object) -> bool: ...
    def __repr__(self) -> str: ...

class FocalSurface:
    """Where the virtual camera focuses: a plane, a mesh, a DEM height field or a depth map."""

    def __init__(self, surface: _SurfaceLike) -> None: ...
    @staticmethod
    def read(path: str) -> FocalSurface:
        """A mesh (OBJ/PLY) or else any GDAL raster (a DEM)."""
    @staticmethod
    def from_depth_map(depth: _Vector, camera: PinholeCamera, cam_from_world: Rigid3d) -> FocalSurface: ...
    @property
    def kind(self) -> str:
        """'plane', 'mesh', 'heightfield' or 'depth_map'."""
    @property
    def source(self) -> str: ...
    @property
    def plane(self) -> Plane | None:
        """The plane (local frame) of a plane surface; None for other kinds."""
    @property
    def file(self) -> str:
        """The file read() read it from, as it is (not moved between CRSs); else ''. What
        to_json carries."""
    def describe(self) -> str: ...
    def in_crs(self, crs: str) -> FocalSurface:
        """A DEM in another CRS transformed into `crs` through PROJ; else the surface itself."""
    def depth_for(
        self,
        light_field: LightField,
        camera: PinholeCamera,
        cam_from_world: Rigid3d,
        offset: float = 0.0,
        view_indices: Sequence[int] = ...,
    ) -> numpy.typing.NDArray[numpy.float32]:
        """Camera z where each pixel's ray first meets the surface; 0 where it misses."""
    def heights_at(self, light_field: LightField, xy: _Vector, offset: float = 0.0) -> _Float64Array:
        """World z under world (x, y) points (N, 2); NaN where vertical rays miss."""
    def __eq__(self, other: object) -> bool: ...
    def __hash__(self) -> int: ...
    def __repr__(self) -> str: ...

_SurfaceLike = Union[FocalSurface, Mesh, Heightfield, Plane, float]

class IntegralResult:
    @property
    def image(self) -> numpy.typing.NDArray[numpy.float32]:
        """float32 (H, W) or (H, W, C); shares memory with the result."""
    @property
    def count(self) -> numpy.typing.NDArray[numpy.uint32]:
        """uint32 (H, W) views per pixel; shares memory with the result."""
    @property
    def variance(self) -> Optional[numpy.typing.NDArray[numpy.float32]]:
        """float32 (H, W) variance of the view samples when options.variance, else None."""
    @property
    def samples(self) -> int: ...
    @property
    def views_used(self) -> int: ...
    @property
    def views_selected(self) -> int: ...
    @property
    def uncovered_pixels(self) -> int: ...
    @property
    def cam_from_world(self) -> Rigid3d: ...
    def __repr__(self) -> str: ...

def render_integral(
    light_field: LightField, options: IntegralOptions, progress: _Progress = None
) -> IntegralResult:
    """Integral rendering with the GIL released; see aos.render_integral."""

def virtual_camera(light_field: LightField, options: IntegralOptions) -> PinholeCamera: ...

class RectifyOptions:
    """Options of make_rectifier (defaults from the C++ struct aos::RectifyOptions)."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        fov_deg: float = ...,
        width: int = ...,
        height: int = ...,
        yaw_deg: float = ...,
        pitch_deg: float = ...,
        roll_deg: float = ...,
        fill: bool = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    fov_deg: float
    """Horizontal field of view of the rectified image, degrees, (0, 180). [deg]"""
    width: int
    """Output width, pixels; 0 = the raw frame's."""
    height: int
    """Output height, pixels; 0 = the raw frame's."""
    yaw_deg: float
    """Turn about the lens's y axis, degrees. [deg]"""
    pitch_deg: float
    """Turn about the lens's x axis, degrees. [deg]"""
    roll_deg: float
    """Turn about the optical axis, degrees. [deg]"""
    fill: bool
    """Pixels the lens does not cover become 0 (black) instead of an error."""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> RectifyOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self) -> None: ...
    def __eq__(self, other: object) -> bool: ...
    def __copy__(self) -> RectifyOptions: ...
    def __deepcopy__(self, memo: dict[int, Any]) -> RectifyOptions: ...
    def __repr__(self) -> str: ...

class Rectifier:
    @property
    def camera(self) -> PinholeCamera: ...
    def rectify(self, image: numpy.typing.ArrayLike) -> _ImageArray:
        """The rectified frame (new array, the input's dtype and channels)."""
    def __repr__(self) -> str: ...

def make_rectifier(lens: LensCamera, options: RectifyOptions) -> Rectifier: ...

class RectifyLightFieldResult:
    """What rectify_light_field returns."""

    @property
    def light_field(self) -> LightField:
        """The light field with every view pinhole (a copy)."""
    @property
    def rectified_views(self) -> int:
        """Views that went through a lens model."""
    def __repr__(self) -> str: ...

def _rectify_light_field(
    light_field: LightField,
    options: RectifyOptions,
    progress: Optional[Callable[[str, int, int], object]] = None,
) -> RectifyLightFieldResult: ...

class CalibrateOptions:
    """Options of calibrate (defaults from the C++ struct aos::CalibrateOptions). aos.calibrate also
    accepts model as a string ('pinhole', 'radtan', 'fisheye', 'omnidir')."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        model: LensModel | Literal['pinhole', 'radtan', 'fisheye', 'omnidir'] = ...,
        pattern_columns: int = ...,
        pattern_rows: int = ...,
        square_size_m: float = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    @property
    def model(self) -> LensModel:
        """Lens model to fit: pinhole, radtan (cv::calibrateCamera), fisheye
        (cv::fisheye::calibrate) or omnidir (cv::omnidir::calibrate, Mei's model)."""
    @model.setter
    def model(
        self, value: LensModel | Literal['pinhole', 'radtan', 'fisheye', 'omnidir']
    ) -> None: ...
    pattern_columns: int
    """Inner corners of the checkerboard per row (>= 2)."""
    pattern_rows: int
    """Inner corners of the checkerboard per column (>= 2)."""
    square_size_m: float
    """Side of one square, metres (> 0). [m]"""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> CalibrateOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self) -> None:
        """ValueError naming the field."""
    def __eq__(self, other: object) -> bool: ...
    def __copy__(self) -> CalibrateOptions: ...
    def __deepcopy__(self, memo: dict[int, Any]) -> CalibrateOptions: ...
    def __repr__(self) -> str: ...

class CalibrationResult:
    @property
    def camera(self) -> LensCamera:
        """The calibrated lens (aos pixel convention: cx = OpenCV's cx + 0.5)."""
    @property
    def rms_px(self) -> float:
        """RMS reprojection error, pixels."""
    @property
    def frames_used(self) -> list[str]: ...
    @property
    def frames_rejected(self) -> list[str]:
        """Frames where the board was not found."""
    def __repr__(self) -> str: ...

def _calibrate(
    frames: Sequence[Union[numpy.typing.ArrayLike, _PathLike]],
    names: Sequence[str],
    options: CalibrateOptions,
    progress: _Progress = None,
) -> CalibrationResult:
    """Frames are numpy arrays (COPIED) or image paths; GIL released. See aos.calibrate."""
def read_camera_file(path: _PathLike) -> LensCamera:
    """Reads a camera file (format 'aos-camera'); ValueError naming the file and the field."""
def _calibration_record(
    result: CalibrationResult, options: Optional[CalibrateOptions] = None
) -> str: ...
def _write_camera_file(path: _PathLike, camera: LensCamera, calibration_json: str = "") -> None:
    """Writes a camera file atomically; see aos.write_camera_file."""

class SurfaceIntegralOptions:
    """Options of render_integral_on_depth (the mean on a depth surface). Defaults from the C++
    struct aos::SurfaceIntegralOptions."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        robust: bool = ...,
        agreement: float = ...,
        min_inlier_fraction: float = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    robust: bool
    """Outlier-rejecting mean instead of the plain mean."""
    agreement: float
    """Half-width of the band within which samples agree, as a fraction of the views' full range
    (255 for 8-bit, 65535 for 16-bit, 1 for float), (0, 1]. [in (0, 1]]"""
    min_inlier_fraction: float
    """Fewest inliers, as a fraction of the pixel's samples, for the robust mean to be used, [0, 1];
    fewer keep the plain mean. [in [0, 1]]"""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> SurfaceIntegralOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self) -> None:
        """ValueError naming the field."""
    def __eq__(self, other: object) -> bool: ...
    def __copy__(self) -> SurfaceIntegralOptions: ...
    def __deepcopy__(self, memo: dict[int, Any]) -> SurfaceIntegralOptions: ...
    def __repr__(self) -> str: ...

class SurfaceIntegralResult:
    @property
    def integral(self) -> IntegralResult:
        """image, count and statistics."""
    @property
    def image(self) -> numpy.typing.NDArray[numpy.float32]:
        """integral.image: float32 (H, W) or (H, W, C); shares memory with the result."""
    @property
    def count(self) -> numpy.typing.NDArray[numpy.uint32]:
        """integral.count: uint32 (H, W) views per pixel; shares memory with the result."""
    @property
    def inliers(self) -> Optional[numpy.typing.NDArray[numpy.uint32]]:
        """uint32 (H, W) samples averaged per pixel (robust only, else None)."""
    @property
    def fallback_pixels(self) -> int: ...
    def __repr__(self) -> str: ...

def _set_simd_kernels(enabled: bool = True, variance: bool = True, row_loads: bool = True) -> None: ...
def _render_integral_on_depth(
    light_field: LightField,
    options: IntegralOptions,
    depth: numpy.typing.ArrayLike,
    surface: SurfaceIntegralOptions,
    progress: _Progress = None,
) -> SurfaceIntegralResult: ...

class MapOptions(ApertureOptions):
    """Options of render_map (an orthographic map looking straight down). Defaults from the C++
    struct aos::MapOptions."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        pixel_size: float = ...,
        width: int = ...,
        extent: Sequence[float] = ...,
        focal_surface: FocalSurface | Mesh | Heightfield | Plane | float = ...,
        surface_offset: float = ...,
        tile_size: int = ...,
        max_pixels: int = ...,
        min_view_count: int = ...,
        aperture_radius: float = ...,
        view_indices: Sequence[int] = ...,
        min_view_angle_deg: float = ...,
        lens_tolerance_px: float = ...,
        num_threads: int = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    pixel_size: float
    """Ground size of a pixel, metres (> 0); 0 = the extent's width / width. [m, >= 0 and finite]"""
    width: int
    """Map width in pixels when pixel_size is 0 (>= 2). [px]"""
    @property
    def extent(self) -> list[float]:
        """World [XMIN, YMIN, XMAX, YMAX] (origin + local, metres); [] = the selected views'
        footprints on the focal plane."""
    @extent.setter
    def extent(self, value: Sequence[float]) -> None: ...
    @property
    def focal_surface(self) -> FocalSurface:
        """Where the map focuses: a plane (a number is the horizontal plane z = that height, local
        frame), a Mesh, a Heightfield (DEM) or a FocalSurface; default the plane z = 0."""
    @focal_surface.setter
    def focal_surface(self, value: FocalSurface | Mesh | Heightfield | Plane | float) -> None: ...
    surface_offset: float
    """Offset of focal_surface along up (towards the views), metres. [m, finite]"""
    tile_size: int
    """Pixels on a side of a render tile, 16 .. 8192. [px, in [16, 8192]]"""
    max_pixels: int
    """The most pixels (width x height) the map may have; more is refused as a likely mistake of
    units. Raise it for a map that large on purpose. [px, in [4, 1e+14]]"""
    min_view_count: int
    """Pixels averaged over fewer views than this are left uncovered (nodata); 0 or 1 keeps every
    pixel a view sees. [>= 0]"""
    @property
    def focal_height(self) -> float | None:
        """Deprecated: use focal_surface."""
    @focal_height.setter
    def focal_height(self, value: FocalSurface | Mesh | Heightfield | Plane | float) -> None: ...
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> MapOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self, view_count: int) -> None:
        """ValueError naming the field."""
    def __eq__(self, other: object) -> bool: ...
    def __copy__(self) -> MapOptions: ...
    def __deepcopy__(self, memo: dict[int, Any]) -> MapOptions: ...
    def __repr__(self) -> str: ...

class DistributedOptions:
    """How aos.distributed.render_map (and aos-render map --workers/--scheduler) spreads a map's
    tiles over Dask. Defaults from the C++ struct aos::DistributedOptions."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        workers: int = ...,
        scheduler: str = ...,
        cache_mb: float = ...,
        share_mb: float = ...,
        dashboard: bool = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    workers: int
    """Worker processes of a local Dask cluster that renders the map's tiles, >= 0; 0 = none (the
    CLI renders in its own process; aos.distributed.render_map then starts one worker). [>= 0]"""
    scheduler: str
    """Address of an existing Dask scheduler (tcp://HOST:PORT); '' = none. Not with workers."""
    cache_mb: float
    """Decoded frames (and, for anomaly imaging, their scores) each Dask worker keeps between tasks,
    MiB, >= 0 (with workers or a scheduler). [MiB, >= 0 and finite]"""
    share_mb: float
    """Decoded frames each worker hands to the other workers of its machine through shared memory,
    MiB, >= 0; 0 = none. [MiB, >= 0 and finite]"""
    dashboard: bool
    """The local cluster also serves Dask's dashboard; needs workers >= 1."""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> DistributedOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self) -> None:
        """ValueError naming the field."""
    def __eq__(self, other: object) -> bool: ...
    def __copy__(self) -> DistributedOptions: ...
    def __deepcopy__(self, memo: dict[int, Any]) -> DistributedOptions: ...
    def __repr__(self) -> str: ...

class ViewerOptions:
    """The browser viewer's own settings (aos.view, aos-render view): where it listens, how many
    pages it serves, whether it opens a browser. Defaults from the C++ struct aos::ViewerOptions."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        host: str = ...,
        port: int = ...,
        max_pages: int = ...,
        render_workers: int = ...,
        open_browser: bool | None = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    host: str
    """Address to listen on; anything but a loopback address makes the viewer reachable from other
    machines (a warning says so)."""
    port: int
    """TCP port; 0 = any free port. [in [0, 65535]]"""
    max_pages: int
    """Pages (browser tabs) served at once; the next is refused until one closes. [in [1, 4096]]"""
    render_workers: int
    """Threads rendering the pages' requests. [in [1, 64]]"""
    open_browser: bool | None
    """Open a browser on the viewer's page: True, False, or None = where a desktop session exists."""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> ViewerOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self) -> None:
        """ValueError naming the field."""
    def __eq__(self, other: object) -> bool: ...
    def __copy__(self) -> ViewerOptions: ...
    def __deepcopy__(self, memo: dict[int, Any]) -> ViewerOptions: ...
    def __repr__(self) -> str: ...

class ViewParams:
    """What one page request of the viewer may set (aos.viewer's session validates a page's values
    by this table): focus, aperture, views, the virtual camera, the display mapping. Defaults
    from the C++ struct aos::ViewParams."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        mode: Literal['perspective', 'map'] = ...,
        focal_height: float = ...,
        tilt_x_deg: float = ...,
        tilt_y_deg: float = ...,
        surface: bool = ...,
        surface_offset: float = ...,
        aperture_radius: float = ...,
        view_first: int = ...,
        view_last: int = ...,
        pose_view: int = ...,
        orbit_deg: float = ...,
        tilt_deg: float = ...,
        pan_x: float = ...,
        pan_y: float = ...,
        pan_z: float = ...,
        fov_deg: float = ...,
        width: int = ...,
        height: int = ...,
        range: Literal['views', 'auto'] = ...,
        gain: float = ...,
        offset: float = ...,
        colormap: Literal['grey', 'turbo', 'iron'] = ...,
        preview: bool = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    mode: Literal['perspective', 'map']
    """perspective (a pinhole virtual camera) or map (render_map: orthographic, looking straight
    down, north-up in the frame's own x/y). [one of perspective or map]"""
    focal_height: float
    """The focal plane z = H, local frame, metres. [m, in [-10000000, 10000000]]"""
    tilt_x_deg: float
    """The focal plane's normal tilted about the y axis, degrees, about the point (pivot x, pivot y,
    H) under the base camera. [deg, in [-80, 80]]"""
    tilt_y_deg: float
    """The focal plane's normal tilted about the x axis, degrees. [deg, in [-80, 80]]"""
    surface: bool
    """Focus on the session's focal surface (a mesh or DEM given at start) instead of the plane."""
    surface_offset: float
    """The focal surface moved this far up (towards the views), metres. [m, in [-10000, 10000]]"""
    aperture_radius: float
    """Radius of the synthetic aperture, metres (the renders' aperture_radius, render/aperture.h);
    inf = every view. [m, >= 0]"""
    view_first: int
    """First view of the half-open range of view indices to integrate (a time window of the flight).
    [>= 0]"""
    view_last: int
    """One past the last view of that range. [>= 0]"""
    pose_view: int
    """The base pose of the virtual camera: a recorded view. [>= 0]"""
    orbit_deg: float
    """Orbit about the vertical axis through the point where the base camera's axis meets the focal
    plane, degrees. [deg, in [-360, 360]]"""
    tilt_deg: float
    """Tilt about the camera's x axis through that point, degrees. [deg, in [-89, 89]]"""
    pan_x: float
    """Camera moved along the world x axis, metres. [m, in [-100000, 100000]]"""
    pan_y: float
    """Camera moved along the world y axis, metres. [m, in [-100000, 100000]]"""
    pan_z: float
    """Camera moved along the world z axis, metres. [m, in [-100000, 100000]]"""
    fov_deg: float
    """Horizontal field of view (zoom), degrees; 0 = the pose view's. [deg, in [0, 179]]"""
    width: int
    """Image width, pixels; 0 = the pose view's. [px, in [8, 2048] or 0]"""
    height: int
    """Image height, pixels; 0 = the pose view's. [px, in [8, 2048] or 0]"""
    range: Literal['views', 'auto']
    """Display range: views (the frames' type range, 0..255 for 8-bit) or auto (1st..99th percentile
    of the covered pixels). [one of views or auto]"""
    gain: float
    """Display: multiplies the normalised value about offset. [in [0.01, 100]]"""
    offset: float
    """Display: the normalised value gain scales about. [in [-10, 10]]"""
    colormap: Literal['grey', 'turbo', 'iron']
    """Display colour map of single-channel data. [one of grey, turbo or iron]"""
    preview: bool
    """A control is being dragged: the full-size image from a spread subset of the selected views
    (every k-th along the flight, as many as fit the frame budget), never a downscaled image."""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> ViewParams:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self, view_count: int) -> None:
        """ValueError naming the field."""
    def __eq__(self, other: object) -> bool: ...
    def __copy__(self) -> ViewParams: ...
    def __deepcopy__(self, memo: dict[int, Any]) -> ViewParams: ...
    def __repr__(self) -> str: ...

class MapResult:
    """What render_map returns: the map and its grid."""

    @property
    def image(self) -> numpy.typing.NDArray[numpy.float32]:
        """float32 (H, W) or (H, W, C), 0 where count is 0; row 0 = largest y; shared.

        ValueError when the map was only streamed to its file (see has_arrays)."""
    @property
    def count(self) -> numpy.typing.NDArray[numpy.uint32]:
        """uint32 (H, W) view samples per pixel; shared. ValueError when only streamed."""
    @property
    def has_arrays(self) -> bool:
        """Whether image and count are held in memory (render_map without path, or arrays=True)."""
    @property
    def geotransform(self) -> tuple[float, float, float, float, float, float]:
        """GDAL's (x_min, p, 0, y_max, 0, -p) in world coordinates."""
    @property
    def crs(self) -> str: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def pixel_size(self) -> float: ...
    @property
    def up_z(self) -> float:
        """+1: up is +z; -1: up is -z."""
    @property
    def samples(self) -> int: ...
    @property
    def uncovered_pixels(self) -> int: ...
    @property
    def views_selected(self) -> int: ...
    @property
    def views_used(self) -> int:
        """Selected views that contributed to at least one pixel."""
    @property
    def tiles(self) -> int: ...
    def __repr__(self) -> str: ...

def _render_map(
    light_field: LightField,
    options: MapOptions,
    path: str,
    force: bool,
    arrays: bool,
    progress: _Progress = None,
) -> MapResult: ...

# Maps window by window in other processes (aos.distributed; map.h MapWindowViews,
# RenderMapWindow, MapGeoTiffWriter). Private: use aos.render_map(..., client=...).
def _map_grid(light_field: LightField, options: MapOptions) -> dict[str, Any]: ...
def _map_window_views(
    light_field: LightField, options: MapOptions, x0: int, y0: int, w: int, h: int
) -> list[int]: ...
def _map_windows_views(
    light_field: LightField, options: MapOptions, windows: Sequence[tuple[int, int, int, int]]
) -> list[list[int]]: ...
def _render_map_window(
    light_field: LightField,
    options: MapOptions,
    x0: int,
    y0: int,
    w: int,
    h: int,
    views: Sequence[int],
) -> dict[str, Any]: ...
def _check_map_covered(
    light_field: LightField, options: MapOptions, uncovered_pixels: int
) -> None: ...

class _MapGeoTiffWriter:
    """Writes a map window by window (map.h MapGeoTiffWriter)."""

    def __init__(
        self,
        light_field: LightField,
        options: MapOptions,
        channels: int,
        path: str,
        force: bool = False,
    ) -> None: ...
    def write(
        self,
        x0: int,
        y0: int,
        image: numpy.typing.ArrayLike,
        count: numpy.typing.ArrayLike,
    ) -> None: ...
    def commit(self, progress: _Progress = None) -> None: ...

class FocalStackOptions:
    """Options of render_focal_stack. Defaults from the C++ struct aos::FocalStackOptions."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        render: IntegralOptions = ...,
        first_plane: Plane | float = ...,
        last_plane: Plane | float = ...,
        ground_plane: Plane | float | None = ...,
        first_offset: float = ...,
        last_offset: float = ...,
        slices: int = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    render: IntegralOptions
    """Virtual camera, aperture, views, threads and variance flag of every slice (IntegralOptions);
    a render.focal_surface that is not a plane makes a terrain-following stack (another plane
    than the default is refused)."""
    @property
    def first_plane(self) -> Plane:
        """Boundary plane of slice 0 (local frame)."""
    @first_plane.setter
    def first_plane(self, value: Plane | float) -> None: ...
    @property
    def last_plane(self) -> Plane:
        """Boundary plane of slice N-1 (local frame)."""
    @last_plane.setter
    def last_plane(self, value: Plane | float) -> None: ...
    @property
    def ground_plane(self) -> Plane | None:
        """A ground plane (e.g. estimate_ground(...).plane): the slices then lie parallel to it at
        first_offset .. last_offset along its normal turned towards the views; None =
        first_plane/last_plane."""
    @ground_plane.setter
    def ground_plane(self, value: Plane | float | None) -> None: ...
    first_offset: float
    """Terrain-following stacks (render.focal_surface not a plane) and stacks around ground_plane:
    offset of slice 0 along up, metres. [m, finite]"""
    last_offset: float
    """Terrain-following stacks and stacks around ground_plane: offset of slice N-1 along up,
    metres. [m, finite]"""
    slices: int
    """Number of slices, 1 .. 100000. [in [1, 100000]]"""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> FocalStackOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self, view_count: int) -> None:
        """ValueError naming the offending field."""
    def __eq__(self, other: object) -> bool: ...
    def __copy__(self) -> FocalStackOptions: ...
    def __deepcopy__(self, memo: dict[int, Any]) -> FocalStackOptions: ...
    def __repr__(self) -> str: ...

class FocalStack:
    @property
    def camera(self) -> PinholeCamera: ...
    @property
    def cam_from_world(self) -> Rigid3d: ...
    @property
    def render(self) -> IntegralOptions: ...
    @property
    def planes(self) -> list[Plane]: ...
    @property
    def offsets(self) -> list[float]: ...
    @property
    def surface(self) -> Optional[FocalSurface]: ...
    @property
    def up(self) -> _Float64Array: ...
    @property
    def images(self) -> numpy.typing.NDArray[numpy.float32]:
        """float32 (N, H, W) or (N, H, W, C), slice index first; a new array (COPY) per access."""
    @property
    def counts(self) -> numpy.typing.NDArray[numpy.uint32]:
        """uint32 (N, H, W); a new array (COPY) per access."""
    @property
    def variances(self) -> Optional[numpy.typing.NDArray[numpy.float32]]:
        """float32 (N, H, W), or None unless rendered with variance; a COPY per access."""
    def __len__(self) -> int: ...
    def __repr__(self) -> str: ...

def _render_focal_stack(
    light_field: LightField, options: FocalStackOptions, progress: _Progress = None
) -> FocalStack: ...
def stack_planes(
    first: _PlaneLike, last: _PlaneLike, slices: int, center: _Vector
) -> list[Plane]: ...
def interpolate_plane(first: _PlaneLike, last: _PlaneLike, s: float, center: _Vector) -> Plane: ...
def plane_depth(
    camera: PinholeCamera, cam_from_world: Rigid3d, plane: _PlaneLike
) -> numpy.typing.NDArray[numpy.float32]: ...
def write_focal_stack(folder: str, stack: FocalStack) -> None: ...
def read_focal_stack(folder: str) -> FocalStack: ...

class MergeMethod:
    sobel: ClassVar[MergeMethod]
    improved: ClassVar[MergeMethod]
    robust: ClassVar[MergeMethod]
    def __init__(self, value: int) -> None: ...
    @property
    def name(self) -> str: ...
    @property
    def value(self) -> int: ...

class MergeOptions:
    """Options of merge_focal_stack and all_in_focus. Defaults from the C++ struct
    aos::MergeOptions. aos.merge_focal_stack also accepts method as a string."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        method: MergeMethod | Literal['sobel', 'improved', 'robust'] = ...,
        window_radius: int = ...,
        smoothing_sigma: float = ...,
        edge_sigma: float = ...,
        smoothing_iterations: int = ...,
        robust: SurfaceIntegralOptions = ...,
        num_threads: int = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    @property
    def method(self) -> MergeMethod:
        """sobel, improved (default) or robust."""
    @method.setter
    def method(self, value: MergeMethod | Literal['sobel', 'improved', 'robust']) -> None: ...
    window_radius: int
    """improved/robust: focus measure window radius, pixels (window 2r+1 on a side), 0..32. [px, in
    [0, 32]]"""
    smoothing_sigma: float
    """improved/robust: spatial sigma of the edge-aware depth smoothing, pixels, [0, 16]; 0 = off.
    [px, in [0, 16]]"""
    edge_sigma: float
    """improved/robust: range sigma of the smoothing, as a fraction of the guide image's contrast
    (1st to 99th percentile), > 0. [> 0 and finite]"""
    smoothing_iterations: int
    """improved/robust: smoothing passes, 0..20. [in [0, 20]]"""
    robust: SurfaceIntegralOptions
    """robust: the outlier-rejecting mean (SurfaceIntegralOptions; its robust flag is forced on)."""
    num_threads: int
    """Worker threads of the merge (slices render with render.num_threads); -1 = all cores. [in [1,
    1024] or -1]"""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> MergeOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self) -> None:
        """ValueError naming the field."""
    def __eq__(self, other: object) -> bool: ...
    def __copy__(self) -> MergeOptions: ...
    def __deepcopy__(self, memo: dict[int, Any]) -> MergeOptions: ...
    def __repr__(self) -> str: ...

class MergeResult:
    @property
    def image(self) -> numpy.typing.NDArray[numpy.float32]: ...
    @property
    def depth(self) -> numpy.typing.NDArray[numpy.float32]: ...
    @property
    def confidence(self) -> numpy.typing.NDArray[numpy.float32]: ...
    @property
    def slice(self) -> numpy.typing.NDArray[numpy.float32]: ...
    @property
    def uncovered_pixels(self) -> int: ...
    @property
    def fallback_pixels(self) -> int: ...
    @property
    def seconds_merge(self) -> float: ...
    @property
    def seconds_render(self) -> float: ...
    @property
    def rendered_fraction(self) -> float: ...
    def __repr__(self) -> str: ...

class AllInFocusOptions:
    """Options of all_in_focus."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        stack: FocalStackOptions = ...,
        merge: MergeOptions = ...,
        coarse_to_fine: int = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    stack: FocalStackOptions
    """The slices (FocalStackOptions)."""
    merge: MergeOptions
    """The merge (MergeOptions)."""
    coarse_to_fine: int
    """0 = off; a factor 2..16: a coarse stack (1/factor the size, every factor-th slice) chooses
    each factor x factor block's slices, only those render at full resolution. [in [2, 16] or 0]"""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> AllInFocusOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self, view_count: int) -> None:
        """ValueError naming the field."""
    def __eq__(self, other: object) -> bool: ...
    def __copy__(self) -> AllInFocusOptions: ...
    def __deepcopy__(self, memo: dict[int, Any]) -> AllInFocusOptions: ...
    def __repr__(self) -> str: ...

def _merge_focal_stack(
    stack: FocalStack,
    options: MergeOptions,
    light_field: Optional[LightField] = None,
    progress: _Progress = None,
) -> MergeResult: ...
def _all_in_focus(
    light_field: LightField, options: AllInFocusOptions, progress: _Progress = None
) -> MergeResult: ...

class QualityOptions:
    """Options of compare_images (defaults from the C++ struct aos::QualityOptions)."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        data_range: float = ...,
        gaussian_sigma: float = ...,
        window_radius: int = ...,
        k1: float = ...,
        k2: float = ...,
        grey: bool = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    data_range: float
    """Peak-to-peak value range L; 0 = from the reference's dtype (uint8 255, uint16 65535, float
    1.0)."""
    gaussian_sigma: float
    """Standard deviation of the SSIM window, pixels (> 0)."""
    window_radius: int
    """SSIM window radius, pixels (>= 1); the window is (2r + 1)^2."""
    k1: float
    """SSIM constant k1, (0, 1)."""
    k2: float
    """SSIM constant k2, (0, 1)."""
    grey: bool
    """Compare luminances: 3- or 4-channel images become Rec. 601 luminance first."""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> QualityOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self) -> None: ...
    def __eq__(self, other: object) -> bool: ...
    def __copy__(self) -> QualityOptions: ...
    def __deepcopy__(self, memo: dict[int, Any]) -> QualityOptions: ...
    def __repr__(self) -> str: ...

class QualityResult:
    """Result of compare_images (see docs/metrics.md)."""

    @property
    def mse(self) -> float: ...
    @property
    def psnr_db(self) -> float: ...
    @property
    def ssim(self) -> float: ...
    @property
    def ssim_channels(self) -> list[float]: ...
    @property
    def color_ssim(self) -> float: ...
    @property
    def data_range(self) -> float: ...
    @property
    def test_scale(self) -> float: ...
    @property
    def note(self) -> str: ...
    @property
    def mse_pixels(self) -> int: ...
    @property
    def ssim_pixels(self) -> int: ...
    def __repr__(self) -> str: ...

class ResolutionOptions:
    """Options of sampling_resolution (defaults from the C++ struct aos::ResolutionOptions)."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        distance_m: float = ...,
        pose_error_px: float = ...,
        pose_error_m: float = ...,
        max_off_axis_deg: float = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    distance_m: float
    """Distance from the camera to the focal plane along its axis, metres (> 0). [m]"""
    pose_error_px: float
    """Pose error in pixels (>= 0), converted to metres with the sample size. [px]"""
    pose_error_m: float
    """Pose error in metres at the focal plane (>= 0); at most one of the two. [m]"""
    max_off_axis_deg: float
    """The back-projected figure counts pixels whose ray is within this angle of the axis, degrees
    in (0, 90). [deg]"""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> ResolutionOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self) -> None: ...
    def __eq__(self, other: object) -> bool: ...
    def __copy__(self) -> ResolutionOptions: ...
    def __deepcopy__(self, memo: dict[int, Any]) -> ResolutionOptions: ...
    def __repr__(self) -> str: ...

class ResolutionResult:
    @property
    def eq2_samples_per_m2(self) -> float: ...
    @property
    def eq2_sample_size_m(self) -> float: ...
    @property
    def samples_per_m2(self) -> float: ...
    @property
    def sample_size_m(self) -> float: ...
    @property
    def pixels_on_plane(self) -> int: ...
    @property
    def pixels_off_axis(self) -> int: ...
    @property
    def footprint_m2(self) -> float: ...
    @property
    def pose_error_m(self) -> float: ...
    @property
    def effective_sample_size_m(self) -> float: ...
    @property
    def effective_samples_per_m2(self) -> float: ...
    def __repr__(self) -> str: ...

def _sampling_resolution(camera: LensCamera, options: ResolutionOptions) -> ResolutionResult: ...

class FlightPlanOptions:
    """Options of plan_flight (defaults from the C++ struct aos::FlightPlanOptions; docs/flight-
    planning.md)."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        shape: Literal['circle', 'sector', 'rectangle', 'polygon', 'line'] = ...,
        coordinates: Literal['world', 'latlon'] = ...,
        crs: str = ...,
        center: Sequence[float] = ...,
        radius_m: float = ...,
        sector_start_deg: float = ...,
        sector_angle_deg: float = ...,
        width_m: float = ...,
        length_m: float = ...,
        vertices: Sequence[Sequence[float]] = ...,
        pattern: Literal['scan', 'grid', 'circles'] = ...,
        spacing_m: float = ...,
        along_spacing_m: float = ...,
        outer_scale: float = ...,
        heading_deg: float = ...,
        min_shots_per_line: int = ...,
        altitude_m: float = ...,
        altitude_mode: Literal['terrain', 'constant'] = ...,
        dem: str = ...,
        ground_height_m: float = ...,
        terrain_up: Literal['+z', '-z'] = ...,
        min_clearance_m: float = ...,
        ground_speed_mps: float = ...,
        hover_s: float = ...,
        battery_min: float = ...,
        max_waypoints: int = ...,
        image_width: int = ...,
        image_height: int = ...,
        fov_deg: float = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    shape: Literal['circle', 'sector', 'rectangle', 'polygon', 'line']
    """circle, sector, rectangle, polygon or line. [one of circle, sector, rectangle, polygon or
    line]"""
    coordinates: Literal['world', 'latlon']
    """world (x, y metres) or latlon (latitude, longitude degrees, WGS84). [one of world or latlon]"""
    crs: str
    """CRS of world coordinates (projected, metres); '' = local frame."""
    @property
    def center(self) -> list[float]:
        """Centre of a circle, sector or rectangle: (x, y) or (lat, lon)."""
    @center.setter
    def center(self, value: Sequence[float]) -> None: ...
    radius_m: float
    """Radius of a circle or sector, metres (> 0). [m]"""
    sector_start_deg: float
    """Sector: bearing of its first edge, degrees. [deg]"""
    sector_angle_deg: float
    """Sector: its angle, degrees in (0, 360]. [deg]"""
    width_m: float
    """Rectangle: size across the heading, metres. [m]"""
    length_m: float
    """Rectangle: size along the heading, metres. [m]"""
    @property
    def vertices(self) -> list[list[float]]:
        """Polygon corners or line points, (x, y) or (lat, lon)."""
    @vertices.setter
    def vertices(self, value: Sequence[Sequence[float]]) -> None: ...
    pattern: Literal['scan', 'grid', 'circles']
    """scan, grid or circles. [one of scan, grid or circles]"""
    spacing_m: float
    """Distance between lines or rings at the centre, metres. [m]"""
    along_spacing_m: float
    """Distance between shots along a line or ring at the centre, metres; 0 = spacing_m. [m]"""
    outer_scale: float
    """Spacing at the edge over spacing at the centre (>= 1)."""
    heading_deg: float
    """Compass direction of the scan lines, degrees. [deg]"""
    min_shots_per_line: int
    """Scan lines with fewer shots inside the shape are not flown (>= 1). [>= 1]"""
    altitude_m: float
    """Height above the ground, metres (> 0). [m]"""
    altitude_mode: Literal['terrain', 'constant']
    """terrain or constant. [one of terrain or constant]"""
    dem: str
    """Terrain mesh (OBJ, PLY) or raster path; '' = flat ground."""
    ground_height_m: float
    """Flat ground's z without a DEM, metres. [m]"""
    terrain_up: Literal['+z', '-z']
    """+z or -z (z down, JKU's F0). [one of +z or -z]"""
    min_clearance_m: float
    """Least height above the terrain of a constant-altitude shot, metres. [m]"""
    ground_speed_mps: float
    """Ground speed, m/s (> 0). [m/s]"""
    hover_s: float
    """Time at each shot, seconds (>= 0). [s]"""
    battery_min: float
    """Flight time one battery allows, minutes (inf: none)."""
    max_waypoints: int
    """Most shots (and scan lines or rings) a plan may have; a larger one is refused first."""
    image_width: int
    """Camera for Eq. 2: width, pixels. [>= 1]"""
    image_height: int
    """Camera for Eq. 2: height, pixels. [>= 1]"""
    fov_deg: float
    """Camera for Eq. 2: horizontal field of view, degrees. [deg]"""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> FlightPlanOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self) -> None: ...
    def __eq__(self, other: object) -> bool: ...
    def __copy__(self) -> FlightPlanOptions: ...
    def __deepcopy__(self, memo: dict[int, Any]) -> FlightPlanOptions: ...
    def __repr__(self) -> str: ...

class Waypoint:
    @property
    def x(self) -> float: ...
    @property
    def y(self) -> float: ...
    @property
    def z(self) -> float: ...
    @property
    def ground_z(self) -> float: ...
    @property
    def agl_m(self) -> float: ...
    @property
    def latitude_deg(self) -> float: ...
    @property
    def longitude_deg(self) -> float: ...
    @property
    def line(self) -> int: ...
    def __repr__(self) -> str: ...

class FlightPlanResult:
    @property
    def waypoints(self) -> list[Waypoint]: ...
    @property
    def crs(self) -> str: ...
    @property
    def outline(self) -> list[tuple[float, float]]: ...
    @property
    def growth_center(self) -> tuple[float, float]: ...
    @property
    def aperture_radius_m(self) -> float: ...
    @property
    def aperture_area_m2(self) -> float: ...
    @property
    def images(self) -> int: ...
    @property
    def lines(self) -> int: ...
    @property
    def length_m(self) -> float: ...
    @property
    def flight_time_s(self) -> float: ...
    @property
    def frames_per_minute(self) -> float: ...
    @property
    def battery_fraction(self) -> float: ...
    @property
    def min_step_m(self) -> float: ...
    @property
    def max_step_m(self) -> float: ...
    @property
    def eq2_samples_per_m2(self) -> float: ...
    @property
    def eq2_sample_size_m(self) -> float: ...
    @property
    def min_agl_m(self) -> float: ...
    @property
    def max_agl_m(self) -> float: ...
    @property
    def warnings(self) -> list[str]: ...
    def __repr__(self) -> str: ...

def _plan_flight(options: FlightPlanOptions, progress: _Progress = None) -> FlightPlanResult: ...
def flight_plan_csv(result: FlightPlanResult) -> str: ...
def flight_plan_geojson(result: FlightPlanResult) -> str: ...
def flight_plan_kml(result: FlightPlanResult) -> str: ...
class PlanPreviewResult:
    @property
    def views(self) -> int: ...
    @property
    def visible_fraction(self) -> float: ...
    @property
    def psnr_db(self) -> float: ...
    @property
    def ssim(self) -> float: ...
    @property
    def single_view_psnr_db(self) -> float: ...
    @property
    def has_target(self) -> bool: ...
    @property
    def contrast_to_noise(self) -> float: ...
    @property
    def integral(self) -> numpy.typing.NDArray[Any]: ...
    @property
    def truth(self) -> numpy.typing.NDArray[Any]: ...
    @property
    def seconds(self) -> float: ...
    def __repr__(self) -> str: ...

def _preview_flight_plan(
    plan: FlightPlanResult, scene: Scene, num_threads: int = -1, progress: _Progress = None
) -> PlanPreviewResult: ...
def flight_plan_map(
    options: FlightPlanOptions, result: FlightPlanResult, size_px: int = 800
) -> numpy.typing.NDArray[numpy.uint8]: ...

def _compare_images(
    test: numpy.typing.ArrayLike,
    reference: numpy.typing.ArrayLike,
    mask: Optional[numpy.typing.ArrayLike] = None,
    options: QualityOptions = ...,
    progress: _Progress = None,
) -> QualityResult: ...
def _progress_selftest(
    total: int,
    num_threads: int = 2,
    sleep_us: int = 0,
    progress: _Progress = None,
    throw_cancelled: bool = False,
) -> int:
    """Test hook for the progress sink (not public API)."""

class Scene:
    """A parsed, checked scene (docs/scenes.md)."""

    @property
    def source(self) -> str: ...
    @property
    def seed(self) -> int: ...
    def to_json(self) -> str: ...
    def view_positions(self) -> list[_Float64Array]: ...
    def has_occluders(self) -> bool: ...
    def __repr__(self) -> str: ...

def load_scene(path: str) -> Scene: ...
def parse_scene(json_text: str, source: str = "<json>", base_dir: str = ".") -> Scene: ...
def default_scene() -> Scene: ...

class SimulateOptions:
    """Options of simulate. Defaults come from the C++ struct aos::SimulateOptions."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        num_threads: int = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    num_threads: int
    """Worker threads; -1 = all cores. [in [1, 1024] or -1]"""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> SimulateOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self) -> None: ...
    def __eq__(self, other: object) -> bool: ...
    def __copy__(self) -> SimulateOptions: ...
    def __deepcopy__(self, memo: dict[int, Any]) -> SimulateOptions: ...
    def __repr__(self) -> str: ...

class GroundTruth:
    """Ground truth seen by the truth camera; arrays share memory with the result."""

    @property
    def camera(self) -> PinholeCamera: ...
    @property
    def cam_from_world(self) -> Rigid3d: ...
    @property
    def ground(self) -> _ImageArray: ...
    @property
    def depth(self) -> numpy.typing.NDArray[numpy.float32]: ...
    @property
    def height(self) -> numpy.typing.NDArray[numpy.float32]: ...
    @property
    def views_seeing(self) -> numpy.typing.NDArray[numpy.uint32]: ...
    @property
    def blocked_fraction(self) -> Optional[numpy.typing.NDArray[numpy.float32]]: ...
    @property
    def image(self) -> _ImageArray:
        """The truth image: the occluder-free ground (as `ground`)."""
    @property
    def ground_height_at_center(self) -> float: ...
    def __repr__(self) -> str: ...

class SimulationResult:
    """What simulate returns."""

    @property
    def light_field(self) -> LightField: ...
    @property
    def true_cam_from_world(self) -> list[Rigid3d]: ...
    @property
    def truth(self) -> GroundTruth: ...
    @property
    def image(self) -> _ImageArray:
        """The truth image (truth.ground): the occluder-free ground seen by the truth camera."""
    @property
    def stats(self) -> dict[str, Any]: ...
    def summary_json(self) -> str: ...
    def __repr__(self) -> str: ...

def _simulate(
    scene: Scene, options: SimulateOptions, progress: _Progress = None
) -> SimulationResult: ...
def write_simulation(result: SimulationResult, scene: Scene, output_dir: str) -> None: ...
def ground_heightfield(
    scene: Scene, extent: Sequence[float] = (0.0, 0.0, 0.0, 0.0)
) -> Heightfield:
    """The scene's ground as a DEM on the simulator's grid (all-zero extent = ground.extent)."""

class DemoOptions:
    """Options of run_demo. Defaults come from the C++ struct aos::DemoOptions."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        num_threads: int = ...,
        all_in_focus_slices: int = ...,
        target_margin_m: float = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    num_threads: int
    """Worker threads of the simulation and the renders; -1 = all cores. [in [1, 1024] or -1]"""
    all_in_focus_slices: int
    """Slices of the all-in-focus stack from the ground to the top of the occluders, 0..1000; 0 = no
    all-in-focus image."""
    target_margin_m: float
    """Ring of ground around each target used as its surroundings in the visibility figures, metres
    (> 0). [m]"""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> DemoOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self) -> None: ...
    def __eq__(self, other: object) -> bool: ...
    def __copy__(self) -> DemoOptions: ...
    def __deepcopy__(self, memo: dict[int, Any]) -> DemoOptions: ...
    def __repr__(self) -> str: ...

class TargetVisibility:
    """How clearly the targets show in one image (demo.h)."""

    @property
    def has_target(self) -> bool: ...
    @property
    def target_pixels(self) -> int: ...
    @property
    def surrounding_pixels(self) -> int: ...
    @property
    def contrast_to_noise(self) -> float: ...
    @property
    def standout_fraction(self) -> float: ...
    def __repr__(self) -> str: ...

class DemoRender:
    """One image of the demo, from the truth camera."""

    @property
    def name(self) -> str: ...
    @property
    def title(self) -> str: ...
    @property
    def focal_height(self) -> float: ...
    @property
    def aperture_radius(self) -> float: ...
    @property
    def image(self) -> numpy.typing.NDArray[numpy.float32]: ...
    @property
    def count(self) -> Optional[numpy.typing.NDArray[numpy.uint32]]: ...
    @property
    def quality(self) -> QualityResult: ...
    @property
    def visibility(self) -> TargetVisibility: ...
    @property
    def seconds(self) -> float: ...
    def __repr__(self) -> str: ...

class DemoResult:
    """What run_demo returns."""

    @property
    def scene(self) -> Scene: ...
    @property
    def options(self) -> DemoOptions: ...
    @property
    def simulation(self) -> SimulationResult: ...
    @property
    def target_mask(self) -> numpy.typing.NDArray[numpy.uint8]: ...
    @property
    def truth_visibility(self) -> TargetVisibility: ...
    @property
    def target_blocked_fraction(self) -> float: ...
    @property
    def ground_height(self) -> float: ...
    @property
    def occluder_height(self) -> float: ...
    @property
    def top_height(self) -> float: ...
    @property
    def renders(self) -> list[DemoRender]: ...
    @property
    def seconds_simulation(self) -> float: ...
    @property
    def seconds_total(self) -> float: ...
    def render(self, name: str) -> DemoRender: ...
    def summary_json(self) -> str: ...
    def index_html(self) -> str: ...
    def __repr__(self) -> str: ...

def _check_demo_folder(folder: str) -> None: ...
def _run_demo(scene: Scene, options: DemoOptions, progress: _Progress = None) -> DemoResult: ...
def write_demo(result: DemoResult, folder: str) -> list[str]: ...

class PosesOptions:
    """Options of estimate_poses (defaults from the C++ struct aos::PosesOptions)."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        colmap: str = ...,
        workspace: str = ...,
        matcher: Literal['sequential', 'spatial', 'exhaustive'] = ...,
        sequential_overlap: int = ...,
        spatial_neighbors: int = ...,
        camera_file: str = ...,
        camera_model: Literal['SIMPLE_PINHOLE', 'PINHOLE', 'SIMPLE_RADIAL', 'RADIAL', 'OPENCV', 'OPENCV_FISHEYE', 'SIMPLE_RADIAL_FISHEYE', 'RADIAL_FISHEYE'] = ...,
        fov_deg: float = ...,
        positions_file: str = ...,
        positions_crs: str = ...,
        exif_positions: bool = ...,
        max_image_size: int = ...,
        max_num_features: int = ...,
        sift_first_octave: int = ...,
        min_registered_fraction: float = ...,
        num_threads: int = ...,
        max_focal_deviation: float = ...,
        flight_height_m: float = ...,
        max_scale_deviation: float = ...,
        allow_implausible: bool = ...,
        preset: Literal['default', 'quick'] = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    colmap: str
    """The COLMAP executable (on PATH or a path)."""
    workspace: str
    """Keep COLMAP's workspace in this new folder; '' = a temporary one, removed."""
    matcher: Literal['sequential', 'spatial', 'exhaustive']
    """'sequential', 'spatial' or 'exhaustive'. [one of sequential, spatial or exhaustive]"""
    sequential_overlap: int
    """Sequential matching: successors each frame is matched with."""
    spatial_neighbors: int
    """Spatial matching: nearest frames (by position) each frame is matched with."""
    camera_file: str
    """Known camera (aos-camera file); '' = self-calibration of camera_model."""
    camera_model: Literal['SIMPLE_PINHOLE', 'PINHOLE', 'SIMPLE_RADIAL', 'RADIAL', 'OPENCV', 'OPENCV_FISHEYE', 'SIMPLE_RADIAL_FISHEYE', 'RADIAL_FISHEYE']
    """COLMAP model to self-calibrate. [one of SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL,
    OPENCV, OPENCV_FISHEYE, SIMPLE_RADIAL_FISHEYE or RADIAL_FISHEYE]"""
    fov_deg: float
    """Self-calibration's starting horizontal FOV, degrees; 0 = COLMAP's guess. [deg]"""
    positions_file: str
    """CSV of name,x,y,z positions (metres): geo-reference and spatial priors."""
    positions_crs: str
    """CRS of positions_file as PROJ names it (e.g. EPSG:4326, EPSG:25833); empty: from the header
    (lat/lon columns are WGS84 degrees, x/y/z metres in an unstated frame)."""
    exif_positions: bool
    """Positions from the frames' EXIF GPS tags (UTM) instead of a file."""
    max_image_size: int
    """Features on frames downscaled to this longest side."""
    max_num_features: int
    """Features per frame."""
    sift_first_octave: int
    """SIFT's first octave: -1 = on the frame upsampled 2x (COLMAP's default), 0 = on the frame
    itself (about 4x faster extraction)."""
    min_registered_fraction: float
    """Error below this fraction of frames registered."""
    num_threads: int
    """COLMAP's threads; -1 = all cores. [in [1, 1024] or -1]"""
    max_focal_deviation: float
    """Self-calibration: refuse a focal length further than this fraction from the fov_deg prior's,
    > 0."""
    flight_height_m: float
    """The cameras' height above the ground as flown, metres (e.g. 35 for a flight 35 m above the
    ground): the geo-referenced median depth is checked against it; 0 = not checked. Needs
    positions. [m]"""
    max_scale_deviation: float
    """Refuse a median depth further than this fraction from flight_height_m, > 0."""
    allow_implausible: bool
    """Keep implausible self-calibrated intrinsics or scene scale with a warning instead of
    refusing."""
    preset: Literal['default', 'quick']
    """'default' or 'quick': quick sets max_image_size 480, max_num_features 512, sift_first_octave
    0, sequential_overlap 3, spatial_neighbors 8 and, with positions, matcher 'spatial', each
    where left at its default (docs/poses.md). [one of default or quick]"""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> PosesOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self) -> None: ...
    def __eq__(self, other: object) -> bool: ...
    def __copy__(self) -> PosesOptions: ...
    def __deepcopy__(self, memo: dict[int, Any]) -> PosesOptions: ...
    def __repr__(self) -> str: ...

class GroundOptions:
    """Options of estimate_ground (defaults from the C++ struct aos::GroundOptions)."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        cell_size_m: float = ...,
        quantile: float = ...,
        min_points_per_cell: int = ...,
        outlier_sigmas: float = ...,
        max_step_m: float = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    cell_size_m: float
    """Side of a DEM cell, metres, > 0. [m]"""
    quantile: float
    """Height quantile of a cell's points taken as its ground, [0, 1)."""
    min_points_per_cell: int
    """Fewest points for a cell to be measured, >= 1."""
    outlier_sigmas: float
    """Cells this many robust sigmas above the plane are canopy candidates, > 0."""
    max_step_m: float
    """A candidate this far above the ground around it is canopy, metres, >= 0. [m]"""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> GroundOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self) -> None: ...
    def __eq__(self, other: object) -> bool: ...
    def __copy__(self) -> GroundOptions: ...
    def __deepcopy__(self, memo: dict[int, Any]) -> GroundOptions: ...
    def __repr__(self) -> str: ...

class GroundResult:
    """Where the ground is (sfm/ground.h)."""

    @property
    def up_sign(self) -> int: ...
    @property
    def plane(self) -> Plane: ...
    @property
    def plane_rms_m(self) -> float: ...
    @property
    def plane_cells(self) -> int: ...
    @property
    def min_x(self) -> float: ...
    @property
    def min_y(self) -> float: ...
    @property
    def cell_size_m(self) -> float: ...
    @property
    def measured_cells(self) -> int: ...
    @property
    def points(self) -> int: ...
    @property
    def z(self) -> numpy.typing.NDArray[numpy.float32]: ...
    def z_at(self, x: float, y: float) -> float: ...
    def heightfield(self, origin: _Vector, crs: str = "") -> Heightfield: ...
    def __repr__(self) -> str: ...

def _estimate_ground(points: numpy.typing.ArrayLike, up_sign: int, options: GroundOptions) -> GroundResult: ...
def _ground_up_sign(points: numpy.typing.ArrayLike, light_field: LightField) -> int: ...

class PosesResult:
    """What estimate_poses found."""

    @property
    def light_field(self) -> LightField: ...
    @property
    def frames(self) -> list[str]: ...
    @property
    def registered(self) -> list[str]: ...
    @property
    def unregistered(self) -> list[str]: ...
    @property
    def warnings(self) -> list[str]: ...
    @property
    def order(self) -> str: ...
    @property
    def time_source(self) -> str: ...
    @property
    def models(self) -> int: ...
    @property
    def points(self) -> int: ...
    @property
    def point_positions(self) -> _Float64Array: ...
    @property
    def observations(self) -> int: ...
    @property
    def mean_reprojection_error_px(self) -> float: ...
    @property
    def median_depth(self) -> float: ...
    @property
    def pose_error(self) -> float: ...
    @property
    def georeferenced(self) -> bool: ...
    @property
    def georeference_rms_m(self) -> float: ...
    @property
    def georeference_frames(self) -> int: ...
    @property
    def world_frame(self) -> str: ...
    @property
    def crs(self) -> str: ...
    @property
    def stage_seconds(self) -> dict[str, float]: ...
    @property
    def workspace(self) -> str: ...
    @property
    def focal_prior_px(self) -> float: ...
    @property
    def focal_deviation(self) -> float: ...
    @property
    def scale_deviation(self) -> float: ...
    @property
    def implausible(self) -> bool: ...
    def __repr__(self) -> str: ...

def _estimate_poses(
    frames_dir: str, options: PosesOptions, progress: _Progress = None
) -> PosesResult: ...

def _import_colmap(
    model_dir: str, images_dir: str, options: PosesOptions, progress: _Progress = None
) -> PosesResult: ...

class TelemetryOptions:
    """Options of import_telemetry (defaults from the C++ struct aos::TelemetryOptions)."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        telemetry_file: str = ...,
        camera_file: str = ...,
        fov_deg: float = ...,
        altitude: Literal['auto', 'gps', 'relative'] = ...,
        altitude_window: int = ...,
        max_altitude_deviation_m: float = ...,
        max_distance_from_centre_m: float = ...,
        frame_interval_s: float = ...,
        time_offset_s: float = ...,
        yaw_reference: Literal['true', 'grid', 'magnetic'] = ...,
        magnetic_declination_deg: float | None = ...,
        altitude_reference: Literal['absolute', 'takeoff'] = ...,
        takeoff_height_m: float | None = ...,
        dem: str = ...,
        home_latitude_deg: float | None = ...,
        home_longitude_deg: float | None = ...,
        grey: bool = ...,
        radiometric: Literal['none', 'flir', 'linear'] = ...,
        kelvin_per_count: float = ...,
        kelvin_offset: float = ...,
        temperature_frames_dir: str = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    telemetry_file: str
    """CSV log frame|time,lat,lon,alt,yaw,pitch,roll; '' = the frames' EXIF GPS and DJI XMP gimbal
    tags."""
    camera_file: str
    """Known camera (aos-camera file, any lens model); '' = a pinhole from fov_deg."""
    fov_deg: float
    """Horizontal field of view of a pinhole camera, degrees, (0, 180); without camera_file. [deg]"""
    altitude: Literal['auto', 'gps', 'relative']
    """EXIF/XMP altitude: 'auto' (XMP RelativeAltitude, else GPSAltitude), 'gps', 'relative'. [one
    of auto, gps or relative]"""
    altitude_window: int
    """Altitude outliers: running-median window in frames, odd >= 3; 0 = no rule."""
    max_altitude_deviation_m: float
    """An altitude further than this from its running median is replaced by it, metres. [m]"""
    max_distance_from_centre_m: float
    """A position farther than this from the flight's centre (median lat, lon) is refused, metres.
    [m]"""
    frame_interval_s: float
    """With a time column: seconds between consecutive frames (view order). [s]"""
    time_offset_s: float
    """With a time column: the log time of the first frame, seconds. [s]"""
    yaw_reference: Literal['true', 'grid', 'magnetic']
    """The north yaw is measured from: 'true', 'grid' (UTM grid north) or 'magnetic' (with
    magnetic_declination_deg). [one of true, grid or magnetic]"""
    magnetic_declination_deg: float | None
    """With yaw_reference 'magnetic': declination, degrees east of true north (west negative), [-90,
    90]. [deg]"""
    altitude_reference: Literal['absolute', 'takeoff']
    """Altitudes are 'absolute' (world heights) or above the 'takeoff' point (plus takeoff_height_m
    or the DEM's height there). [one of absolute or takeoff]"""
    takeoff_height_m: float | None
    """With altitude_reference 'takeoff': the take-off ground's world height, metres; unset =
    sampled from dem. [m]"""
    dem: str
    """DEM raster (GeoTIFF, any CRS) the take-off height is sampled from under the home point."""
    home_latitude_deg: float | None
    """Take-off point latitude, WGS84 degrees; unset = the first frame's. [deg]"""
    home_longitude_deg: float | None
    """Take-off point longitude, WGS84 degrees; unset = the first frame's. [deg]"""
    grey: bool
    """Integrate the frames as grey (false-colour thermal): recorded in the light field, applied at
    every load."""
    radiometric: Literal['none', 'flir', 'linear']
    """Pixel values: 'none', 'flir' (FLIR radiometric JPEGs -> temperature frames, exiftool) or
    'linear' (16-bit counts, kelvin_per_count). [one of none, flir or linear]"""
    kelvin_per_count: float
    """With radiometric 'linear': kelvin per count, > 0 (FLIR TLinear: 0.01 or 0.04). [K]"""
    kelvin_offset: float
    """With radiometric 'linear': the temperature of count 0, kelvin. [K]"""
    temperature_frames_dir: str
    """With radiometric 'flir': new folder for the 16-bit temperature frames (0.01 K per unit)."""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> TelemetryOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self) -> None: ...

class AltitudeOutlier:
    """An altitude replaced by its running median."""

    @property
    def frame(self) -> str: ...
    @property
    def altitude_m(self) -> float: ...
    @property
    def median_m(self) -> float: ...

class TelemetryResult:
    """What import_telemetry made."""

    @property
    def light_field(self) -> LightField: ...
    @property
    def frames(self) -> list[str]: ...
    @property
    def source(self) -> str: ...
    @property
    def altitude_outliers(self) -> list[AltitudeOutlier]: ...
    @property
    def warnings(self) -> list[str]: ...
    @property
    def order(self) -> str: ...
    @property
    def time_source(self) -> str: ...
    @property
    def altitude_source(self) -> str: ...
    @property
    def yaw_reference(self) -> str: ...
    @property
    def declination_deg(self) -> float: ...
    @property
    def max_convergence_deg(self) -> float: ...
    @property
    def radiometric(self) -> str: ...
    @property
    def first_frame_median_c(self) -> float: ...
    @property
    def first_frame_low_c(self) -> float: ...
    @property
    def first_frame_high_c(self) -> float: ...
    @property
    def altitude_reference(self) -> str: ...
    @property
    def takeoff_height_m(self) -> float: ...
    @property
    def takeoff_height_from(self) -> str: ...

def _import_telemetry(
    frames_dir: str, options: TelemetryOptions, progress: _Progress = None
) -> TelemetryResult: ...

class VideoFramesOptions:
    """Options of import_video's frames (defaults from the C++ struct aos::VideoFramesOptions)."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        srt_file: str = ...,
        frame_every_s: float = ...,
        frame_every_m: float = ...,
        srt_altitude: Literal['relative', 'absolute'] = ...,
        fixed_pitch_deg: float | None = ...,
        srt_offset_s: float = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    srt_file: str
    """DJI subtitle telemetry (.SRT) of the video: time, position, altitudes, gimbal angles where
    present."""
    frame_every_s: float
    """Take a frame every this many seconds of video (frame_every_m 0). [s, >= 0 and finite]"""
    frame_every_m: float
    """Take a frame every this many metres of flight instead; 0 = by time. [m, >= 0 and finite]"""
    srt_altitude: Literal['relative', 'absolute']
    """Which SRT altitude becomes alt: 'relative' (above the take-off point) or 'absolute'. [one of
    relative or absolute]"""
    fixed_pitch_deg: float | None
    """Camera pitch when the SRT has no gimbal angles (-90 = nadir); the yaw is then the direction
    of flight. [deg]"""
    srt_offset_s: float
    """The SRT time of the video's first frame, seconds. [s, finite]"""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> VideoFramesOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self) -> None: ...

class VideoFramesResult:
    """The frames import_video took."""

    @property
    def frames(self) -> list[str]: ...
    @property
    def times_s(self) -> list[float]: ...
    @property
    def video_frames(self) -> int: ...
    @property
    def fps(self) -> float: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def srt_samples(self) -> int: ...
    @property
    def srt_skipped_blocks(self) -> int: ...
    @property
    def yaw_from(self) -> str: ...
    @property
    def pitch_from(self) -> str: ...
    @property
    def altitude_from(self) -> str: ...

class VideoImportResult:
    """What import_video wrote."""

    @property
    def frames(self) -> VideoFramesResult: ...
    @property
    def telemetry(self) -> TelemetryResult: ...
    @property
    def light_field_path(self) -> str: ...

def _import_video(
    video: str,
    output_dir: str,
    options: VideoFramesOptions,
    telemetry: TelemetryOptions,
    progress: _Progress = None,
) -> VideoImportResult: ...

class OdmGeoEntry:
    """One image line of an OpenDroneMap geo.txt."""

    @property
    def line(self) -> int: ...
    @property
    def image(self) -> str: ...
    @property
    def position(self) -> tuple[float, float, float]: ...
    @property
    def has_z(self) -> bool: ...
    @property
    def yaw_pitch_roll_deg(self) -> tuple[float, float, float] | None: ...
    @property
    def accuracy_m(self) -> tuple[float, float] | None: ...
    @property
    def extras(self) -> str: ...

class OdmGeoFile:
    """An OpenDroneMap image geolocation file (sfm/odm.h)."""

    @property
    def projection(self) -> str: ...
    @property
    def crs(self) -> str: ...
    @property
    def entries(self) -> list[OdmGeoEntry]: ...

def read_odm_geo(path: str) -> OdmGeoFile: ...
def write_odm_geo(path: str, light_field: LightField, overwrite: bool = False) -> None: ...

class OdmGcp:
    """One sighting of a ground control point (a gcp_list.txt line)."""

    def __init__(self, position: _Vector, pixel: Sequence[float], image: str, name: str = "",
                 extras: str = "") -> None: ...
    @property
    def line(self) -> int: ...
    @property
    def position(self) -> _Float64Array: ...
    @property
    def pixel(self) -> _Float64Array: ...
    @property
    def image(self) -> str: ...
    @property
    def name(self) -> str: ...
    @property
    def extras(self) -> str: ...

class OdmGcpFile:
    """An OpenDroneMap ground control file (sfm/odm.h)."""

    def __init__(self, projection: str, points: Sequence[OdmGcp]) -> None: ...
    @property
    def projection(self) -> str: ...
    @property
    def crs(self) -> str: ...
    @property
    def points(self) -> list[OdmGcp]: ...

def read_odm_gcp(path: str) -> OdmGcpFile: ...
def write_odm_gcp(path: str, gcp_file: OdmGcpFile, overwrite: bool = False) -> None: ...

class GcpResidual:
    """How one ground control sighting agrees with a pose."""

    @property
    def line(self) -> int: ...
    @property
    def image(self) -> str: ...
    @property
    def name(self) -> str: ...
    @property
    def view(self) -> int: ...
    @property
    def predicted(self) -> _Float64Array: ...
    @property
    def observed(self) -> _Float64Array: ...
    @property
    def error_px(self) -> float: ...
    @property
    def ground_error_m(self) -> _Float64Array: ...
    @property
    def ground_error_norm_m(self) -> float: ...

class GcpCheckResult:
    """What check_gcps measured."""

    @property
    def residuals(self) -> list[GcpResidual]: ...
    @property
    def rms_px(self) -> float: ...
    @property
    def max_px(self) -> float: ...
    @property
    def rms_ground_m(self) -> float: ...
    @property
    def max_ground_m(self) -> float: ...

def check_gcps(light_field: LightField, gcps: OdmGcpFile) -> GcpCheckResult: ...
def read_positions(path: str, crs: str = "") -> dict[str, tuple[float, float, float]]: ...

class DetectOptions:
    """Options of detect (defaults from the C++ struct aos::DetectOptions): the anomaly scores, the
    threshold, the blobs."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        detector: Literal['rx', 'rx-local', 'anomaly-imaging', 'temperature'] = ...,
        channels: Literal['auto', 'grey', 'rgb', 'hsv', 'rgb+thermal'] = ...,
        trim_fraction: float = ...,
        robust_iterations: int = ...,
        regularization: float = ...,
        inner_window_px: int = ...,
        outer_window_px: int = ...,
        one_sided: bool = ...,
        quantile: float | None = ...,
        false_alarm_rate: float | None = ...,
        min_score: float | None = ...,
        robust_sigmas: float | None = ...,
        min_temperature_c: float | None = ...,
        inner_window_m: float = ...,
        outer_window_m: float = ...,
        min_area_px: int = ...,
        max_detections: int = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    detector: Literal['rx', 'rx-local', 'anomaly-imaging', 'temperature']
    """Scores: 'rx' (global Reed-Xiaoli), 'rx-local' (dual window, the default), 'anomaly-imaging'
    (RX per frame, integrated) or 'temperature' (degrees C, radiometric light fields). [one of
    rx, rx-local, anomaly-imaging or temperature]"""
    channels: Literal['auto', 'grey', 'rgb', 'hsv', 'rgb+thermal']
    """Features: 'auto' (all channels), 'grey', 'rgb', 'hsv' (S cos H, S sin H, V) or 'rgb+thermal'
    (4 channels). [one of auto, grey, rgb, hsv or rgb+thermal]"""
    trim_fraction: float
    """Share of the highest-scoring pixels left out of the robust background; 0 = classical RX. [in
    [0, 0.5)]"""
    robust_iterations: int
    """Concentration steps of the robust background estimate. [in [0, 20]]"""
    regularization: float
    """Ridge added to the covariance, relative to trace / d (keeps flat or rank-deficient images
    invertible). [>= 0 and finite]"""
    inner_window_px: int
    """rx-local: side of the inner guard window, pixels, odd. [px, >= 1]"""
    outer_window_px: int
    """rx-local: side of the background window, pixels, odd, > inner_window_px. [px, >= 3]"""
    one_sided: bool
    """rx and anomaly-imaging of one feature (grey or thermal): only values above the background
    mean score (warm spots); lower ones score 0."""
    quantile: float | None
    """Threshold at this quantile of the scores, (0, 1): 0.999 = the top 0.1 % of the pixels; unset
    = not used (no rule given: false_alarm_rate 1e-8; anomaly-imaging quantile 0.998, one-sided
    robust_sigmas 13.5)."""
    false_alarm_rate: float | None
    """Threshold: per-pixel false-alarm rate of a Gaussian background, (0, 1) (the chi-square
    quantile); unset = not used."""
    min_score: float | None
    """Threshold: an absolute score (squared Mahalanobis distance), >= 0; unset = not used."""
    robust_sigmas: float | None
    """Threshold: the covered scores' median plus this many robust standard deviations (1.4826 x
    median absolute deviation), > 0; unset = not used."""
    min_temperature_c: float | None
    """Detector 'temperature': the temperature a pixel must exceed, degrees C. [C]"""
    inner_window_m: float
    """rx-local on a render: guard window on the ground, metres (replaces inner_window_px there).
    [m, > 0 and finite]"""
    outer_window_m: float
    """rx-local on a render: background window on the ground, metres, > inner_window_m. [m, > 0 and
    finite]"""
    min_area_px: int
    """Blobs smaller than this many pixels are dropped. [px, >= 1]"""
    max_detections: int
    """At most this many detections (the highest peaks) are kept. [>= 1]"""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> DetectOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self) -> None: ...

class Detection:
    """One detection: a blob of pixels above the threshold."""

    @property
    def pixel(self) -> tuple[float, float]: ...
    @property
    def area_px(self) -> int: ...
    @property
    def peak_score(self) -> float: ...
    @property
    def mean_score(self) -> float: ...
    @property
    def box(self) -> tuple[int, int, int, int]: ...
    @property
    def local(self) -> tuple[float, float, float]: ...
    @property
    def world(self) -> tuple[float, float, float]: ...
    @property
    def lon_lat(self) -> Optional[tuple[float, float]]: ...
    @property
    def views(self) -> list[int]: ...
    @property
    def peak_celsius(self) -> float: ...
    @property
    def mean_celsius(self) -> float: ...
    @property
    def sightings(self) -> int: ...
    @property
    def first_seen(self) -> str: ...
    @property
    def last_seen(self) -> str: ...

class DetectResult:
    """What detect found, and what it was found in."""

    @property
    def render(self) -> IntegralResult: ...
    @property
    def camera(self) -> PinholeCamera: ...
    @property
    def ground_sampling_m(self) -> float: ...
    @property
    def windows_px(self) -> tuple[int, int]: ...
    @property
    def scores(self) -> numpy.typing.NDArray[numpy.float32]: ...
    @property
    def dimensions(self) -> int: ...
    @property
    def threshold(self) -> float: ...
    @property
    def threshold_rule(self) -> str: ...
    @property
    def flagged_pixels(self) -> int: ...
    @property
    def detections(self) -> list[Detection]: ...
    @property
    def dropped(self) -> int: ...
    @property
    def crs(self) -> str: ...
    @property
    def geotransform(self) -> Optional[tuple[float, float, float, float, float, float]]: ...
    @property
    def pixels(self) -> _Float64Array: ...
    @property
    def world(self) -> _Float64Array: ...
    @property
    def lon_lat(self) -> Optional[_Float64Array]: ...
    @property
    def peak_scores(self) -> _Float64Array: ...
    def write(self, path: str, overwrite: bool = False) -> None: ...
    def overlay(self) -> numpy.typing.NDArray[numpy.uint8]: ...
    def __len__(self) -> int: ...

class LiveOptions:
    """Options of live integration (defaults from the C++ struct aos::LiveOptions): the window, the
    virtual camera, the tracks."""

    _fields: ClassVar[tuple[str, ...]]
    def __init__(
        self,
        *,
        window_frames: int = ...,
        window_m: float = ...,
        window_s: float = ...,
        follow: Literal['latest', 'fixed', 'map'] = ...,
        detect: bool = ...,
        merge_radius_m: float = ...,
        max_tracks: int = ...,
    ) -> None:
        """Defaults from C++; unknown names raise TypeError."""
    window_frames: int
    """Live: the newest frames integrated (the sliding window). [>= 1]"""
    window_m: float
    """Live: views farther than this from the newest view (horizontally, metres) leave the window
    too; inf = no distance window. [m, > 0]"""
    window_s: float
    """Live: views taken more than this many seconds before the newest leave the window too; inf =
    no time window. [s, > 0]"""
    follow: Literal['latest', 'fixed', 'map']
    """Live: the virtual camera follows the 'latest' view, stays 'fixed' (--cam-from-world / the
    options' pose), or is the orthographic 'map' of a fixed area (--extent). [one of latest,
    fixed or map]"""
    detect: bool
    """Live: run the detector on every update (true by default; --detect=false integrates only)."""
    merge_radius_m: float
    """Live: detections closer than this, metres, are one track. [m, > 0 and finite]"""
    max_tracks: int
    """Live: at most this many tracks are kept (the most sighted). [>= 1]"""
    def to_json(self) -> str:
        """The options as one JSON object (lightfield/options_json.h)."""
    @staticmethod
    def from_json(text: str) -> LiveOptions:
        """Default options with the JSON object's members read in (ValueError naming the key)."""
    def check(self) -> None: ...

class LiveTrack:
    """One place found during a live run: its strongest sighting."""

    @property
    def detection(self) -> Detection: ...
    @property
    def sightings(self) -> int: ...
    @property
    def first_update(self) -> int: ...
    @property
    def last_update(self) -> int: ...
    @property
    def first_frame(self) -> str: ...
    @property
    def last_frame(self) -> str: ...

class LiveIntegrator:
    """Live, in-flight integration (docs/live.md): a sliding window of the newest views,
    re-rendered and searched after each add; equal to the batch render of the window."""

    def __init__(
        self,
        base: LightField = ...,
        options: IntegralOptions = ...,
        detect_options: DetectOptions = ...,
        live_options: LiveOptions = ...,
        map_options: Optional[MapOptions] = None,
    ) -> None: ...
    def add(
        self,
        image: numpy.typing.ArrayLike,
        camera: Union[PinholeCamera, LensCamera],
        cam_from_world: Rigid3d,
        name: str,
        update: bool = True,
        time_s: float = ...,
    ) -> list[str]: ...
    def add_view(self, view: View, update: bool = True, time_s: float = ...) -> list[str]: ...
    def remove(self, name: str, update: bool = True) -> bool: ...
    def update(self) -> None: ...
    @property
    def image(self) -> Optional[numpy.typing.NDArray[numpy.float32]]: ...
    @property
    def count(self) -> Optional[numpy.typing.NDArray[numpy.uint32]]: ...
    @property
    def detections(self) -> list[Detection]: ...
    @property
    def result(self) -> DetectResult: ...
    @property
    def tracks(self) -> list[LiveTrack]: ...
    @property
    def window(self) -> LightField: ...
    @property
    def updates(self) -> int: ...
    @property
    def path(self) -> list[tuple[float, float, float]]: ...
    def state_json(self) -> str: ...
    def render_options(self) -> IntegralOptions: ...
    def tracks_result(self) -> DetectResult: ...

def _detect(
    light_field: LightField,
    options: IntegralOptions,
    detect: DetectOptions,
    progress: Optional[Callable[[str, int, int], object]] = None,
) -> DetectResult: ...
def _detect_map(
    light_field: LightField,
    options: MapOptions,
    detect: DetectOptions,
    progress: Optional[Callable[[str, int, int], object]] = None,
) -> DetectResult: ...
def _detect_on_rendered_map(
    light_field: LightField,
    options: MapOptions,
    detect: DetectOptions,
    image: numpy.typing.ArrayLike,
    count: numpy.typing.ArrayLike,
    views_used: int = 0,
    views_selected: int = 0,
    anomaly_scores: Optional[numpy.typing.ArrayLike] = None,
) -> DetectResult: ...
def _quantised_frame_scores(
    frame: numpy.typing.ArrayLike, detect: DetectOptions
) -> numpy.typing.NDArray[numpy.uint16]: ...

_frame_score_step: float

def anomaly_scores(
    image: numpy.typing.ArrayLike,
    count: Optional[numpy.typing.ArrayLike] = None,
    options: DetectOptions = ...,
    radiometry: Optional[Radiometry] = None,
) -> numpy.typing.NDArray[numpy.float32]: ...
