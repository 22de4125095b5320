"""Quality metrics from Python, against an independent numpy implementation of the definitions
in docs/metrics.md (Gaussian-window SSIM of Wang et al. 2004)."""
import json
import math
import shutil
import subprocess

import numpy as np
import pytest

import aos


def _gaussian_filter(image: np.ndarray, sigma: float = 1.5, radius: int = 5) -> np.ndarray:
    """Separable Gaussian filter, valid region only (the window inside the image)."""
    offsets = np.arange(-radius, radius + 1)
    kernel = np.exp(-0.5 * (offsets / sigma) ** 2)
    kernel /= kernel.sum()
    rows = sum(k * image[:, radius + o: image.shape[1] - radius + o] for k, o in zip(kernel, offsets))
    return sum(k * rows[radius + o: rows.shape[0] - radius + o, :] for k, o in zip(kernel, offsets))


def _reference_ssim(a: np.ndarray, b: np.ndarray, data_range: float) -> float:
    a, b = a.astype(np.float64), b.astype(np.float64)
    c1, c2 = (0.01 * data_range) ** 2, (0.03 * data_range) ** 2
    mu_a, mu_b = _gaussian_filter(a), _gaussian_filter(b)
    var_a = _gaussian_filter(a * a) - mu_a ** 2
    var_b = _gaussian_filter(b * b) - mu_b ** 2
    cov = _gaussian_filter(a * b) - mu_a * mu_b
    ssim_map = ((2 * mu_a * mu_b + c1) * (2 * cov + c2)) / ((mu_a ** 2 + mu_b ** 2 + c1) * (var_a + var_b + c2))
    return float(ssim_map.mean())


def test_matches_an_independent_ssim_and_psnr():
    rng = np.random.default_rng(3)
    reference = rng.integers(0, 256, (48, 64)).astype(np.uint8)
    test = np.clip(reference.astype(int) + rng.integers(-20, 21, reference.shape), 0, 255).astype(np.uint8)
    result = aos.compare_images(test, reference)
    mse = float(np.mean((test.astype(float) - reference) ** 2))
    assert result.mse == pytest.approx(mse, rel=1e-12)
    assert result.psnr_db == pytest.approx(10 * math.log10(255 ** 2 / mse), rel=1e-12)
    assert result.ssim == pytest.approx(_reference_ssim(test, reference, 255.0), abs=1e-9)
    assert result.color_ssim == result.ssim
    assert result.ssim_pixels == (48 - 10) * (64 - 10)


def test_options_by_keyword_and_masks():
    image = np.linspace(0, 1, 40 * 30, dtype=np.float32).reshape(30, 40)
    assert aos.compare_images(image, image).data_range == 1.0
    assert aos.compare_images(image, image, data_range=2.0).data_range == 2.0
    with pytest.raises(TypeError):
        aos.compare_images(image, image, sigma=2.0)
    with pytest.raises(ValueError, match="window_radius"):
        aos.compare_images(image, image, window_radius=0)
    broken = image.copy()
    broken[:, 0] = 5.0
    mask = np.ones(image.shape, np.uint32)
    mask[:, 0] = 0
    assert aos.compare_images(broken, image, mask=mask).mse == 0.0
    assert aos.compare_images(broken, image).mse > 0.0


def test_integral_of_the_default_scene_beats_a_single_view():
    """The point of AOS: against the occluder-free ground truth, the integral focused on the
    ground is better than a single occluded view (PSNR and SSIM)."""
    scene = aos.default_scene()
    result = aos.simulate(scene)
    truth = result.truth
    options = dict(cam_from_world=truth.cam_from_world, fov_deg=truth.camera.fov_x_deg(),
                   width=truth.camera.width, height=truth.camera.height,
                   focal_plane=aos.Plane.at_height(truth.ground_height_at_center))
    integral = aos.render_integral(result.light_field, **options).image
    single = aos.render_integral(result.light_field, aperture_radius=0.0, **options).image
    a = aos.compare_images(integral, truth.ground)
    s = aos.compare_images(single, truth.ground)
    # Measured here (the forest scene, RGB): integral 23.1 dB / SSIM 0.95, single view 19.7 dB /
    # 0.74.
    assert a.psnr_db > s.psnr_db + 1.0
    assert a.ssim > s.ssim + 0.1


def test_mismatched_sample_types_are_normalised_or_refused(tmp_path) -> None:
    """8-bit against a 16-bit truth is compared by each type's range (it compared raw codes)."""
    rng = np.random.default_rng(3)
    truth16 = rng.integers(0, 65536, (48, 64)).astype(np.uint16)
    test8 = np.clip(np.round(truth16 / 257.0) + rng.normal(0, 4, truth16.shape), 0, 255)
    test8 = test8.astype(np.uint8)
    same_scale = aos.compare_images(test8.astype(np.uint16) * np.uint16(257), truth16)
    mixed = aos.compare_images(test8, truth16)
    assert mixed.test_scale == 257.0 and "scaled by 257" in mixed.note
    assert mixed.data_range == 65535.0
    assert abs(mixed.psnr_db - same_scale.psnr_db) < 1e-9 and mixed.psnr_db > 30.0
    assert aos.compare_images(truth16, truth16).note == ""
    # A float render in the views' units against an 8-bit truth: compared in 8-bit units.
    render = test8.astype(np.float32)
    truth8 = np.round(truth16 / 257.0).astype(np.uint8)
    result = aos.compare_images(render, truth8)
    assert result.data_range == 255.0 and "units of the uint8" in result.note
    assert abs(result.psnr_db - aos.compare_images(test8, truth8).psnr_db) < 1e-9
    # A float image normalised to [0, 1] against an 8-bit truth is refused, not scored.
    with pytest.raises(ValueError, match="looks normalised"):
        aos.compare_images(render / 255.0, truth8)
    # The CLI says what it did.
    aos.write_image(str(tmp_path / "test.png"), test8)
    aos.write_image(str(tmp_path / "truth.png"), truth16)
    exe = shutil.which("aos-render")
    if exe:
        done = subprocess.run([exe, "metrics", str(tmp_path / "test.png"),
                               str(tmp_path / "truth.png"), "--json"], capture_output=True,
                              text=True)
        assert done.returncode == 0, done.stderr
        assert "scaled by 257" in done.stderr
        assert abs(json.loads(done.stdout)["psnr_db"] - same_scale.psnr_db) < 1e-6
