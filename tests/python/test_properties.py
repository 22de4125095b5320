"""Property-based tests (hypothesis) of the geometric core through the Python API: lens
project/unproject round trips for the four models, Rigid3d identities, plane depth and focal-plane
interpolation against their formulas, and the renderer's plane-induced reprojection (the
homography pinhole views take, and the direct lens path) against an analytic reprojection.

Every example is drawn deterministically (derandomize=True), so a failure reproduces on every run.
Tolerances are derived next to each assertion from the arithmetic the code does: double
precision is eps = 2.2e-16, float32 is 2^-24 = 6e-8 relative.
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import aos

EPS = np.finfo(np.float64).eps  # 2.2e-16
FLOAT32_REL = 2.0**-24  # half an ulp of float32, relative

# Deterministic and fast: the same examples on every run, no per-example deadline (the first
# call of a module function may be slow on a cold cache).
PROPERTY = settings(derandomize=True, max_examples=150, deadline=None, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])

# Geo-referenced coordinates: a UTM-sized offset (zone 33N near Linz is ~ 5.35e6 m northing).
UTM_OFFSET = np.array([448_251.123, 5_353_712.456, 312.5])


def finite(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False)


def angle_between(a: np.ndarray, b: np.ndarray) -> float:
    """Angle between two vectors, radians (atan2 form: accurate at 0 and at pi)."""
    return math.atan2(np.linalg.norm(np.cross(a, b)), float(np.dot(a, b)))


def direction(theta: float, phi: float) -> np.ndarray:
    """Unit vector at angle theta from the optical axis (+z), azimuth phi."""
    return np.array([math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi),
                     math.cos(theta)])


# --- Lens models -----------------------------------------------------------------------------

# Largest normalised (distorted) radius of the frame's half-diagonal drawn per model: up to a
# 157-degree diagonal for pinholes, 127 degrees for radtan (a perspective lens), and distorted
# radii of 3 (about 172 degrees for an equidistant fisheye) for fisheye and omnidir frames.
FRAME_RADIUS = {aos.LensModel.pinhole: 5.0, aos.LensModel.radtan: 2.0,
                aos.LensModel.fisheye: 3.0, aos.LensModel.omnidir: 3.0}


@st.composite
def intrinsics(draw: st.DrawFn, model: aos.LensModel) -> dict:
    width = draw(st.integers(16, 4000))
    height = draw(st.integers(16, 4000))
    half_diagonal = 0.5 * math.hypot(width, height)
    fx = half_diagonal / draw(finite(0.2, FRAME_RADIUS[model]))  # diagonals from ~23 degrees
    return dict(width=width, height=height, fx=fx, fy=fx * draw(finite(0.8, 1.25)),
                cx=width * draw(finite(0.3, 0.7)), cy=height * draw(finite(0.3, 0.7)))


@st.composite
def lenses(draw: st.DrawFn, model: aos.LensModel) -> aos.LensCamera:
    """A valid lens of `model` (invalid draws, e.g. a radtan fold inside the frame, are
    rejected by the constructor and skipped)."""
    k = draw(intrinsics(model))
    distortion: list[float] = []  # the model's natural length: pinhole none
    xi = skew = 0.0
    if model == aos.LensModel.radtan:
        distortion = [draw(finite(-0.3, 0.3)), draw(finite(-0.1, 0.1)),
                      draw(finite(-0.01, 0.01)), draw(finite(-0.01, 0.01)),
                      draw(finite(-0.05, 0.05))]
    elif model == aos.LensModel.fisheye:
        distortion = [draw(finite(-0.1, 0.1)), draw(finite(-0.02, 0.02)),
                      draw(finite(-0.005, 0.005)), draw(finite(-0.001, 0.001))]
    elif model == aos.LensModel.omnidir:
        distortion = [draw(finite(-0.3, 0.3)), draw(finite(-0.05, 0.05)),
                      draw(finite(-0.005, 0.005)), draw(finite(-0.005, 0.005))]
        xi = draw(finite(0.0, 3.0))
        skew = draw(finite(-1.0, 1.0))
    try:
        return aos.LensCamera(model, k["width"], k["height"], k["fx"], k["fy"], k["cx"], k["cy"],
                              distortion=distortion, xi=xi, skew=skew)
    except ValueError:
        assume(False)
        raise  # unreachable


def describe(lens: aos.LensCamera) -> str:
    return (f"{lens.model.name} {lens.width}x{lens.height} fx={lens.fx!r} fy={lens.fy!r} "
            f"cx={lens.cx!r} cy={lens.cy!r} distortion={lens.distortion!r} xi={lens.xi!r} "
            f"skew={lens.skew!r} max_radius={lens.max_radius!r} theta_max={lens.theta_max!r}")


def normalised(lens: aos.LensCamera, pixel: np.ndarray) -> tuple[float, float]:
    """Normalised distorted coordinates of a pixel (the inverse of the affine part)."""
    y = (pixel[1] - lens.cy) / lens.fy
    return (pixel[0] - lens.cx - lens.skew * y) / lens.fx, y


def newton_starts_well(lens: aos.LensCamera, pixel: np.ndarray) -> bool:
    """The round trips are asserted where the distorted point lies within 99 % of max_radius:
    right at the fold the map's slope vanishes, and the inverse's sensitivity with it (the fold
    itself is checked by test_frame_near_the_fold_unprojects)."""
    if lens.model not in (aos.LensModel.radtan, aos.LensModel.omnidir):
        return True
    return math.hypot(*normalised(lens, pixel)) <= 0.99 * lens.max_radius


def omnidir_radius(theta: float, xi: float) -> float:
    """Undistorted normalised radius of a ray at angle theta in Mei's unified model."""
    denominator = math.cos(theta) + xi
    return math.sin(theta) / denominator if denominator > 0.0 else math.inf


def valid_angle(lens: aos.LensCamera) -> float:
    """The largest ray angle (radians) inside the lens's valid field: theta_max, further limited
    by max_radius (radtan, omnidir) and, for radtan, by r <= 2 (63 degrees; far past any
    perspective frame drawn here, and it keeps the distorted radius below ~1e2)."""
    model = lens.model
    if model == aos.LensModel.pinhole:
        return math.atan(3.0)
    if model == aos.LensModel.fisheye:
        return lens.theta_max
    if model == aos.LensModel.radtan:
        return math.atan(min(lens.max_radius, 2.0))
    # omnidir: r(theta) increases on [0, theta_max); bisect for r = max_radius.
    limit = lens.theta_max
    if omnidir_radius(limit * (1 - 1e-12), lens.xi) <= lens.max_radius:
        return limit
    lo, hi = 0.0, limit
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if omnidir_radius(mid, lens.xi) <= lens.max_radius:
            lo = mid
        else:
            hi = mid
    return lo


MODELS = [aos.LensModel.pinhole, aos.LensModel.radtan, aos.LensModel.fisheye,
          aos.LensModel.omnidir]


@st.composite
def lens_and_point(draw: st.DrawFn) -> tuple[aos.LensCamera, np.ndarray, float]:
    """A lens and a camera-frame point at up to 95 % of its valid angle (so the distortion's
    slope is bounded away from the fold), at a distance from 1 mm to 10 km."""
    lens = draw(lenses(draw(st.sampled_from(MODELS))))
    theta = draw(finite(0.0, 0.95)) * valid_angle(lens)
    phi = draw(finite(0.0, 2 * math.pi))
    distance = draw(finite(1e-3, 1e4))
    return lens, distance * direction(theta, phi), theta


@given(lens_and_point())
@PROPERTY
def test_lens_point_round_trip(case) -> None:
    lens, point, theta = case
    pixel = lens.project(point)
    assert pixel is not None, \
        f"{describe(lens)}: a point {math.degrees(theta):.3f} deg off-axis (valid) did not project"
    assume(newton_starts_well(lens, pixel))
    ray = lens.unproject(pixel)
    assert ray is not None, f"{describe(lens)}: pixel {pixel!r} of a valid point did not unproject"
    # Unit ray.
    assert abs(np.linalg.norm(ray) - 1.0) <= 4 * EPS
    # Bound: Unproject's Newton iteration stops at a residual of at most 1e-15 (1 + |x_d| + |y_d|)
    # in normalised distorted coordinates, i.e. 1e-15 relative to the point's distorted
    # radius; that moves the ray by the residual over the distortion's slope there (bounded
    # away from 0 at 95 % of the valid field, but not by a constant proven for every draw),
    # a few 1e-15 rad for slopes above 0.1. Rounding of the pixel and of the trigonometry adds a
    # few eps. Stated: 1e-12 rad (measured over 5000 examples: 4.5e-15 rad).
    assert angle_between(ray, point) <= 1e-12
    again = lens.project(ray)
    assert again is not None
    # Reprojection: the same residual times fx, relative to the pixel's magnitude (points far
    # outside the frame give |u| up to ~5e4 px): 1e-9 px per 1000 px (measured: 1.1e-11).
    assert np.max(np.abs(again - pixel)) <= 1e-9 * max(1.0, np.max(np.abs(pixel)) / 1e3)


@st.composite
def lens_and_pixel(draw: st.DrawFn) -> tuple[aos.LensCamera, np.ndarray]:
    lens = draw(lenses(draw(st.sampled_from(MODELS))))
    u = draw(finite(0.0, 1.0)) * lens.width
    v = draw(finite(0.0, 1.0)) * lens.height
    return lens, np.array([u, v])


def circle_edge(lens: aos.LensCamera) -> float:
    """A lower bound of the distorted normalised radius of the image circle's edge."""
    if lens.model == aos.LensModel.fisheye:
        t = lens.theta_max
        k1, k2, k3, k4 = lens.distortion[:4]
        return t * (1 + k1 * t**2 + k2 * t**4 + k3 * t**6 + k4 * t**8)
    r = omnidir_radius(valid_angle(lens), lens.xi)
    k1, k2, p1, p2 = lens.distortion[:4]
    # The tangential terms move a point of radius r by at most 3 (|p1| + |p2|) r^2.
    return r * (1 + k1 * r**2 + k2 * r**4) - 3 * (abs(p1) + abs(p2)) * r**2


@given(lens_and_pixel())
@PROPERTY
def test_lens_pixel_round_trip(case) -> None:
    lens, pixel = case
    ray = lens.unproject(pixel)
    batch = lens.unproject_pixels(pixel[None, :])[0]
    if ray is None:
        assume(newton_starts_well(lens, pixel))
        # Pinhole and radtan lenses cover their whole frame (a radtan fold inside it is refused);
        # fisheye and omni frames end at the image circle.
        assert lens.model in (aos.LensModel.fisheye, aos.LensModel.omnidir), \
            f"{describe(lens)}: pixel {pixel!r} inside the frame has no ray"
        assert np.isnan(batch).all()
        x, y = normalised(lens, pixel)
        # Outside the circle (1e-9 relative: the edge's own rounding).
        assert math.hypot(x, y) >= (1 - 1e-9) * circle_edge(lens), \
            f"{describe(lens)}: pixel {pixel!r} inside the image circle has no ray"
        return
    np.testing.assert_array_equal(batch, ray)  # the vectorised call is the same function
    assert abs(np.linalg.norm(ray) - 1.0) <= 4 * EPS
    again = lens.project(ray)
    assert again is not None, f"{describe(lens)}: ray {ray} of pixel {pixel} did not project back"
    # Bound: the Newton residual 1e-15 (1 + |x_d| + |y_d|) (normalised; |x_d| + |y_d| < 18 inside
    # the frames drawn) is in pixels at most 1e-15 x 19 fx, with fx <= 1.4e4 px (a 4000 x 4000
    # frame with a 23-degree diagonal): < 2.7e-10 px; the rounding of u (|u| < 4e3 px) adds
    # ~1e-12. Stated: 1e-9 px (measured over 5000 examples: 1.0e-11 px).
    assert np.max(np.abs(again - pixel)) <= 1e-9


def corner_grid(lens: aos.LensCamera) -> np.ndarray:
    """Every integer pixel corner of the frame, (N, 2)."""
    u, v = np.meshgrid(np.arange(lens.width + 1.0), np.arange(lens.height + 1.0))
    return np.stack([u.ravel(), v.ravel()], axis=1)


# Two defects the properties above found in lens.cpp, now mended: Unproject's undamped Newton
# iteration overshot past the radial fold (pixels with a ray got none), and Finalize checked
# the radial fold only (tangential terms that fold inside the frame were accepted).

@pytest.mark.parametrize("model, distortion, size, centre", [
    # Radtan: fold at r = 1.83 (distorted 2.08), frame corners at distorted 1.98, so Finalize
    # rightly accepts it and every frame pixel has a ray; those at distorted radius > 1.82 get
    # none.
    (aos.LensModel.radtan, [0.25, -0.0625, 0.0, 0.0, 0.0], 140, 70.0),
    # Omnidir (xi = 0): image circle edge at distorted radius 3.37; pixels from 2.34 out to it
    # get no ray (a ring of the circle lost).
    (aos.LensModel.omnidir, [0.25, -0.03125, 0.0, 0.0], 400, 200.0),
])
def test_frame_near_the_fold_unprojects(model, distortion, size, centre) -> None:
    lens = aos.LensCamera(model, size, size, 50.0, 50.0, centre, centre, distortion=distortion)
    pixels = corner_grid(lens)
    rays = lens.unproject_pixels(pixels)
    radius = np.hypot(pixels[:, 0] - centre, pixels[:, 1] - centre) / 50.0
    r = lens.max_radius
    edge = r * (1 + distortion[0] * r**2 + distortion[1] * r**4)  # the fold's distorted radius
    has_ray = radius < edge * (1 - 1e-9)
    missing = int(np.isnan(rays[has_ray, 0]).sum())
    assert missing == 0, f"{missing} of {int(has_ray.sum())} pixel corners with a ray got none"


def test_radtan_whose_tangential_terms_fold_inside_the_frame_is_refused() -> None:
    # p1 = 0.05 with the frame's top edge at y = -1.70: y + p1 (x^2 + 3 y^2) = -1.70 has no real
    # solution on the column x = 0 (discriminant 1 - 12 p1 1.70 < 0), so pixels near (320, 0)
    # have no ray, against lens.h's "a radtan lens must cover its frame".
    lens_args = (aos.LensModel.radtan, 640, 480, 141.0, 141.0, 320.0, 240.0)
    with pytest.raises(ValueError, match="folds the image"):
        aos.LensCamera(*lens_args, distortion=[0.0, 0.0, 0.05, 0.0, 0.0])


@given(lenses(aos.LensModel.fisheye), finite(0.0, 1.0), finite(0.0, 2 * math.pi))
@PROPERTY
def test_fisheye_masks_rays_past_its_field(lens, fraction, phi) -> None:
    # Rays between theta_max and 180 degrees (behind the lens included) have no pixel.
    assume(lens.theta_max < math.pi * (1 - 1e-6))
    theta = lens.theta_max + (math.pi - lens.theta_max) * (0.001 + 0.999 * fraction)
    assert lens.project(direction(theta, phi)) is None


@given(st.sampled_from([aos.LensModel.pinhole, aos.LensModel.radtan]).flatmap(lenses),
       finite(0.0, 1.0), finite(0.0, 2 * math.pi), finite(1e-3, 1e4))
@PROPERTY
def test_perspective_lenses_mask_points_behind(lens, fraction, phi, distance) -> None:
    # Perspective models image only z > 0: every point at 90 to 180 degrees (z <= 0, the
    # camera's own plane z = 0 included) is masked.
    point = distance * direction(0.5 * math.pi * (1.0 + fraction), phi)
    point[2] = min(point[2], 0.0)  # cos(pi / 2) rounds to +6e-17
    assert lens.project(point) is None


@given(lenses(aos.LensModel.omnidir), finite(0.0, 1.0), finite(0.0, 2 * math.pi))
@PROPERTY
def test_omnidir_masks_rays_past_its_field(lens, fraction, phi) -> None:
    # Past theta_max (where 1 + xi cos(theta) or cos(theta) + xi reaches 0) the unified model
    # is not one-to-one; such rays must not project.
    assume(lens.theta_max < math.pi * (1 - 1e-6))
    theta = lens.theta_max + (math.pi - lens.theta_max) * (0.001 + 0.999 * fraction)
    assert lens.project(direction(theta, phi)) is None


# --- Rigid transforms ------------------------------------------------------------------------

@st.composite
def rotations(draw: st.DrawFn) -> np.ndarray:
    """A rotation matrix from a random unit quaternion (orthonormal to a few eps)."""
    q = np.array([draw(finite(-1.0, 1.0)) for _ in range(4)])
    assume(np.linalg.norm(q) > 0.1)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def vectors(scale: float) -> st.SearchStrategy[np.ndarray]:
    return st.tuples(finite(-scale, scale), finite(-scale, scale),
                     finite(-scale, scale)).map(np.array)


# Translations up to UTM size (1e7 m).
rigids = st.builds(aos.Rigid3d, rotations(), vectors(1e7))


def apply(transform: aos.Rigid3d, point: np.ndarray) -> np.ndarray:
    return transform.rotation @ point + transform.translation


def compose(b_from_a: aos.Rigid3d, a_from_o: aos.Rigid3d) -> aos.Rigid3d:
    """b_from_o (Rigid3d has no composition in the Python API; done here in float64)."""
    return aos.Rigid3d(b_from_a.rotation @ a_from_o.rotation,
                       b_from_a.rotation @ a_from_o.translation + b_from_a.translation)


@given(rigids, vectors(1e7))
@PROPERTY
def test_rigid_inverse_identities(b_from_a, point) -> None:
    a_from_b = b_from_a.inverse()
    scale = 1.0 + np.linalg.norm(b_from_a.translation) + np.linalg.norm(point)
    # Bound: R^T R = I to ~4 eps for the quaternion rotation; each product rounds to a few eps of
    # the largest term (|t|, |x| <= 1.7e7 m), so 16 eps * scale (~6e-8 m at 1.7e7 m).
    tol = 16 * EPS * scale
    np.testing.assert_allclose(a_from_b.rotation, b_from_a.rotation.T, rtol=0, atol=0)
    np.testing.assert_allclose(apply(a_from_b, apply(b_from_a, point)), point, rtol=0, atol=tol)
    np.testing.assert_allclose(a_from_b.inverse().matrix3x4, b_from_a.matrix3x4, rtol=0, atol=tol)
    # The centre -R^T t is where the inverse maps the origin (the camera centre for cam_from_world).
    np.testing.assert_allclose(b_from_a.center, a_from_b.translation, rtol=0, atol=tol)
    np.testing.assert_allclose(apply(b_from_a, b_from_a.center), 0.0, rtol=0, atol=tol)
    # [R | t] round trip is exact.
    np.testing.assert_array_equal(
        aos.Rigid3d.from_matrix3x4(b_from_a.matrix3x4).matrix3x4, b_from_a.matrix3x4)


@given(rigids, rigids, vectors(1e7))
@PROPERTY
def test_rigid_inverse_of_composition(c_from_b, b_from_a, point) -> None:
    # (C o B)^-1 = B^-1 o C^-1, and the composition maps a point like the two maps in turn.
    c_from_a = compose(c_from_b, b_from_a)
    scale = (1.0 + np.linalg.norm(c_from_b.translation) + np.linalg.norm(b_from_a.translation)
             + np.linalg.norm(point))
    tol = 32 * EPS * scale  # two products of the bound above
    np.testing.assert_allclose(apply(c_from_a, point), apply(c_from_b, apply(b_from_a, point)),
                               rtol=0, atol=tol)
    np.testing.assert_allclose(c_from_a.inverse().matrix3x4,
                               compose(b_from_a.inverse(), c_from_b.inverse()).matrix3x4,
                               rtol=0, atol=tol)
    # The composition's centre is b_from_a's inverse applied to c_from_b's centre.
    np.testing.assert_allclose(c_from_a.center, apply(b_from_a.inverse(), c_from_b.center),
                               rtol=0, atol=tol)


@given(vectors(1e6), vectors(1e3), vectors(1.0))
@PROPERTY
def test_look_at_geometry(offset, eye_local, up) -> None:
    # Camera centre, optical axis and up direction of look_at, at UTM-sized coordinates.
    target_local = np.zeros(3)
    view = target_local - eye_local
    assume(np.linalg.norm(view) > 1e-2 and np.linalg.norm(up) > 1e-2)
    sine = np.linalg.norm(np.cross(view, up)) / (np.linalg.norm(view) * np.linalg.norm(up))
    assume(sine > 1e-3)  # look_at refuses up parallel to the viewing direction
    eye = offset + eye_local
    target = offset + target_local
    cam_from_world = aos.look_at(eye, target, up)
    rotation = cam_from_world.rotation
    np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), rtol=0, atol=8 * EPS)
    assert np.linalg.det(rotation) > 0.0
    # Bound: the centre -R^T t with |t| <= |R eye| ~ 1e6 m: a few eps of 1.7e6 m (< 4e-9 m).
    np.testing.assert_allclose(cam_from_world.center, eye, rtol=0,
                               atol=16 * EPS * (1 + np.linalg.norm(eye)))
    # The target lies on the optical axis (+z), at its distance; bound as above.
    in_cam = apply(cam_from_world, target)
    tol = 32 * EPS * (1 + np.linalg.norm(eye))
    np.testing.assert_allclose(in_cam, [0.0, 0.0, np.linalg.norm(eye - target)], rtol=0, atol=tol)
    # `up` appears up in the image: camera y (down) has a negative component along up.
    assert (rotation @ up)[1] < 0.0


# --- Planes ----------------------------------------------------------------------------------

@st.composite
def unit_vectors(draw: st.DrawFn) -> np.ndarray:
    """Uniform on the sphere (z uniform in [-1, 1], azimuth uniform)."""
    z = draw(finite(-1.0, 1.0))
    phi = draw(finite(0.0, 2 * math.pi))
    s = math.sqrt(max(0.0, 1.0 - z * z))
    return np.array([s * math.cos(phi), s * math.sin(phi), z])


@st.composite
def camera_and_plane(draw: st.DrawFn):
    """A small pinhole camera, its pose (looking at a target ~ 1 to 500 m away) and a plane,
    optionally all moved to UTM-sized coordinates."""
    width, height = draw(st.integers(1, 24)), draw(st.integers(1, 24))
    camera = aos.PinholeCamera.from_fov(width, height, draw(finite(5.0, 150.0)))
    offset = draw(st.sampled_from([np.zeros(3), UTM_OFFSET]))
    target = draw(vectors(50.0))
    eye = target + draw(unit_vectors()) * draw(finite(1.0, 500.0))
    up = draw(unit_vectors())
    assume(np.linalg.norm(np.cross(target - eye, up)) > 1e-2 * np.linalg.norm(target - eye))
    cam_from_world = aos.look_at(eye + offset, target + offset, up)
    plane_point = target + draw(vectors(20.0))
    plane = aos.Plane(plane_point + offset, draw(unit_vectors()) * draw(finite(0.01, 100.0)))
    return camera, cam_from_world, plane, eye + offset


@given(camera_and_plane())
@PROPERTY
def test_plane_depth_matches_ray_plane_formula(case) -> None:
    camera, cam_from_world, plane, eye = case
    depth = aos.plane_depth(camera, cam_from_world, plane)
    assert depth.dtype == np.float32 and depth.shape == (camera.height, camera.width)
    # Analytic: the ray C + t D, D = R^T K^-1 (u, v, 1) with pixel centres at +0.5, meets the
    # plane n . (X - p) = 0 at t = n . (p - C) / n . D; D's camera z is 1, so t is the depth.
    u, v = np.meshgrid(np.arange(camera.width) + 0.5, np.arange(camera.height) + 0.5)
    rays_cam = np.stack([(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy,
                         np.ones_like(u)], axis=-1)
    rays_world = rays_cam @ cam_from_world.rotation  # rows: R^T d
    normal = plane.normal / np.linalg.norm(plane.normal)
    centre = cam_from_world.center
    h = float(normal @ (plane.point - centre))
    f = rays_world @ normal
    with np.errstate(divide="ignore", invalid="ignore"):
        t = h / f
    expected = np.where((t > 0) & np.isfinite(t), t, 0.0)
    # Bound: float32 output (2^-24 relative), plus the double-precision conditioning of h (its
    # cancellation: eps (|p| + |C|) / |h|, large at UTM scale) and of f (eps |D| / |f|, large for
    # grazing rays), 8 eps each.
    norm_d = np.linalg.norm(rays_world, axis=-1)
    positive = expected > 0  # then h != 0 and f != 0
    cond = np.zeros_like(expected)
    cond[positive] = 8 * EPS * ((np.linalg.norm(plane.point) + np.linalg.norm(centre)) / abs(h)
                                + norm_d[positive] / np.abs(f[positive]))
    with np.errstate(over="ignore"):  # depths of near-parallel rays may reach 1e300
        tol = expected * (FLOAT32_REL + cond)
    # Pixels whose ray is within 1e-9 of parallel to the plane may round either way: skipped.
    decided = np.abs(f) > 1e-9 * norm_d
    assume(decided.any())
    np.testing.assert_array_less(np.abs(depth - expected)[decided], tol[decided] + 1e-30)
    # Zero exactly where the plane is behind the camera or parallel to the ray.
    # In float32: a depth below its smallest subnormal (a camera within ~1e-45 of the plane) is 0.
    assert ((depth > 0) == (expected.astype(np.float32) > 0))[decided].all()


def plane_distance(plane: aos.Plane, centre: np.ndarray) -> tuple[np.ndarray, float]:
    n = plane.normal / np.linalg.norm(plane.normal)
    return n, float(n @ (plane.point - centre))


@given(vectors(100.0), unit_vectors(), finite(-50.0, 50.0), unit_vectors(), finite(-50.0, 50.0),
       finite(0.0, 1.0), st.sampled_from([np.zeros(3), UTM_OFFSET]))
@PROPERTY
def test_interpolate_plane_follows_its_formula(centre, n0, h0, n1, h1, s, offset) -> None:
    # focal_stack.h: n = normalize((1 - s) n0 + s n1') and h = (1 - s) h0 + s h1', where
    # (n1', h1') = (n1, h1) negated if n1 . n0 < 0; planes stored through C + h n.
    centre = centre + offset
    first = aos.Plane(centre + h0 * n0, n0 * 3.0)  # any normal length
    last = aos.Plane(centre + h1 * n1, n1 * 0.5)
    if n1 @ n0 < 0:
        n1, h1 = -n1, -h1
    m = (1 - s) * n0 + s * n1
    assume(np.linalg.norm(m) > 1e-3)
    plane = aos.interpolate_plane(first, last, s, centre)
    n, h = plane_distance(plane, centre)
    sign = 1.0 if n @ m > 0 else -1.0  # a plane's normal has no side
    # Bound: normalising m (|m| > 1e-3) costs a few eps / |m|; the plane point C + h n at UTM
    # scale (|C| ~ 5e6 m) is rounded to eps |C| ~ 1e-9 m, which moves h by that much.
    np.testing.assert_allclose(sign * n, m / np.linalg.norm(m), rtol=0,
                               atol=64 * EPS / np.linalg.norm(m))
    assert abs(sign * h - ((1 - s) * h0 + s * h1)) <= 16 * EPS * (np.linalg.norm(centre) + 100.0)


@given(vectors(100.0), unit_vectors(), finite(-50.0, 50.0), finite(-50.0, 50.0),
       st.integers(1, 60))
@PROPERTY
def test_stack_planes_of_parallel_planes_are_equally_spaced(centre, n0, h0, h1, slices) -> None:
    first = aos.Plane(centre + h0 * n0, n0)
    last = aos.Plane(centre + h1 * n0, -2.0 * n0)  # same plane family, normal flipped
    planes = aos.stack_planes(first, last, slices, centre)
    assert len(planes) == slices
    for i, plane in enumerate(planes):
        n, h = plane_distance(plane, centre)
        sign = 1.0 if n @ n0 > 0 else -1.0
        s = 0.5 if slices == 1 else i / (slices - 1)
        np.testing.assert_allclose(sign * n, n0, rtol=0, atol=8 * EPS)
        # Bound: h and C + h n rounded at |C| + |h| <= 260 m: 16 eps of that (< 1e-12 m).
        tol = 16 * EPS * (np.linalg.norm(centre) + 100.0)
        assert abs(sign * h - ((1 - s) * h0 + s * h1)) <= tol


# --- The renderer's reprojection (homography and lens path) -----------------------------------

@st.composite
def single_view_scenes(draw: st.DrawFn, lens_model: Optional[aos.LensModel] = None):
    """One view looking at a random plane, and a virtual camera looking at the same plane from
    elsewhere; optionally at UTM-sized coordinates and with a lens model on the view."""
    offset = draw(st.sampled_from([np.zeros(3), UTM_OFFSET]))
    target = draw(vectors(20.0))
    normal = draw(unit_vectors())
    plane = aos.Plane(target + offset, normal)

    def eye_above() -> np.ndarray:
        # Within ~70 degrees of the normal, 5 to 200 m from the target.
        side = draw(unit_vectors())
        tilt = draw(finite(0.0, 2.5))
        d = normal + tilt * (side - (side @ normal) * normal)
        return target + d / np.linalg.norm(d) * draw(finite(5.0, 200.0))

    up = draw(unit_vectors())
    view_eye, virtual_eye = eye_above(), eye_above()
    for eye in (view_eye, virtual_eye):
        view = target - eye
        assume(np.linalg.norm(np.cross(view, up)) > 0.05 * np.linalg.norm(view))
    view_width, view_height = draw(st.integers(32, 160)), draw(st.integers(32, 160))
    view_fov = draw(finite(20.0, 100.0))
    pinhole = aos.PinholeCamera.from_fov(view_width, view_height, view_fov)
    camera: object = pinhole
    if lens_model is not None:
        if lens_model == aos.LensModel.radtan:
            distortion = [draw(finite(-0.2, 0.2)), draw(finite(-0.05, 0.05)),
                          draw(finite(-0.005, 0.005)), draw(finite(-0.005, 0.005)), 0.0]
        else:
            distortion = [draw(finite(-0.05, 0.05)), draw(finite(-0.01, 0.01)), 0.0, 0.0]
        try:
            camera = aos.LensCamera(lens_model, view_width, view_height, pinhole.fx, pinhole.fy,
                                    pinhole.cx, pinhole.cy, distortion=distortion)
        except ValueError:
            assume(False)
    view_pose = aos.look_at(view_eye + offset, target + offset, up)
    virtual = dict(
        cam_from_world=aos.look_at(virtual_eye + offset, target + offset + draw(vectors(3.0)), up),
        width=draw(st.integers(8, 40)), height=draw(st.integers(8, 40)),
        fov_deg=draw(finite(10.0, 120.0)))
    return camera, view_pose, plane, virtual


def ramp_lightfield(camera, view_pose, axis: int) -> aos.LightField:
    """One float32 view whose pixel (i, j) holds its own centre coordinate i + 0.5 (axis 0) or
    j + 0.5 (axis 1): bilinear interpolation of this linear ramp returns the sampled position
    exactly wherever both taps are inside the frame ([0.5, w - 0.5])."""
    u, v = np.meshgrid(np.arange(camera.width, dtype=np.float32) + 0.5,
                       np.arange(camera.height, dtype=np.float32) + 0.5)
    light_field = aos.LightField()
    light_field.add_view(u if axis == 0 else v, camera, view_pose)
    return light_field


def analytic_reprojection(camera, view_pose, plane, virtual, depth_scale: float = 1.0):
    """Each virtual pixel's ray meets the focal plane at X; X's pixel in the view (NaN where the
    ray misses the plane, meets it behind the virtual camera or X is outside the view's field).
    depth_scale moves X along the ray (X = C + depth_scale t D), for error bounds."""
    virtual_camera = aos.PinholeCamera.from_fov(virtual["width"], virtual["height"],
                                                virtual["fov_deg"])
    cam_from_world = virtual["cam_from_world"]
    u, v = np.meshgrid(np.arange(virtual["width"]) + 0.5, np.arange(virtual["height"]) + 0.5)
    rays = np.stack([(u - virtual_camera.cx) / virtual_camera.fx,
                     (v - virtual_camera.cy) / virtual_camera.fy, np.ones_like(u)], axis=-1)
    rays = rays @ cam_from_world.rotation  # world directions R^T d
    # Local frame relative to the virtual camera centre (double precision, as the renderer).
    centre = cam_from_world.center
    normal = plane.normal / np.linalg.norm(plane.normal)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (normal @ (plane.point - centre)) / (rays @ normal)
    points = rays * (depth_scale * t)[..., None]  # X - C
    view_from_centre = view_pose.rotation @ centre + view_pose.translation
    in_view = points @ view_pose.rotation.T + view_from_centre
    pixels = np.full(u.shape + (2,), np.nan)
    ok = (t > 0) & np.isfinite(t)
    if isinstance(camera, aos.LensCamera):
        # The lens decides (a fisheye sees points behind its image plane, past 90 degrees).
        for index in zip(*np.nonzero(ok)):
            pixel = camera.project(in_view[index])
            if pixel is not None:
                pixels[index] = pixel
    else:
        ok &= in_view[..., 2] > 0
        pixels[ok, 0] = camera.fx * in_view[ok, 0] / in_view[ok, 2] + camera.cx
        pixels[ok, 1] = camera.fy * in_view[ok, 1] / in_view[ok, 2] + camera.cy
    return pixels


def check_reprojection(camera, view_pose, plane, virtual) -> None:
    expected = analytic_reprojection(camera, view_pose, plane, virtual)
    # Lens views: every sample projected exactly (lens_tolerance_px 0; the local homographies of
    # the default are tested against this exact path in test_lens.py and surface_integral_test).
    options = dict(virtual, focal_surface=plane, aperture_radius=math.inf, min_view_angle_deg=0.0,
                   num_threads=2, lens_tolerance_px=0.0)
    width, height = camera.width, camera.height
    margin = 1e-6
    u, v = expected[..., 0], expected[..., 1]
    inside = (u >= margin) & (u <= width - margin) & (v >= margin) & (v <= height - margin)
    outside = ~((u >= -margin) & (u <= width + margin) & (v >= -margin) & (v <= height + margin))
    assume(inside.any())  # the renderer refuses a plane no pixel sees in front
    interior = ((u > 0.5 + margin) & (u < width - 0.5 - margin) & (v > 0.5 + margin)
                & (v < height - 0.5 - margin))
    # Bound, pinhole views (the homography path; AVX2 kernel for 1-channel float): the kernel
    # carries the homogeneous coordinates U, V, W in float32 and takes U / W, V / W, the bilinear
    # weights and the sample in float32: each rounding is 2^-24 relative, i.e. <= 2^-24 max(w, h)
    # px; 32 of them (measured: < 7 at 160 px).
    tolerance = np.full(u.shape, 32 * FLOAT32_REL * max(width, height))
    if isinstance(camera, aos.LensCamera):
        # Lens views are sampled through the lens from the plane's float32 depth map: X is
        # rebuilt as C + depth D with depth rounded to 2^-24 relative; that moves X along the
        # ray, and its pixel by the difference below (computed with 2^-23, two roundings).
        moved = analytic_reprojection(camera, view_pose, plane, virtual, 1.0 + 2.0**-23)
        tolerance = tolerance + np.nan_to_num(np.max(np.abs(moved - expected), axis=-1), nan=0.0)
    for axis in (0, 1):
        result = aos.render_integral(ramp_lightfield(camera, view_pose, axis), **options)
        count = result.count
        # A view contributes exactly where the focal point is in front of it and inside
        # [0, w] x [0, h] (pixels within 1e-6 px of the frame's edge may go either way).
        assert (count[inside] == 1).all()
        assert (count[outside] == 0).all()
        error = np.abs(result.image - expected[..., axis])
        assert (error[interior] <= tolerance[interior]).all(), \
            f"axis {axis}: error {error[interior].max()} px > {tolerance[interior].min()} px"


@given(single_view_scenes())
@settings(PROPERTY, max_examples=60)
def test_render_single_view_matches_plane_reprojection(case) -> None:
    # The renderer's plane-induced homography, checked through its result: each pixel's value is
    # the view pixel it sampled. Tolerance: check_reprojection.
    check_reprojection(*case)


@given(st.sampled_from([aos.LensModel.radtan, aos.LensModel.fisheye]).flatmap(
    lambda model: single_view_scenes(model)))
@settings(PROPERTY, max_examples=30)
def test_render_single_lens_view_matches_lens_projection(case) -> None:
    # Direct lens sampling: the view pixel is the lens model's projection of the focal point.
    check_reprojection(*case)
