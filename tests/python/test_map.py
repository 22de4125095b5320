"""Maps (aos-render map, aos.render_map): orthographic renders written as Cloud-Optimised GeoTIFFs,
read back independently with rasterio. A simulated flight over a dark ground with one bright
target at a known position checks that the geotransform places pixels where they are; the CRS,
overviews, nodata/count band, tiling bit for bit, an independent numpy reference, the z-down rule
and bad input that leaves nothing behind."""

from __future__ import annotations

import json
import math
import pickle
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import aos

rasterio = pytest.importorskip("rasterio")

EXE = shutil.which("aos-render")

TARGET = (3.0, -2.0)  # local x, y of the bright 1 m x 1 m target's centre
ORIGIN = (600000.0, 5200000.0, 0.0)  # UTM-sized world coordinates
ALTITUDE = 20.0
HALF_FOOTPRINT = ALTITUDE * math.tan(math.radians(30.0))  # 64 x 64 views, 60 degrees

SCENE = {
    "ground": {"texture": {"type": "constant", "color": 0.1}},
    "targets": [{"center": list(TARGET), "size": [1.0, 1.0],
                 "texture": {"type": "constant", "color": 0.95}}],
    "camera": {"width": 64, "height": 64, "fov_deg": 60},
    "sampling": {"altitude": ALTITUDE, "grid": 3, "aperture": {"diameter": 6}},
    "truth": {"width": 8, "height": 8, "blocked_fraction": False},
}


def run(*args: str) -> subprocess.CompletedProcess:
    assert EXE is not None
    return subprocess.run([EXE, *args], capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def flight() -> aos.LightField:
    light_field = aos.simulate(SCENE).light_field
    light_field.origin = ORIGIN
    light_field.crs = "EPSG:32633"
    return light_field


@pytest.fixture(scope="module")
def flight_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("sim") / "flight"
    scene = folder.parent / "scene.json"
    scene.write_text(json.dumps(SCENE))
    result = run("simulate", str(scene), "-o", str(folder), "-q")
    assert result.returncode == 0, result.stderr
    return folder / "lightfield.json"


def expected_count(light_field: aos.LightField, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Views whose (square, nadir) footprint on z = 0 holds each local point."""
    count = np.zeros(x.shape, dtype=np.int64)
    for view in light_field.views:
        cx, cy, _ = view.cam_from_world.center
        count += (np.abs(x - cx) <= HALF_FOOTPRINT) & (np.abs(y - cy) <= HALF_FOOTPRINT)
    return count


def test_a_simulated_flight_lands_where_the_geotransform_says(
        flight: aos.LightField, tmp_path: Path) -> None:
    path = tmp_path / "map.tif"
    # Wider than the footprints, so that some pixels are seen by no view.
    extent = [ORIGIN[0] - 20.0, ORIGIN[1] - 18.0, ORIGIN[0] + 20.0, ORIGIN[1] + 18.0]
    result = aos.render_map(flight, pixel_size=0.1, extent=extent, path=path, arrays=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map.tif"]  # no temporary files
    assert result.geotransform == (extent[0], 0.1, 0.0, extent[3], 0.0, -0.1)
    assert (result.width, result.height) == (400, 360)
    with rasterio.open(path) as src:
        assert src.crs == rasterio.crs.CRS.from_epsg(32633)
        assert src.count == 2 and src.descriptions == ("value", "count")
        assert src.width == 400 and src.height == 360
        assert src.transform.almost_equals(rasterio.Affine(0.1, 0.0, extent[0], 0.0, -0.1, extent[3]))
        assert src.overviews(1) == [2] and src.overviews(2) == [2]  # down to one 256 block
        assert src.tags(ns="IMAGE_STRUCTURE").get("LAYOUT") == "COG"
        value = src.read(1)
        count = src.read(2)
        masked = src.read(1, masked=True)
        # The target's centre, through rasterio's own inverse of the geotransform.
        row, col = src.index(ORIGIN[0] + TARGET[0], ORIGIN[1] + TARGET[1])
        x, y = src.xy(row, col)  # that pixel's centre
    half = 0.05 + 1e-6  # half a pixel (the target centre lies on a pixel edge here)
    assert abs(x - (ORIGIN[0] + TARGET[0])) <= half and abs(y - (ORIGIN[1] + TARGET[1])) <= half
    assert value[row, col] > 0.9 * 0.95 * 255  # bright: the target is there
    # The target's intensity-weighted centroid lies within half a pixel of its true centre.
    excess = np.where(np.isfinite(value), value - 0.1 * 255, 0.0)
    excess[excess < 0.2 * 0.85 * 255] = 0.0
    rows, cols = np.nonzero(excess)
    weights = excess[rows, cols]
    centroid_x = extent[0] + (np.sum(weights * (cols + 0.5)) / weights.sum()) * 0.1
    centroid_y = extent[3] - (np.sum(weights * (rows + 0.5)) / weights.sum()) * 0.1
    assert abs(centroid_x - (ORIGIN[0] + TARGET[0])) < 0.05
    assert abs(centroid_y - (ORIGIN[1] + TARGET[1])) < 0.05
    # Count band: the views whose footprint holds the pixel centre (away from footprint edges);
    # count 0 is nodata (NaN) in the value band, masked by rasterio.
    cols_all, rows_all = np.meshgrid(np.arange(400), np.arange(360))
    local_x = extent[0] - ORIGIN[0] + (cols_all + 0.5) * 0.1
    local_y = extent[3] - ORIGIN[1] - (rows_all + 0.5) * 0.1
    truth = expected_count(flight, local_x, local_y)
    near_edge = np.zeros(truth.shape, dtype=bool)
    for view in flight.views:
        cx, cy, _ = view.cam_from_world.center
        for distance in (np.abs(local_x - cx), np.abs(local_y - cy)):
            near_edge |= np.abs(distance - HALF_FOOTPRINT) < 1e-6
    assert not near_edge.any()
    np.testing.assert_array_equal(count, truth.astype(np.float32))
    assert (truth == 0).sum() > 1000 and result.uncovered_pixels == (truth == 0).sum()
    assert np.isnan(value[truth == 0]).all() and np.isfinite(value[truth > 0]).all()
    np.testing.assert_array_equal(masked.mask, truth == 0)
    # The file holds what was returned.
    np.testing.assert_array_equal(result.count, count.astype(np.uint32))
    np.testing.assert_array_equal(result.image[truth > 0], value[truth > 0])
    assert (result.image[truth == 0] == 0).all()


def test_the_map_agrees_with_a_numpy_reference(flight: aos.LightField) -> None:
    result = aos.render_map(flight, pixel_size=0.13, focal_surface=0.0)
    x0, p, _, y0, _, _ = result.geotransform
    rng = np.random.default_rng(5)
    rows = rng.integers(0, result.height, 300)
    cols = rng.integers(0, result.width, 300)
    views = [(v.cam_from_world, v.camera, v.image.astype(np.float64)) for v in flight.views]
    checked = 0
    for row, col in zip(rows, cols):
        point = np.array([x0 + (col + 0.5) * p - ORIGIN[0], y0 - (row + 0.5) * p - ORIGIN[1], 0.0])
        samples = []
        for pose, camera, image in views:
            in_cam = pose.rotation @ point + pose.translation
            if in_cam[2] <= 0:
                continue
            u = camera.fx * in_cam[0] / in_cam[2] + camera.cx
            v = camera.fy * in_cam[1] / in_cam[2] + camera.cy
            if not (0 <= u <= camera.width and 0 <= v <= camera.height):
                continue
            # Bilinear at pixel centres +0.5, edges replicated.
            sx, sy = u - 0.5, v - 0.5
            ix, iy = math.floor(sx), math.floor(sy)
            ax, ay = sx - ix, sy - iy
            h, w = image.shape
            def tap(i: int, j: int) -> float:
                return image[min(max(j, 0), h - 1), min(max(i, 0), w - 1)]
            top = tap(ix, iy) + ax * (tap(ix + 1, iy) - tap(ix, iy))
            bottom = tap(ix, iy + 1) + ax * (tap(ix + 1, iy + 1) - tap(ix, iy + 1))
            samples.append(top + ay * (bottom - top))
        assert result.count[row, col] == len(samples)
        if samples:
            assert result.image[row, col] == pytest.approx(np.mean(samples), abs=1e-3)
            checked += 1
    assert checked > 250


def test_cli_map_tiles_change_no_bit_and_report(flight_file: Path, tmp_path: Path) -> None:
    whole, tiled = tmp_path / "whole.tif", tmp_path / "tiled.tif"
    result = run("map", str(flight_file), "--pixel-size", "0.09", "--tile-size", "8192",
                 "-o", str(whole), "--json")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["tiles"] == 1 and report["crs"] == ""
    # Every view sees part of the footprints' union.
    assert report["views_used"] == report["views_selected"] == 9
    # No CRS in the light field: a warning, and a map without one.
    assert "has no CRS" in result.stderr
    result = run("map", str(flight_file), "--pixel-size", "0.09", "--tile-size", "40",
                 "-o", str(tiled), "--json")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["tiles"] > 50
    with rasterio.open(whole) as a, rasterio.open(tiled) as b:
        assert a.crs is None
        assert a.transform == b.transform
        # The default extent: the footprints (3 x 3 views 3 m apart), widened to whole pixels.
        assert a.bounds.left <= -3.0 - HALF_FOOTPRINT < a.bounds.left + 0.09
        assert a.bounds.top - 0.09 < 3.0 + HALF_FOOTPRINT <= a.bounds.top
        assert np.array_equal(a.read(), b.read(), equal_nan=True)


def test_max_pixels_bounds_a_map_from_python_and_the_cli(flight: aos.LightField,
                                                        flight_file: Path,
                                                        tmp_path: Path) -> None:
    """max_pixels (MapOptions) is one field of the table: Python takes it, the CLI has
    --max-pixels, and both refuse a map over it naming the field."""
    with pytest.raises(ValueError, match="more than max_pixels 100"):
        aos.render_map(flight, pixel_size=0.09, max_pixels=100)
    assert aos.render_map(flight, pixel_size=0.5, max_pixels=10**6).image.size <= 10**6
    out = tmp_path / "m.tif"
    result = run("map", str(flight_file), "--pixel-size", "0.09", "--max-pixels", "100",
                 "-o", str(out))
    assert result.returncode != 0 and "more than max_pixels 100" in result.stderr
    assert not out.exists()
    result = run("map", str(flight_file), "--max-pixels", "2", "--pixel-size", "0.09",
                 "-o", str(out))
    assert result.returncode == 2 and "max_pixels: must be in [4, " in result.stderr
    assert "[option --max-pixels]" in result.stderr


def test_a_map_with_a_path_is_streamed_unless_its_arrays_are_asked_for(
        flight: aos.LightField, tmp_path: Path) -> None:
    options = dict(pixel_size=0.1, tile_size=32, extent=[ORIGIN[0] + 1.0, ORIGIN[1] - 4.0,
                                                       ORIGIN[0] + 6.0, ORIGIN[1] + 0.5])
    streamed = aos.render_map(flight, path=tmp_path / "streamed.tif", **options)
    kept = aos.render_map(flight, path=tmp_path / "kept.tif", arrays=True, **options)
    in_memory = aos.render_map(flight, **options)
    assert not streamed.has_arrays and kept.has_arrays and in_memory.has_arrays
    with pytest.raises(ValueError, match="arrays=True"):
        streamed.image
    with pytest.raises(ValueError, match="arrays=True"):
        streamed.count
    for name in ("geotransform", "width", "height", "crs", "samples", "uncovered_pixels",
                 "views_selected", "views_used", "tiles"):
        assert getattr(streamed, name) == getattr(kept, name) == getattr(in_memory, name), name
    assert streamed.tiles == 4
    np.testing.assert_array_equal(kept.image, in_memory.image)
    with rasterio.open(tmp_path / "streamed.tif") as a, rasterio.open(tmp_path / "kept.tif") as b:
        assert np.array_equal(a.read(), b.read(), equal_nan=True)
        np.testing.assert_array_equal(a.read(2), in_memory.count.astype(np.float32))
    # Views used: the views 3 m apart have footprints 23 m wide, so all 9 see the extent; with
    # aperture 0 each pixel takes the view nearest to its vertical line, here only the one
    # centred at local (3, -3).
    assert streamed.views_selected == 9 and streamed.views_used == 9
    nearest = aos.render_map(flight, pixel_size=0.1, aperture_radius=0.0,
                             extent=[ORIGIN[0] + 2.0, ORIGIN[1] - 3.5, ORIGIN[0] + 3.5,
                                     ORIGIN[1] - 2.0])
    assert nearest.views_used == 1 and nearest.views_selected == 9
    with pytest.raises(ValueError, match="give a path"):
        aos.render_map(flight, arrays=False, **options)


def test_z_down_frames_map_in_their_own_x_y(flight: aos.LightField) -> None:
    # The same flight in a z-down frame (x, y, z) -> (x, -y, -z), as JKU/F0 poses are: up is
    # -z, and the target at local (3, -2) is at (3, 2) in the new frame's x/y.
    flip = np.diag([1.0, -1.0, -1.0])
    down = aos.LightField()
    for view in flight.views:
        pose = view.cam_from_world
        down.add_view(view.image, view.camera,
                      aos.Rigid3d(pose.rotation @ flip, pose.translation), name=view.name)
    result = aos.render_map(down, pixel_size=0.1, focal_surface=0.0)
    assert result.up_z == -1.0
    x0, p, _, y0, _, _ = result.geotransform
    col = int((TARGET[0] - x0) // p)
    row = int((y0 - (-TARGET[1])) // p)
    assert result.image[row, col] > 0.9 * 0.95 * 255
    # The original z-up frame has it at y = -2, and nothing bright at y = +2.
    up = aos.render_map(flight, pixel_size=0.1, focal_surface=0.0)
    assert up.up_z == 1.0
    ux0, up_p, _, uy0, _, _ = up.geotransform
    ucol = int((ORIGIN[0] + TARGET[0] - ux0) // up_p)
    assert up.image[int((uy0 - (ORIGIN[1] + TARGET[1])) // up_p), ucol] > 0.9 * 0.95 * 255
    assert up.image[int((uy0 - (ORIGIN[1] - TARGET[1])) // up_p), ucol] < 0.2 * 255


def snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


@pytest.mark.parametrize("args, names", [
    (["--pixel-size", "0"], "--pixel-size"),
    (["--pixel-size", "-0.1"], "--pixel-size"),
    (["--pixel-size", "0.1", "--extent", "10", "0", "-10", "5"], "--extent"),
    (["--pixel-size", "1e-5"], "--pixel-size"),  # 3 x 10^12 pixels
    (["--pixel-size", "500"], "--pixel-size"),  # one pixel
])
def test_cli_bad_sizes_write_nothing(flight_file: Path, tmp_path: Path, args: list[str],
                                     names: str) -> None:
    out = tmp_path / "out"
    out.mkdir()
    result = run("map", str(flight_file), *args, "-o", str(out / "map.tif"))
    assert result.returncode != 0
    lines = [line for line in result.stderr.splitlines() if "error" in line]
    assert len(lines) == 1 and names in lines[0], result.stderr
    assert not any(out.iterdir())


def test_cli_bad_outputs_write_nothing(flight_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    existing = out / "map.tif"
    existing.write_bytes(b"keep me")
    before = snapshot(out)
    result = run("map", str(flight_file), "--pixel-size", "0.1", "-o", str(existing))
    assert result.returncode != 0 and "map.tif" in result.stderr and "--force" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert snapshot(out) == before
    for target in (out / "missing" / "map.tif", Path("/proc/aos_map_test.tif")):
        result = run("map", str(flight_file), "--pixel-size", "0.1", "-o", str(target))
        assert result.returncode != 0 and str(target) in result.stderr, result.stderr
        errors = [line for line in result.stderr.splitlines() if "error" in line]
        assert len(errors) == 1
    assert snapshot(out) == before
    # Never over an input, --force or not: the light field or a frame (data loss otherwise).
    frames = flight_file.parent / "views"
    frame_before = (frames / "0003.png").read_bytes()
    for target in (flight_file, frames / "0003.png"):
        result = run("map", str(flight_file), "--pixel-size", "0.1", "-o", str(target), "--force")
        assert result.returncode != 0 and "input" in result.stderr, result.stderr
    assert (frames / "0003.png").read_bytes() == frame_before
    assert sorted(p.name for p in frames.iterdir())[0] == "0000.png"
    # --force replaces it with a GeoTIFF.
    result = run("map", str(flight_file), "--pixel-size", "0.1", "-o", str(existing), "--force",
                 "-q")
    assert result.returncode == 0, result.stderr
    assert sorted(p.name for p in out.iterdir()) == ["map.tif"]
    with rasterio.open(existing) as src:
        assert src.count == 2


def test_python_errors_name_the_field_or_file(flight: aos.LightField, flight_file: Path,
                                              tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="pixel_size"):
        aos.render_map(flight, pixel_size=-1.0)
    with pytest.raises(ValueError, match="extent"):
        aos.render_map(flight, pixel_size=0.1, extent=[1.0, 0.0, 0.0, 1.0])
    with pytest.raises(TypeError, match="unexpected keyword argument .pixel_sise."):
        aos.render_map(flight, pixel_sise=0.1)  # type: ignore[call-arg]
    path = tmp_path / "map.tif"
    path.write_bytes(b"x")
    with pytest.raises(ValueError, match="map.tif: exists"):
        aos.render_map(flight, pixel_size=0.1, path=path)
    bad = aos.LightField()
    for view in flight.views:
        bad.add_view(view.image, view.camera, view.cam_from_world)
    with pytest.raises(ValueError, match="EPSG:999999"):  # refused as soon as it is set
        bad.crs = "EPSG:999999"
        aos.render_map(bad, pixel_size=0.1, path=tmp_path / "other.tif")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map.tif"]
    # Never over a frame of the light field, even with force.
    loaded = aos.load_lightfield(str(flight_file)).light_field
    frame = Path(loaded.views[0].image_path)
    before = frame.read_bytes()
    with pytest.raises(ValueError, match="input"):
        aos.render_map(loaded, pixel_size=0.1, path=frame, force=True)
    assert frame.read_bytes() == before
    # A pixel count instead of a size.
    by_width = aos.render_map(flight, width=100)
    assert by_width.width == 100


def test_a_map_on_a_dem_is_the_map_on_its_plane_and_holes_are_nodata(
        flight: aos.LightField, flight_file: Path, tmp_path: Path) -> None:
    """The focal surface of a map: a flat DEM at world z = ORIGIN z + h (with the offset making up
    the rest) renders the map of the plane z = h to float rounding; a nodata hole in the DEM is
    nodata (count 0) in the map; the CLI takes the DEM as --focal-surface."""
    h, offset = 0.5, 0.25
    x0, y0 = ORIGIN[0] - 20.0, ORIGIN[1] + 20.0  # DEM's top-left corner (world)
    heights = np.full((40, 40), ORIGIN[2] + h - offset, np.float32)
    heights[18:22, 30:34] = np.nan  # a hole: world x 10..14, y -2..2 around the local frame
    dem = aos.Heightfield(heights, (x0, 1.0, 0.0, y0, 0.0, -1.0))
    extent = [ORIGIN[0] - 9.0, ORIGIN[1] - 9.0, ORIGIN[0] + 15.0, ORIGIN[1] + 9.0]
    plane = aos.render_map(flight, pixel_size=0.25, extent=extent, focal_surface=h)
    on_dem = aos.render_map(flight, pixel_size=0.25, extent=extent, focal_surface=dem,
                            surface_offset=offset)
    assert on_dem.geotransform == plane.geotransform
    # The DEM's triangles cover pixel centres from x0 + 0.5 to x0 + 39.5 (cell centres), except
    # the cells touching the hole: world x in (x0 + 29.5, x0 + 34.5), y in (y0 - 22.5, y0 - 17.5).
    rows, cols = np.mgrid[0:plane.count.shape[0], 0:plane.count.shape[1]]
    gt = plane.geotransform
    wx = gt[0] + (cols + 0.5) * gt[1]
    wy = gt[3] + (rows + 0.5) * gt[5]
    in_hole = (wx > x0 + 29.5) & (wx < x0 + 34.5) & (wy < y0 - 17.5) & (wy > y0 - 22.5)
    assert in_hole.any()
    assert np.all(on_dem.count[in_hole] == 0)
    keep = ~in_hole
    np.testing.assert_array_equal(on_dem.count[keep], plane.count[keep])
    np.testing.assert_allclose(on_dem.image[keep], plane.image[keep], atol=1e-4)
    # An offset moves the default plane as it moves the DEM: the plane at h, offset by 1 m up.
    moved = aos.render_map(flight, pixel_size=0.25, extent=extent, focal_surface=h - 1.0,
                           surface_offset=1.0)
    np.testing.assert_array_equal(moved.image, plane.image)
    # The CLI takes the DEM as --focal-surface. The simulated file keeps origin 0, so its DEM
    # and extent are in the local frame.
    local_dem = aos.Heightfield(np.full((40, 40), h - offset, np.float32),
                                (-20.0, 1.0, 0.0, 20.0, 0.0, -1.0))
    local_dem.write(str(tmp_path / "dem.tif"))
    local_extent = [str(v - o) for v, o in zip(extent, [ORIGIN[0], ORIGIN[1]] * 2)]
    result = run("map", str(flight_file), "--pixel-size", "0.25", "--extent", *local_extent,
                 "--focal-surface", str(tmp_path / "dem.tif"), "--surface-offset", str(offset),
                 "-o", str(tmp_path / "map.tif"), "-q")
    assert result.returncode == 0, result.stderr
    with rasterio.open(tmp_path / "map.tif") as written:
        assert written.tags()["AOS_SURFACE_OFFSET"] == "0.25"
        expected = np.where(plane.count > 0, plane.image, np.nan)  # nodata where no view sees
        np.testing.assert_allclose(written.read(1), expected, atol=1e-4)


def test_a_dem_in_another_crs_is_refused_or_transformed(flight: aos.LightField,
                                                        tmp_path: Path) -> None:
    """A flat DEM written in ETRS89 / UTM 33N (EPSG:25833) under a light field in WGS84 / UTM 33N
    (EPSG:32633): the two differ by well under a metre, so reading one as the other would look
    plausible. The core refuses it, naming both; in_crs transforms it through PROJ (what the
    CLI does itself), and the map then equals the plane's."""
    h = 0.5
    heights = np.full((60, 60), ORIGIN[2] + h, np.float32)
    dem = aos.Heightfield(heights, (ORIGIN[0] - 30.0, 1.0, 0.0, ORIGIN[1] + 30.0, 0.0, -1.0),
                          "EPSG:25833")
    dem.write(str(tmp_path / "dem.tif"))
    surface = aos.FocalSurface.read(str(tmp_path / "dem.tif"))
    extent = [ORIGIN[0] - 9.0, ORIGIN[1] - 9.0, ORIGIN[0] + 9.0, ORIGIN[1] + 9.0]
    # The core refuses it, naming both CRSs (with their names) ...
    with pytest.raises(ValueError, match=r"dem.tif is in EPSG:25833 \(ETRS89 / UTM zone 33N\) "
                                         r"but the light field is in EPSG:32633 \(WGS 84 / UTM "
                                         r"zone 33N\)"):
        surface.heights_at(flight, np.zeros((1, 2)))
    moved = surface.in_crs("EPSG:32633")
    assert "EPSG:25833 -> EPSG:32633" in moved.describe()
    assert moved.kind == "mesh"
    plane = aos.render_map(flight, pixel_size=0.25, extent=extent, focal_surface=h)
    on_dem = aos.render_map(flight, pixel_size=0.25, extent=extent, focal_surface=moved)
    np.testing.assert_array_equal(on_dem.count, plane.count)
    np.testing.assert_allclose(on_dem.image, plane.image, atol=1e-3)
    # ... and aos.render_map, like the CLI, moves it itself: a DEM as read, or its path.
    for given in (surface, str(tmp_path / "dem.tif")):
        direct = aos.render_map(flight, pixel_size=0.25, extent=extent, focal_surface=given)
        np.testing.assert_array_equal(direct.count, on_dem.count)
        np.testing.assert_array_equal(direct.image, on_dem.image)
    # The same surface in its own CRS comes back unchanged.
    assert surface.in_crs("EPSG:25833") == surface
    # A Heightfield read from the file keeps its name, which the messages give (it was blank).
    read = aos.Heightfield.read(str(tmp_path / "dem.tif"))
    assert read.source == str(tmp_path / "dem.tif")
    assert pickle.loads(pickle.dumps(read)).source == read.source
    with pytest.raises(ValueError, match=r"dem.tif is in EPSG:25833 \(ETRS89"):
        aos.FocalSurface(read).heights_at(flight, np.zeros((1, 2)))


def test_render_integral_takes_what_the_cli_takes_and_names_a_surface_above_the_cameras(
        flight: aos.LightField, tmp_path: Path) -> None:
    """aos.render_integral takes a focal surface as a path (a mesh or DEM, as --focal-surface
    FILE) and moves a DEM in another CRS into the light field's (as the CLI does): the render on
    a flat DEM in ETRS89 / UTM 33N equals the plane's. A render covering no pixel raises, and a
    terrain above the cameras (altitudes above the take-off point against a DEM's heights) is
    named as such, with both heights."""
    h = 0.5
    geotransform = (ORIGIN[0] - 30.0, 1.0, 0.0, ORIGIN[1] + 30.0, 0.0, -1.0)
    path = tmp_path / "dem.tif"
    aos.Heightfield(np.full((60, 60), ORIGIN[2] + h, np.float32), geotransform,
                    "EPSG:25833").write(str(path))
    plane = aos.render_integral(flight, pose_view=4, focal_surface=h)
    assert plane.uncovered_pixels == 0
    for given in (str(path), path, aos.FocalSurface.read(str(path)),
                  aos.Heightfield.read(str(path))):
        on_dem = aos.render_integral(flight, pose_view=4, focal_surface=given)
        np.testing.assert_array_equal(on_dem.count, plane.count)
        np.testing.assert_allclose(on_dem.image, plane.image, atol=1e-3)
    high = tmp_path / "high.tif"
    aos.Heightfield(np.full((60, 60), ORIGIN[2] + 300.0, np.float32), geotransform,
                    "EPSG:25833").write(str(high))
    with pytest.raises(ValueError, match=r"high.tif \(EPSG:25833 -> EPSG:32633\): no pixel is covered: the surface lies above "
                                         r"the cameras .*its world z is 300 and the cameras' 20"):
        aos.render_integral(flight, pose_view=4, focal_surface=str(high))
    with pytest.raises(ValueError, match=r"focal_surface: the plane lies behind the virtual camera"
                                         r".*; the surface lies above the cameras .*world z is 25 "
                                         r"and the cameras' 20"):
        aos.render_integral(flight, pose_view=4, focal_surface=25.0)
    with pytest.raises(ValueError, match="no.tif"):
        aos.render_integral(flight, pose_view=4, focal_surface=str(tmp_path / "no.tif"))


def test_cli_a_dem_that_covers_none_of_the_map_is_refused_like_integral(flight_file: Path,
                                                                      tmp_path: Path) -> None:
    """Before: a DEM in UTM (EPSG:25833) under the simulated flight (local frame, no CRS), or a
    DEM beside the flight, exited 0 with an all-nodata GeoTIFF ("0 of 9 views"), where
    `aos-render integral` refuses such a surface. The map makes integral's check: exit 1, one
    error naming the DEM and the likely cause, no file."""
    utm = aos.Heightfield(np.full((40, 40), 0.5, np.float32),
                          (ORIGIN[0] - 20.0, 1.0, 0.0, ORIGIN[1] + 20.0, 0.0, -1.0), "EPSG:25833")
    utm.write(str(tmp_path / "utm.tif"))
    aos.Heightfield(np.full((40, 40), 300.0, np.float32), (ORIGIN[0] - 20.0, 1.0, 0.0, ORIGIN[1] + 20.0, 0.0, -1.0),
                    "EPSG:25833").write(str(tmp_path / "utm300.tif"))
    beside = aos.Heightfield(np.full((10, 10), 0.5, np.float32), (200.0, 1.0, 0.0, 210.0, 0.0, -1.0))
    beside.write(str(tmp_path / "beside.tif"))
    out = tmp_path / "out"
    out.mkdir()
    for dem, extent, words in (
            ("utm.tif", [], ["utm.tif: no pixel is covered: the surface does not cover the map",
                             "the surface is in EPSG:25833 (ETRS89 / UTM zone 33N) but the light field has none"]),
            ("utm.tif", ["--extent", "-9", "-9", "9", "9"], ["utm.tif: no pixel is covered"]),
            # Heights of 300 m lie above the views (z 20, local): up flips, and the footprints
            # on its plane were "unbounded; give the extent" (exit 2). Named first now, beside
            # the CRS.
            ("utm300.tif", [], ["utm300.tif: no pixel is covered: the surface lies above the "
                                "cameras (behind them, as they look): its world z is 300 and the "
                                "cameras' 20", "the surface is in EPSG:25833 (ETRS89 / UTM zone "
                                "33N) but the light field has none"]),
            ("beside.tif", ["--extent", "-9", "-9", "9", "9"],
             ["beside.tif: no pixel is covered", "it spans x 200.5 .. 209.5, y 200.5 .. 209.5 (world), "
              "the map x -9 .. 9, y -9 .. 9"])):
        result = run("map", str(flight_file), "--pixel-size", "0.25", *extent, "--focal-surface",
                     str(tmp_path / dem), "-o", str(out / "map.tif"))
        assert result.returncode == 1, result.stderr
        errors = [line for line in result.stderr.splitlines() if "error" in line]
        assert len(errors) == 1, result.stderr
        for word in words:
            assert word in errors[0], result.stderr
        assert not any(out.iterdir())
    # integral's own refusal of the same DEM is the same sentence (one check, not two copies).
    result = run("integral", str(flight_file), "--pose-view", "4", "--focal-surface",
                 str(tmp_path / "beside.tif"), "-o", str(out / "integral.tif"))
    assert result.returncode == 1 and "beside.tif: no pixel is covered: the surface does not cover the virtual " \
        "camera's view (or no view sees it); check its extent and CRS" in result.stderr, result.stderr
    assert not any(out.iterdir())


def test_python_render_map_refuses_a_surface_that_covers_none_of_it(flight: aos.LightField,
                                                                   tmp_path: Path) -> None:
    beside = aos.Heightfield(np.full((10, 10), ORIGIN[2], np.float32),
                             (ORIGIN[0] + 200.0, 1.0, 0.0, ORIGIN[1] + 210.0, 0.0, -1.0))
    extent = [ORIGIN[0] - 9.0, ORIGIN[1] - 9.0, ORIGIN[0] + 9.0, ORIGIN[1] + 9.0]
    with pytest.raises(ValueError, match="focal_surface: no pixel is covered: the surface does not cover the map"):
        aos.render_map(flight, pixel_size=0.25, extent=extent, focal_surface=beside)
    with pytest.raises(ValueError, match="no pixel is covered"):
        aos.render_map(flight, pixel_size=0.25, extent=extent, focal_surface=beside, path=tmp_path / "m.tif")
    assert not any(tmp_path.iterdir())


def block_means(image: np.ndarray, count: np.ndarray, f: int) -> tuple[np.ndarray, np.ndarray]:
    """The overview of factor f by its definition: over each f x f block of the map (partial at
    the right and bottom edges), the mean of the values of the pixels with samples (NaN where
    none) and the mean count of all its pixels, in float64."""
    h, w = count.shape
    oh, ow = -(-h // f), -(-w // f)
    pad = ((0, oh * f - h), (0, ow * f - w))
    valid = np.pad(count > 0, pad)
    pixels = np.pad(np.ones_like(count, bool), pad)
    values = np.pad(np.where(count > 0, image, 0.0).astype(np.float64), pad)
    counts = np.pad(count.astype(np.float64), pad)

    def blocks(a: np.ndarray) -> np.ndarray:
        return a.reshape(oh, f, ow, f).sum(axis=(1, 3))

    n = blocks(valid.astype(np.float64))
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(n > 0, blocks(values) / n, np.nan)
    return mean, blocks(counts) / blocks(pixels.astype(np.float64))


def overview_bands(path: Path) -> list[np.ndarray]:
    with rasterio.open(path) as dataset:
        levels = len(dataset.overviews(1))
    out = []
    for level in range(levels):
        with rasterio.open(path, overview_level=level) as overview:
            out.append(overview.read())
    return out


@pytest.mark.parametrize("channels", [1, 3])
def test_the_cog_overviews_are_the_block_means_of_the_map(tmp_path: Path, channels: int) -> None:
    """The writer fills the overviews window by window (tiles aligned to the largest factor):
    each level is the block mean of the map itself (values over pixels with samples, NaN where
    none; the count over all pixels), as GDAL's AVERAGE defines it. Unaligned tiles fall back to
    GDAL's own overviews, with the same levels."""
    scene = dict(SCENE, ground={"texture": {"type": "noise", "square": 0.3, "seed": 5}},
                 camera=dict(SCENE["camera"], channels=channels))
    lf = aos.simulate(scene).light_field
    options = dict(pixel_size=0.03, extent=[-16.0, -15.0, 14.0, 13.0])  # 1000 x 934 pixels
    aligned = aos.render_map(lf, path=tmp_path / "a.tif", arrays=True, tile_size=64, **options)
    assert aligned.uncovered_pixels > 0  # the corners: nodata must stay out of the means
    image = aligned.image if channels > 1 else aligned.image[..., None]
    with rasterio.open(tmp_path / "a.tif") as dataset:
        factors = dataset.overviews(1)
    assert factors == [2, 4]  # halving (rounded down) until a level fits in one 256-pixel block
    for f, bands in zip(factors, overview_bands(tmp_path / "a.tif")):
        assert bands.shape[0] == channels + 1
        for c in range(channels + 1):
            mean, mean_count = block_means(image[..., min(c, channels - 1)], aligned.count, f)
            if c == channels:
                np.testing.assert_allclose(bands[c], mean_count, rtol=2e-7)
                continue
            assert bands[c].shape == mean.shape
            assert np.array_equal(np.isnan(bands[c]), np.isnan(mean))
            # float32 output of a float64 mean: within rounding of the value.
            np.testing.assert_allclose(bands[c][~np.isnan(mean)], mean[~np.isnan(mean)],
                                       rtol=2e-7, atol=1e-6)
    unaligned = aos.render_map(lf, path=tmp_path / "u.tif", tile_size=50, **options)
    assert unaligned.tiles > aligned.tiles
    with rasterio.open(tmp_path / "u.tif") as dataset, rasterio.open(tmp_path / "a.tif") as a:
        assert np.array_equal(dataset.read(), a.read(), equal_nan=True)
        assert dataset.overviews(1) == [2, 4]
    gdal_value = overview_bands(tmp_path / "u.tif")[0][0]
    mean, _ = block_means(image[..., 0], aligned.count, 2)
    inner = (slice(1, min(gdal_value.shape[0], mean.shape[0]) - 1),
             slice(1, min(gdal_value.shape[1], mean.shape[1]) - 1))
    both = ~np.isnan(gdal_value[inner]) & ~np.isnan(mean[inner])
    np.testing.assert_allclose(gdal_value[inner][both], mean[inner][both], rtol=1e-5, atol=1e-4)


def test_overview_levels_and_a_fill_that_falls_back(flight: aos.LightField, tmp_path: Path) -> None:
    """Levels as GDAL's COG driver counts them (513 pixels wide: one level, 256 after halving
    rounded down); a writer whose first windows filled the overviews and whose later one did not
    align gives GDAL's overviews over the whole map, not a mix of both."""
    options = aos.MapOptions(pixel_size=0.05, tile_size=512,
                             extent=[ORIGIN[0] - 12.0, ORIGIN[1] - 10.0, ORIGIN[0] + 13.64,
                                     ORIGIN[1] + 10.0])
    single = aos.render_map(flight, options, path=tmp_path / "w513.tif", arrays=True)
    assert (single.width, single.height) == (513, 400)
    with rasterio.open(tmp_path / "w513.tif") as dataset:
        assert dataset.overviews(1) == [2]
    writer = aos._core._MapGeoTiffWriter(flight, options, 1, str(tmp_path / "mixed.tif"), False)
    image = single.image.astype(np.float32)
    count = single.count
    writer.write(0, 0, image[:256, :256], count[:256, :256])      # aligned: fills level 1
    writer.write(256, 0, image[:256, 256:], count[:256, 256:])    # aligned (ends at the edge)
    writer.write(0, 256, image[256:301], count[256:301])          # ends mid-block: unaligned
    writer.write(0, 301, image[301:], count[301:])
    writer.commit(None)
    # The reference: GDAL's overviews from the start (the first window already unaligned).
    gdal = aos._core._MapGeoTiffWriter(flight, options, 1, str(tmp_path / "gdal.tif"), False)
    gdal.write(0, 0, image[:301], count[:301])
    gdal.write(0, 301, image[301:], count[301:])
    gdal.commit(None)
    with rasterio.open(tmp_path / "mixed.tif") as a, rasterio.open(tmp_path / "w513.tif") as b:
        assert np.array_equal(a.read(), b.read(), equal_nan=True)
    mixed = overview_bands(tmp_path / "mixed.tif")[0]
    assert np.array_equal(mixed, overview_bands(tmp_path / "gdal.tif")[0], equal_nan=True)
    # ... which differ from the exact block means the filled overviews hold (GDAL's 513 -> 256
    # pixels are not 2 x 2 blocks), so the test tells the two apart.
    assert not np.array_equal(mixed[:, :200, :200], overview_bands(tmp_path / "w513.tif")[0][:, :200, :200],
                              equal_nan=True)


def test_min_view_count_in_maps_from_its_one_definition(flight: aos.LightField, flight_file: Path,
                                                        tmp_path: Path) -> None:
    """MapOptions.min_view_count was added as one row of the map's field table (map.h) and its
    use on each tile (map.cpp): the keyword, the JSON form, the CLI flag (map --min-view-count)
    and the viewer's map mode (which copies the fields MapOptions shares with the render
    options) come from that row (issue 32's "add one option" check). Thin pixels become nodata,
    the others keep every bit."""
    everything = aos.render_map(flight, focal_surface=0.0, width=96)
    counts = everything.count
    least = int(np.median(counts[counts > 0]))
    thin = counts < least
    assert least > 1 and np.any(thin & (counts > 0))
    thick = aos.render_map(flight, focal_surface=0.0, width=96, min_view_count=least)
    assert np.all(thick.count[thin] == 0) and np.all(thick.image[thin] == 0)
    np.testing.assert_array_equal(thick.count[~thin], counts[~thin])
    np.testing.assert_array_equal(thick.image[~thin], everything.image[~thin])
    options = aos.MapOptions(width=96, min_view_count=least)
    assert aos.MapOptions.from_json(options.to_json()).min_view_count == least
    with pytest.raises(ValueError, match="min_view_count"):
        aos.render_map(flight, focal_surface=0.0, width=96, min_view_count=-1)
    result = subprocess.run(["aos-render", "map", str(flight_file), "--focal-height", "0",
                             "--width", "96", "--min-view-count", str(least), "-o",
                             str(tmp_path / "m.tif"), "-q"],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    # The viewer's map mode starts from the render options it was given.
    from aos.viewer.session import Session

    session = Session(flight, render_options=aos.IntegralOptions(min_view_count=least),
                      num_threads=1)
    shown = session.map_options(session.parse({"mode": "map", "width": 96}))
    assert shown.min_view_count == least
