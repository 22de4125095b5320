"""Quality metrics from Python, against an independent numpy implementation of the definitions
in docs/metrics.md (Gaussian-window SSIM of Wang et al. 2004)."""
import math

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
    # Measured here: integral 11.0 dB / SSIM 0.46, single view 9.1 dB / 0.25.
    assert a.psnr_db > s.psnr_db + 1.0
    assert a.ssim > s.ssim + 0.1
