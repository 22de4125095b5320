"""Bindings of lightfield/lightfield.h, lightfield/formats.h and image/image_io.h: the numpy copy
rules, dtypes, errors, and file round trips."""

from __future__ import annotations

import gc
import pickle

import numpy as np
import pytest

import aos

from conftest import nadir_pose


def _camera(width: int = 8, height: int = 6) -> aos.PinholeCamera:
    return aos.PinholeCamera.from_fov(width, height, 60.0)


def _ramp(shape: tuple[int, ...], dtype: type) -> np.ndarray:
    return (np.arange(int(np.prod(shape))) % 200).reshape(shape).astype(dtype)


def test_add_view_copies_the_input() -> None:
    light_field = aos.LightField()
    image = _ramp((6, 8), np.uint8)
    expected = image.copy()
    light_field.add_view(image, _camera(), nadir_pose(0, 0, 10), name="a")
    image[:] = 7  # the light field holds its own copy
    np.testing.assert_array_equal(light_field.views[0].image, expected)
    # View.image is a copy too: changing it does not change the view.
    view_image = light_field.views[0].image
    view_image[:] = 9
    np.testing.assert_array_equal(light_field.views[0].image, expected)


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
@pytest.mark.parametrize("channels", [1, 3])
def test_add_view_keeps_dtype_and_shape(dtype: type, channels: int) -> None:
    shape = (6, 8) if channels == 1 else (6, 8, channels)
    image = _ramp(shape, dtype)
    light_field = aos.LightField()
    light_field.add_view(image, _camera(), nadir_pose(0, 0, 10))
    stored = light_field.views[0].image
    assert stored.dtype == np.dtype(dtype)
    assert stored.shape == shape
    np.testing.assert_array_equal(stored, image)
    assert light_field.image_bytes() == image.nbytes


def test_add_view_converts_float64_and_accepts_any_strides() -> None:
    light_field = aos.LightField()
    image64 = _ramp((6, 8), np.float64) / 7.0
    light_field.add_view(image64, _camera(), nadir_pose(0, 0, 10))
    stored = light_field.views[0].image
    assert stored.dtype == np.float32
    np.testing.assert_array_equal(stored, image64.astype(np.float32))
    # A transposed (Fortran-ordered) array and a strided slice.
    transposed = _ramp((8, 6), np.uint16).T
    light_field.add_view(transposed, _camera(), nadir_pose(1, 0, 10))
    np.testing.assert_array_equal(light_field.views[1].image, transposed)
    strided = _ramp((12, 16, 2), np.uint8)[::2, ::2, 0]
    light_field.add_view(strided, _camera(), nadir_pose(2, 0, 10))
    np.testing.assert_array_equal(light_field.views[2].image, strided)
    # Nested lists go through numpy.asarray (here int64, rejected below); uint8 lists work.
    light_field.add_view(np.asarray(strided.tolist(), dtype=np.uint8), _camera(),
                         nadir_pose(3, 0, 10))
    assert len(light_field) == 4


@pytest.mark.parametrize("dtype", [np.int64, np.int8, np.bool_, np.complex64])
def test_add_view_rejects_other_dtypes(dtype: type) -> None:
    light_field = aos.LightField()
    with pytest.raises(ValueError, match=np.dtype(dtype).name):
        light_field.add_view(np.zeros((6, 8), dtype), _camera(), nadir_pose(0, 0, 10))


def test_add_view_rejects_uint32_and_bad_shapes() -> None:
    light_field = aos.LightField()
    with pytest.raises(ValueError, match="uint32"):
        light_field.add_view(np.zeros((6, 8), np.uint32), _camera(), nadir_pose(0, 0, 10))
    with pytest.raises(ValueError, match="shape"):
        light_field.add_view(np.zeros((6, 8, 1, 1), np.uint8), _camera(), nadir_pose(0, 0, 10))
    with pytest.raises(ValueError, match="channels"):
        light_field.add_view(np.zeros((6, 8, 5), np.uint8), _camera(), nadir_pose(0, 0, 10))
    with pytest.raises(ValueError, match="empty"):
        light_field.add_view(np.zeros((0, 8), np.uint8), _camera(), nadir_pose(0, 0, 10))
    assert len(light_field) == 0


def test_add_view_rejects_size_mismatch() -> None:
    light_field = aos.LightField()
    with pytest.raises(ValueError, match="8x6"):
        light_field.add_view(np.zeros((8, 6), np.uint8), _camera(8, 6), nadir_pose(0, 0, 10))
    with pytest.raises(ValueError, match="fx"):
        bad_camera = aos.PinholeCamera(8, 6, 0.0, 1.0, 4.0, 3.0)
        light_field.add_view(np.zeros((6, 8), np.uint8), bad_camera, nadir_pose(0, 0, 10))


def test_view_properties_and_origin(make_lightfield) -> None:
    light_field = make_lightfield(views_per_side=2, width=16, height=12)
    assert len(light_field) == 4
    views = light_field.views
    assert isinstance(views, list) and len(views) == 4
    view = views[3]
    assert view.name == "0003"
    assert view.image_path == ""
    assert (view.camera.width, view.camera.height) == (16, 12)
    np.testing.assert_allclose(view.cam_from_world.center, [0.5, 0.5, 10.0], atol=1e-12)
    assert view.image.shape == (12, 16)
    assert "0003" in repr(view)
    np.testing.assert_array_equal(light_field.origin, [0, 0, 0])
    light_field.origin = (500000.25, 5300000.5, 310.0)  # UTM-sized, kept in double
    np.testing.assert_array_equal(light_field.origin, [500000.25, 5300000.5, 310.0])
    assert light_field.image_bytes() == 4 * 16 * 12
    assert repr(light_field).startswith("LightField(views=4")


def test_lightfield_file_round_trip(tmp_path, make_lightfield) -> None:
    light_field = make_lightfield(views_per_side=2, width=16, height=12, value=77)
    light_field.origin = (1000.5, 2000.25, 30.0)
    path = tmp_path / "lf.json"
    aos.write_lightfield(path, light_field)
    result = aos.load_lightfield(str(path))
    assert result.format == "aos"
    loaded = result.light_field
    assert len(loaded) == len(light_field)
    np.testing.assert_array_equal(loaded.origin, light_field.origin)
    for original, view in zip(light_field.views, loaded.views):
        np.testing.assert_array_equal(view.image, original.image)
        np.testing.assert_allclose(view.cam_from_world.matrix3x4,
                                   original.cam_from_world.matrix3x4, atol=1e-12)
        assert view.camera.fx == pytest.approx(original.camera.fx)
        assert view.image_path != ""
    # Poses and cameras only.
    without_images = aos.load_lightfield(path, load_images=False).light_field
    assert len(without_images) == len(light_field)
    assert without_images.views[0].image is None


@pytest.mark.parametrize(
    "dtype, extension", [(np.uint8, ".png"), (np.uint16, ".png"), (np.float32, ".exr")]
)
def test_image_file_round_trip(tmp_path, dtype: type, extension: str) -> None:
    image = _ramp((5, 7, 3), dtype)
    path = tmp_path / f"image{extension}"
    aos.write_image(path, image)
    read = aos.read_image(str(path))
    assert read.dtype == np.dtype(dtype)
    np.testing.assert_array_equal(read, image)
    # Result images share memory with the decoded C++ image instead of copying it; the array
    # keeps the storage alive on its own.
    assert not read.flags.owndata and read.base is not None
    del image
    gc.collect()
    assert read.sum() > 0


def test_write_image_options_and_errors(tmp_path) -> None:
    values = np.array([[0.0, 0.5], [1.0, 2.0]], dtype=np.float64)
    path = tmp_path / "scaled.png"
    aos.write_image(path, values, sample_type="uint16", range_min=0.0, range_max=1.0,
                    description="test")
    read = aos.read_image(path)
    assert read.dtype == np.uint16
    np.testing.assert_array_equal(read, [[0, 32768], [65535, 65535]])  # clamped above range_max
    with pytest.raises(ValueError):
        aos.write_image(tmp_path / "x.png", values, sample_type="int7")
    with pytest.raises(ValueError, match="int64"):
        aos.write_image(tmp_path / "x.png", np.zeros((2, 2), np.int64))
    with pytest.raises(ValueError, match="range"):
        aos.write_image(tmp_path / "x.png", values, range_min=1.0, range_max=1.0)
    with pytest.raises(ValueError, match="not found"):
        aos.read_image(tmp_path / "missing.png")


def test_add_view_refuses_non_finite_pixels() -> None:
    light_field = aos.LightField()
    image = np.zeros((6, 8), np.float32)
    image[2, 5] = np.inf
    camera = aos.PinholeCamera.from_fov(8, 6, 50.0)
    with pytest.raises(ValueError, match=r"pixel \(5, 2\) channel 0 is infinite"):
        light_field.add_view(image, camera, aos.Rigid3d(), name="hot.exr")
    assert len(light_field) == 0


def test_view_camera_is_one_lens_camera_however_the_view_was_made(tmp_path) -> None:
    # A view kept its intrinsics twice (a PinholeCamera and a LensCamera); a pinhole view added in
    # memory had an empty lens (width 0), so aos.sampling_resolution(view.lens) failed until the
    # light field was written and read back. Now view.camera is the one LensCamera.
    light_field = aos.LightField()
    camera = aos.PinholeCamera.from_fov(64, 48, 60.0)
    light_field.add_view(np.zeros((48, 64), np.uint8), camera, nadir_pose(0, 0, 10), name="a.png")
    fisheye = aos.LensCamera(aos.LensModel.fisheye, 64, 48, 30.0, 30.0, 32.0, 24.0,
                             [0.01, 0.0, 0.0, 0.0])
    light_field.add_view(np.ones((48, 64), np.uint8), fisheye, nadir_pose(1, 0, 10), name="b.png")
    lens = light_field.views[0].camera
    assert isinstance(lens, aos.LensCamera)
    assert (lens.model, lens.width, lens.height, lens.fx, lens.cx) == (
        aos.LensModel.pinhole, 64, 48, camera.fx, camera.cx)
    assert lens.pinhole() == camera
    assert lens == aos.LensCamera.from_pinhole(camera)
    assert light_field.views[1].camera == fisheye
    in_memory = aos.sampling_resolution(lens, distance_m=10.0).sample_size_m
    assert in_memory == aos.sampling_resolution(camera, distance_m=10.0).sample_size_m
    path = tmp_path / "lf.json"
    aos.write_lightfield(str(path), light_field)
    loaded = aos.load_lightfield(str(path)).light_field
    assert loaded.views[0].camera == lens and loaded.views[1].camera == fisheye
    assert aos.sampling_resolution(loaded.views[0].camera, distance_m=10.0).sample_size_m == in_memory
    for a, b in zip(loaded.views, light_field.views):
        assert a.camera == b.camera and a.cam_from_world == b.cam_from_world
        np.testing.assert_array_equal(a.image, b.image)
    # The loaded views differ only in name and image_path (the written files): a light field
    # rebuilt from them with add_view equals the original, and so does a pickle round trip.
    rebuilt = aos.LightField()
    for view, original in zip(loaded.views, light_field.views):
        rebuilt.add_view(view.image, view.camera, view.cam_from_world, name=original.name)
    assert rebuilt == light_field
    assert pickle.loads(pickle.dumps(light_field)) == light_field


def test_view_lens_is_a_deprecated_alias_of_camera() -> None:
    light_field = aos.LightField()
    camera = aos.PinholeCamera.from_fov(16, 12, 60.0)
    light_field.add_view(np.zeros((12, 16), np.uint8), camera, aos.Rigid3d(), name="a.png")
    view = light_field.views[0]
    with pytest.warns(DeprecationWarning, match="View.camera"):
        assert view.lens == view.camera


def test_view_pickled_by_the_previous_version_still_loads() -> None:
    # Before one camera per view, the pickled state held "camera" (a PinholeCamera) and "lens".
    camera = aos.PinholeCamera.from_fov(16, 12, 60.0)
    fisheye = aos.LensCamera(aos.LensModel.fisheye, 16, 12, 8.0, 8.0, 8.0, 6.0, [0.01, 0, 0, 0])
    image = np.zeros((12, 16), np.uint8)
    for pinhole_camera, lens, expected in [
            (camera, aos.LensCamera.from_pinhole(camera), aos.LensCamera.from_pinhole(camera)),
            (fisheye.pinhole(), fisheye, fisheye)]:
        view = aos.View.__new__(aos.View)
        view.__setstate__({"name": "a.png", "image_path": "", "camera": pinhole_camera,
                           "lens": lens, "cam_from_world": aos.Rigid3d(), "image": image})
        assert view.camera == expected

def test_unpickling_a_view_checks_it_as_add_view_does() -> None:
    # A view whose pickled pixels hold NaN (or inf) is refused like add_view refuses them; so is
    # a bad pose, with or without pixels.
    camera = aos.PinholeCamera.from_fov(16, 12, 60.0)
    light_field = aos.LightField()
    light_field.add_view(np.ones((12, 16), np.float32), camera, aos.Rigid3d(), name="a.tif")
    state = light_field.views[0].__getstate__()
    for bad in (np.nan, np.inf):
        image = np.ones((12, 16), np.float32)
        image[3, 5] = bad
        with pytest.raises(ValueError, match=r"a\.tif.*\(5, 3\)"):
            aos.LightField().add_view(image, camera, aos.Rigid3d(), name="a.tif")
        view = aos.View.__new__(aos.View)
        with pytest.raises(ValueError, match=r"a\.tif.*\(5, 3\)"):
            view.__setstate__(dict(state, image=image))
    bad_pose = aos.Rigid3d(translation=(np.nan, 0.0, 0.0))
    for changes in ({"image": None, "cam_from_world": bad_pose}, {"cam_from_world": bad_pose}):
        with pytest.raises(ValueError, match="cam_from_world"):
            aos.View.__new__(aos.View).__setstate__(dict(state, **changes))
    assert pickle.loads(pickle.dumps(light_field)) == light_field
