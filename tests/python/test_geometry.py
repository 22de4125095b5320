"""Bindings of geometry/rigid.h and geometry/pinhole.h."""

from __future__ import annotations

import math

import numpy as np
import pytest

import aos


def test_look_at_axes_and_center() -> None:
    # Camera at (0, 0, 10) looking at the origin, world +y up in the image: OpenCV axes give
    # z (forward) = -world z, y (image down) = -world y, x = y cross z = +world x.
    cam_from_world = aos.look_at((0, 0, 10), (0, 0, 0), up=(0, 1, 0))
    rotation = cam_from_world.rotation
    assert rotation.shape == (3, 3) and rotation.dtype == np.float64
    np.testing.assert_allclose(rotation[2], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(rotation[1], [0, -1, 0], atol=1e-12)
    np.testing.assert_allclose(rotation[0], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(cam_from_world.center, [0, 0, 10], atol=1e-12)
    # The target lies on the optical axis, 10 m ahead.
    point_in_cam = rotation @ np.zeros(3) + cam_from_world.translation
    np.testing.assert_allclose(point_in_cam, [0, 0, 10], atol=1e-12)


def test_look_at_default_up_and_errors() -> None:
    cam_from_world = aos.look_at(np.array([5.0, 0, 0]), [0, 0, 0])  # up defaults to +z
    np.testing.assert_allclose(cam_from_world.rotation[1], [0, 0, -1], atol=1e-12)
    with pytest.raises(ValueError, match="distinct"):
        aos.look_at((1, 2, 3), (1, 2, 3))
    # Without an up vector, looking straight down works: image y is world -y (north up in a
    # y-north frame); an explicit up along the viewing direction is refused.
    nadir = aos.look_at((0, 0, 10), (0, 0, 0))
    np.testing.assert_allclose(nadir.rotation[2], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(nadir.center, [0, 0, 10], atol=1e-12)
    with pytest.raises(ValueError, match="parallel"):
        aos.look_at((0, 0, 10), (0, 0, 0), up=(0, 0, 1))


def test_rigid_inverse_round_trip() -> None:
    cam_from_world = aos.look_at((3.0, -2.0, 40.0), (1.0, 4.0, 0.5), up=(0.2, 1.0, 0.1))
    world_from_cam = cam_from_world.inverse()
    point = np.array([0.3, -7.0, 12.0])
    in_cam = cam_from_world.rotation @ point + cam_from_world.translation
    back = world_from_cam.rotation @ in_cam + world_from_cam.translation
    np.testing.assert_allclose(back, point, atol=1e-12)
    np.testing.assert_allclose(world_from_cam.translation, cam_from_world.center, atol=1e-12)
    again = world_from_cam.inverse()
    np.testing.assert_allclose(again.matrix3x4, cam_from_world.matrix3x4, atol=1e-12)


def test_rigid_matrix3x4_and_constructor() -> None:
    rotation = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    transform = aos.Rigid3d(rotation, (1, 2, 3))
    m = transform.matrix3x4
    assert m.shape == (3, 4) and m.dtype == np.float64
    np.testing.assert_array_equal(m[:, :3], rotation)
    np.testing.assert_array_equal(m[:, 3], [1, 2, 3])
    np.testing.assert_array_equal(aos.Rigid3d.from_matrix3x4(m).matrix3x4, m)
    np.testing.assert_array_equal(aos.Rigid3d.from_matrix3x4(m.ravel().tolist()).matrix3x4, m)
    with pytest.raises(ValueError, match="3x4"):
        aos.Rigid3d.from_matrix3x4(np.zeros((3, 3)))
    identity = aos.Rigid3d()
    np.testing.assert_array_equal(identity.rotation, np.eye(3))
    np.testing.assert_array_equal(identity.translation, np.zeros(3))
    assert repr(transform).startswith("Rigid3d(")
    with pytest.raises(TypeError):
        aos.Rigid3d(np.eye(4))
    with pytest.raises(TypeError):
        aos.Rigid3d(translation=(1, 2))


def test_rigid_properties_are_copies() -> None:
    transform = aos.Rigid3d(translation=[1.0, 2.0, 3.0])
    transform.translation[0] = 99.0  # changes a copy only
    assert transform.translation[0] == 1.0
    transform.translation = np.array([4.0, 5.0, 6.0])
    np.testing.assert_array_equal(transform.translation, [4, 5, 6])


def test_pinhole_from_fov_and_projection() -> None:
    camera = aos.PinholeCamera.from_fov(640, 480, 90.0)
    assert camera.fx == pytest.approx(320.0)  # 0.5 * width / tan(45 deg)
    assert camera.fy == camera.fx
    assert (camera.cx, camera.cy) == (320.0, 240.0)
    assert camera.fov_x_deg() == pytest.approx(90.0)
    camera = aos.PinholeCamera.from_fov(512, 256, 50.0)
    assert camera.fx == pytest.approx(256.0 / math.tan(math.radians(25.0)), rel=1e-12)
    np.testing.assert_allclose(
        camera.K, [[camera.fx, 0, 256.0], [0, camera.fy, 128.0], [0, 0, 1]], rtol=1e-15
    )
    pixel = camera.project((1.0, -0.5, 4.0))
    np.testing.assert_allclose(camera.unproject(pixel) * 4.0, [1.0, -0.5, 4.0], atol=1e-12)
    # The optical axis hits the principal point, i.e. the image centre.
    np.testing.assert_allclose(camera.project(np.array([0.0, 0.0, 2.0])), [256.0, 128.0])
    with pytest.raises(ValueError, match="fov_deg"):
        aos.PinholeCamera.from_fov(64, 64, 180.0)


def test_pinhole_fields_and_check() -> None:
    camera = aos.PinholeCamera(32, 24, 20.0, 21.0, 16.0, 12.0)
    assert (camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy) == (
        32, 24, 20.0, 21.0, 16.0, 12.0)
    camera.check()
    camera.fx = -1.0
    with pytest.raises(ValueError, match="fx"):
        camera.check("my camera")
    assert "PinholeCamera(width=32" in repr(camera)


def test_plane() -> None:
    plane = aos.Plane()
    np.testing.assert_array_equal(plane.point, [0, 0, 0])
    np.testing.assert_array_equal(plane.normal, [0, 0, 1])
    plane = aos.Plane.at_height(12.5)
    np.testing.assert_array_equal(plane.point, [0, 0, 12.5])
    plane = aos.Plane(point=[1, 2, 3], normal=(0, 1, 0))
    np.testing.assert_array_equal(plane.normal, [0, 1, 0])
    assert repr(plane).startswith("Plane(point=")


def test_nan_rotation_rejected_when_adding_a_view() -> None:
    camera = aos.PinholeCamera.from_fov(8, 6, 60.0)
    rotation = np.eye(3)
    rotation[0, 0] = np.nan
    light_field = aos.LightField()
    with pytest.raises(ValueError, match="cam_from_world"):
        light_field.add_view(np.zeros((6, 8), np.uint8), camera, aos.Rigid3d(rotation))
    with pytest.raises(ValueError, match="cam_from_world"):  # not orthonormal
        light_field.add_view(np.zeros((6, 8), np.uint8), camera, aos.Rigid3d(2.0 * np.eye(3)))
    assert len(light_field) == 0
