"""Radiometric thermal frames: FLIR radiometric JPEGs to temperatures (through ExifTool), 16-bit
counts with a linear calibration, the unit recorded in the light field, and grey imports."""

from __future__ import annotations

import copy
import json
import pickle
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

import aos
from flir_util import CALIBRATION, ZERO_C, kelvin_of_raw, stored, write_flir_jpeg

pytestmark = pytest.mark.skipif(shutil.which("exiftool") is None,
                                reason="exiftool (libimage-exiftool-perl) is not installed")

HEADER = "frame,lat,lon,alt,yaw,pitch,roll\n"
HEIGHT, WIDTH = 48, 64


def scene_celsius(seed: int) -> np.ndarray:
    """Ground from 5 to 25 C with a warm 36.5 C person-sized patch."""
    rng = np.random.default_rng(seed)
    celsius = 5.0 + 20.0 * rng.random((HEIGHT, WIDTH))
    celsius[20:26, 30:34] = 36.5
    return celsius


def flight(folder: Path, names: list[str]) -> Path:
    rows = [f"{name},{48.0 + 1e-4 * i:.10f},15.0,{100.0:.4f},0,-90,0\n"
            for i, name in enumerate(names)]
    csv = folder / "log.csv"
    csv.write_text(HEADER + "".join(rows))
    return csv


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["aos-render", *args], capture_output=True, text=True, timeout=120)


def test_flir_jpegs_become_known_temperatures(tmp_path: Path) -> None:
    """Counts made from known temperatures with FLIR's model come back as those temperatures.
    Tolerances from the maths: a count is rounded to an integer (half a count is 0.5 / (dW/dT)
    kelvin, about 0.004 K here) and the temperature frame to 0.01 K (0.005 K); against the exact
    inverse of the written counts only the second remains."""
    frames = tmp_path / "frames"
    frames.mkdir()
    names = ["1.jpg", "2.jpg", "10.jpg"]
    truth, counts = {}, {}
    for i, name in enumerate(names):
        truth[name] = scene_celsius(i)
        # PNG raw data (FLIR's usual, bytes swapped) and raw TIFF data, both read.
        counts[name] = write_flir_jpeg(frames / name, truth[name], png=(i != 1))
    csv = flight(tmp_path, names)
    out = tmp_path / "kelvin"
    result = aos.import_telemetry(frames, telemetry_file=str(csv), fov_deg=40.0,
                                  radiometric="flir", temperature_frames_dir=str(out))
    lf = result.light_field
    assert lf.radiometry == aos.Radiometry(0.01, 0.0)
    assert result.radiometric == "flir"
    assert [v.name for v in lf.views] == names  # natural order, names kept
    assert sorted(p.name for p in out.iterdir()) == ["1.png", "10.png", "2.png"]
    c = stored(CALIBRATION)
    for view in lf.views:
        values = aos.read_image(view.image_path)
        assert values.dtype == np.uint16 and values.shape == (HEIGHT, WIDTH)
        celsius = lf.radiometry.celsius(values)
        exact = kelvin_of_raw(counts[view.name], c) - ZERO_C
        assert np.abs(celsius - exact).max() <= 0.005 + 1e-9
        assert np.abs(celsius - truth[view.name]).max() <= 0.005 + 0.005
    assert result.first_frame_median_c == pytest.approx(np.median(truth["1.jpg"]), abs=0.3)
    # The light field file records the unit; a render of it is read with the same map.
    path = tmp_path / "lf.json"
    aos.write_lightfield(str(path), lf)
    assert json.loads(path.read_text())["radiometry"] == {"kelvin_per_unit": 0.01,
                                                          "kelvin_offset": 0.0}
    loaded = aos.load_lightfield(str(path)).light_field
    assert loaded.radiometry == lf.radiometry
    assert loaded.views[0].image.shape == (HEIGHT, WIDTH)


def test_window_emissivity_humidity_and_byte_order_are_modelled(tmp_path: Path) -> None:
    """A camera behind an IR window (transmission 0.8 at 30 C), an object of emissivity 0.7 at
    80 m in humid warm air: the same independent model's counts come back as the temperatures;
    and a PNG stored in its own byte order (not FLIR's swapped one) is recognised by its
    smoothness, with a warning, not read as noise."""
    frames = tmp_path / "frames"
    frames.mkdir()
    window = dict(CALIBRATION, window_transmission=0.8, window_c=30.0, emissivity=0.7,
                  distance_m=80.0, humidity=0.9, air_c=28.0)
    truth = {"w.jpg": scene_celsius(5), "plain.jpg": scene_celsius(6)}
    counts = {"w.jpg": write_flir_jpeg(frames / "w.jpg", truth["w.jpg"], calibration=window),
              "plain.jpg": write_flir_jpeg(frames / "plain.jpg", truth["plain.jpg"],
                                           swap_png=False)}
    csv = flight(tmp_path, list(truth))
    result = aos.import_telemetry(frames, telemetry_file=str(csv), fov_deg=40.0,
                                  radiometric="flir", temperature_frames_dir=str(tmp_path / "k"))
    assert any("plain.jpg: RawThermalImage (PNG): read in the file's byte order" in w
               for w in result.warnings), result.warnings
    assert not any("w.jpg" in w for w in result.warnings)
    for view in result.light_field.views:
        celsius = result.light_field.radiometry.celsius(aos.read_image(view.image_path))
        calibration = window if view.name == "w.jpg" else CALIBRATION
        exact = kelvin_of_raw(counts[view.name], stored(calibration)) - ZERO_C
        assert np.abs(celsius - exact).max() <= 0.005 + 1e-9, view.name
        # Half a count is more kelvin through a window and a low emissivity: 0.02 K here.
        assert np.abs(celsius - truth[view.name]).max() <= 0.005 + 0.02, view.name


def test_cli_flir_import_reports_temperatures_and_bad_files_write_nothing(tmp_path: Path) -> None:
    frames = tmp_path / "frames"
    frames.mkdir()
    names = ["a.jpg", "b.jpg"]
    for i, name in enumerate(names):
        write_flir_jpeg(frames / name, scene_celsius(i))
    csv = flight(tmp_path, names)
    out, kelvin = tmp_path / "lf.json", tmp_path / "kelvin"
    done = run("import-telemetry", str(frames), "-o", str(out), "--telemetry-file", str(csv),
               "--frames-fov-deg", "40", "--radiometric", "flir", "--temperature-frames-dir",
               str(kelvin))
    assert done.returncode == 0, done.stderr
    assert "temperatures: FLIR radiometric frames converted" in done.stdout
    assert "kelvin = 0.01 * value + 0" in done.stdout
    assert json.loads(out.read_text())["radiometry"]["kelvin_per_unit"] == 0.01
    # A render states its temperatures; metrics against a temperature frame give RMSE in kelvin.
    render = tmp_path / "render.tif"
    done = run("integral", str(out), "--pose-view", "0", "--focal-surface", "0", "-o",
               str(render), "--json")
    assert done.returncode == 0, done.stderr
    low, median, high = json.loads(done.stdout)["temperature_c"]
    assert 5.0 <= low < median < high <= 36.5
    done = run("metrics", str(render), str(kelvin / "a.png"), "--json")
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["rmse_k"] == pytest.approx(0.01 * report["mse"] ** 0.5)
    # The map's GeoTIFF says how its value band reads as temperature.
    rasterio = pytest.importorskip("rasterio")
    done = run("map", str(out), "--pixel-size", "1", "--focal-height", "0", "-o",
               str(tmp_path / "map.tif"))
    assert done.returncode == 0, done.stderr
    with rasterio.open(tmp_path / "map.tif") as dataset:
        assert dataset.tags()["AOS_TEMPERATURE"] == "kelvin = 0.01 * value + 0"
        assert dataset.descriptions[0] == "value (kelvin = 0.01 * value + 0)"

    # A plain JPEG among them: one error naming the file and the tag; nothing written.
    aos.write_image(str(frames / "c.jpg"), np.zeros((HEIGHT, WIDTH, 3), np.uint8))
    csv = flight(tmp_path, names + ["c.jpg"])
    out2, kelvin2 = tmp_path / "lf2.json", tmp_path / "kelvin2"
    done = run("import-telemetry", str(frames), "-o", str(out2), "--telemetry-file", str(csv),
               "--frames-fov-deg", "40", "--radiometric", "flir", "--temperature-frames-dir",
               str(kelvin2))
    assert done.returncode != 0
    assert "c.jpg" in done.stderr and "PlanckR1" in done.stderr, done.stderr
    assert not out2.exists() and not kelvin2.exists()
    assert [p for p in tmp_path.iterdir() if p.name.startswith(".kelvin2")] == []

    # The options belong together.
    done = run("import-telemetry", str(frames), "-o", str(out2), "--telemetry-file", str(csv),
               "--frames-fov-deg", "40", "--radiometric", "flir")
    assert done.returncode != 0 and "temperature_frames_dir" in done.stderr


def test_implausible_calibration_is_refused_naming_the_file(tmp_path: Path) -> None:
    """Counts that no byte order turns into a plausible temperature (-100..200 C) are refused."""
    frames = tmp_path / "frames"
    frames.mkdir()
    write_flir_jpeg(frames / "x.jpg", scene_celsius(0))
    # The stored PlanckR1 made 1000 times larger: the counts no longer fit the constants
    # (the scene would be at about -150 C).
    data = (frames / "x.jpg").read_bytes()
    old = struct.pack("<f", np.float32(CALIBRATION["R1"]))
    assert data.count(old) == 1
    (frames / "x.jpg").write_bytes(
        data.replace(old, struct.pack("<f", np.float32(CALIBRATION["R1"] * 1000))))
    csv = flight(tmp_path, ["x.jpg"])
    with pytest.raises(ValueError, match=r"x\.jpg: RawThermalImage: .*plausible"):
        aos.import_telemetry(frames, telemetry_file=str(csv), fov_deg=40.0, radiometric="flir",
                             temperature_frames_dir=str(tmp_path / "k"))
    assert not (tmp_path / "k").exists()


def test_linear_counts_record_their_calibration_and_are_checked(tmp_path: Path) -> None:
    frames = tmp_path / "frames"
    frames.mkdir()
    celsius = scene_celsius(3)
    counts = np.rint((celsius + ZERO_C) / 0.04).astype(np.uint16)  # FLIR TLinear, 0.04 K
    for name in ["1.png", "2.png"]:
        aos.write_image(str(frames / name), counts)
    csv = flight(tmp_path, ["1.png", "2.png"])
    result = aos.import_telemetry(frames, telemetry_file=str(csv), fov_deg=40.0,
                                  radiometric="linear", kelvin_per_count=0.04)
    radiometry = result.light_field.radiometry
    assert radiometry == aos.Radiometry(0.04, 0.0)
    assert np.abs(radiometry.celsius(counts) - celsius).max() <= 0.02 + 1e-9
    assert result.first_frame_median_c == pytest.approx(np.median(celsius), abs=0.05)
    assert radiometry.value_of_celsius(36.5) == pytest.approx((36.5 + ZERO_C) / 0.04)
    # A wrong calibration (centikelvin read as 0.4 K): the scene would be at ~3000 C.
    with pytest.raises(ValueError, match="kelvin_per_count, kelvin_offset: .*median"):
        aos.import_telemetry(frames, telemetry_file=str(csv), fov_deg=40.0,
                             radiometric="linear", kelvin_per_count=0.4)
    with pytest.raises(ValueError, match="kelvin_per_count: radiometric 'linear' needs"):
        aos.import_telemetry(frames, telemetry_file=str(csv), fov_deg=40.0, radiometric="linear")
    with pytest.raises(ValueError, match="kelvin_per_count: applies to radiometric 'linear'"):
        aos.import_telemetry(frames, telemetry_file=str(csv), fov_deg=40.0, kelvin_per_count=0.04)
    # 8-bit frames are not counts.
    eight = tmp_path / "eight"
    eight.mkdir()
    for name in ["1.png", "2.png"]:
        aos.write_image(str(eight / name), np.zeros((HEIGHT, WIDTH), np.uint8))
    with pytest.raises(ValueError, match=r"1\.png: radiometric 'linear' reads 16-bit"):
        aos.import_telemetry(eight, telemetry_file=str(csv), fov_deg=40.0,
                             radiometric="linear", kelvin_per_count=0.04)


def test_radiometry_survives_copy_and_pickle_and_is_checked(tmp_path: Path,
                                                           make_lightfield) -> None:
    """(Rectify, files and the other fields: test_python_api.py's field survival test.)"""
    lf = make_lightfield()
    assert lf.radiometry is None and lf.grey is False
    with pytest.raises(ValueError, match="kelvin_per_unit"):
        aos.Radiometry(0.0)
    grey_lf = lf
    grey_lf.radiometry = aos.Radiometry(0.01, 1.5)
    grey_lf.grey = True
    for other in (copy.copy(grey_lf), copy.deepcopy(grey_lf), pickle.loads(pickle.dumps(grey_lf))):
        assert other.radiometry == aos.Radiometry(0.01, 1.5) and other.grey
    assert "radiometry='kelvin = 0.01 * value + 1.5'" in repr(grey_lf)
    assert pickle.loads(pickle.dumps(aos.Radiometry(0.04, 2.0))) == aos.Radiometry(0.04, 2.0)
    # Temperatures are one channel: a radiometry on RGB views is refused, naming the view.
    rgb = make_lightfield(channels=3)
    with pytest.raises(ValueError, match="radiometry: temperature frames have one channel"):
        rgb.radiometry = aos.Radiometry(0.01, 0.0)
    assert rgb.radiometry is None


def test_grey_import_is_recorded_and_applied_at_every_load(tmp_path: Path) -> None:
    frames = tmp_path / "frames"
    frames.mkdir()
    rgb = np.zeros((HEIGHT, WIDTH, 3), np.uint8)
    rgb[..., 0] = 200
    for name in ["1.png", "2.png"]:
        aos.write_image(str(frames / name), rgb)
    csv = flight(tmp_path, ["1.png", "2.png"])
    out = tmp_path / "lf.json"
    done = run("import-telemetry", str(frames), "-o", str(out), "--telemetry-file", str(csv),
               "--frames-fov-deg", "40", "--grey")
    assert done.returncode == 0, done.stderr
    assert "integrated as grey" in done.stdout
    assert json.loads(out.read_text())["grey"] is True
    lf = aos.load_lightfield(str(out)).light_field
    assert lf.grey and lf.views[0].image.shape == (HEIGHT, WIDTH)
    assert int(lf.views[0].image[0, 0]) == round(0.299 * 200)
    # Written again, it stays grey.
    again = tmp_path / "again.json"
    aos.write_lightfield(str(again), lf)
    assert json.loads(again.read_text())["grey"] is True
    with pytest.raises(ValueError, match="grey: radiometric frames have one channel"):
        aos.import_telemetry(frames, telemetry_file=str(csv), fov_deg=40.0, grey=True,
                             radiometric="linear", kelvin_per_count=0.01)
