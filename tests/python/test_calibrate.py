"""Lens calibration from Python (aos.calibrate) and camera files: checkerboard frames rendered
with numpy through a known LensCamera, fitted back."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import aos

COLUMNS, ROWS, SQUARE = 9, 6, 0.025  # CalibrateOptions' defaults: 9 x 6 inner corners, 25 mm


def _truth() -> aos.LensCamera:
    # About 56 degrees across 320 pixels, barrel distortion of a typical small lens.
    return aos.LensCamera(aos.LensModel.radtan, 320, 240, 300.0, 298.0, 161.5, 118.5,
                          distortion=[-0.15, 0.05, 0.001, -0.0005, 0.0])


def _rotation(ax_deg: float, ay_deg: float) -> np.ndarray:
    a, b = math.radians(ax_deg), math.radians(ay_deg)
    rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    return ry @ rx


def _pixel_rays(lens: aos.LensCamera, samples: int) -> np.ndarray:
    """Unit rays (H * samples * W * samples, 3) through a samples x samples grid in each pixel,
    row by row of the supersampled grid."""
    offsets = (np.arange(samples) + 0.5) / samples
    u = (np.arange(lens.width)[:, None] + offsets[None, :]).ravel()
    v = (np.arange(lens.height)[:, None] + offsets[None, :]).ravel()
    return lens.unproject_pixels(np.stack(np.meshgrid(u, v), axis=-1).reshape(-1, 2))


def _board_frame(lens: aos.LensCamera, rays: np.ndarray, samples: int, rotation: np.ndarray,
                 translation: np.ndarray) -> np.ndarray:
    """The board (inner corners at (c, r) * SQUARE, a white margin of one square) on grey, seen
    through `lens` (its `rays` from _pixel_rays) with the board frame at cam_from_board =
    (rotation, translation); the samples averaged to uint8."""
    normal = rotation[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = (normal @ translation) / (rays @ normal)
        points = (depth[:, None] * rays - translation) @ rotation  # board_from_cam, row vectors
    bu, bv = points[:, 0] / SQUARE, points[:, 1] / SQUARE
    value = np.full(len(rays), 128.0)
    on_board = (depth > 0) & (bu >= -2) & (bu < COLUMNS + 1) & (bv >= -2) & (bv < ROWS + 1)
    value[on_board] = 255.0
    squares = on_board & (bu >= -1) & (bu < COLUMNS) & (bv >= -1) & (bv < ROWS)
    black = (np.floor(bu[squares]) + np.floor(bv[squares])) % 2 == 0
    value[np.flatnonzero(squares)[black]] = 0.0
    value = value.reshape(lens.height, samples, lens.width, samples).mean(axis=(1, 3))
    return np.round(value).astype(np.uint8)


def _board_frames(lens: aos.LensCamera, distance: float = 0.3,
                  samples: int = 3) -> list[np.ndarray]:
    rays = _pixel_rays(lens, samples)
    angles = [(0, 0), (25, 0), (-25, 0), (0, 25), (0, -25), (20, 20), (-20, 15), (15, -20)]
    centre_in_board = np.array([0.5 * (COLUMNS - 1) * SQUARE, 0.5 * (ROWS - 1) * SQUARE, 0.0])
    frames = []
    for index, (ax, ay) in enumerate(angles):
        rotation = _rotation(ax, ay)
        translation = (np.array([0.01 * (index % 3 - 1), 0.008 * (index % 2), distance])
                       - rotation @ centre_in_board)
        frames.append(_board_frame(lens, rays, samples, rotation, translation))
    return frames


@pytest.fixture(scope="module")
def frames() -> list[np.ndarray]:
    return _board_frames(_truth())


def test_calibrate_recovers_a_radtan_lens_from_arrays(frames: list[np.ndarray]) -> None:
    truth = _truth()
    # Any dtype the Image binding takes: uint8 (H, W), (H, W, 3), uint16 and float32.
    mixed = list(frames)
    mixed[1] = frames[1].astype(np.float32) / 255.0
    mixed[2] = frames[2].astype(np.uint16) * 257
    mixed[3] = np.repeat(frames[3][:, :, None], 3, axis=2)
    mixed.append(np.zeros_like(frames[0]))  # no board
    stages = []
    result = aos.calibrate(mixed, progress=lambda stage, done, total: stages.append(stage))
    assert isinstance(result, aos.CalibrationResult)
    assert result.frames_used == [f"frame_{i:04d}" for i in range(8)]
    assert result.frames_rejected == ["frame_0008"]
    assert "find corners" in stages
    # Corners exact up to the 3 x 3 supersampled rendering and 8-bit grey (measured: 0.14 px; 0.10
    # with 4 x 4 samples, as in the C++ tests); 8 boards at +-25 degrees pin fx down to a fraction
    # of a percent (measured: 0.3 %).
    assert result.rms_px < 0.2
    camera = result.camera
    assert camera.model == aos.LensModel.radtan
    assert (camera.width, camera.height) == (320, 240)
    assert camera.fx == pytest.approx(truth.fx, rel=0.01)
    assert camera.fy == pytest.approx(truth.fy, rel=0.01)
    assert camera.cx == pytest.approx(truth.cx, abs=1.0)
    assert camera.cy == pytest.approx(truth.cy, abs=1.0)
    # The mapping where the boards were seen (their corners span about 55..280 x 48..200 px). A
    # small frame seen by 8 boards fixes its principal point only to a few tenths of a pixel
    # (measured: 0.17 and 0.30 px off; 0.73 px at worst over this grid, 0.40 on average), so this is
    # a check of the conventions, not of OpenCV's accuracy (the C++ tests hold that to 0.5 px).
    u, v = np.meshgrid(np.arange(60.0, 280.0, 10.0), np.arange(50.0, 200.0, 10.0))
    pixels = np.stack([u.ravel(), v.ravel()], axis=1)
    for pixel, ray in zip(pixels, truth.unproject_pixels(pixels)):
        assert np.linalg.norm(camera.project(ray) - pixel) < 1.0, pixel
    assert "radtan" in repr(result) and "frames_used=8" in repr(result)


def test_calibrate_reads_paths_and_takes_options(frames: list[np.ndarray], tmp_path) -> None:
    paths = []
    for index, frame in enumerate(frames[:5]):
        paths.append(tmp_path / f"board_{index}.png")
        aos.write_image(paths[-1], frame)
    options = aos.CalibrateOptions(model=aos.LensModel.pinhole)
    result = aos.calibrate([str(paths[0])] + paths[1:], options=options, square_size_m=SQUARE)
    assert result.frames_used == [str(path) for path in paths]  # names default to the paths
    assert result.camera.model == aos.LensModel.pinhole
    assert result.camera.distortion == []  # a pinhole has none
    # A pinhole fit of a barrel-distorted lens: the residual is the distortion, pixels.
    assert result.rms_px > 0.2
    named = aos.calibrate(frames[:4], names=["a", "b", "c", "d"], model="fisheye")
    assert named.frames_used == ["a", "b", "c", "d"]
    assert named.camera.model == aos.LensModel.fisheye
    assert options.model == aos.LensModel.pinhole and options.square_size_m == SQUARE  # not changed


def test_calibrate_errors_name_the_option_or_the_frame(frames: list[np.ndarray]) -> None:
    with pytest.raises(ValueError, match="pattern_columns"):
        aos.calibrate(frames[:3], pattern_columns=1)
    with pytest.raises(ValueError, match="pattern_rows"):
        aos.calibrate(frames[:3], pattern_rows=0)
    with pytest.raises(ValueError, match="square_size_m"):
        aos.calibrate(frames[:3], square_size_m=0.0)
    with pytest.raises(ValueError, match="square_size_m"):
        aos.calibrate(frames[:3], square_size_m=math.nan)
    with pytest.raises(ValueError, match="model: unknown lens model 'kannala'"):
        aos.calibrate(frames[:3], model="kannala")
    with pytest.raises(TypeError, match="pattern_cols"):
        aos.calibrate(frames[:3], pattern_cols=9)
    with pytest.raises(ValueError, match="frame_0002: is 160x120, the first frame 320x240"):
        aos.calibrate([frames[0], frames[1], frames[2][::2, ::2]])
    with pytest.raises(ValueError, match="frame_0001: unsupported dtype int16"):
        aos.calibrate([frames[0], frames[1].astype(np.int16)])
    with pytest.raises(ValueError, match="missing.png: image file not found"):
        aos.calibrate([frames[0], "missing.png"])
    with pytest.raises(ValueError, match="names"):
        aos.calibrate(frames[:3], names=["a", "b"])
    with pytest.raises(ValueError, match="frames: none given"):
        aos.calibrate([])
    with pytest.raises(ValueError, match=r"found in 0 frames; at least 3 are needed \(not found "
                                         r"in: frame_0000, frame_0001, frame_0002\)"):
        aos.calibrate([np.zeros((240, 320), np.uint8)] * 3)


def test_camera_file_round_trip(frames: list[np.ndarray], tmp_path) -> None:
    options = aos.CalibrateOptions(pattern_columns=COLUMNS, pattern_rows=ROWS, square_size_m=SQUARE)
    result = aos.calibrate(frames[:6] + [np.zeros_like(frames[0])], options=options)
    path = tmp_path / "camera.json"
    aos.write_camera_file(path, result.camera, result, options)
    camera = aos.read_camera_file(path)
    for field in ("model", "width", "height", "fx", "fy", "cx", "cy", "xi", "skew"):
        assert getattr(camera, field) == getattr(result.camera, field), field
    assert list(camera.distortion) == list(result.camera.distortion)
    # The record `aos-render calibrate` writes.
    record = json.loads(path.read_text())["calibration"]
    assert record == {"rms_px": result.rms_px, "frames_used": result.frames_used,
                      "frames_rejected": ["frame_0006"], "pattern": "9x6",
                      "square_size_m": SQUARE}
    # A free-form record, or none; an omnidir lens keeps xi and skew.
    omni = aos.LensCamera(aos.LensModel.omnidir, 640, 480, 360.0, 358.0, 322.5, 238.5,
                          distortion=[-0.06, 0.01, 0.0006, -0.0004], xi=1.0, skew=0.1)
    aos.write_camera_file(str(tmp_path / "omni.json"), omni, {"note": "by hand"})
    assert json.loads((tmp_path / "omni.json").read_text())["calibration"] == {"note": "by hand"}
    back = aos.read_camera_file(str(tmp_path / "omni.json"))
    assert (back.model, back.xi, back.skew) == (aos.LensModel.omnidir, 1.0, 0.1)
    aos.write_camera_file(tmp_path / "plain.json", omni)
    assert "calibration" not in json.loads((tmp_path / "plain.json").read_text())
    with pytest.raises(ValueError, match="version: must be 1"):
        (tmp_path / "bad.json").write_text(json.dumps(
            dict(json.loads((tmp_path / "plain.json").read_text()), version=2)))
        aos.read_camera_file(tmp_path / "bad.json")
    bad = aos.LensCamera(aos.LensModel.radtan, 320, 240, 300.0, 300.0, 160.0, 120.0)
    bad.fx = -1.0
    with pytest.raises(ValueError, match="fx/fy"):
        aos.write_camera_file(tmp_path / "neg.json", bad)
    with pytest.raises(ValueError, match="JSON"):
        aos.write_camera_file(tmp_path / "nan.json", omni, {"rms_px": math.nan})
    with pytest.raises(TypeError, match="calibration must be"):
        aos.write_camera_file(tmp_path / "x.json", omni, "rms 0.1")  # type: ignore[arg-type]
