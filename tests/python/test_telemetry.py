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


def test_cli_flight_across_the_antimeridian_is_one_zone_and_metres_apart(tmp_path: Path) -> None:
    """Issue 31: a flight at 16.5 S across longitude 180 landed in a zone half a world away
    (northings near 20,000 km, convergence up to 180 degrees). One zone from the flight's centre
    keeps every view within the flight's few metres and the convergence near 3 x sin(16.5)."""
    names = write_frames(tmp_path / "frames", 4)
    longitudes = [179.99997, 179.99999, -179.99999, -179.99997]
    log = tmp_path / "log.csv"
    log.write_text(HEADER + "".join(f"{name},-16.5,{lon:.5f},100,0,-90,0\n"
                                    for name, lon in zip(names, longitudes)))
    out = tmp_path / "lf.json"
    done = run("import-telemetry", str(tmp_path / "frames"), "--telemetry-file", str(log),
               "--frames-fov-deg", "60", "-o", str(out), "--json")
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["crs"] in ("EPSG:32760", "EPSG:32701")
    assert report["max_convergence_deg"] == pytest.approx(0.85, abs=0.01)
    lf = aos.load_lightfield(str(out), load_images=False).light_field
    centres = np.array([view.cam_from_world.center for view in lf.views])
    # 0.00002 degrees of longitude at 16.5 S: 2.13 m (UTM scale within 0.1%), eastwards, turned
    # from grid east by the convergence (2.13 m x sin 0.85 deg = 0.032 m of northing).
    spacing = 0.00002 * 111320.0 * np.cos(np.radians(16.5))
    np.testing.assert_allclose(np.diff(centres[:, 0]), spacing, rtol=0.005)
    np.testing.assert_allclose(np.abs(np.diff(centres[:, 1])), 0.032, atol=0.002)
    # Against rasterio (GDAL/PROJ) in the zone aos chose.
    eastings, northings = rasterio_transform("EPSG:4326", report["crs"], longitudes, [-16.5] * 4)
    np.testing.assert_allclose(centres[:, 0] + lf.origin[0], eastings, atol=1e-3)
    np.testing.assert_allclose(centres[:, 1] + lf.origin[1], northings, atol=1e-3)


def implausible_logs(names: list[str]) -> dict[str, tuple[str, str]]:
    """Logs with one implausible row (or half of them), and what the refusal must say."""
    good = flight_csv(names, [120.0] * len(names)).splitlines(keepends=True)

    def with_row(row: int, text: str) -> str:
        rows = list(good)
        rows[row + 1] = text
        return "".join(rows)

    half = list(good)
    for row in range(1, 1 + len(names) // 2):
        half[row] = half[row].replace(",48.", ",-48.")
    return {
        "swapped": (with_row(3, f"{names[3]},15.0,48.0003,120,0,-90,0\n"),
                    "log.csv: line 5 (frame f03.png): lat, lon: (15, 48.0003) is "),
        "radians": (with_row(3, f"{names[3]},0.837763,0.261799,120,0,-90,0\n"),
                    "in radians, not degrees?"),
        "hemisphere": ("".join(half), "km from the flight's centre"),
        "altitude": (with_row(3, f"{names[3]},48.0003,15.0,-1e308,0,-90,0\n"),
                     "log.csv: line 5: alt: -1e+308 is outside the plausible altitudes"),
    }


@pytest.mark.parametrize("case", ["swapped", "radians", "hemisphere", "altitude"])
def test_cli_refuses_an_implausible_row_naming_line_and_field(tmp_path: Path, case: str) -> None:
    names = write_frames(tmp_path / "frames", 6)
    text, message = implausible_logs(names)[case]
    log = tmp_path / "log.csv"
    log.write_text(text)
    out = tmp_path / "lf.json"
    done = run("import-telemetry", str(tmp_path / "frames"), "--telemetry-file", str(log),
               "--frames-fov-deg", "60", "-o", str(out))
    assert done.returncode == 1, done.stderr
    assert message in done.stderr
    assert done.stderr.count("error") == 1
    assert not out.exists()


def test_max_distance_from_centre_is_one_option_in_cli_and_python(tmp_path: Path) -> None:
    names = write_frames(tmp_path / "frames", 6)
    log = tmp_path / "log.csv"
    log.write_text(implausible_logs(names)["swapped"][0])
    with pytest.raises(ValueError, match="km from the flight's centre"):
        aos.import_telemetry(tmp_path / "frames", telemetry_file=str(log), fov_deg=60.0)
    assert aos.TelemetryOptions().max_distance_from_centre_m == 50000.0
    # A flight that is truly that large is taken when the bound is raised, in both.
    result = aos.import_telemetry(tmp_path / "frames", telemetry_file=str(log), fov_deg=60.0,
                                  max_distance_from_centre_m=1e7)
    assert len(result.light_field.views) == 6
    done = run("import-telemetry", str(tmp_path / "frames"), "--telemetry-file", str(log),
               "--frames-fov-deg", "60", "--max-distance-from-centre-m", "1e7",
               "-o", str(tmp_path / "lf.json"))
    assert done.returncode == 0, done.stderr
    with pytest.raises(ValueError, match="max_distance_from_centre_m: must be > 0"):
        aos.import_telemetry(tmp_path / "frames", telemetry_file=str(log), fov_deg=60.0,
                             max_distance_from_centre_m=-1.0)


def test_cli_reads_a_byte_order_mark_and_quoted_fields(tmp_path: Path) -> None:
    """A CSV saved by a spreadsheet: a UTF-8 byte-order mark, CRLF, quoted fields."""
    names = write_frames(tmp_path / "frames", 3)
    rows = "".join(f'"{name}","{48.0 + 1e-4 * i:.4f}",15.0,120,0,-90,0\r\n'
                   for i, name in enumerate(names))
    log = tmp_path / "log.csv"
    log.write_bytes(b"\xef\xbb\xbf" + (HEADER.replace("\n", "\r\n") + rows).encode())
    done = run("import-telemetry", str(tmp_path / "frames"), "--telemetry-file", str(log),
               "--frames-fov-deg", "60", "-o", str(tmp_path / "lf.json"), "--json")
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["views"] == 3
