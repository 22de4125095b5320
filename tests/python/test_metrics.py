"""Quality metrics from Python, against an independent numpy implementation of the definitions
in docs/metrics.md (Gaussian-window SSIM of Wang et al. 2004)."""
import json
import math
import os
import shutil
import signal
import struct
import subprocess
import time

import numpy as np
import pytest

import aos
from signal_util import wait_until_it_catches


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
                   focal_surface=aos.Plane.at_height(truth.ground_height_at_center))
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


def _metrics_cli(*args: str, env: dict | None = None, **kwargs) -> subprocess.Popen:
    exe = shutil.which("aos-render")
    if exe is None:
        pytest.skip("aos-render is not on PATH")
    return subprocess.Popen([exe, "metrics", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env, **kwargs)


def test_cli_metrics_checks_the_comparisons_memory_before_decoding(tmp_path) -> None:
    # Two 3000 x 3000 8-bit images decode to 8.6 MiB each, under a 12 MiB budget one at a time
    # (the readers' own check), not together with the SSIM's working planes: refused from the
    # headers, naming both files, instead of being allocated (or killed by the kernel).
    zeros = np.zeros((3000, 3000), np.uint8)
    aos.write_image(str(tmp_path / "a.png"), zeros)
    aos.write_image(str(tmp_path / "b.png"), zeros)
    env = dict(os.environ, AOS_MEMORY_LIMIT_MB="12")
    done = _metrics_cli(str(tmp_path / "a.png"), str(tmp_path / "b.png"), env=env)
    out, err = done.communicate(timeout=60)
    assert done.returncode == 1, err
    assert out == ""
    assert f"{tmp_path / 'a.png'} against {tmp_path / 'b.png'}: images of 3000x3000x1" in err
    assert "AOS_MEMORY_LIMIT_MB" in err and len(err.strip().splitlines()) == 1
    env["AOS_MEMORY_LIMIT_MB"] = "40"
    done = _metrics_cli(str(tmp_path / "a.png"), str(tmp_path / "b.png"), env=env)
    out, err = done.communicate(timeout=60)
    assert done.returncode == 0 and "PSNR inf" in out, err


def _raw_tiff(path, image: np.ndarray) -> None:
    """An uncompressed 8-bit grey TIFF in one strip (fast to write, unlike a compressed one)."""
    height, width = image.shape
    entries = [(256, 4, width), (257, 4, height), (258, 3, 8), (259, 3, 1), (262, 3, 1),
               (273, 4, 0), (277, 3, 1), (278, 4, height), (279, 4, width * height)]
    data_offset = 8 + 2 + 12 * len(entries) + 4
    body = struct.pack("<H", len(entries))
    for tag, kind, value in entries:
        value = data_offset if tag == 273 else value
        packed = struct.pack("<I", value) if kind == 4 else struct.pack("<HH", value, 0)
        body += struct.pack("<HHI", tag, kind, 1) + packed
    body += struct.pack("<I", 0)
    with open(path, "wb") as file:
        file.write(b"II*\x00" + struct.pack("<I", 8) + body)
        file.write(np.ascontiguousarray(image, np.uint8).tobytes())


def test_cli_metrics_stops_on_sigterm(tmp_path) -> None:
    # 8000 x 8000 random images take seconds to compare; SIGTERM half a second into the work
    # must stop the comparison within 2 s with the interrupted exit code and no result.
    rng = np.random.default_rng(8)
    image = rng.integers(0, 256, (8000, 8000), dtype=np.uint8)
    _raw_tiff(tmp_path / "a.tif", image)
    _raw_tiff(tmp_path / "b.tif", image // 2)
    assert aos.read_image(str(tmp_path / "b.tif"))[17, 4000] == image[17, 4000] // 2
    done = _metrics_cli(str(tmp_path / "a.tif"), str(tmp_path / "b.tif"))
    wait_until_it_catches(done.pid)
    time.sleep(0.5)
    done.send_signal(signal.SIGTERM)
    start = time.monotonic()
    try:
        out, err = done.communicate(timeout=2.0)
    finally:
        done.kill()
    assert time.monotonic() - start < 2.0
    assert done.returncode == 143, err   # 128 + SIGTERM
    assert "PSNR" not in out and "interrupted" in err


def test_compare_images_polls_progress_and_checks_memory(monkeypatch) -> None:
    image = (np.arange(300 * 2000) % 251).astype(np.uint8).reshape(300, 2000)
    calls = []

    def stop(stage: str, done: int, total: int) -> None:
        calls.append((stage, done, total))
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        aos.compare_images(image, image, progress=stop)
    assert calls and calls[0][0] == "metrics"
    reports = []
    assert aos.compare_images(image, image, progress=lambda *a: reports.append(a)).ssim == 1.0
    assert reports[-1][1] == reports[-1][2] > 1
    monkeypatch.setenv("AOS_MEMORY_LIMIT_MB", "1")
    with pytest.raises(ValueError, match=r"compare: images of 2000x300x1 pixels: needs .*"
                                         r"AOS_MEMORY_LIMIT_MB"):
        aos.compare_images(image, image)
