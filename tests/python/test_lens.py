"""Lens models from Python and the CLI: the sampling resolution (the paper's Eq. 2 and
Appendix A), LensCamera, rectification of frames and of light fields."""

from __future__ import annotations

import json
import math
import os
import subprocess

import numpy as np
import pytest

import aos


def test_paper_figures_from_python() -> None:
    # n = 3.5 MP (1871^2), FOV 80 degrees, h = 35 m: about 1,014 samples/m^2, p = 3.1 cm.
    camera = aos.PinholeCamera.from_fov(1871, 1871, 80.0)
    result = aos.sampling_resolution(camera, distance_m=35.0)
    assert result.eq2_samples_per_m2 == pytest.approx(1871**2 / (2 * 35 * math.tan(math.radians(40))) ** 2)
    assert result.eq2_samples_per_m2 == pytest.approx(1014, abs=1.0)
    assert result.sample_size_m == pytest.approx(0.0314, abs=1e-4)
    # p' = p + 2 e with e = 4.23 cm.
    with_error = aos.sampling_resolution(camera, distance_m=35.0, pose_error_m=0.0423)
    assert with_error.effective_sample_size_m == pytest.approx(result.sample_size_m + 0.0846)
    assert 1.0 / (0.0318 + 2 * 0.0423) ** 2 == pytest.approx(73.8, abs=0.05)  # the paper's 74
    with pytest.raises(ValueError, match="not both"):
        aos.sampling_resolution(camera, pose_error_m=0.1, pose_error_px=1.0)


def test_paper_figures_from_the_cli() -> None:
    done = subprocess.run(["aos-render", "resolution", "--width", "1871", "--height", "1871",
                           "--lens-fov-deg", "80", "--distance-m", "35", "--pose-error-m", "0.0423",
                           "--json"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    figures = json.loads(done.stdout)
    assert figures["eq2_samples_per_m2"] == pytest.approx(1014, abs=1.0)
    assert figures["effective_sample_size_m"] == pytest.approx(figures["sample_size_m"] + 0.0846)
    folded = subprocess.run(["aos-render", "resolution", "--width", "640", "--height", "480",
                             "--lens-fov-deg", "80", "--model", "radtan", "--distortion", "-0.5"],
                            capture_output=True, text=True)
    assert folded.returncode == 2 and "folds the image" in folded.stderr


def test_lens_camera_round_trip_and_masks() -> None:
    lens = aos.LensCamera(aos.LensModel.omnidir, 1024, 1024, 250.0, 250.0, 512.0, 512.0,
                          distortion=[-0.1, 0.01, 0.0005, 0.0002], xi=0.9)
    ray = np.array([math.sin(1.55), 0.0, math.cos(1.55)])  # 88.8 degrees off-axis
    pixel = lens.project(ray)
    assert pixel is not None
    np.testing.assert_allclose(lens.unproject(pixel), ray, atol=1e-9)
    assert lens.unproject([math.nan, 512.0]) is None
    # A fisheye whose distortion stops increasing at some angle: pixels beyond that radius (its
    # image circle) have no ray.
    fisheye = aos.LensCamera(aos.LensModel.fisheye, 200, 200, 40.0, 40.0, 100.0, 100.0,
                             distortion=[-0.05, 0.0, 0.0, 0.0])
    assert fisheye.theta_max < math.pi
    assert fisheye.unproject([100.0, 100.0]) is not None
    assert fisheye.unproject([100.0 + 1e4, 100.0]) is None
    with pytest.raises(ValueError, match="xi"):
        aos.LensCamera(aos.LensModel.omnidir, 64, 64, 50.0, 50.0, 32.0, 32.0, xi=-1.0)


def test_cli_rectify_keeps_bit_depth_and_refuses_uncovered_views(tmp_path) -> None:
    camera = {"format": "aos-camera", "version": 1, "model": "fisheye", "width": 160, "height": 120,
              "fx": 60.0, "fy": 60.0, "cx": 80.0, "cy": 60.0, "distortion": [0.02, 0, 0, 0, 0]}
    (tmp_path / "cam.json").write_text(json.dumps(camera))
    frame = (np.arange(160 * 120, dtype=np.uint16).reshape(120, 160) * 3)
    aos.write_image(str(tmp_path / "f0.png"), frame)
    done = subprocess.run(["aos-render", "rectify", str(tmp_path / "f0.png"), "--camera",
                           str(tmp_path / "cam.json"), "--rectified-fov-deg", "60", "--width", "80",
                           "--height", "60", "-q", "-o", str(tmp_path / "out")],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    out = aos.read_image(str(tmp_path / "out" / "f0.png"))
    assert out.dtype == np.uint16 and out.shape == (60, 80)
    rectified = json.loads((tmp_path / "out" / "camera.json").read_text())
    assert rectified["model"] == "pinhole" and rectified["width"] == 80
    refused = subprocess.run(["aos-render", "rectify", str(tmp_path / "f0.png"), "--camera",
                              str(tmp_path / "cam.json"), "--rectified-fov-deg", "179", "-o",
                              str(tmp_path / "wide")], capture_output=True, text=True)
    assert refused.returncode == 2 and "does not cover" in refused.stderr
    assert not (tmp_path / "wide").exists()


def test_simulated_fisheye_light_field_renders_directly_and_after_rectify(tmp_path) -> None:
    # The simulator records views through a fisheye (views carry the lens); rendering them
    # directly and after `aos-render rectify --lightfield` both give the simulator's truth.
    scene = {"seed": 2, "ground": {"texture": {"type": "noise", "square": 1.0}},
             "camera": {"width": 192, "height": 192, "lens": "fisheye", "fov_deg": 180,
                        "distortion": [0.01], "bit_depth": 32},
             "sampling": {"grid": 3, "aperture": {"diameter": 8.0}},
             "truth": {"fov_deg": 40.0, "width": 64, "height": 64}}
    simulation = aos.simulate(scene, tmp_path / "sim")
    assert simulation.stats["lens_rays"] == simulation.stats["primary_rays"] > 0
    raw = aos.load_lightfield(str(tmp_path / "sim" / "lightfield.json")).light_field
    assert all(view.camera.model == aos.LensModel.fisheye for view in raw.views)
    done = subprocess.run(["aos-render", "rectify", "--lightfield",
                           str(tmp_path / "sim" / "lightfield.json"), "--rectified-fov-deg", "100", "-q",
                           "-o", str(tmp_path / "rect")], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    rectified = aos.load_lightfield(str(tmp_path / "rect" / "lightfield.json")).light_field
    assert all(view.camera.model == aos.LensModel.pinhole for view in rectified.views)
    assert rectified.views[0].camera.width == 192
    # The same from Python (the core's RectifyLightField): identical cameras, poses and pixels
    # (float views: the CLI stores them as float32 TIFFs, so nothing is lost on the way).
    in_python = aos.rectify_light_field(raw, fov_deg=100)
    assert in_python.rectified_views == 9 and repr(in_python).startswith("RectifyLightFieldResult")
    for mine, written in zip(in_python.light_field.views, rectified.views):
        assert mine.camera == written.camera and mine.cam_from_world == written.cam_from_world
        np.testing.assert_array_equal(mine.image, written.image)
    with pytest.raises(ValueError, match=r"fov_deg: .*does not cover.*\(view "):
        aos.rectify_light_field(raw, fov_deg=100, pitch_deg=80)
    truth = simulation.truth
    options = dict(cam_from_world=truth.cam_from_world, fov_deg=truth.camera.fov_x_deg(),
                   width=64, height=64)
    direct = aos.render_integral(raw, **options)
    two_step = aos.render_integral(rectified, **options)
    assert (direct.count == 9).all() and (two_step.count == 9).all()
    ones = np.ones((64, 64), np.uint8)
    direct_psnr = aos.compare_images(direct.image, truth.ground, ones, data_range=1.0).psnr_db
    two_step_psnr = aos.compare_images(two_step.image, truth.ground, ones, data_range=1.0).psnr_db
    # Both resample a smooth texture finely (views ~10 cm per pixel, texture lattice 1 m);
    # rectifying adds a second resampling, which costs quality.
    assert direct_psnr > 35.0 and two_step_psnr > 30.0
    assert direct_psnr > two_step_psnr


def test_lens_tolerance_from_python_and_the_cli(tmp_path) -> None:
    # Direct sampling through local homographies (lens_tolerance_px, default 0.02 view pixels)
    # against the exact projection of every sample (0), on simulated fisheye and omnidirectional
    # frames: the sample positions differ by at most about the tolerance, so a bilinear sample
    # by at most the tolerance times the frame's largest neighbour steps (Gx + Gy); twice that
    # is allowed (the tolerance is checked at the quads' nodes), plus float rounding.
    for name, lens in (("fisheye", {"lens": "fisheye", "fov_deg": 180, "distortion": [0.01]}),
                       ("omnidir", {"lens": "omnidir", "fov_deg": 200, "xi": 1.2,
                                    "distortion": [-0.05, 0.01]})):
        scene = {"seed": 3, "ground": {"texture": {"type": "noise", "square": 1.0}},
                 "camera": {"width": 256, "height": 256, "bit_depth": 32, **lens},
                 "sampling": {"grid": 3, "aperture": {"diameter": 8.0}},
                 "truth": {"fov_deg": 60.0, "width": 160, "height": 160}}
        simulation = aos.simulate(scene, tmp_path / name)
        raw, truth = simulation.light_field, simulation.truth
        options = dict(cam_from_world=truth.cam_from_world, fov_deg=truth.camera.fov_x_deg(),
                       width=160, height=160)
        assert aos.IntegralOptions().lens_tolerance_px == 0.02
        fast = aos.render_integral(raw, **options)
        exact = aos.render_integral(raw, **options, lens_tolerance_px=0.0)
        np.testing.assert_array_equal(fast.count, exact.count)
        steps = max(float(np.abs(np.diff(v.image, axis=1)).max() + np.abs(np.diff(v.image, axis=0)).max())
                    for v in raw.views)
        difference = float(np.abs(fast.image - exact.image).max())
        assert 0.0 < difference <= 2 * 0.02 * steps + 1e-5, (name, difference, steps)
        ones = np.ones((160, 160), np.uint8)
        psnr = [aos.compare_images(r.image, truth.ground, ones, data_range=1.0).psnr_db
                for r in (fast, exact)]
        assert abs(psnr[0] - psnr[1]) < 0.05, (name, psnr)
        with pytest.raises(ValueError, match="lens_tolerance_px"):
            aos.render_integral(raw, **options, lens_tolerance_px=1.5)
    # The CLI's flag sets the same field: 0 renders, 1.5 is refused naming it.
    lightfield = str(tmp_path / "omnidir" / "lightfield.json")
    common = ["aos-render", "integral", lightfield, "--pose-view", "4", "--fov-deg", "60",
              "--width", "32", "--height", "32", "-q"]
    done = subprocess.run(common + ["--lens-tolerance-px", "0", "-o", str(tmp_path / "exact.tif")],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    done = subprocess.run(common + ["--lens-tolerance-px", "1.5", "-o", str(tmp_path / "bad.tif")],
                          capture_output=True, text=True)
    assert done.returncode != 0 and "lens_tolerance_px" in done.stderr, done.stderr


def test_cli_resolution_of_wide_lenses_is_sane() -> None:
    """A fisheye's field of view goes through its own radial map (180 degrees was refused with
    a pinhole message) and the back-projected sample size leaves out the pixels near the horizon
    (it printed 124 m)."""
    def resolution(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run(["aos-render", "resolution", "--width", "1024", "--height", "1024",
                               "--distance-m", "35", "--json", *args], capture_output=True,
                              text=True)

    for fov in ("170", "180"):
        done = resolution("--model", "fisheye", "--lens-fov-deg", fov)
        assert done.returncode == 0, done.stderr
        r = json.loads(done.stdout)
        # Equidistant: fx = (w / 2) / (fov / 2 in radians); at nadir p = d / fx.
        fx = 512.0 / math.radians(float(fov) / 2.0)
        assert abs(r["eq2_sample_size_m"] - 35.0 / fx) < 1e-9
        assert r["eq2_sample_size_m"] < r["sample_size_m"] < 3.0 * r["eq2_sample_size_m"]
        assert r["pixels_off_axis"] > 0
    # A 60-degree fisheye: every pixel within 60 degrees of the axis, none left out.
    r = json.loads(resolution("--model", "fisheye", "--lens-fov-deg", "60").stdout)
    assert r["pixels_off_axis"] == 0 and r["sample_size_m"] < 0.05
    refused = resolution("--lens-fov-deg", "180")
    assert refused.returncode == 2 and "pinhole lens's field of view" in refused.stderr


def test_rectify_checks_its_memory_before_allocating(tmp_path, monkeypatch) -> None:
    # A 2000 x 2000 frame decodes to 3.8 MiB, under a 20 MiB budget; the resampling maps (8 bytes
    # a rectified pixel: 31 MiB) and the rectified frames are not: refused from the headers,
    # naming the frame and the camera file, before anything is allocated or written.
    side = 2000
    camera = {"format": "aos-camera", "version": 1, "model": "fisheye", "width": side,
              "height": side, "fx": side / 3, "fy": side / 3, "cx": side / 2, "cy": side / 2,
              "distortion": [0, 0, 0, 0]}
    (tmp_path / "cam.json").write_text(json.dumps(camera))
    aos.write_image(str(tmp_path / "f0.png"), np.zeros((side, side), np.uint8))
    env = dict(os.environ, AOS_MEMORY_LIMIT_MB="20")
    done = subprocess.run(["aos-render", "rectify", str(tmp_path / "f0.png"), "--camera",
                           str(tmp_path / "cam.json"), "--rectified-fov-deg", "60", "-o",
                           str(tmp_path / "out")], capture_output=True, text=True, env=env)
    assert done.returncode == 1, done.stderr
    assert "f0.png" in done.stderr and "cam.json" in done.stderr, done.stderr
    assert "AOS_MEMORY_LIMIT_MB" in done.stderr and "2000x2000" in done.stderr, done.stderr
    assert not (tmp_path / "out").exists()
    # The library: the maps of make_rectifier, and rectify_light_field's new views.
    lens = aos.LensCamera(aos.LensModel.fisheye, side, side, side / 3, side / 3, side / 2,
                          side / 2, [0, 0, 0, 0])
    light_field = aos.LightField()
    light_field.add_view(np.zeros((side, side), np.uint8), lens, aos.Rigid3d(), name="f0.png")
    monkeypatch.setenv("AOS_MEMORY_LIMIT_MB", "20")
    with pytest.raises(ValueError, match=r"width/height: rectified frames of 2000x2000 pixels"):
        aos.make_rectifier(lens, aos.RectifyOptions(fov_deg=60))
    with pytest.raises(ValueError, match=r"rectify: 1 lens views: needs .* AOS_MEMORY_LIMIT_MB"):
        aos.rectify_light_field(light_field, fov_deg=60, width=1600, height=1600)
    monkeypatch.setenv("AOS_MEMORY_LIMIT_MB", "100")
    assert aos.rectify_light_field(light_field, fov_deg=60, width=200,
                                   height=200).rectified_views == 1
