"""import-telemetry (CLI) and aos.import_telemetry: a flight's CSV log becomes a geo-referenced
light field; positions checked against rasterio's own transform (GDAL/PROJ, independent of
aos), the heading convention, the altitude-outlier report and bad input; LightField.crs."""

from __future__ import annotations

import json
import pickle
import subprocess
from pathlib import Path

import numpy as np
import pytest
from rasterio.warp import transform as rasterio_transform

import aos

HEADER = "frame,lat,lon,alt,yaw,pitch,roll\n"


def write_frames(folder: Path, count: int) -> list[str]:
    folder.mkdir()
    names = [f"f{i:02d}.png" for i in range(count)]
    for name in names:
        aos.write_image(str(folder / name), np.zeros((6, 8), np.uint8))
    return names


def flight_csv(names: list[str], altitudes: list[float]) -> str:
    """Nadir views on zone 33's central meridian (15 E: grid north is true north), 0.0001
    degrees of latitude apart, yaw 0 (image up at north)."""
    rows = [f"{name},{48.0 + 1e-4 * i:.10f},15.0,{altitudes[i]:.4f},0,-90,0\n"
            for i, name in enumerate(names)]
    return HEADER + "".join(rows)


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["aos-render", *args], capture_output=True, text=True, timeout=120)


def test_cli_flight_lands_where_proj_says(tmp_path: Path) -> None:
    names = write_frames(tmp_path / "frames", 6)
    log = tmp_path / "log.csv"
    log.write_text(flight_csv(names, [120.0] * 6))
    out = tmp_path / "lf.json"
    done = run("import-telemetry", str(tmp_path / "frames"), "--telemetry-file", str(log),
               "--frames-fov-deg", "60", "-o", str(out), "--json")
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["crs"] == "EPSG:32633"
    assert report["views"] == 6
    assert report["altitude_outliers"]["frames"] == []
    assert json.loads(out.read_text())["crs"] == "EPSG:32633"
    lf = aos.load_lightfield(str(out), load_images=False).light_field
    assert lf.crs == "EPSG:32633"
    lats = [48.0 + 1e-4 * i for i in range(6)]
    eastings, northings = rasterio_transform("EPSG:4326", "EPSG:32633", [15.0] * 6, lats)
    for i, view in enumerate(lf.views):
        centre = view.cam_from_world.center + lf.origin
        assert centre[0] == pytest.approx(eastings[i], abs=1e-3)
        assert centre[1] == pytest.approx(northings[i], abs=1e-3)
        assert centre[2] == pytest.approx(120.0, abs=1e-9)
        # Nadir, yaw 0: looking down, image up (-camera y) at north (+y).
        rotation = np.asarray(view.cam_from_world.rotation)
        np.testing.assert_allclose(rotation[2], [0, 0, -1], atol=1e-9)
        np.testing.assert_allclose(-rotation[1], [0, 1, 0], atol=1e-9)
    # The origin is a round point near the flight.
    assert lf.origin[0] % 100 == 0 and lf.origin[1] % 100 == 0 and lf.origin[2] == 0


def test_altitude_outliers_are_listed_in_the_json_report(tmp_path: Path) -> None:
    names = write_frames(tmp_path / "frames", 9)
    altitudes = [120.0] * 9
    altitudes[4] = 180.0  # a barometer jump
    log = tmp_path / "log.csv"
    log.write_text(flight_csv(names, altitudes))
    done = run("import-telemetry", str(tmp_path / "frames"), "--telemetry-file", str(log),
               "--frames-fov-deg", "60", "--altitude-window", "5", "-o", str(tmp_path / "lf.json"),
               "--json")
    assert done.returncode == 0, done.stderr
    outliers = json.loads(done.stdout)["altitude_outliers"]
    assert outliers == {"frames": ["f04.png"], "altitude_m": [180.0], "median_m": [120.0]}
    assert "altitude outlier: f04.png: 180 m replaced by the running median 120 m" in done.stderr
    # Python: the same, through the same Options struct.
    result = aos.import_telemetry(tmp_path / "frames", telemetry_file=str(log), fov_deg=60.0,
                                  altitude_window=5)
    assert [(o.frame, o.altitude_m, o.median_m) for o in result.altitude_outliers] == [
        ("f04.png", 180.0, 120.0)]
    assert result.light_field.views[4].cam_from_world.center[2] == pytest.approx(120.0)
    with pytest.raises(TypeError):
        aos.import_telemetry(tmp_path / "frames", telemetry_file=str(log), fov=60.0)


def test_bad_input_names_file_line_and_field_and_writes_nothing(tmp_path: Path) -> None:
    names = write_frames(tmp_path / "frames", 3)
    log = tmp_path / "log.csv"
    out = tmp_path / "lf.json"
    cases = {
        "frame,lat,lon,alt,yaw,pitch\n": "log.csv: line 1: the header has no roll column",
        HEADER + "f00.png,48,15,100,0,-90,0\nf01.png,48,east,100,0,-90,0\n":
            "log.csv: line 3: lon: \"east\" is not a number",
        HEADER + "f00.png,-91,15,100,0,-90,0\n": "log.csv: line 2: lat: -91 is outside [-90, 90]",
        HEADER + "f00.png,48,15,100,0,-90,0\nf09.png,48,15,100,0,-90,0\n":
            "log.csv: line 3: frame: \"f09.png\" names no frame",
    }
    for text, message in cases.items():
        log.write_text(text)
        done = run("import-telemetry", str(tmp_path / "frames"), "--telemetry-file", str(log),
                   "--frames-fov-deg", "60", "-o", str(out))
        assert done.returncode == 1
        assert message in done.stderr
        assert done.stderr.count("error") == 1
        assert not out.exists()
    with pytest.raises(ValueError, match="fov_deg: a camera is needed"):
        aos.import_telemetry(tmp_path / "frames", telemetry_file=str(log))
    assert names


def test_lightfield_crs_property_is_checked_and_round_trips(tmp_path: Path, make_lightfield) -> None:
    lf = make_lightfield()
    assert lf.crs == ""
    lf.crs = "EPSG:25833"
    assert "crs='EPSG:25833'" in repr(lf)
    with pytest.raises(ValueError, match="geographic"):
        lf.crs = "EPSG:4326"
    with pytest.raises(ValueError, match="not known to PROJ"):
        lf.crs = "EPSG:999999"
    assert lf.crs == "EPSG:25833"
    aos.write_lightfield(str(tmp_path / "lf.json"), lf)
    back = aos.load_lightfield(str(tmp_path / "lf.json")).light_field
    assert back.crs == "EPSG:25833"
    copy = pickle.loads(pickle.dumps(lf))
    assert copy.crs == "EPSG:25833" and copy == lf
    copy.crs = ""
    assert copy != lf  # equality compares the CRS
