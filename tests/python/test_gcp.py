"""OpenDroneMap ground control (gcp_list.txt): read, write, and checked against a light field's
poses (aos-render check-gcp, aos.check_gcps), against a hand projection of nadir views."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

import aos

W, H, FOV = 64, 48, 60.0
ALTITUDE = 50.0
ORIGIN = (500000.0, 5300000.0, 0.0)  # UTM 33N, on its central meridian


def nadir_lightfield() -> aos.LightField:
    lf = aos.LightField()
    camera = aos.PinholeCamera.from_fov(W, H, FOV)
    for i, x in enumerate((-5.0, 0.0, 5.0)):
        pose = aos.look_at((x, 0.0, ALTITUDE), (x, 0.0, 0.0), up=(0.0, 1.0, 0.0))
        lf.add_view(np.zeros((H, W), np.uint8), camera, pose, name=f"DJI_{i:04d}.JPG")
    lf.origin = ORIGIN
    lf.crs = "EPSG:32633"
    return lf


def hand_pixel(point_local: np.ndarray, centre_x: float) -> tuple[float, float]:
    """A nadir camera with image up = north: u grows east, v grows south (aos pixel
    coordinates: the principal point at the image centre, W/2, H/2)."""
    f = (W / 2.0) / np.tan(np.radians(FOV / 2.0))
    depth = ALTITUDE - point_local[2]
    return (W / 2.0 + f * (point_local[0] - centre_x) / depth,
            H / 2.0 - f * point_local[1] / depth)


POINTS = {"g1": np.array([1.5, 2.0, 0.4]), "g2": np.array([-3.0, -4.0, -0.2])}


def gcp_file(shift_px: float = 0.0) -> aos.OdmGcpFile:
    """Sightings of g1 in views 0 and 1 and of g2 in view 2, in ODM pixels (aos - 0.5);
    the last one marked `shift_px` pixels to the right."""
    sightings = [("g1", 0, -5.0), ("g1", 1, 0.0), ("g2", 2, 5.0)]
    points = []
    for k, (name, view, centre_x) in enumerate(sightings):
        local = POINTS[name]
        u, v = hand_pixel(local, centre_x)
        if k == len(sightings) - 1:
            u += shift_px
        world = np.asarray(ORIGIN) + local
        points.append(aos.OdmGcp(tuple(world), (u - 0.5, v - 0.5), f"DJI_{view:04d}.JPG", name))
    return aos.OdmGcpFile("WGS84 UTM 33N", points)


def test_gcps_on_true_poses_have_no_error_and_a_shift_is_measured(tmp_path: Path) -> None:
    lf = nadir_lightfield()
    result = aos.check_gcps(lf, gcp_file())
    assert result.rms_px < 1e-6 and result.rms_ground_m < 1e-6
    assert [r.view for r in result.residuals] == [0, 1, 2]
    # 3 px to the right at 50.2 m: 3 * depth / f metres east on the ground.
    shifted = aos.check_gcps(lf, gcp_file(shift_px=3.0))
    f = (W / 2.0) / np.tan(np.radians(FOV / 2.0))
    last = shifted.residuals[-1]
    assert last.error_px == pytest.approx(3.0, abs=1e-6)
    assert last.ground_error_m[0] == pytest.approx(3.0 * (ALTITUDE + 0.2) / f, abs=1e-6)
    assert abs(last.ground_error_m[1]) < 1e-6
    assert shifted.max_px == pytest.approx(3.0, abs=1e-6)
    assert shifted.rms_px == pytest.approx(np.sqrt(9.0 / 3.0), abs=1e-6)


def test_gcp_file_round_trips_and_reads_geographic_points(tmp_path: Path) -> None:
    path = tmp_path / "gcp_list.txt"
    aos.write_odm_gcp(str(path), gcp_file())
    again = aos.read_odm_gcp(str(path))
    assert again.crs == "EPSG:32633" and len(again.points) == 3
    for a, b in zip(gcp_file().points, again.points):
        np.testing.assert_allclose(a.position, b.position, atol=1e-6)
        np.testing.assert_allclose(a.pixel, b.pixel, atol=1e-9)
        assert (a.image, a.name) == (b.image, b.name)
    with pytest.raises(ValueError, match="exists"):
        aos.write_odm_gcp(str(path), gcp_file())
    # The same points as longitude/latitude (EPSG:4326): PROJ moves them; same residuals.
    from rasterio.warp import transform  # rasterio (GDAL/PROJ) is a test dependency
    lines = ["EPSG:4326"]
    for p in gcp_file().points:
        (lon,), (lat,) = transform("EPSG:32633", "EPSG:4326", [p.position[0]], [p.position[1]])
        lines.append(f"{lon:.12f} {lat:.12f} {p.position[2]} {p.pixel[0]} {p.pixel[1]} "
                     f"{p.image} {p.name} extra words")
    geographic = tmp_path / "gcp_wgs84.txt"
    geographic.write_text("\n".join(lines) + "\n")
    read = aos.read_odm_gcp(str(geographic))
    assert read.points[0].extras == "extra words"
    assert aos.check_gcps(nadir_lightfield(), read).rms_px < 1e-3


def test_cli_check_gcp_reports_and_refuses_bad_files(tmp_path: Path) -> None:
    lf_path = tmp_path / "lf.json"
    aos.write_lightfield(str(lf_path), nadir_lightfield())
    gcps = tmp_path / "gcp_list.txt"
    aos.write_odm_gcp(str(gcps), gcp_file(shift_px=2.0))
    done = subprocess.run(["aos-render", "check-gcp", str(lf_path), str(gcps), "--json"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["max_px"] == pytest.approx(2.0, abs=1e-6)
    assert report["sightings"]["name"] == ["g1", "g1", "g2"]
    done = subprocess.run(["aos-render", "check-gcp", str(lf_path), str(gcps)],
                          capture_output=True, text=True, timeout=60)
    assert "3 sightings: RMS" in done.stdout and "g2 in DJI_0002.JPG (view 2)" in done.stdout
    bad = tmp_path / "bad.txt"
    bad.write_text("EPSG:32633\n500001 5300002 0 10 10\n")
    done = subprocess.run(["aos-render", "check-gcp", str(lf_path), str(bad)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode != 0 and "bad.txt: line 2: expected geo_x" in done.stderr
    bad.write_text("EPSG:32633\n500001 5300002 0 10 10 nowhere.jpg g9\n")
    done = subprocess.run(["aos-render", "check-gcp", str(lf_path), str(bad)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode != 0 and "line 2: image_name" in done.stderr
    assert "nowhere.jpg" in done.stderr
