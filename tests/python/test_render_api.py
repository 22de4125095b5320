"""Plumbing of the render API: IntegralOptions/SimulateOptions as bound from C++, the kwargs
merge of aos.render_integral, results shared with numpy, progress callbacks and cancellation.
The renderer's numbers are tested in C++ (tests/cpp/integral_test.cpp); here only what the
bindings could get wrong."""

from __future__ import annotations

import copy
import json
import math
import os
import shutil
import signal
import threading

import numpy as np
import pytest

import aos
from aos import _core

INTEGRAL_FIELDS = (
    "cam_from_world", "pose_view", "fov_deg", "width", "height", "focal_surface",
    "surface_offset", "variance", "min_view_count",
    # The aperture block (render/aperture.h), shared with MapOptions.
    "aperture_radius", "view_indices", "min_view_angle_deg", "lens_tolerance_px", "num_threads",
)
SIMULATE_FIELDS = ("num_threads",)


def test_integral_options_defaults_match_the_header() -> None:
    options = aos.IntegralOptions()
    assert aos.IntegralOptions._fields == INTEGRAL_FIELDS
    np.testing.assert_array_equal(options.cam_from_world.matrix3x4, np.eye(3, 4))
    assert options.pose_view == -1
    # 0 = from the pose view, else 50 degrees and 512 x 512 (aos.virtual_camera).
    assert options.fov_deg == 0.0
    assert (options.width, options.height) == (0, 0)
    assert options.aperture_radius == math.inf
    np.testing.assert_array_equal(options.focal_surface.plane.point, [0, 0, 0])
    np.testing.assert_array_equal(options.focal_surface.plane.normal, [0, 0, 1])
    assert options.focal_surface.kind == "plane" and options.surface_offset == 0.0
    assert options.view_indices == []
    assert options.min_view_angle_deg == 1.0
    assert options.num_threads == -1
    assert options.variance is False
    assert options.lens_tolerance_px == 0.02
    text = repr(options)
    assert text.startswith("IntegralOptions(")
    for name in INTEGRAL_FIELDS:
        assert f"{name}=" in text
    assert "aperture_radius=inf" in text


def test_integral_options_kwargs_and_copies() -> None:
    options = aos.IntegralOptions(width=64, height=32, view_indices=(2, 0),
                                  focal_surface=aos.Plane.at_height(3.0), aperture_radius=0.0)
    assert (options.width, options.height) == (64, 32)
    assert options.view_indices == [2, 0]
    assert options.focal_surface.plane.point[2] == 3.0
    assert options.aperture_radius == 0.0
    with pytest.raises(TypeError, match="widht"):
        aos.IntegralOptions(widht=3)
    with pytest.raises(TypeError):
        aos.IntegralOptions(64)  # keywords only
    with pytest.raises(TypeError):
        aos.IntegralOptions(width="wide")
    duplicate = copy.copy(options)
    duplicate.width = 8
    duplicate.focal_surface.plane.point = (0, 0, 9)  # nested objects are copied too (C++ value semantics)
    assert options.width == 64 and options.focal_surface.plane.point[2] == 3.0
    assert copy.deepcopy(options).height == 32


def test_check_errors_are_value_errors() -> None:
    with pytest.raises(ValueError, match="width"):
        aos.IntegralOptions(width=-1).check(1)
    with pytest.raises(ValueError, match="fov_deg"):
        aos.IntegralOptions(fov_deg=180.0).check(1)
    with pytest.raises(ValueError, match="pose_view"):
        aos.IntegralOptions(pose_view=5).check(3)
    aos.IntegralOptions().check(3)


def test_render_integral_kwargs_errors(make_lightfield) -> None:
    light_field = make_lightfield(views_per_side=1)
    with pytest.raises(TypeError, match="aperture"):
        aos.render_integral(light_field, aperture=1.0)
    with pytest.raises(TypeError, match="IntegralOptions"):
        aos.render_integral(light_field, options=aos.SimulateOptions())
    with pytest.raises(TypeError):
        aos.render_integral(light_field, aos.IntegralOptions(), None)  # progress is keyword-only


def test_virtual_camera(make_lightfield) -> None:
    light_field = make_lightfield(width=16, height=12, fov_deg=60.0)
    options = aos.IntegralOptions(width=100, height=50, fov_deg=40.0)
    camera = aos.virtual_camera(light_field, options)
    expected = aos.PinholeCamera.from_fov(100, 50, 40.0)
    assert (camera.width, camera.height) == (100, 50)
    assert camera.fx == pytest.approx(expected.fx) and camera.cy == pytest.approx(25.0)
    # Nothing given: 50 degrees and 512 x 512.
    camera = aos.virtual_camera(light_field, aos.IntegralOptions())
    assert (camera.width, camera.height) == (512, 512)
    assert camera.fx == pytest.approx(aos.PinholeCamera.from_fov(512, 512, 50.0).fx)
    # With a pose view, what is not given is the view's: its field of view and size.
    camera = aos.virtual_camera(light_field, aos.IntegralOptions(pose_view=4))
    assert (camera.width, camera.height) == (16, 12)
    assert camera.fx == pytest.approx(aos.PinholeCamera.from_fov(16, 12, 60.0).fx)
    camera = aos.virtual_camera(light_field, aos.IntegralOptions(pose_view=4, width=32))
    assert (camera.width, camera.height) == (32, 12)
    assert camera.fx == pytest.approx(aos.PinholeCamera.from_fov(32, 12, 60.0).fx)


def _centre_options(**kwargs) -> aos.IntegralOptions:
    # The virtual camera takes the pose of the centre view of a 3x3 grid and matches its camera,
    # focused on the ground; every pixel then sees at least the centre view.
    base = dict(pose_view=4, fov_deg=60.0, width=16, height=12, focal_surface=aos.Plane.at_height(0))
    base.update(kwargs)
    return aos.IntegralOptions(**base)


def test_render_integral_on_a_constant_lightfield(make_lightfield) -> None:
    light_field = make_lightfield(views_per_side=3, value=100, dtype=np.uint8)
    options = _centre_options()
    result = aos.render_integral(light_field, options, num_threads=2)
    image, count = result.image, result.count
    assert image.dtype == np.float32 and image.shape == (12, 16)
    assert count.dtype == np.uint32 and count.shape == (12, 16)
    assert (count >= 1).all()
    # Every view holds 100 everywhere, so every average of views is 100 (float rounding only).
    np.testing.assert_allclose(image, 100.0, rtol=1e-6)
    assert result.samples == int(count.sum())
    assert result.uncovered_pixels == int((count == 0).sum()) == 0
    assert result.views_selected == 9
    assert 1 <= result.views_used <= 9
    np.testing.assert_allclose(result.cam_from_world.matrix3x4,
                               light_field.views[4].cam_from_world.matrix3x4, atol=1e-12)
    # Zero copy: every access views the same C++ buffer, which outlives the result object.
    assert np.shares_memory(result.image, result.image)
    assert np.shares_memory(result.count, result.count)
    del result
    assert float(image.mean()) == pytest.approx(100.0)
    assert "IntegralResult(" in repr(aos.render_integral(light_field, options))


def test_render_integral_kwargs_override_a_copy(make_lightfield) -> None:
    light_field = make_lightfield(views_per_side=3, value=50, dtype=np.float32, channels=3)
    options = _centre_options()
    result = aos.render_integral(light_field, options, width=8, height=6, view_indices=[4])
    assert result.image.shape == (6, 8, 3) and result.image.dtype == np.float32
    assert result.views_selected == 1
    assert (options.width, options.height, options.view_indices) == (16, 12, [])
    with pytest.raises(ValueError, match="pose_view"):
        aos.render_integral(light_field, options, pose_view=9)


def test_render_integral_progress(make_lightfield) -> None:
    light_field = make_lightfield(views_per_side=3)
    calls = []

    def progress(stage: str, done: int, total: int) -> None:
        calls.append((stage, done, total, threading.get_ident()))

    aos.render_integral(light_field, _centre_options(width=128, height=96),
                        progress=progress)
    assert calls, "the progress callback was never called"
    assert all(isinstance(stage, str) and 0 <= done <= total for stage, done, total, _ in calls)
    assert calls[-1][1] == calls[-1][2]  # the last report says done == total
    assert {thread for *_, thread in calls} == {threading.get_ident()}


def test_render_integral_progress_error_cancels(make_lightfield) -> None:
    light_field = make_lightfield(views_per_side=3)
    calls = []

    def progress(stage: str, done: int, total: int) -> None:
        calls.append(done)
        raise RuntimeError("stop rendering")

    with pytest.raises(RuntimeError, match="stop rendering"):
        aos.render_integral(light_field, _centre_options(width=256, height=192),
                            progress=progress)
    assert len(calls) == 1  # never called again after it raised


def test_simulate_options_and_kwargs() -> None:
    assert aos.SimulateOptions._fields == SIMULATE_FIELDS
    assert aos.SimulateOptions().num_threads == -1
    with pytest.raises(TypeError, match="threads"):
        aos.simulate(aos.default_scene(), threads=1)
    with pytest.raises(TypeError, match="Scene, a dict or a path"):
        aos.simulate(42)


# The progress sink itself, through a test hook that follows the algorithms' ProgressSink
# contract with real worker threads (works before the algorithms exist).

def test_progress_sink_reports_throttled_from_the_calling_thread() -> None:
    calls = []

    def progress(stage: str, done: int, total: int) -> None:
        calls.append((stage, done, total, threading.get_ident()))

    # 400 units of 1 ms on 2 threads: about 0.2 s of work, so a handful of reports at most.
    done = _core._progress_selftest(400, num_threads=2, sleep_us=1000, progress=progress)
    assert done == 400
    assert calls[0][:3] == ("selftest", 0, 400)
    assert calls[-1][1:3] == (400, 400)
    assert sum(1 for call in calls if call[1] == call[2]) == 1
    assert len(calls) <= 2 + 0.2 / 0.1 * 4  # start + end + every 0.1 s (generous for slow CI)
    assert [call[1] for call in calls] == sorted(call[1] for call in calls)
    assert {call[3] for call in calls} == {threading.get_ident()}


def test_progress_sink_callback_error_cancels() -> None:
    calls = []

    def progress(stage: str, done: int, total: int) -> None:
        calls.append(done)
        if done > 0:
            raise RuntimeError("enough")

    with pytest.raises(RuntimeError, match="enough"):
        _core._progress_selftest(100000, num_threads=2, sleep_us=100, progress=progress)
    assert len(calls) == 2  # start, then the report that raised; the work stopped early


def test_progress_sink_rejects_non_callables() -> None:
    with pytest.raises(TypeError, match="progress"):
        _core._progress_selftest(10, progress=42)


def test_cancelled_becomes_keyboard_interrupt() -> None:
    with pytest.raises(KeyboardInterrupt):
        _core._progress_selftest(10, throw_cancelled=True)


@pytest.mark.skipif(not hasattr(signal, "SIGINT") or os.name != "posix", reason="POSIX signals")
def test_ctrl_c_interrupts_without_a_callback() -> None:
    # SIGINT arrives while the C++ loop runs with the GIL released; the sink's periodic
    # PyErr_CheckSignals() on the calling (main) thread turns it into KeyboardInterrupt.
    # A process started in the background by a non-interactive shell (`cmd &`, some CI runners)
    # inherits SIGINT as ignored, and Python then installs no handler: install Python's own for
    # the test, as an interactive session has it.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(0.2, os.kill, args=(os.getpid(), signal.SIGINT))
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            _core._progress_selftest(100000, num_threads=2, sleep_us=1000)  # ~50 s unless stopped
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, previous)


def test_min_view_count_from_its_one_definition(make_lightfield, tmp_path) -> None:
    # min_view_count was added as one row of IntegralOptions' field table (integral.h) and its
    # use in RenderIntegral: the keyword, the JSON form, the CLI flag and the viewer's renders
    # all come from that row (issue 32's "add one option" check).
    lf = make_lightfield(views_per_side=5, spacing=3.0, fov_deg=50.0, value=80.0)
    base = dict(pose_view=12, fov_deg=100.0, width=48, height=40, focal_surface=0.0)
    everything = aos.render_integral(lf, **base)
    counts = everything.count
    least = int(np.median(counts[counts > 0]))
    assert 1 < least and np.any((counts > 0) & (counts < least))
    thick = aos.render_integral(lf, **base, min_view_count=least)
    thin = counts < least
    assert np.all(thick.count[thin] == 0) and np.all(thick.image[thin] == 0)
    np.testing.assert_array_equal(thick.count[~thin], counts[~thin])
    np.testing.assert_array_equal(thick.image[~thin], everything.image[~thin])
    assert thick.uncovered_pixels == int(np.sum(thin))
    # The JSON form (the view and map --workers hand-off) and a range error naming the field.
    options = aos.IntegralOptions(**base, min_view_count=least)
    assert aos.IntegralOptions.from_json(options.to_json()).min_view_count == least
    with pytest.raises(ValueError, match="min_view_count"):
        aos.render_integral(lf, **base, min_view_count=-2)
    # The viewer: a render starts from the options it was given.
    from aos.viewer.session import Session

    session = Session(lf, render_options=aos.IntegralOptions(min_view_count=least), num_threads=1)
    params = session.parse({"pose_view": 12, "fov_deg": 100, "width": 48, "height": 40})
    shown = session.render_raw(params)
    assert not np.any((shown.count > 0) & (shown.count < least))


@pytest.mark.skipif(shutil.which("aos-render") is None, reason="aos-render is not on PATH")
def test_min_view_count_on_the_command_line(make_lightfield, tmp_path) -> None:
    # The CLI flag, bound by no line of its own (Flags::Remaining).
    import subprocess

    exe = shutil.which("aos-render")
    lf = make_lightfield(views_per_side=5, spacing=3.0, fov_deg=50.0, value=80.0)
    base = dict(pose_view=12, fov_deg=100.0, width=48, height=40, focal_surface=0.0)
    least = 4
    thick = aos.render_integral(lf, **base, min_view_count=least)
    assert np.any(thick.count == 0) and np.all((thick.count == 0) | (thick.count >= least))
    aos.write_lightfield(str(tmp_path / "lf.json"), lf)
    result = subprocess.run([exe, "integral", str(tmp_path / "lf.json"), "--pose-view", "12",
                             "--fov-deg", "100", "--width", "48", "--height", "40",
                             "--min-view-count", str(least), "-o", str(tmp_path / "a.tif"),
                             "--count", str(tmp_path / "n.tif"), "-q"],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    np.testing.assert_array_equal(aos.read_image(str(tmp_path / "n.tif")), thick.count)


def test_min_view_count_in_stacks_and_all_in_focus(make_lightfield) -> None:
    # Every slice of a stack drops its thin pixels; the coarse-to-fine all-in-focus, whose
    # passes integrate at points, refuses the option instead of ignoring it.
    lf = make_lightfield(views_per_side=5, spacing=3.0, fov_deg=50.0, value=80.0)
    camera = dict(pose_view=12, fov_deg=100.0, width=48, height=40)
    stack = aos.render_focal_stack(lf, **camera, first_plane=0.0, last_plane=1.0, slices=2,
                                   min_view_count=4)
    for count in stack.counts:
        assert np.any(count == 0) and np.all((count == 0) | (count >= 4))
    with pytest.raises(ValueError, match="min_view_count: the coarse-to-fine"):
        aos.all_in_focus(lf, **camera, first_plane=0.0, last_plane=1.0, slices=2,
                         min_view_count=4, coarse_to_fine=2)


def test_a_stack_file_keeps_every_render_field(make_lightfield, tmp_path) -> None:
    # stack.json stores the render options in their JSON form (every field of the table but the
    # focus, which is the slices'): a field added to IntegralOptions travels with the stack.
    lf = make_lightfield(views_per_side=5, spacing=3.0, fov_deg=50.0, value=80.0)
    stack = aos.render_focal_stack(lf, pose_view=12, fov_deg=100.0, width=48, height=40,
                                   first_plane=0.0, last_plane=1.0, slices=2, min_view_count=4,
                                   lens_tolerance_px=0.05, view_indices=list(range(20)))
    aos.write_focal_stack(str(tmp_path / "stack"), stack)
    render = aos.read_focal_stack(str(tmp_path / "stack")).render
    assert (render.min_view_count, render.lens_tolerance_px) == (4, 0.05)
    assert render.view_indices == list(range(20)) and render.fov_deg == stack.render.fov_deg
    text = json.loads((tmp_path / "stack" / "stack.json").read_text())["render"]
    assert "focal_surface" not in text and text["min_view_count"] == 4
