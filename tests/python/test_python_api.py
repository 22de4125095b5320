"""The Python surface fits the ecosystem: results that are images have `.image` (a focal stack's
slices one ndarray), every class has a repr, values pickle, copy and compare (process pools and
Dask need it), lens distortion lists have their model's length, keyword options are typed for
mypy and routed by one generic mechanism, a number is a horizontal plane, and a missing virtual
camera pose is named as such."""

from __future__ import annotations

import concurrent.futures
import copy
import json
import multiprocessing
import pickle
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import aos
from conftest import build_lightfield, nadir_pose

RENDER = dict(pose_view=4, focal_surface=aos.Plane.at_height(0.0), num_threads=1)
STACK = dict(pose_view=4, first_plane=aos.Plane.at_height(-1.0),
             last_plane=aos.Plane.at_height(1.0), slices=3, num_threads=1)


def textured_lightfield(channels: int = 1) -> aos.LightField:
    """A 3 x 3 grid of nadir views of a random texture (seeded), so renders differ per pixel."""
    rng = np.random.default_rng(7)
    light_field = aos.LightField()
    camera = aos.PinholeCamera.from_fov(16, 12, 60.0)
    shape = (12, 16) if channels == 1 else (12, 16, channels)
    for j in range(3):
        for i in range(3):
            image = rng.integers(0, 256, shape, dtype=np.uint8)
            light_field.add_view(image, camera, nadir_pose(i - 1.0, j - 1.0, 10.0),
                                 name=f"{3 * j + i:04d}")
    return light_field


def lens_lightfield() -> aos.LightField:
    """A light field with a pinhole view and a raw fisheye view, origin far away."""
    light_field = textured_lightfield()
    fisheye = aos.LensCamera(aos.LensModel.fisheye, 16, 12, 8.0, 8.0, 8.0, 6.0,
                             distortion=[0.01, -0.002, 0.0, 0.0])
    light_field.add_view(np.arange(16 * 12, dtype=np.uint8).reshape(12, 16), fisheye,
                         nadir_pose(0.5, 0.5, 9.0), name="fisheye")
    light_field.origin = (543210.123456, 5432109.876543, 312.5)
    return light_field


def loaded_with_pose_source(tmp_path: Path) -> aos.LoadResult:
    """A light field read from a file (names, image paths) with a pose_source record."""
    path = tmp_path / "lf.json"
    aos.write_lightfield(path, lens_lightfield())
    document = json.loads(path.read_text())
    document["pose_source"] = {"method": "colmap", "mean_reprojection_error_px": 0.5,
                               "median_depth": 20.0, "pose_error": 0.04, "georeferenced": True,
                               "georeference_rms_m": 0.3, "world_frame": "UTM 33N (WGS84)",
                               "unregistered": ["x.png", "y.png"]}
    path.write_text(json.dumps(document))
    return aos.load_lightfield(path)


# The light-field-level fields (not the views), each set to a value unlike its default below.
LIGHT_FIELD_FIELDS = ("origin", "crs", "pose_source", "masked", "grey", "radiometry")


def test_every_light_field_field_survives_rectify_copy_pickle_and_files(tmp_path: Path) -> None:
    """rectify_light_field dropped the crs (EPSG:32633 became ''), and the next render on a DEM
    covered nothing. Every field of a light field but its views carries through rectify,
    copy, pickle and a write/read; a field added to LightField fails here until listed."""
    properties = {name for name in dir(aos.LightField)
                  if isinstance(getattr(aos.LightField, name), property)}
    assert properties - {"views"} == set(LIGHT_FIELD_FIELDS)
    light_field = loaded_with_pose_source(tmp_path).light_field
    light_field.crs = "EPSG:32633"
    light_field.grey = True
    light_field.radiometry = aos.Radiometry(0.04, 1.5)
    assert light_field.pose_source is not None and tuple(light_field.origin) != (0, 0, 0)

    def fields(lf: aos.LightField) -> dict:
        return {name: (tuple(getattr(lf, name)) if name == "origin" else
                       pickle.dumps(getattr(lf, name))) for name in LIGHT_FIELD_FIELDS}

    expected = fields(light_field)
    assert fields(aos.rectify_light_field(light_field, fov_deg=60).light_field) == expected
    assert fields(copy.copy(light_field)) == expected
    assert fields(pickle.loads(pickle.dumps(light_field))) == expected
    aos.write_lightfield(tmp_path / "again.json", light_field)
    assert fields(aos.load_lightfield(tmp_path / "again.json").light_field) == expected
    # masked (a written light field is never masked): through rectify and pickle.
    aos.write_image(str(tmp_path / "mask.png"), np.full((12, 16), 255, np.uint8))
    masked = aos.load_lightfield(tmp_path / "again.json", mask=tmp_path / "mask.png").light_field
    assert masked.masked
    assert fields(aos.rectify_light_field(masked, fov_deg=60).light_field) == fields(masked)
    assert fields(pickle.loads(pickle.dumps(masked))) == fields(masked)


def test_enum_options_take_their_names() -> None:
    """aos.MergeOptions(method="robust") was a TypeError listing signatures (only the functions'
    keywords took names); an unknown name is a ValueError with the choices."""
    assert aos.MergeOptions(method="robust").method == aos.MergeMethod.robust
    assert aos.CalibrateOptions(model="fisheye").model == aos.LensModel.fisheye
    options = aos.MergeOptions()
    options.method = "sobel"
    assert options.method == aos.MergeMethod.sobel
    options.method = aos.MergeMethod.improved
    assert options == aos.MergeOptions(method="improved")
    with pytest.raises(ValueError, match=r"method: unknown value 'median' \(one of sobel, "
                                         r"improved, robust\)"):
        aos.MergeOptions(method="median")
    with pytest.raises(TypeError, match="method: expected MergeMethod or the name"):
        aos.MergeOptions(method=2)


# --- 1. results have .image; a focal stack's slices are one ndarray --------------------------

def test_every_image_result_has_image() -> None:
    light_field = textured_lightfield()
    integral = aos.render_integral(light_field, **RENDER)
    assert integral.image.shape == (12, 16)
    depth = np.full((12, 16), 10.0, np.float32)
    on_depth = aos.render_integral_on_depth(light_field, depth, pose_view=4, num_threads=1)
    np.testing.assert_array_equal(on_depth.image, on_depth.integral.image)
    np.testing.assert_array_equal(on_depth.count, on_depth.integral.count)
    # Depth 10 from view 4 (at z = 10, looking down) is the plane z = 0: the same image up to
    # float rounding of the per-sample path (integral.h), well under 1e-3 grey levels.
    np.testing.assert_allclose(on_depth.image, integral.image, atol=1e-3)
    stack = aos.render_focal_stack(light_field, **STACK)
    merged = aos.merge_focal_stack(stack, method="sobel")
    assert merged.image.shape == (12, 16)
    streamed = aos.all_in_focus(light_field, method="sobel", **STACK)
    np.testing.assert_array_equal(streamed.image, merged.image)
    simulation = aos.simulate({"camera": {"width": 16, "height": 12, "fov_deg": 60},
                               "sampling": {"grid": 2}, "truth": {"width": 8, "height": 8}},
                              num_threads=1)
    # A simulation's image is its truth: the occluder-free ground seen by the truth camera.
    assert simulation.image.shape[:2] == (8, 8)
    np.testing.assert_array_equal(simulation.image, simulation.truth.ground)
    np.testing.assert_array_equal(simulation.truth.image, simulation.truth.ground)


@pytest.mark.parametrize("channels", [1, 3])
def test_focal_stack_slices_are_one_ndarray(channels: int) -> None:
    light_field = textured_lightfield(channels)
    stack = aos.render_focal_stack(light_field, variance=True, **STACK)
    images, counts, variances = stack.images, stack.counts, stack.variances
    shape = (3, 12, 16) if channels == 1 else (3, 12, 16, channels)
    assert isinstance(images, np.ndarray) and images.shape == shape and images.dtype == np.float32
    assert counts.shape == (3, 12, 16) and counts.dtype == np.uint32
    assert variances is not None and variances.shape == (3, 12, 16)
    for index, plane in enumerate(stack.planes):
        single = aos.render_integral(light_field, pose_view=4, focal_surface=plane, variance=True,
                                     num_threads=1)
        np.testing.assert_array_equal(images[index], single.image)
        np.testing.assert_array_equal(counts[index], single.count)
        np.testing.assert_array_equal(variances[index], single.variance)
    # A copy per access: changing it leaves the stack as it was.
    images[:] = -1.0
    assert (stack.images >= 0).all()
    assert aos.render_focal_stack(light_field, **STACK).variances is None


# --- 2. every public class has a repr ---------------------------------------------------------

PUBLIC_CLASSES = sorted(name for name in aos.__all__ if isinstance(getattr(aos, name), type))


@pytest.mark.parametrize("name", PUBLIC_CLASSES)
def test_every_public_class_defines_a_repr(name: str) -> None:
    cls = getattr(aos, name)
    assert cls.__repr__ is not object.__repr__, f"{name} has only the default <... object at 0x>"


def test_reprs_say_what_the_object_is(tmp_path: Path) -> None:
    loaded = loaded_with_pose_source(tmp_path)
    light_field = textured_lightfield()
    stack = aos.render_focal_stack(light_field, **STACK)
    fisheye = aos.LensCamera(aos.LensModel.fisheye, 64, 48, 30.0, 30.0, 32.0, 24.0,
                             distortion=[0.01, 0.0, 0.0, 0.0])
    objects = [
        aos.look_at((0, 0, 10), (0, 0, 0)), aos.Plane(21.0), aos.PinholeCamera.from_fov(4, 3, 60),
        fisheye, loaded, loaded.light_field, loaded.light_field.views[-1],
        loaded.light_field.pose_source, aos.render_integral(light_field, **RENDER),
        aos.render_integral_on_depth(light_field, np.full((12, 16), 10.0, np.float32),
                                     pose_view=4),
        stack, aos.merge_focal_stack(stack), aos.make_rectifier(fisheye, aos.RectifyOptions()),
        aos.compare_images(np.zeros((16, 16), np.uint8), np.zeros((16, 16), np.uint8)),
        aos.sampling_resolution(aos.PinholeCamera.from_fov(64, 48, 60), distance_m=30.0),
        aos.default_scene(), aos.MergeMethod.robust, aos.LensModel.omnidir,
    ]
    objects += [getattr(aos, name)() for name in PUBLIC_CLASSES
                if hasattr(getattr(aos, name), "_fields")]
    for value in objects:
        text = repr(value)
        assert " object at 0x" not in text and type(value).__name__ in text, text
    assert "fisheye" in repr(fisheye) and "distortion=[0.01, 0, 0, 0]" in repr(fisheye)
    assert "fisheye" in repr(loaded.light_field.views[-1])  # the view's lens
    assert "colmap" in repr(loaded.light_field.pose_source)
    assert repr(aos.Plane(21.0)) == repr(aos.Plane.at_height(21.0))


# --- 3. pickle, copy, deepcopy and == ---------------------------------------------------------

OPTIONS_CLASSES = sorted(name for name in aos.__all__ if hasattr(getattr(aos, name), "_fields"))


def test_all_options_structs_are_covered() -> None:
    assert set(OPTIONS_CLASSES) >= {
        "IntegralOptions", "SurfaceIntegralOptions", "FocalStackOptions", "MergeOptions",
        "AllInFocusOptions", "SimulateOptions", "QualityOptions", "ResolutionOptions",
        "RectifyOptions", "CalibrateOptions", "PosesOptions"}


def changed(value: Any, field: str = "") -> Any:
    """A value of the same type that differs from `value` (nested options: every field)."""
    if hasattr(type(value), "_fields"):
        result = copy.copy(value)
        for name in type(value)._fields:
            setattr(result, name, changed(getattr(value, name), name))
        return result
    members = getattr(type(value), "__members__", None)
    if members is not None:
        return next(member for member in members.values() if member != value)
    if isinstance(value, bool):
        return not value
    if isinstance(value, (int, float)):
        return 1.5 if isinstance(value, float) and np.isinf(value) else type(value)(value + 3)
    if isinstance(value, str):
        return value + "x"
    if isinstance(value, list) and field == "vertices":  # FlightPlanOptions: (x, y) pairs
        return [[2.0, 5.0], [3.0, 6.0]]
    if isinstance(value, list):
        return [2, 5]
    if isinstance(value, aos.Plane):
        return aos.Plane((1.0, 2.0, 3.0), (0.0, 1.0, 1.0))
    if isinstance(value, aos.Rigid3d):
        return aos.look_at((1.0, 2.0, 30.0), (0.0, 0.0, 0.0))
    if value is None and field == "open_browser":  # ViewerOptions.open_browser
        return True
    if value is None and field in ("magnetic_declination_deg", "takeoff_height_m",
                                   "home_latitude_deg", "home_longitude_deg",  # TelemetryOptions
                                   "fixed_pitch_deg",  # VideoFramesOptions
                                   "min_score", "min_temperature_c",  # DetectOptions
                                   "robust_sigmas"):
        return 1.5
    if value is None and field == "false_alarm_rate":  # DetectOptions
        return 1e-4
    if value is None and field == "quantile":  # DetectOptions
        return 0.99
    if value is None and field == "ground_plane":  # FocalStackOptions.ground_plane
        return aos.Plane((1.0, 2.0, 3.0), (0.0, 1.0, 1.0))
    if isinstance(value, aos.FocalSurface):  # IntegralOptions/MapOptions.focal_surface
        return aos.FocalSurface(aos.Mesh([[0, 0, 1], [1, 0, 1], [0, 1, 1]], [[0, 1, 2]]))
    raise AssertionError(f"no changed value for {value!r}")


def round_trips(value: Any) -> list[Any]:
    return [pickle.loads(pickle.dumps(value)), pickle.loads(pickle.dumps(value, protocol=2)),
            copy.copy(value), copy.deepcopy(value)]


@pytest.mark.parametrize("name", OPTIONS_CLASSES)
def test_options_pickle_copy_and_compare(name: str) -> None:
    cls = getattr(aos, name)
    default = cls()
    for field in cls._fields:
        # == looks at every field: change one and they differ.
        one = copy.copy(default)
        setattr(one, field, changed(getattr(default, field), field))
        assert one != default, f"{name}.{field} is not compared"
    every = changed(default)
    assert every != default
    for value in (default, every):
        for back in round_trips(value):
            assert type(back) is cls and back == value and back is not value
    with pytest.raises(ValueError, match=f"{name}: pickled state has an unknown key 'bogus'"):
        cls.__new__(cls).__setstate__({**every.__getstate__(), "bogus": 1})


def test_nested_options_copy_deeply() -> None:
    options = aos.AllInFocusOptions()
    back = pickle.loads(pickle.dumps(options))
    back.stack.render.width = 99
    back.merge.robust.agreement = 0.5
    assert options.stack.render.width == 0 and options.merge.robust.agreement == 0.02
    assert back != options and copy.deepcopy(back) == back


def test_geometry_values_pickle_copy_and_compare() -> None:
    values = [
        aos.look_at((3.0, -2.0, 40.0), (1.0, 4.0, 0.5), up=(0.2, 1.0, 0.1)),
        aos.Plane((1.0, 2.0, 3.0), (0.1, 0.2, 0.9)),
        aos.PinholeCamera(640, 480, 500.5, 501.25, 320.5, 240.25),
        aos.LensCamera(aos.LensModel.radtan, 320, 240, 300.0, 298.0, 161.5, 118.5,
                       distortion=[-0.15, 0.05, 0.001, -0.0005, 0.0]),
        aos.LensCamera(aos.LensModel.fisheye, 200, 200, 40.0, 40.0, 100.0, 100.0,
                       distortion=[-0.05, 0.0, 0.0, 0.0]),
        aos.LensCamera(aos.LensModel.omnidir, 640, 480, 360.0, 358.0, 322.5, 238.5,
                       distortion=[-0.06, 0.01, 0.0006, -0.0004], xi=1.0, skew=0.1),
    ]
    for value in values:
        for back in round_trips(value):
            assert type(back) is type(value) and back == value and back is not value
    lens = values[-1]
    back = pickle.loads(pickle.dumps(lens))
    assert (back.max_radius, back.theta_max) == (lens.max_radius, lens.theta_max)
    assert back.project((0.3, 0.2, 1.0)) is not None
    np.testing.assert_array_equal(back.project((0.3, 0.2, 1.0)), lens.project((0.3, 0.2, 1.0)))
    # == is exact and can fail.
    assert aos.Plane.at_height(1.0) != aos.Plane.at_height(1.0 + 1e-12)
    assert values[0] != values[0].inverse()
    assert values[2] != aos.PinholeCamera(640, 480, 500.5, 501.25, 320.5, 240.0)
    assert values[4] != values[3] and values[0] != values[1]


def test_light_field_pickles_with_its_pixels_and_fields(tmp_path: Path) -> None:
    loaded = loaded_with_pose_source(tmp_path)
    light_field = loaded.light_field
    assert light_field.pose_source is not None and light_field.views[0].image_path
    for back in round_trips(light_field) + [pickle.loads(pickle.dumps(loaded)).light_field]:
        assert back == light_field
        np.testing.assert_array_equal(back.origin, light_field.origin)
        assert back.pose_source == light_field.pose_source
        assert back.pose_source.unregistered == ["x.png", "y.png"]
        for view, original in zip(back.views, light_field.views):
            assert (view.name, view.image_path) == (original.name, original.image_path)
            assert view.camera == original.camera
            assert view.cam_from_world == original.cam_from_world
            np.testing.assert_array_equal(view.image, original.image)
        np.testing.assert_array_equal(aos.render_integral(back, **RENDER).image,
                                      aos.render_integral(light_field, **RENDER).image)
    assert pickle.loads(pickle.dumps(loaded)) == loaded
    # == sees one pixel.
    other = textured_lightfield()
    changed_pixel = aos.LightField()
    for index, view in enumerate(other.views):
        image = view.image
        if index == 8:
            image[11, 15] ^= 1
        changed_pixel.add_view(image, view.camera, view.cam_from_world, name=view.name)
    assert changed_pixel != other and pickle.loads(pickle.dumps(other)) == other
    # Light fields loaded without their images pickle too.
    poses_only = aos.load_lightfield(tmp_path / "lf.json", load_images=False).light_field
    assert pickle.loads(pickle.dumps(poses_only)) == poses_only
    assert pickle.loads(pickle.dumps(poses_only)).views[0].image is None


def render_in_worker(light_field: aos.LightField, pose_view: int) -> np.ndarray:
    return aos.render_integral(light_field, pose_view=pose_view,
                               focal_surface=aos.Plane.at_height(0.0), num_threads=1).image.copy()


def test_process_pool_renders_a_pickled_light_field() -> None:
    light_field = lens_lightfield()
    context = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(max_workers=2, mp_context=context) as pool:
        images = list(pool.map(render_in_worker, [light_field] * 2, [4, 0]))
    for image, pose_view in zip(images, [4, 0]):
        np.testing.assert_array_equal(image, render_in_worker(light_field, pose_view))


# --- 4. distortion lists have their model's natural length ------------------------------------

@pytest.mark.parametrize("model, length", [
    (aos.LensModel.radtan, 5), (aos.LensModel.fisheye, 4), (aos.LensModel.omnidir, 4),
    (aos.LensModel.pinhole, 0)])
def test_distortion_has_the_models_natural_length(model: aos.LensModel, length: int) -> None:
    values = [0.01, -0.001, 0.0, 0.0, 0.0][:length]
    lens = aos.LensCamera(model, 640, 480, 400.0, 400.0, 320.0, 240.0, distortion=values)
    assert lens.distortion == values
    assert aos.LensCamera(model, 640, 480, 400.0, 400.0, 320.0, 240.0).distortion == [0.0] * length
    lens.distortion = [0.0] * length
    assert lens.distortion == [0.0] * length
    for wrong in {length + 1, max(length - 1, 0) if length else 2}:
        with pytest.raises(ValueError, match=f"distortion: the {model.name} model takes {length}"):
            aos.LensCamera(model, 640, 480, 400.0, 400.0, 320.0, 240.0, distortion=[0.0] * wrong)
        with pytest.raises(ValueError, match=f"the {model.name} model"):
            lens.distortion = [0.0] * wrong


# --- 5. keyword options are typed: mypy rejects pose_view="191" -------------------------------

def run_mypy(tmp_path: Path, code: str) -> subprocess.CompletedProcess:
    pytest.importorskip("mypy")
    snippet = tmp_path / "snippet.py"
    snippet.write_text(textwrap.dedent(code))
    return subprocess.run(
        [sys.executable, "-m", "mypy", "--no-error-summary", "--cache-dir",
         str(tmp_path / ".mypy_cache"), str(snippet)],
        capture_output=True, text=True, cwd=tmp_path, timeout=300)


def test_mypy_checks_the_keyword_options(tmp_path: Path) -> None:
    wrong = run_mypy(tmp_path, """\
        import aos
        lf = aos.LightField()
        aos.render_integral(lf, pose_view="191")
        aos.all_in_focus(lf, method="best")
        aos.render_focal_stack(lf, focal_plane=2.0)
        aos.plan_flight(shape="cirlce")
    """)
    assert wrong.returncode == 1, wrong.stdout + wrong.stderr
    assert ('snippet.py:3: error: Argument "pose_view" to "render_integral" has incompatible '
            'type "str"; expected "int"') in wrong.stdout
    assert 'snippet.py:4: error: Argument "method" to "all_in_focus"' in wrong.stdout
    assert 'snippet.py:5: error: Unexpected keyword argument "focal_plane"' in wrong.stdout
    assert 'snippet.py:6: error: Argument "shape" to "plan_flight"' in wrong.stdout
    right = run_mypy(tmp_path, """\
        import aos
        lf = aos.LightField()
        aos.render_integral(lf, pose_view=191, focal_surface=21.0, view_indices=[1, 2])
        aos.all_in_focus(lf, method="robust", num_threads=3, first_plane=0, agreement=0.1)
        options = aos.IntegralOptions(focal_surface=2.0)
        options.focal_surface = 3.0
        images = aos.render_focal_stack(lf, first_plane=0.0, last_plane=aos.Plane(5.0)).images
        lens = aos.LensCamera(aos.LensModel.fisheye, 9, 9, 1.0, 1.0, 4.5, 4.5,
                              distortion=[0.1, 0.0, 0.0, 0.0])
    """)
    assert right.returncode == 0, right.stdout + right.stderr


# The router of each wrapper and the TypedDict of its keywords (aos._keywords).
ROUTED = [
    ("_RENDER_INTEGRAL", "IntegralKeywords"),
    ("_RENDER_FOCAL_STACK", "FocalStackKeywords"),
    ("_MERGE_FOCAL_STACK", "MergeKeywords"),
    ("_ALL_IN_FOCUS", "AllInFocusKeywords"),
    ("_RENDER_INTEGRAL_ON_DEPTH", "SurfaceIntegralKeywords"),
    ("_RENDER_MAP", "MapKeywords"),
    ("_SIMULATE", "SimulateKeywords"),
    ("_RUN_DEMO", "DemoKeywords"),
    ("_COMPARE_IMAGES", "QualityKeywords"),
    ("_SAMPLING_RESOLUTION", "ResolutionKeywords"),
    ("_CALIBRATE", "CalibrateKeywords"),
    ("_ESTIMATE_POSES", "PosesKeywords"),
    ("_IMPORT_COLMAP", "PosesKeywords"),
    ("_RECTIFY_LIGHT_FIELD", "RectifyKeywords"),
]


@pytest.mark.parametrize("router_name, keywords_name", ROUTED)
def test_typed_keywords_are_the_routed_fields(router_name: str, keywords_name: str) -> None:
    from aos import _keywords

    keywords = getattr(_keywords, keywords_name)
    assert set(keywords.__optional_keys__) == getattr(aos, router_name).names()
    assert not keywords.__required_keys__


# --- 6. a number is a horizontal plane --------------------------------------------------------

def test_a_number_is_a_horizontal_plane() -> None:
    assert aos.Plane(21.0) == aos.Plane.at_height(21.0) == aos.Plane(21)
    assert aos.IntegralOptions(focal_surface=2.5).focal_surface.plane == aos.Plane.at_height(2.5)
    options = aos.FocalStackOptions(first_plane=-1, last_plane=np.float64(3.0))
    assert (options.first_plane, options.last_plane) == (aos.Plane.at_height(-1.0),
                                                         aos.Plane.at_height(3.0))
    options.render.focal_surface = 4.0
    assert options.render.focal_surface.plane == aos.Plane.at_height(4.0)
    assert aos.stack_planes(0.0, 2, 3, (0.0, 0.0, 10.0))[1] == aos.Plane.at_height(1.0)
    light_field = textured_lightfield()
    by_number = aos.render_integral(light_field, pose_view=4, focal_surface=0.5)
    by_plane = aos.render_integral(light_field, pose_view=4, focal_surface=aos.Plane.at_height(0.5))
    np.testing.assert_array_equal(by_number.image, by_plane.image)
    stack = aos.render_focal_stack(light_field, pose_view=4, first_plane=0, last_plane=2.0,
                                   slices=3)
    assert stack.planes == [aos.Plane.at_height(z) for z in (0.0, 1.0, 2.0)]
    with pytest.raises(TypeError, match="focal_surface: expected a FocalSurface, Mesh, Heightfield, "
                                        "Plane or a number"):
        aos.render_integral(light_field, pose_view=4, focal_surface=True)
    with pytest.raises(TypeError):
        aos.Plane(True)
    with pytest.raises(TypeError, match="a height takes no normal"):
        aos.Plane(2.0, (0.0, 0.0, 1.0))


# --- 7. a missing virtual camera pose is named -------------------------------------------------

def test_missing_pose_says_give_pose_view_or_cam_from_world() -> None:
    light_field = build_lightfield()
    depth = np.full((12, 16), 10.0, np.float32)
    calls = [
        lambda: aos.render_integral(light_field),
        lambda: aos.render_integral(light_field, options=aos.IntegralOptions(width=8)),
        lambda: aos.render_focal_stack(light_field, first_plane=0.0, last_plane=1.0, slices=2),
        lambda: aos.all_in_focus(light_field, first_plane=0.0, last_plane=1.0, slices=2),
        lambda: aos.render_integral_on_depth(light_field, depth),
    ]
    for call in calls:
        with pytest.raises(ValueError, match="no virtual camera pose: give pose_view or "
                                             "cam_from_world"):
            call()
    # A pose given either way renders.
    aos.render_integral(light_field, pose_view=0)
    aos.render_integral(light_field, cam_from_world=nadir_pose(0.0, 0.0, 10.0))


# --- 8. one generic keyword routing; num_threads limits render and merge -----------------------

@pytest.fixture
def captured(monkeypatch: pytest.MonkeyPatch) -> dict[str, Any]:
    """Replaces the core calls of the wrappers by recorders of the options they get."""
    seen: dict[str, Any] = {}

    def record(key: str, value: Any) -> Any:
        seen[key] = value
        return value

    monkeypatch.setattr(aos._core, "_all_in_focus",
                        lambda lf, options, progress=None: record("aif", options))
    monkeypatch.setattr(aos._core, "_merge_focal_stack",
                        lambda stack, options, lf=None, progress=None: record("merge", options))
    monkeypatch.setattr(aos._core, "_render_integral_on_depth",
                        lambda lf, options, depth, surface, progress=None:
                        record("depth", (options, surface)))
    return seen


def test_all_in_focus_num_threads_limits_render_and_merge(captured: dict[str, Any]) -> None:
    aos.all_in_focus(build_lightfield(), pose_view=0, num_threads=3)
    options = captured["aif"]
    assert options.stack.render.num_threads == 3 and options.merge.num_threads == 3
    expected = aos.AllInFocusOptions()
    expected.stack.render.pose_view = 0
    expected.stack.render.num_threads = 3
    expected.merge.num_threads = 3
    assert options == expected  # nothing else changed


def test_keywords_go_to_the_field_of_their_name(captured: dict[str, Any]) -> None:
    given = aos.AllInFocusOptions()
    aos.all_in_focus(build_lightfield(), given, pose_view=0, method="robust", agreement=0.1,
                     robust=True, slices=5, first_plane=1.0, width=32, smoothing_iterations=2)
    options = captured["aif"]
    assert options.merge.method == aos.MergeMethod.robust
    assert options.merge.robust.agreement == 0.1 and options.merge.robust.robust
    assert options.stack.slices == 5 and options.stack.first_plane == aos.Plane.at_height(1.0)
    assert options.stack.render.width == 32 and options.merge.smoothing_iterations == 2
    assert given == aos.AllInFocusOptions()  # the caller's options are not changed
    # A nested struct and a field inside it: the struct first, whatever the order of keywords.
    aos.all_in_focus(build_lightfield(), slices=7, pose_view=0,
                     stack=aos.FocalStackOptions(slices=3, last_plane=4.0))
    assert captured["aif"].stack.slices == 7
    assert captured["aif"].stack.last_plane == aos.Plane.at_height(4.0)
    surface = aos.SurfaceIntegralOptions(agreement=0.3, min_inlier_fraction=0.2)
    aos.merge_focal_stack(None, robust=surface, method="improved")  # type: ignore[arg-type]
    assert captured["merge"].robust == surface
    render = aos.IntegralOptions(width=7)
    aos.render_integral_on_depth(build_lightfield(), None, render, pose_view=1, robust=True)
    integral, surf = captured["depth"]
    assert (integral.pose_view, integral.width, surf.robust) == (1, 7, True)
    assert render.pose_view == -1


def test_bad_keywords_are_refused_with_the_valid_names() -> None:
    light_field = build_lightfield()
    with pytest.raises(TypeError, match=r"all_in_focus\(\) got an unexpected keyword argument "
                                        r"'slice_count' \(options: .*first_plane.*slices"):
        aos.all_in_focus(light_field, slice_count=5)
    # The slices replace a plane focal_surface, which a stack would ignore: refused, not dropped
    # (also in its deprecated spelling, and in the options given whole).
    plane = aos.Plane.at_height(3.0)
    ignored = "render.focal_surface: a plane here would be ignored"
    for function in (aos.render_focal_stack, aos.all_in_focus):
        for value in (plane, 3.0, np.float32(3.0), aos.FocalSurface(plane)):
            with pytest.raises(ValueError, match=ignored):
                function(light_field, pose_view=0, focal_surface=value)
        with pytest.warns(DeprecationWarning), pytest.raises(ValueError, match=ignored):
            function(light_field, pose_view=0, focal_plane=plane)
    with pytest.raises(ValueError, match=ignored):
        aos.render_focal_stack(light_field, aos.FocalStackOptions(
            render=aos.IntegralOptions(pose_view=0, focal_surface=plane)))
    with pytest.raises(TypeError, match=r"render_integral\(\): pose_view: expected int, got str"):
        aos.render_integral(light_field, pose_view="191")  # type: ignore[typeddict-item]
    with pytest.raises(ValueError, match=r"method: unknown merge method 'best' \(sobel, improved "
                                         r"or robust\)"):
        aos.all_in_focus(light_field, pose_view=0, method="best")  # type: ignore[typeddict-item]
    # A name at two plain fields that are not one shared setting is ambiguous.
    router = aos._Router("f", aos.IntegralOptions, aos.FocalStackOptions)
    with pytest.raises(TypeError, match=r"f\(\): keyword argument 'width' is ambiguous "
                                        r"\(width, render.width\)"):
        router.apply([aos.IntegralOptions(), aos.FocalStackOptions()], {"width": 8})
    roots = [aos.IntegralOptions(), aos.FocalStackOptions()]
    router.apply(roots, {"num_threads": 2, "slices": 4})
    assert roots[0].num_threads == 2 and roots[1].render.num_threads == 2
    assert roots[1].slices == 4
