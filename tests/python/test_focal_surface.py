"""Focal surfaces beyond planes: meshes (OBJ/PLY), DEM rasters (GeoTIFF) and depth maps render as
the plane they describe; offsets move along up; F0 on its terrain mesh against an independent
numpy ray caster. The F0 part skips when ../shared/data/jku-f0 is absent."""
from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
from pathlib import Path

import warnings

import numpy as np
import pytest

import aos

from conftest import nadir_pose

REPO = Path(__file__).resolve().parents[2]
DATA = Path(os.environ.get("AOS_JKU_F0", REPO.parent / "shared" / "data" / "jku-f0"))
POSES = DATA / "poses" / "poses.json"
DEM = DATA / "dem" / "dem_lr.obj"
FOV_DEG = 50.815436217896945


def _textured_lightfield() -> aos.LightField:
    """5 x 5 nadir views, 3 m apart at 20 m, of a smooth texture on the ground z = 0.3 (rendered
    analytically per view pixel)."""
    light_field = aos.LightField()
    camera = aos.PinholeCamera.from_fov(64, 64, 50.0)
    f = camera.fx
    for j in range(5):
        for i in range(5):
            cx, cy = (i - 2) * 3.0, (j - 2) * 3.0
            pose = nadir_pose(cx, cy, 20.0)
            u, v = np.meshgrid(np.arange(64) + 0.5, np.arange(64) + 0.5)
            ray = np.stack([(u - 32) / f, (v - 32) / f, np.ones_like(u)], -1) @ np.asarray(pose.rotation)
            t = (0.3 - 20.0) / ray[..., 2]
            x, y = cx + t * ray[..., 0], cy + t * ray[..., 1]
            value = 128 + 60 * np.sin(2.1 * x + 0.4) * np.cos(1.7 * y) + 50 * np.sin(1.3 * x - 2.3 * y + 1)
            light_field.add_view(np.clip(value, 0, 255).astype(np.float32), camera, pose, name=f"{j}{i}")
    return light_field


CAMERA = dict(cam_from_world=aos.look_at((0.7, -0.4, 20), (0, 1, 0), up=(0, 1, 0)), fov_deg=60.0,
              width=40, height=30)

SQUARE_OBJ = "v -100 -100 {h}\nv 100 -100 {h}\nv 100 100 {h}\nv -100 100 {h}\nf 1 2 3 4\n"
SQUARE_PLY = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty double x\nproperty double y\n"
              "property double z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
              "-100 -100 {h}\n100 -100 {h}\n100 100 {h}\n-100 100 {h}\n4 0 1 2 3\n")


def test_a_plane_as_obj_ply_dem_and_depth_map_renders_as_the_plane(tmp_path):
    # Per-sample (depth map) and homography renders place samples ~1e-5 view px apart; the
    # texture's slope is <= ~60 grey per view pixel, so values agree within 1e-3 grey and counts
    # exactly (as the C++ test focal_surface/SurfaceRender...).
    rasterio = pytest.importorskip("rasterio")
    light_field = _textured_lightfield()
    plane = aos.render_integral(light_field, focal_surface=0.3, **CAMERA)
    (tmp_path / "square.obj").write_text(SQUARE_OBJ.format(h=0.3))
    (tmp_path / "square.ply").write_text(SQUARE_PLY.format(h=0.3))
    # A DEM written independently of aos (rasterio): 2 x 2 pixels of 200 m, centres at +-100 m.
    with rasterio.open(tmp_path / "square_rio.tif", "w", driver="GTiff", width=2, height=2, count=1,
                       dtype="float32", transform=rasterio.transform.from_origin(-200, 200, 200, 200)) as dst:
        dst.write(np.full((1, 2, 2), 0.3, np.float32))
    aos.Heightfield(np.full((2, 2), 0.3, np.float32), (-200, 200, 0, 200, 0, -200)).write(str(tmp_path / "square_aos.tif"))
    camera = aos.virtual_camera(light_field, aos.IntegralOptions(**CAMERA))
    depth = aos.plane_depth(camera, CAMERA["cam_from_world"], aos.Plane.at_height(0.3))
    surfaces = {
        "obj": aos.Mesh.read(str(tmp_path / "square.obj")),
        "ply": aos.Mesh.read(str(tmp_path / "square.ply")),
        "rasterio dem": aos.Heightfield.read(str(tmp_path / "square_rio.tif")),
        "aos dem": aos.FocalSurface.read(str(tmp_path / "square_aos.tif")),
        "depth map": aos.FocalSurface.from_depth_map(depth, camera, CAMERA["cam_from_world"]),
    }
    for name, surface in surfaces.items():
        # A surface is accepted as focal_surface= and, deprecated, as focal_plane= (it warns).
        for key in ("focal_plane", "focal_surface"):
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                result = aos.render_integral(light_field, **{key: surface}, **CAMERA)
            assert [str(w.message) for w in caught if w.category is DeprecationWarning] == (
                ["render_integral(): focal_plane= is deprecated; use focal_surface="]
                if key == "focal_plane" else [])
            np.testing.assert_array_equal(result.count, plane.count, err_msg=name)
            assert np.max(np.abs(result.image - plane.image)) < 1e-3, name
            assert result.uncovered_pixels == plane.uncovered_pixels == 0


def test_an_offset_moves_the_mesh_along_up_and_pickles(tmp_path):
    light_field = _textured_lightfield()
    (tmp_path / "square.obj").write_text(SQUARE_OBJ.format(h=0.3))
    mesh = aos.Mesh.read(str(tmp_path / "square.obj"))
    plane = aos.render_integral(light_field, focal_surface=0.3 + 0.45, **CAMERA)
    options = aos.IntegralOptions(focal_surface=mesh, surface_offset=0.45, **CAMERA)
    moved = aos.render_integral(light_field, options)
    np.testing.assert_array_equal(moved.count, plane.count)
    assert np.max(np.abs(moved.image - plane.image)) < 1e-3
    unmoved = aos.render_integral(light_field, focal_surface=mesh, **CAMERA)
    assert np.max(np.abs(unmoved.image - plane.image)) > 1.0
    # Options holding a surface, and the surfaces themselves, pickle.
    again = pickle.loads(pickle.dumps(options))
    assert again.focal_surface.kind == "mesh" and again.surface_offset == 0.45
    np.testing.assert_array_equal(aos.render_integral(light_field, again).image, moved.image)
    assert pickle.loads(pickle.dumps(mesh)) == mesh
    # A surface read from a file keeps its file's name through pickling (the JSON form of the
    # options that hold it names the file: the view and map --workers hand-off).
    read = aos.FocalSurface.read(str(tmp_path / "square.obj"))
    assert read.file == str(tmp_path / "square.obj")
    copied = pickle.loads(pickle.dumps(read))
    assert copied.file == read.file and copied == read
    with_surface = aos.IntegralOptions(focal_surface=read)
    assert pickle.loads(pickle.dumps(with_surface)).to_json() == with_surface.to_json()
    assert pickle.loads(pickle.dumps(aos.FocalSurface(mesh))).file == ""
    # An offset moves a plane along up as it moves a mesh: the same image as the moved plane.
    plane_moved = aos.render_integral(light_field, surface_offset=0.45, focal_surface=0.3, **CAMERA)
    np.testing.assert_array_equal(plane_moved.image, plane.image)


def test_heightfield_arrays_geotransform_crs_and_nodata(tmp_path):
    rasterio = pytest.importorskip("rasterio")
    heights = np.arange(12, dtype=np.float32).reshape(3, 4)
    heights[1, 2] = -9999
    with rasterio.open(tmp_path / "dem.tif", "w", driver="GTiff", width=4, height=3, count=1, dtype="float32",
                       crs="EPSG:32633", nodata=-9999,
                       transform=rasterio.transform.from_origin(500000, 5300000, 0.5, 0.5)) as dst:
        dst.write(heights[None])
    field = aos.Heightfield.read(str(tmp_path / "dem.tif"))
    assert field.heights.shape == (3, 4) and field.heights.dtype == np.float32
    assert np.isnan(field.heights[1, 2]) and field.heights[2, 3] == 11
    assert field.geotransform == (500000, 0.5, 0, 5300000, 0, -0.5)
    assert "32633" in field.crs
    assert pickle.loads(pickle.dumps(field)) == field
    # The nodata pixel leaves out the 4 cells around it: 6 cells - 4 = 2 cells, 4 triangles.
    assert field.to_mesh().triangles.shape == (4, 3)


def test_bad_meshes_and_dems_are_value_errors_naming_file_and_field(tmp_path):
    (tmp_path / "nan.obj").write_text("v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(ValueError, match=r"nan.obj: line 2: v: y is not finite"):
        aos.Mesh.read(str(tmp_path / "nan.obj"))
    (tmp_path / "empty.ply").write_text("ply\nformat ascii 1.0\nend_header\n")
    with pytest.raises(ValueError, match=r"empty.ply: the mesh has no vertices"):
        aos.Mesh.read(str(tmp_path / "empty.ply"))
    with pytest.raises(ValueError, match=r"geotransform: rotated"):
        aos.Heightfield(np.zeros((2, 2), np.float32), (0, 1, 0.5, 0, 0, -1))
    with pytest.raises(ValueError, match=r"every pixel is nodata"):
        aos.Heightfield(np.full((2, 2), np.nan, np.float32), (0, 1, 0, 0, 0, -1))


def _aos_render() -> str:
    built = REPO / "build" / "cpp" / "aos-render"
    return str(built) if built.exists() else "aos-render"


def test_cli_focal_surface_renders_and_refuses_bad_files_writing_nothing(tmp_path):
    light_field = _textured_lightfield()
    aos.write_lightfield(str(tmp_path / "lf.json"), light_field)
    (tmp_path / "square.obj").write_text(SQUARE_OBJ.format(h=0.3))
    pose = ",".join(str(v) for v in np.asarray(CAMERA["cam_from_world"].rotation).ravel()) + ","
    look = "--look-at=0.7,-0.4,20,0,1,0,0,1,0"
    common = [_aos_render(), "integral", str(tmp_path / "lf.json"), look, "--fov-deg", "60", "--width", "40",
              "--height", "30"]
    run = subprocess.run(common + ["--focal-surface", str(tmp_path / "square.obj"), "--surface-offset", "0.45",
                                   "-o", str(tmp_path / "mesh.tif")], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    run = subprocess.run(common + ["--focal-height", "0.75", "-o", str(tmp_path / "plane.tif")],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    mesh_image, plane_image = aos.read_image(str(tmp_path / "mesh.tif")), aos.read_image(str(tmp_path / "plane.tif"))
    assert np.max(np.abs(mesh_image.astype(np.float64) - plane_image)) < 1e-3
    (tmp_path / "bad.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n")
    (tmp_path / "rotated.tif").write_bytes(b"not a raster")
    for bad, words in (("bad.obj", "bad.obj: line 4: f: corner 3"), ("rotated.tif", "rotated.tif"),
                       ("missing.ply", "missing.ply")):
        out = tmp_path / f"out_{bad}.tif"
        run = subprocess.run(common + ["--focal-surface", str(tmp_path / bad), "-o", str(out)],
                             capture_output=True, text=True)
        assert run.returncode != 0
        assert words in run.stderr and len(run.stderr.strip().splitlines()) == 1, run.stderr
        assert not out.exists()


# ---- F0 on its terrain mesh ----

def _read_obj(path: Path):
    vertices, faces = [], []
    for line in path.read_text().splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            vertices.append([float(p) for p in parts[1:4]])
        elif parts[0] == "f":
            idx = [int(p.split("/")[0]) for p in parts[1:]]
            idx = [i - 1 if i > 0 else len(vertices) + i for i in idx]
            faces.extend([idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1))
    return np.array(vertices), np.array(faces)


def _ray_mesh(origin, directions, vertices, faces):
    """Moller-Trumbore: the nearest t > 0 of each ray (N, 3) against all triangles, NaN on miss."""
    v0, v1, v2 = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    e1, e2 = v1 - v0, v2 - v0
    best = np.full(len(directions), np.nan)
    for n, d in enumerate(directions):
        p = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, p)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            s = origin - v0
            u = np.einsum("ij,ij->i", s, p) * inv
            q = np.cross(s, e1)
            v = (q @ d) * inv
            t = np.einsum("ij,ij->i", e2, q) * inv
        ok = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
        if ok.any():
            best[n] = t[ok].min()
    return best


@pytest.mark.skipif(not (POSES.exists() and DEM.exists()), reason=f"JKU F0 data not found at {DATA}")
def test_f0_on_dem_lr_covers_every_pixel_and_matches_a_numpy_ray_caster():
    light_field = aos.load_lightfield(str(POSES), fov_deg=FOV_DEG).light_field
    mesh = aos.Mesh.read(str(DEM))
    result = aos.render_integral(light_field, pose_view=191, fov_deg=FOV_DEG, width=512, height=512,
                                 focal_surface=mesh)
    assert result.uncovered_pixels == 0
    assert np.all(np.isfinite(result.image))

    # Independent reference at 300 random pixels: float64 rays from the JSON poses, Moller-Trumbore
    # against the OBJ's triangles, projection into every view, bilinear sampling (edges replicated
    # inside [0, w] x [0, h]), grazing test against the horizontal (>= 1 degree), mean.
    entries = json.loads(POSES.read_text())["images"]
    poses = [np.array([[float(v) for v in row] for row in e["M3x4"]]) for e in entries]
    vertices, faces = _read_obj(DEM)
    rng = np.random.default_rng(15)
    px = rng.integers(0, 512, 300)
    py = rng.integers(0, 512, 300)
    f = 256 / np.tan(np.radians(FOV_DEG) / 2)
    R_v, t_v = poses[191][:, :3], poses[191][:, 3]
    c = -R_v.T @ t_v
    rays = np.stack([(px + 0.5 - 256) / f, (py + 0.5 - 256) / f, np.ones(300)], -1) @ R_v
    t = _ray_mesh(c, rays, vertices, faces)
    assert np.all(np.isfinite(t))
    X = c + t[:, None] * rays
    total, count = np.zeros(300), np.zeros(300, np.int64)
    for view, pose in zip(light_field.views, poses):
        image = view.image.astype(np.float64)
        h_img, w_img = image.shape
        R, tr = pose[:, :3], pose[:, 3]
        P = X @ R.T + tr
        with np.errstate(divide="ignore", invalid="ignore"):
            u = f * P[:, 0] / P[:, 2] + w_img / 2
            v = f * P[:, 1] / P[:, 2] + h_img / 2
        to_view = (-R.T @ tr) - X
        sin_angle = np.abs(to_view[:, 2]) / np.linalg.norm(to_view, axis=1)
        ok = (P[:, 2] > 0) & (u >= 0) & (u <= w_img) & (v >= 0) & (v <= h_img) & (sin_angle >= np.sin(np.radians(1.0)))
        sx, sy = np.where(ok, u - 0.5, 0), np.where(ok, v - 0.5, 0)
        x0, y0 = np.floor(sx).astype(int), np.floor(sy).astype(int)
        ax, ay = sx - x0, sy - y0

        def tap(yy, xx):
            return image[np.clip(yy, 0, h_img - 1), np.clip(xx, 0, w_img - 1)]

        top = tap(y0, x0) * (1 - ax) + tap(y0, x0 + 1) * ax
        bottom = tap(y0 + 1, x0) * (1 - ax) + tap(y0 + 1, x0 + 1) * ax
        total += np.where(ok, top * (1 - ay) + bottom * ay, 0)
        count += ok
    reference = total / np.maximum(count, 1)
    rendered = result.image[py, px].astype(np.float64)
    same_views = result.count[py, px] == count
    difference = np.abs(rendered - reference)[same_views]
    print(f"F0 on dem_lr.obj vs numpy: {same_views.mean():.3f} of pixels with the same views; "
          f"max |diff| {difference.max():.4f}, mean {difference.mean():.5f} grey")
    # The ray casts agree to float32 depth rounding (~3e-6 m at ~40 m: ~3e-5 view px); samples
    # then differ by float32 position rounding (~1e-4 px) times the frames' gradient (<= ~100 grey
    # per px): 0.01 grey. A view seeing a focal point within that of its image border can be in
    # one count and not the other, hence the allowance of a few pixels.
    assert same_views.mean() > 0.98
    assert difference.max() < 0.02


# ---- Terrain-following focal stacks (a surface at N offsets along up) ----

def test_terrain_following_stack_and_all_in_focus_from_python(tmp_path):
    # The ground is z = 0.3; the "DEM" given is 0.5 m too low (z = -0.2). Offsets 0 .. 1 in 11
    # slices (0.1 m apart): the merge must find offset 0.5 (slice 5) and the stack's slices are
    # the plane stack at z = -0.2 .. 0.8 (counts equal, values within 1e-3 grey as above).
    light_field = _textured_lightfield()
    (tmp_path / "low.obj").write_text(SQUARE_OBJ.format(h=-0.2))
    low = aos.Mesh.read(str(tmp_path / "low.obj"))
    stack = aos.render_focal_stack(light_field, focal_surface=low, first_offset=0.0, last_offset=1.0,
                                   slices=11, **CAMERA)
    assert len(stack) == 11 and stack.planes == [] and stack.surface is not None
    assert stack.offsets[0] == 0.0 and stack.offsets[-1] == 1.0 and list(stack.up) == [0, 0, 1]
    planes = aos.render_focal_stack(light_field, first_plane=-0.2, last_plane=0.8, slices=11, **CAMERA)
    assert np.array_equal(stack.counts, planes.counts)
    assert np.max(np.abs(stack.images.astype(np.float64) - planes.images)) < 1e-3
    result = aos.all_in_focus(light_field, focal_surface=low, first_offset=0.0, last_offset=1.0,
                              slices=11, **CAMERA)
    inner = result.slice[8:22, 10:30]
    assert np.all(np.abs(inner - 5.0) <= 0.5), inner  # half a slice, as the plane-stack tests
    # The merged depth lies on the ground z = 0.3 (camera z of the plane), within half a slice.
    camera = aos.virtual_camera(light_field, aos.IntegralOptions(**CAMERA))
    ground = aos.plane_depth(camera, CAMERA["cam_from_world"], aos.Plane.at_height(0.3))
    assert np.max(np.abs(result.depth[8:22, 10:30] - ground[8:22, 10:30])) < 0.06
    # Round trip through a folder keeps the surface, and merging it gives the pipeline's depth.
    aos.write_focal_stack(str(tmp_path / "stack"), stack)
    read = aos.read_focal_stack(str(tmp_path / "stack"))
    assert read.offsets == stack.offsets and read.surface is not None
    assert np.array_equal(aos.merge_focal_stack(read).depth, aos.merge_focal_stack(stack).depth)
    # surface_offset is not a stack option (the offsets replace it).
    with pytest.raises(TypeError, match="surface_offset"):
        aos.render_focal_stack(light_field, focal_surface=low, surface_offset=1.0, **CAMERA)


def test_cli_terrain_following_stack_merge_and_allinfocus(tmp_path):
    light_field = _textured_lightfield()
    aos.write_lightfield(str(tmp_path / "lf.json"), light_field)
    (tmp_path / "low.obj").write_text(SQUARE_OBJ.format(h=-0.2))
    camera = ["--look-at=0.7,-0.4,20,0,1,0,0,1,0", "--fov-deg", "60", "--width", "40", "--height", "30"]
    terrain = ["--focal-surface", str(tmp_path / "low.obj"), "--first-offset", "0", "--last-offset", "1",
               "--slices", "11"]
    run = subprocess.run([_aos_render(), "stack", str(tmp_path / "lf.json"), *camera, *terrain,
                          "-o", str(tmp_path / "stack")], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    meta = json.loads((tmp_path / "stack" / "stack.json").read_text())
    assert meta["surface"]["file"] == "surface.ply" and meta["surface"]["up"] == [0.0, 0.0, 1.0]
    assert [s["offset"] for s in meta["slices"]][::5] == [0.0, 0.5, 1.0]
    run = subprocess.run([_aos_render(), "merge", str(tmp_path / "stack"), "-o", str(tmp_path / "merged")],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    run = subprocess.run([_aos_render(), "allinfocus", str(tmp_path / "lf.json"), *camera, *terrain,
                          "-o", str(tmp_path / "aif")], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    merged = aos.read_image(str(tmp_path / "merged" / "depth.tif"))
    pipeline = aos.read_image(str(tmp_path / "aif" / "depth.tif"))
    assert np.array_equal(merged, pipeline)
    slice_map = aos.read_image(str(tmp_path / "aif" / "slice.tif"))
    assert np.all(np.abs(slice_map[8:22, 10:30] - 5.0) <= 0.5)
    # Planes and a surface together, or offsets without a surface: one clear error, nothing written.
    for extra, words in ((["--focal-surface", str(tmp_path / "low.obj"), "--first-plane", "0"], "--first-plane"),
                         (["--first-offset", "1"], "--first-offset")):
        out = tmp_path / f"bad{len(words)}"
        run = subprocess.run([_aos_render(), "stack", str(tmp_path / "lf.json"), *camera, *extra, "-o", str(out)],
                             capture_output=True, text=True)
        assert run.returncode != 0 and words in run.stderr, run.stderr
        assert not out.exists()


def test_gdal_leaves_no_libtiff_noise_on_later_tiff_writes(tmp_path, capfd):
    # Once GDAL's GTiff driver has run, libtiff reported OpenImageIO's TIFF writes through GDAL:
    # "ERROR 1: TIFFSetField: ... Unknown tag 306" on complete files. RegisterGdal filters them.
    aos.write_image(str(tmp_path / "before.tif"), np.zeros((4, 4), np.float32))
    aos.Heightfield(np.zeros((2, 2), np.float32), (0, 2, 0, 2, 0, -2)).write(str(tmp_path / "dem.tif"))
    aos.write_image(str(tmp_path / "after.tif"), np.ones((4, 4), np.float32))
    captured = capfd.readouterr()
    assert "ERROR" not in captured.err and "TIFF" not in captured.err, captured.err
    assert np.array_equal(aos.read_image(str(tmp_path / "after.tif")), np.ones((4, 4), np.float32))


def test_cli_stack_around_the_ground_estimated_from_points(tmp_path):
    # Points on the ground z = 0.3 under a "canopy" of points 3-6 m above it (as COLMAP's points
    # of a forest): the robust ground plane is z = 0.3, and --first-offset -0.5 --last-offset 0.5
    # put the slices on z = -0.2 .. 0.8 (stack.json's planes).
    light_field = _textured_lightfield()
    aos.write_lightfield(str(tmp_path / "lf.json"), light_field)
    rng = np.random.default_rng(3)
    ground = np.column_stack([rng.uniform(-12, 12, 400), rng.uniform(-12, 12, 400), np.full(400, 0.3)])
    canopy = np.column_stack([rng.uniform(-12, 12, 300), rng.uniform(-12, 12, 300), rng.uniform(3.3, 6.3, 300)])
    points = np.vstack([ground, canopy])
    header = ("ply\nformat ascii 1.0\nelement vertex %d\nproperty double x\nproperty double y\n"
              "property double z\nend_header\n" % len(points))
    (tmp_path / "points.ply").write_text(header + "\n".join(" ".join(repr(float(v)) for v in p) for p in points) + "\n")
    camera = ["--look-at=0.7,-0.4,20,0,1,0,0,1,0", "--fov-deg", "60", "--width", "40", "--height", "30"]
    run = subprocess.run([_aos_render(), "stack", str(tmp_path / "lf.json"), *camera, "--ground",
                          str(tmp_path / "points.ply"), "--first-offset", "-0.5", "--last-offset", "0.5",
                          "--slices", "3", "-o", str(tmp_path / "stack")], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "ground: plane through" in run.stderr
    meta = json.loads((tmp_path / "stack" / "stack.json").read_text())
    heights = [s["plane"]["point"][2] for s in meta["slices"]]
    normals = [s["plane"]["normal"] for s in meta["slices"]]
    assert np.allclose(heights, [-0.2, 0.3, 0.8], atol=1e-9), heights
    assert np.allclose(normals, [[0, 0, 1]] * 3, atol=1e-9), normals
    # The same from Python: estimate_ground's plane as ground_plane.
    stack = aos.render_focal_stack(light_field, ground_plane=aos.Plane.at_height(0.3), first_offset=-0.5,
                                   last_offset=0.5, slices=3, **CAMERA)
    assert np.allclose([p.point[2] for p in stack.planes], [-0.2, 0.3, 0.8])
    # --ground with planes, or a file with too few points: one error, nothing written.
    (tmp_path / "few.ply").write_text(header.replace("vertex %d" % len(points), "vertex 2") + "0 0 0\n1 1 0\n")
    for extra, words in ((["--ground", str(tmp_path / "points.ply"), "--first-plane", "0"], "--first-plane"),
                         (["--ground", str(tmp_path / "few.ply")], "few.ply")):
        out = tmp_path / f"bad{len(words)}"
        run = subprocess.run([_aos_render(), "stack", str(tmp_path / "lf.json"), *camera, *extra, "-o", str(out)],
                             capture_output=True, text=True)
        assert run.returncode != 0 and words in run.stderr, run.stderr
        assert not out.exists()


def test_cli_a_surface_that_covers_part_or_none_of_the_view_is_said_loudly(tmp_path):
    # A square DEM-like mesh 4 m wide under part of the view: count-0 pixels and a warning with
    # the fraction; a mesh far away: an error naming the file, nothing written.
    light_field = _textured_lightfield()
    aos.write_lightfield(str(tmp_path / "lf.json"), light_field)
    small = "v -2 -2 0.3\nv 2 -2 0.3\nv 2 2 0.3\nv -2 2 0.3\nf 1 2 3 4\n"
    far = "v 500 500 0.3\nv 504 500 0.3\nv 504 504 0.3\nv 500 504 0.3\nf 1 2 3 4\n"
    (tmp_path / "small.obj").write_text(small)
    (tmp_path / "far.obj").write_text(far)
    common = [_aos_render(), "integral", str(tmp_path / "lf.json"), "--look-at=0.7,-0.4,20,0,1,0,0,1,0",
              "--fov-deg", "60", "--width", "40", "--height", "30"]
    run = subprocess.run(common + ["--focal-surface", str(tmp_path / "small.obj"), "-o",
                                   str(tmp_path / "small.tif")], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    count = aos.render_integral(light_field, focal_surface=aos.Mesh.read(str(tmp_path / "small.obj")),
                                **CAMERA).count
    fraction = 100.0 * np.count_nonzero(count == 0) / count.size
    assert 0 < fraction < 100
    import re
    said = re.search(r"small\.obj: ([0-9.]+)% of the pixels are uncovered", run.stderr)
    assert said and abs(float(said.group(1)) - fraction) < 1e-3, (fraction, run.stderr)
    out = tmp_path / "far.tif"
    run = subprocess.run(common + ["--focal-surface", str(tmp_path / "far.obj"), "-o", str(out)],
                         capture_output=True, text=True)
    assert run.returncode != 0 and "far.obj: no pixel is covered" in run.stderr, run.stderr
    assert not out.exists()


# ---- Coordinates past what the float ray cast holds (issue 31) ----
#
# A surface at z = 1e20 (or DEM heights of +-3e38, an undeclared nodata value) used to reach
# Embree, which aborted the process (assert ray.valid(), exit 134) and took the Python
# interpreter with it. The cases run in a child interpreter, so that an abort fails the test
# instead of killing pytest: the child runs each case, records the ValueError's message (or
# "ok", or another exception's type), and prints them as JSON; an abort shows as a negative
# return code and no JSON.

EXTREMES = ["1e20", "3e38", "-3e38", "1e300", "nan", "inf"]

_CHILD = """
import json
import sys
import numpy as np
import aos
outcomes = {}
for label, code in json.loads(sys.argv[1]):
    try:
        exec(code, {"np": np, "aos": aos})
        outcomes[label] = "ok"
    except ValueError as error:
        outcomes[label] = "ValueError: " + str(error)
    except Exception as error:
        outcomes[label] = type(error).__name__ + ": " + str(error)
print(json.dumps(outcomes))
"""


def _in_child(cases: list[tuple[str, str]], env: dict | None = None) -> dict[str, str]:
    run = subprocess.run([sys.executable, "-c", _CHILD, json.dumps(cases)], capture_output=True, text=True,
                         timeout=120, env=env)
    assert run.returncode == 0, (run.returncode, run.stderr[-2000:])  # an abort is a signal
    return json.loads(run.stdout.strip().splitlines()[-1])


def _refused(outcome: str, *words: str) -> None:
    assert outcome.startswith("ValueError: "), outcome
    for word in words:
        assert word in outcome, (word, outcome)


# Renders the surface read from PATH with a small light field: what aborted before.
_RENDER = """
light_field = aos.LightField()
camera = aos.PinholeCamera.from_fov(16, 16, 50.0)
for i in range(3):
    light_field.add_view(np.zeros((16, 16), np.float32), camera,
                         aos.look_at((i - 1.0, 0, 20), (i - 1.0, 0.1, 0), up=(0, 1, 0)))
surface = aos.FocalSurface.read(PATH)
aos.render_integral(light_field, focal_surface=surface, fov_deg=60.0, width=16, height=12,
                    cam_from_world=aos.look_at((0, 0, 20), (0, 0.1, 0), up=(0, 1, 0)))
"""


def _render(path: Path) -> str:
    return f"PATH = {str(path)!r}\n" + _RENDER


def _ply_square(z: float) -> bytes:
    header = ("ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty double x\n"
              "property double y\nproperty double z\nelement face 1\n"
              "property list uchar int vertex_indices\nend_header\n").encode()
    vertices = np.array([[-100, -100, 0], [100, -100, 0], [100, 100, z], [-100, 100, 0]], "<f8")
    return header + vertices.tobytes() + bytes([4]) + np.arange(4, dtype="<i4").tobytes()


def test_extreme_mesh_and_plane_coordinates_are_value_errors_not_aborts(tmp_path):
    cases = []
    for i, value in enumerate(EXTREMES):
        (tmp_path / f"e{i}.obj").write_text(f"v -100 -100 0\nv 100 -100 0\nv 100 100 {value}\nv -100 100 0\nf 1 2 3 4\n")
        (tmp_path / f"e{i}.ply").write_bytes(_ply_square(float(value)))
        cases += [
            (f"obj {value}", _render(tmp_path / f"e{i}.obj")),
            (f"ply {value}", _render(tmp_path / f"e{i}.ply")),
            (f"Mesh.read {value}", f"aos.Mesh.read({str(tmp_path / f'e{i}.ply')!r})"),
            # A Mesh made of arrays, and planes given by numbers.
            (f"Mesh {value}", f"aos.Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, float('{value}')]]), [[0, 1, 2]])"),
            (f"FocalSurface {value}", f"aos.FocalSurface(float('{value}'))"),
            (f"focal_plane {value}", "lf = aos.LightField()\n"
             "lf.add_view(np.zeros((8, 8), np.float32), aos.PinholeCamera.from_fov(8, 8, 50.0), aos.look_at((0, 0, 20), (0, 0.1, 0)))\n"
             f"aos.render_integral(lf, focal_surface=float('{value}'), pose_view=0)"),
        ]
    outcomes = _in_child(cases)
    for i, value in enumerate(EXTREMES):
        field = "is not finite" if value in ("nan", "inf") else "beyond +-1000000000 m"
        _refused(outcomes[f"obj {value}"], f"e{i}.obj: line 3: v: z ", field)
        _refused(outcomes[f"ply {value}"], f"e{i}.ply: element vertex 2: z ", field)
        _refused(outcomes[f"Mesh.read {value}"], f"e{i}.ply: element vertex 2: z ")
        _refused(outcomes[f"Mesh {value}"], "Mesh: vertex 2: z ", field)
        _refused(outcomes[f"FocalSurface {value}"], "focal_surface: plane: point")
        _refused(outcomes[f"focal_plane {value}"], "focal_surface: plane: point")


def test_extreme_dem_heights_are_value_errors_not_aborts(tmp_path):
    rasterio = pytest.importorskip("rasterio")
    cases = []
    for i, value in enumerate(EXTREMES):
        heights = np.zeros((4, 5), np.float64)
        heights[2, 3] = float(value)  # 1e300 needs float64; GDAL reads it as float32
        with rasterio.open(tmp_path / f"dem{i}.tif", "w", driver="GTiff", width=5, height=4, count=1,
                           dtype="float64", transform=rasterio.Affine(50, 0, -100, 0, -50, 100)) as dst:
            dst.write(heights[None])
        cases += [(f"dem {value}", _render(tmp_path / f"dem{i}.tif")),
                  (f"Heightfield {value}",
                   f"aos.Heightfield(np.full((2, 2), float('{value}'), np.float32), (0, 1, 0, 0, 0, -1))")]
    outcomes = _in_child(cases)
    for i, value in enumerate(EXTREMES):
        if value == "nan":
            # NaN is nodata in a DEM: the raster is read (and renders) with a hole; all NaN is
            # "every pixel is nodata".
            assert outcomes["dem nan"] == "ok", outcomes["dem nan"]
            _refused(outcomes["Heightfield nan"], "every pixel is nodata")
            continue
        _refused(outcomes[f"dem {value}"], f"dem{i}.tif: heights: pixel (3, 2) (column, row) ")
        _refused(outcomes[f"Heightfield {value}"], "Heightfield: heights: pixel (0, 0) (column, row) ")


def test_extreme_depth_maps_and_cameras_are_value_errors_and_far_map_points_miss():
    cases = []
    for value in ("1e20", "3e38"):
        cases.append((f"depth {value}", f"""
camera = aos.PinholeCamera.from_fov(6, 5, 50.0)
depth = np.full((5, 6), 10.0, np.float32)
depth[2, 3] = float('{value}')
aos.FocalSurface.from_depth_map(depth, camera, aos.look_at((0, 0, 20), (0, 0.1, 0), up=(0, 1, 0)))
"""))
        # A finite mesh seen from a camera that far; the map's vertical lines that far miss.
        cases.append((f"camera {value}", f"""
mesh = aos.Mesh(np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0.]]), [[0, 1, 2], [0, 2, 3]])
camera = aos.PinholeCamera.from_fov(8, 8, 50.0)
light_field = aos.LightField()
light_field.add_view(np.zeros((8, 8), np.float32), camera, aos.look_at((0, 0, 20), (0, 0.1, 0), up=(0, 1, 0)))
heights = aos.FocalSurface(mesh).heights_at(light_field, np.array([[float('{value}'), 0.0], [0.5, 0.5]]))
assert np.isnan(heights[0]) and heights[1] == 0.0, heights
aos.render_integral(light_field, focal_surface=mesh, fov_deg=60.0, width=8, height=8,
                    cam_from_world=aos.look_at((0, 0, float('{value}')), (0, 0.1, 0), up=(0, 1, 0)))
"""))
    outcomes = _in_child(cases)
    for value in ("1e20", "3e38"):
        _refused(outcomes[f"depth {value}"], "depth: pixel (3, 2): depth ")
        _refused(outcomes[f"camera {value}"], "cam_from_world: the virtual camera's centre lies")


@pytest.mark.parametrize("value", ["1e20", "-3e38", "1e300", "nan"])
def test_cli_extreme_surfaces_exit_1_writing_nothing(tmp_path, value):
    light_field = _textured_lightfield()
    aos.write_lightfield(str(tmp_path / "lf.json"), light_field)
    (tmp_path / "e.obj").write_text(f"v -100 -100 0\nv 100 -100 0\nv 100 100 {value}\nv -100 100 0\nf 1 2 3 4\n")
    camera = ["--look-at=0.7,-0.4,20,0,1,0,0,1,0", "--fov-deg", "60", "--width", "40", "--height", "30"]
    for command, extra in (("integral", camera), ("map", ["--pixel-size", "0.5"])):
        out = tmp_path / f"{command}.tif"
        run = subprocess.run([_aos_render(), command, str(tmp_path / "lf.json"), *extra, "--focal-surface",
                              str(tmp_path / "e.obj"), "-o", str(out)], capture_output=True, text=True, timeout=120)
        assert run.returncode == 1, (command, run.returncode, run.stderr)
        assert "e.obj: line 3: v: z " in run.stderr, run.stderr
        assert not out.exists()
    # A plane given by numbers: refused as bad input, never a signal.
    run = subprocess.run([_aos_render(), "integral", str(tmp_path / "lf.json"), *camera, "--focal-height", value,
                          "-o", str(tmp_path / "plane.tif")], capture_output=True, text=True, timeout=120)
    assert run.returncode in (1, 2) and "--focal-height" in run.stderr, (run.returncode, run.stderr)
    assert not (tmp_path / "plane.tif").exists()


def test_a_ply_header_of_2e9_vertices_is_refused_naming_the_file_not_bad_alloc(tmp_path):
    # Before: "error: std::bad_alloc" (the reader reserved 48 GB), naming no file.
    header = ("ply\nformat binary_little_endian 1.0\nelement vertex 2000000000\nproperty double x\n"
              "property double y\nproperty double z\nend_header\n")
    (tmp_path / "huge.ply").write_bytes(header.encode() + bytes(48))
    with pytest.raises(ValueError, match=r"huge.ply: PLY header: element vertex 2000000000: the file cannot hold"):
        aos.Mesh.read(str(tmp_path / "huge.ply"))
    light_field = _textured_lightfield()
    aos.write_lightfield(str(tmp_path / "lf.json"), light_field)
    run = subprocess.run([_aos_render(), "integral", str(tmp_path / "lf.json"), "--look-at=0.7,-0.4,20,0,1,0,0,1,0",
                          "--focal-surface", str(tmp_path / "huge.ply"), "-o", str(tmp_path / "out.tif")],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 1 and "huge.ply: PLY header: element vertex 2000000000" in run.stderr, run.stderr
    assert "bad_alloc" not in run.stderr
    # Counts the file holds but the memory budget (AOS_MEMORY_LIMIT_MB) does not: refused naming
    # the limit, where without it the file is read (and refused for having no faces).
    (tmp_path / "budget.ply").write_bytes(header.replace("2000000000", "50000").encode() + bytes(50000 * 24))
    case = [("read", f"aos.Mesh.read({str(tmp_path / 'budget.ply')!r})")]
    _refused(_in_child(case)["read"], "budget.ply: the mesh has no triangles")
    _refused(_in_child(case, env=dict(os.environ, AOS_MEMORY_LIMIT_MB="1"))["read"], "budget.ply",
             "AOS_MEMORY_LIMIT_MB")
