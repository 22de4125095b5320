"""The keyword arguments of the aos wrappers, typed for type checkers.

Each wrapper (``aos.render_integral(light_field, **kwargs)``, ...) routes its keywords by name to
the fields of its C++ Options structs (see ``aos._Router``); these TypedDicts give those keywords
their types, so that ``**kwargs: Unpack[IntegralKeywords]`` lets mypy reject
``aos.render_integral(lf, pose_view="191")``. One key per routed field name: the test
tests/python/test_python_api.py checks them against the Options structs, so they cannot drift.
Types follow the bindings: a plane may be given as a number (its height, ``Plane.at_height``) and
an enum by its name.
"""

from __future__ import annotations

from typing import Literal, Optional, Sequence, TypedDict, Union

from ._core import (
    FocalSurface,
    Heightfield,
    Mesh,
    FocalStackOptions,
    IntegralOptions,
    LensModel,
    MergeMethod,
    MergeOptions,
    Plane,
    Rigid3d,
    SurfaceIntegralOptions,
)

# A plane, or a number: the horizontal plane at that height.
PlaneLike = Union[Plane, float]
MergeMethodLike = Union[MergeMethod, Literal["sobel", "improved", "robust"]]
LensModelLike = Union[LensModel, Literal["pinhole", "radtan", "fisheye", "omnidir"]]


class VirtualCameraKeywords(TypedDict, total=False):
    """Fields of IntegralOptions except the focal plane: the virtual camera and the views."""

    cam_from_world: Rigid3d
    pose_view: int
    fov_deg: float
    width: int
    height: int
    aperture_radius: float
    view_indices: Sequence[int]
    min_view_angle_deg: float
    num_threads: int
    variance: bool
    lens_tolerance_px: float


class IntegralKeywords(VirtualCameraKeywords, total=False):
    """Fields of IntegralOptions (render_integral). ``focal_plane`` also takes a Mesh,
    Heightfield or FocalSurface (then it is the focal_surface)."""

    focal_plane: Union[PlaneLike, Mesh, Heightfield, FocalSurface]
    focal_surface: Union[FocalSurface, Mesh, Heightfield, PlaneLike, None]
    surface_offset: float


class SurfaceIntegralKeywords(VirtualCameraKeywords, total=False):
    """Fields of IntegralOptions (but the focal surface: the depth map is the surface) and
    SurfaceIntegralOptions (render_integral_on_depth)."""

    focal_plane: PlaneLike

    robust: bool
    agreement: float
    min_inlier_fraction: float


class MapKeywords(TypedDict, total=False):
    """Fields of MapOptions (render_map)."""

    pixel_size: float
    width: int
    extent: Sequence[float]
    focal_height: float
    focal_surface: Union[FocalSurface, Mesh, Heightfield, PlaneLike, None]
    surface_offset: float
    aperture_radius: float
    view_indices: Sequence[int]
    min_view_angle_deg: float
    lens_tolerance_px: float
    tile_size: int
    num_threads: int


class FocalStackKeywords(VirtualCameraKeywords, total=False):
    """Fields of FocalStackOptions and of its render options (render_focal_stack); the slices'
    planes come from first_plane and last_plane, so focal_plane is not one. With
    ``focal_surface`` the stack follows that surface from first_offset to last_offset."""

    render: IntegralOptions
    first_plane: PlaneLike
    last_plane: PlaneLike
    focal_surface: Union[FocalSurface, Mesh, Heightfield, PlaneLike, None]
    ground_plane: Optional[PlaneLike]
    first_offset: float
    last_offset: float
    slices: int


class MergeKeywords(TypedDict, total=False):
    """Fields of MergeOptions and of its robust mean (merge_focal_stack). ``robust`` is the
    SurfaceIntegralOptions, or its flag."""

    method: MergeMethodLike
    window_radius: int
    smoothing_sigma: float
    edge_sigma: float
    smoothing_iterations: int
    robust: Union[SurfaceIntegralOptions, bool]
    agreement: float
    min_inlier_fraction: float
    num_threads: int


class AllInFocusKeywords(FocalStackKeywords, MergeKeywords, total=False):
    """Fields of AllInFocusOptions, nested ones included (all_in_focus). ``num_threads`` sets
    the rendering and the merge."""

    stack: FocalStackOptions
    merge: MergeOptions
    coarse_to_fine: int


class DemoKeywords(TypedDict, total=False):
    """Fields of DemoOptions (run_demo)."""

    num_threads: int
    all_in_focus_slices: int
    target_margin_m: float


class SimulateKeywords(TypedDict, total=False):
    """Fields of SimulateOptions (simulate)."""

    num_threads: int


class QualityKeywords(TypedDict, total=False):
    """Fields of QualityOptions (compare_images)."""

    data_range: float
    gaussian_sigma: float
    window_radius: int
    k1: float
    k2: float
    grey: bool


class ResolutionKeywords(TypedDict, total=False):
    """Fields of ResolutionOptions (sampling_resolution)."""

    distance_m: float
    pose_error_px: float
    pose_error_m: float
    max_off_axis_deg: float


class FlightPlanKeywords(TypedDict, total=False):
    """Fields of FlightPlanOptions (plan_flight)."""

    shape: Literal["circle", "sector", "rectangle", "polygon", "line"]
    coordinates: Literal["world", "latlon"]
    crs: str
    center: Sequence[float]
    radius_m: float
    sector_start_deg: float
    sector_angle_deg: float
    width_m: float
    length_m: float
    vertices: Sequence[Sequence[float]]
    pattern: Literal["scan", "grid", "circles"]
    spacing_m: float
    along_spacing_m: float
    outer_scale: float
    heading_deg: float
    min_shots_per_line: int
    altitude_m: float
    altitude_mode: Literal["terrain", "constant"]
    dem: str
    ground_height_m: float
    terrain_up: Literal["+z", "-z"]
    min_clearance_m: float
    ground_speed_mps: float
    hover_s: float
    battery_min: float
    max_waypoints: int
    image_width: int
    image_height: int
    fov_deg: float


class RectifyKeywords(TypedDict, total=False):
    """Fields of RectifyOptions (rectify_light_field)."""

    fov_deg: float
    width: int
    height: int
    yaw_deg: float
    pitch_deg: float
    roll_deg: float
    fill: bool


class CalibrateKeywords(TypedDict, total=False):
    """Fields of CalibrateOptions (calibrate)."""

    model: LensModelLike
    pattern_columns: int
    pattern_rows: int
    square_size_m: float


class TelemetryKeywords(TypedDict, total=False):
    """Fields of TelemetryOptions (import_telemetry)."""

    telemetry_file: str
    camera_file: str
    fov_deg: float
    altitude: str
    altitude_window: int
    max_altitude_deviation_m: float
    max_distance_from_centre_m: float
    frame_interval_s: float
    time_offset_s: float


class PosesKeywords(TypedDict, total=False):
    """Fields of PosesOptions (estimate_poses, import_colmap)."""

    colmap: str
    workspace: str
    matcher: str
    sequential_overlap: int
    spatial_neighbors: int
    camera_file: str
    camera_model: str
    fov_deg: float
    positions_file: str
    positions_crs: str
    exif_positions: bool
    max_image_size: int
    max_num_features: int
    sift_first_octave: int
    min_registered_fraction: float
    num_threads: int
    max_focal_deviation: float
    flight_height_m: float
    max_scale_deviation: float
    allow_implausible: bool
    preset: str


class GroundKeywords(TypedDict, total=False):
    """Fields of GroundOptions (estimate_ground)."""

    cell_size_m: float
    quantile: float
    min_points_per_cell: int
    outlier_sigmas: float
    max_step_m: float
