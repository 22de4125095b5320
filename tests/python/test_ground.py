"""`aos-render ground`: the ground from reconstructed points (a DEM GeoTIFF read back with
rasterio), the flight's height above it or above a given terrain, and bad input."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import aos
from conftest import build_lightfield

rasterio = pytest.importorskip("rasterio")

ORIGIN = (500000.0, 5300000.0, 200.0)
ALTITUDE = 30.0


def terrain_z(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Local z of the ground: a 6 % slope and a 1.5 m hill."""
    return 0.06 * x + 0.03 * y + 1.5 * np.exp(-((x - 10) ** 2 + (y + 5) ** 2) / (2 * 12.0**2))


def write_ply(path: Path, points: np.ndarray) -> None:
    """Binary little-endian PLY of double x, y, z, written independently of aos."""
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(points)}\n"
              "property double x\nproperty double y\nproperty double z\nend_header\n")
    path.write_bytes(header.encode() + np.asarray(points, "<f8").tobytes())


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["aos-render", *map(str, args)], capture_output=True, text=True,
                          timeout=120)


@pytest.fixture
def flight(tmp_path: Path) -> Path:
    """A 5 x 5 grid of nadir views 30 m above the local zero, geo-referenced at ORIGIN, and the
    points a reconstruction of the forest under it gives: ground under 60 % of the area, crowns
    4-18 m up elsewhere, a 10 x 10 m block seen only as canopy."""
    light_field = build_lightfield(views_per_side=5, spacing=8.0, altitude=ALTITUDE, width=32,
                                   height=24)
    light_field.origin = ORIGIN
    light_field.crs = "EPSG:32633"
    aos.write_lightfield(tmp_path / "lf.json", light_field)
    rng = np.random.default_rng(5)
    x = rng.uniform(-40, 40, 15000)
    y = rng.uniform(-40, 40, 15000)
    ground = terrain_z(x, y) + rng.normal(0, 0.05, x.size)
    hidden = (x > -20) & (x < -10) & (y > 10) & (y < 20)
    crown = hidden | (rng.uniform(size=x.size) < 0.4)
    z = np.where(crown, terrain_z(x, y) + rng.uniform(4, 18, x.size), ground)
    write_ply(tmp_path / "points.ply", np.stack([x, y, z], 1) + np.array(ORIGIN))
    return tmp_path


def test_ground_dem_lands_where_its_geotransform_says(flight: Path) -> None:
    result = run("ground", flight / "lf.json", "--points", flight / "points.ply", "-o",
                 flight / "ground.tif", "--json")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["up"] == "+z"
    with rasterio.open(flight / "ground.tif") as dem:
        heights = dem.read(1)
        assert dem.transform.e < 0  # north up
        assert dem.crs.to_epsg() == 32633  # the light field's
        rows, cols = np.mgrid[0:dem.height, 0:dem.width]
        xs, ys = rasterio.transform.xy(dem.transform, rows.ravel(), cols.ravel())
    local_x = np.asarray(xs) - ORIGIN[0]
    local_y = np.asarray(ys) - ORIGIN[1]
    truth = ORIGIN[2] + terrain_z(local_x, local_y)
    # Every cell within 0.35 m of the terrain under its centre (see ground_test.cpp), also under
    # the block seen only as canopy.
    assert np.abs(heights.ravel() - truth).max() < 0.35
    # The views fly 30 m above the local zero: above the ground by 30 - terrain under them.
    centres = np.array([[i * 8.0 - 16, j * 8.0 - 16] for j in range(5) for i in range(5)])
    expected = ALTITUDE - terrain_z(centres[:, 0], centres[:, 1])
    assert report["height_above_ground_m"]["median"] == pytest.approx(np.median(expected), abs=0.35)
    assert report["views_over_ground"] == 25
    # The same DEM as a known terrain gives the same heights; and it is a focal surface.
    again = run("ground", flight / "lf.json", "--terrain", flight / "ground.tif", "--json")
    assert again.returncode == 0, again.stderr
    assert json.loads(again.stdout)["height_above_ground_m"] == report["height_above_ground_m"]


@pytest.mark.parametrize("case", ["both", "neither", "no_output", "nan_point", "exists",
                                  "output_is_input", "bad_cell", "not_tif"])
def test_ground_bad_input_fails_cleanly(case: str, flight: Path) -> None:
    out = flight / "ground.tif"
    args = ["ground", flight / "lf.json", "--points", flight / "points.ply", "-o", out]
    expected = {"both": "either --points", "neither": "either --points",
                "no_output": "-o:", "nan_point": "points.ply: element vertex 1: y is not finite",
                "exists": "exists", "output_is_input": "output",
                "bad_cell": "cell_size_m: must be > 0 metres",
                # It wrote a GeoTIFF named ground.xyz (exit 0) before.
                "not_tif": "ground.xyz: a height field is written as a GeoTIFF"}[case]
    if case == "both":
        args += ["--terrain", flight / "points.ply"]
    elif case == "neither":
        args = ["ground", flight / "lf.json", "-o", out]
    elif case == "no_output":
        args = args[:-2]
    elif case == "nan_point":
        (flight / "points.ply").write_text(
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
            "property double z\nend_header\n0 0 0\n1 nan 0\n2 2 2\n")
    elif case == "exists":
        out.write_bytes(b"keep")
    elif case == "output_is_input":
        args[-1] = flight / "points.ply"
    elif case == "bad_cell":
        args += ["--cell-size-m", "0"]
    elif case == "not_tif":
        args[-1] = flight / "ground.xyz"
    before = {p.name: p.read_bytes() for p in flight.iterdir() if p.is_file()}
    result = run(*args)
    assert result.returncode != 0
    assert expected in result.stderr, result.stderr
    after = {p.name: p.read_bytes() for p in flight.iterdir() if p.is_file()}
    assert after == before  # nothing written, nothing changed


def test_poses_points_output_feeds_ground(flight: Path) -> None:
    """import-colmap --points-output writes the model's points in world coordinates."""
    from conftest import write_colmap_text_model
    model = flight / "model"
    write_colmap_text_model(flight / "lf.json", model)
    points = np.array([[1.5, -2.25, 3.0], [10.0, 20.0, -5.125]])
    (model / "points3D.txt").write_text(
        "".join(f"{k + 1} {p[0]} {p[1]} {p[2]} 255 255 255 0.5\n" for k, p in enumerate(points)))
    result = run("import-colmap", model, "--images-dir", flight / "views", "-o",
                 flight / "imported.json", "--points-output", flight / "model_points.ply",
                 "--json")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["points_output"] == str(flight / "model_points.ply")
    data = (flight / "model_points.ply").read_bytes()
    assert data.startswith(b"ply\n")
    body = data[data.index(b"end_header\n") + len(b"end_header\n"):]
    # Not geo-referenced: the model's frame is the light field's (origin 0), points unchanged.
    np.testing.assert_array_equal(np.frombuffer(body, "<f8").reshape(-1, 3), points)


def test_estimate_ground_in_python_matches_the_cli(flight: Path) -> None:
    """aos.estimate_ground on local points gives the DEM the CLI wrote, cell for cell."""
    light_field = aos.load_lightfield(str(flight / "lf.json")).light_field
    data = (flight / "points.ply").read_bytes()
    body = data[data.index(b"end_header\n") + len(b"end_header\n"):]
    points = np.frombuffer(body, "<f8").reshape(-1, 3) - np.array(ORIGIN)
    result = aos.estimate_ground(light_field, points, cell_size_m=5.0)
    assert result.up_sign == 1
    assert result.plane.normal[2] > 0.99
    dem = result.heightfield(light_field.origin, "EPSG:32633")
    assert run("ground", flight / "lf.json", "--points", flight / "points.ply", "-o",
               flight / "ground.tif").returncode == 0
    with rasterio.open(flight / "ground.tif") as written:
        np.testing.assert_array_equal(written.read(1), dem.heights)
    with pytest.raises(ValueError, match="cell_size_m"):
        aos.estimate_ground(light_field, points, cell_size_m=-1.0)
    with pytest.raises(TypeError):
        aos.estimate_ground(light_field, points, cell_size=5.0)  # type: ignore[call-arg]


def test_a_z_down_frame_is_said_loudly(tmp_path: Path) -> None:
    """JKU-style frames have z down: the DEM then holds z values growing downwards, right as a
    focal surface but not elevations, and the CLI says so."""
    light_field = build_lightfield(views_per_side=3, spacing=8.0, altitude=-30.0, width=32,
                                   height=24)
    aos.write_lightfield(tmp_path / "lf.json", light_field)
    rng = np.random.default_rng(2)
    x, y = rng.uniform(-30, 30, 4000), rng.uniform(-30, 30, 4000)
    write_ply(tmp_path / "points.ply", np.stack([x, y, -terrain_z(x, y)], 1))
    result = run("ground", tmp_path / "lf.json", "--points", tmp_path / "points.ply", "-o",
                 tmp_path / "ground.tif", "--json")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["up"] == "-z"
    assert "z axis points down" in result.stderr and "not elevations" in result.stderr
    # The views fly 30 m above the local zero: 30 - terrain under them above the ground, as
    # in a z-up frame.
    centres = np.array([[i * 8.0 - 8, j * 8.0 - 8] for j in range(3) for i in range(3)])
    expected = 30.0 - terrain_z(centres[:, 0], centres[:, 1])
    report = json.loads(result.stdout)
    assert report["height_above_ground_m"]["median"] == pytest.approx(np.median(expected), abs=0.35)
