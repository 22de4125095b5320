"""The simulator from Python and the CLI: scenes as dicts, paths or Scene objects, written
outputs, key-path errors, and bad input that leaves nothing behind."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import aos

EXE = shutil.which("aos-render")

SMALL = {
    "occluders": {"voxels": {"center": [0, 0, 8], "size": [20, 20, 8], "grid": [40, 40, 16],
                             "density": 0.5}},
    "camera": {"width": 32, "height": 24, "fov_deg": 60},
    "sampling": {"grid": 3, "aperture": {"diameter": 10}},
    "truth": {"width": 16, "height": 16},
}


def run(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    assert EXE is not None
    return subprocess.run([EXE, *args], capture_output=True, text=True, cwd=cwd, timeout=120)


def snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_simulate_a_dict_and_render_its_truth_camera() -> None:
    result = aos.simulate(SMALL)
    assert len(result.light_field) == 9
    assert len(result.true_cam_from_world) == 9
    truth = result.truth
    assert truth.ground.shape == (16, 16) and truth.ground.dtype == np.uint8
    assert truth.depth.dtype == np.float32 and truth.blocked_fraction.dtype == np.float32
    assert truth.views_seeing.dtype == np.uint32
    assert 0.0 <= truth.blocked_fraction.min() and truth.blocked_fraction.max() <= 1.0
    stats = result.stats
    assert stats["primary_rays"] == 9 * 32 * 24
    assert stats["occluder_bvh"] and not stats["ground_bvh"]
    assert abs(stats["nadir_blocked_fraction"] - 0.5) < 0.1
    image = aos.render_integral(result.light_field, cam_from_world=truth.cam_from_world,
                                fov_deg=truth.camera.fov_x_deg(), width=16, height=16).image
    assert image.shape == (16, 16) and np.isfinite(image).all()


def test_scene_objects_paths_and_the_json_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(SMALL))
    from_path = aos.load_scene(str(path))
    assert from_path.source == str(path)
    assert len(from_path.view_positions()) == 9 and from_path.has_occluders()
    text = from_path.to_json()
    assert aos.parse_scene(text).to_json() == text
    a = aos.simulate(from_path)
    b = aos.simulate(path)
    np.testing.assert_array_equal(a.light_field.views[4].image, b.light_field.views[4].image)
    default = aos.default_scene()
    assert "default" in default.source and default.has_occluders()


def test_simulate_writes_a_folder_that_loads_back(tmp_path: Path) -> None:
    out = tmp_path / "out"
    result = aos.simulate(SMALL, out)
    names = set(snapshot(out))
    assert {"lightfield.json", "lightfield_true.json", "scene.json", "truth/ground.png",
            "truth/depth.tif", "truth/height.tif", "truth/views_seeing.tif",
            "truth/blocked_fraction.tif", "truth/truth.json"} <= names
    assert sum(name.startswith("views/") for name in names) == 9
    loaded = aos.load_lightfield(str(out / "lightfield.json")).light_field
    np.testing.assert_array_equal(loaded.views[3].image, result.light_field.views[3].image)
    summary = json.loads((out / "truth" / "truth.json").read_text())
    assert summary["stats"]["primary_rays"] == result.stats["primary_rays"]
    # scene.json reproduces the same simulation.
    again = aos.simulate(out / "scene.json")
    np.testing.assert_array_equal(again.light_field.views[8].image, result.light_field.views[8].image)
    with pytest.raises(ValueError, match="not empty"):
        aos.simulate(SMALL, out)


def test_errors_name_the_key_path() -> None:
    with pytest.raises(ValueError, match=r"/occluders/voxels/density: 1\.5 is outside \[0, 1\)"):
        aos.simulate({"occluders": {"voxels": {"density": 1.5}}})
    with pytest.raises(ValueError, match=r"/camera/widht: unknown key"):
        aos.simulate({"camera": {"widht": 64}})
    with pytest.raises(ValueError, match=r"/sampling/grid: expected a whole number"):
        aos.parse_scene('{"sampling": {"grid": "9"}}')


def test_progress_is_reported_and_can_cancel() -> None:
    stages = []

    def progress(stage: str, done: int, total: int) -> None:
        stages.append(stage)

    aos.simulate(SMALL, progress=progress)
    assert {"geometry", "views", "ground truth"} <= set(stages)

    def stop(stage: str, done: int, total: int) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        aos.simulate(SMALL, progress=stop)


@pytest.mark.skipif(EXE is None, reason="aos-render is not on PATH (pip install .)")
@pytest.mark.parametrize(
    "scene, fragment",
    [
        ('{"occluders": {"voxels": {"densty": 0.5}}}', "/occluders/voxels/densty: unknown key"),
        ('{"camera": {"width": "512"}}', "/camera/width: expected a whole number"),
        ('{"occluders": {"voxels": {"density": 1.0}}}', "/occluders/voxels/density: 1 is outside"),
        ('{"occluders": {"voxels": {"size": [10, -2, 10]}}}', "/occluders/voxels/size/1"),
        ('{"ground": {"height": 30}}', "is not above the ground"),
        ('{"occluders": {"voxels": {"center": [0, 0, 20], "size": [40, 40, 4]}}}',
         "inside the voxel occluder volume"),
        ('{"seed": 1,', "not valid JSON"),
    ],
)
def test_cli_bad_scenes_fail_cleanly(tmp_path: Path, scene: str, fragment: str) -> None:
    path = tmp_path / "scene.json"
    path.write_text(scene)
    before = snapshot(tmp_path)
    result = run("simulate", str(path), "-o", str(tmp_path / "out"), "-q")
    assert result.returncode == 1
    lines = [line for line in result.stderr.splitlines() if line.startswith("aos-render: error:")]
    assert len(lines) == 1, result.stderr
    assert str(path) in lines[0] and fragment in lines[0], lines[0]
    assert snapshot(tmp_path) == before  # no output, no temporary folder, input unchanged
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.json"]


@pytest.mark.skipif(EXE is None, reason="aos-render is not on PATH (pip install .)")
def test_cli_simulate_writes_and_never_overwrites(tmp_path: Path) -> None:
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(SMALL))
    out = tmp_path / "out"
    result = run("simulate", str(path), "-o", str(out), "-q")
    assert result.returncode == 0, result.stderr
    assert (out / "lightfield.json").is_file() and (out / "truth" / "ground.png").is_file()
    written = snapshot(out)
    again = run("simulate", str(path), "-o", str(out), "-q")
    assert again.returncode == 1 and "not an empty folder" in again.stderr
    assert snapshot(out) == written
    printed = run("simulate", str(path), "--print-scene")
    assert printed.returncode == 0 and json.loads(printed.stdout)["sampling"]["grid"] == 3


SCENES = sorted((Path(__file__).resolve().parents[2] / "scenes").glob("*.json"))


@pytest.mark.parametrize("path", SCENES, ids=[p.name for p in SCENES])
def test_example_scenes_parse_and_round_trip(path: Path) -> None:
    scene = aos.load_scene(str(path))
    text = scene.to_json()
    assert aos.parse_scene(text, "again", str(path.parent)).to_json() == text


def test_the_scene_camera_takes_the_fields_of_every_aos_camera(tmp_path: Path) -> None:
    """The scene's camera reads the same camera fields as every other format (json_codec.h):
    `model` (its older name `lens`), fov_deg or fx, fy, cx, cy, distortion, xi, skew. A pinhole
    given by the intrinsics its field of view implies gives identical views; a fisheye from a
    camera file simulates through that exact lens; contradictions are refused."""
    base = {"camera": {"width": 48, "height": 40, "fov_deg": 50},
            "sampling": {"altitude": 35, "grid": 2, "aperture": {"diameter": 6}},
            "truth": {"width": 8, "height": 8, "blocked_fraction": False}}
    by_fov = aos.simulate(base)
    pinhole = aos.PinholeCamera.from_fov(48, 40, 50)
    explicit = json.loads(json.dumps(base))
    del explicit["camera"]["fov_deg"]
    explicit["camera"].update({"model": "pinhole", "fx": pinhole.fx, "fy": pinhole.fy,
                               "cx": pinhole.cx, "cy": pinhole.cy})
    by_intrinsics = aos.simulate(explicit)
    assert by_intrinsics.truth.camera == by_fov.truth.camera
    for a, b in zip(by_fov.light_field.views, by_intrinsics.light_field.views):
        assert a.camera == b.camera and np.array_equal(a.image, b.image)
    # A camera file's fisheye, its camera fields pasted into a scene.
    lens = aos.LensCamera(model=aos.LensModel.fisheye, width=48, height=40, fx=20.0, fy=20.0,
                          cx=24.0, cy=20.0, distortion=[0.01, 0.0, 0.0, 0.0])
    aos.write_camera_file(tmp_path / "fisheye.json", lens)
    document = json.loads((tmp_path / "fisheye.json").read_text())
    scene = json.loads(json.dumps(base))
    scene["camera"] = {key: document[key] for key in
                       ("model", "width", "height", "fx", "fy", "cx", "cy", "distortion", "xi",
                        "skew") if key in document}
    scene["truth"]["fov_deg"] = 40
    simulated = aos.simulate(scene)
    assert simulated.light_field.views[0].camera == aos.read_camera_file(tmp_path / "fisheye.json")
    for bad, fragment in (({"lens": "pinhole", "model": "pinhole"}, "give model or lens"),
                          ({"fx": 10.0}, "give either fov_deg or fx, fy, cx, cy"),
                          ({"fx": 10.0, "fy": 10.0, "cx": 1.0, "cy": 1.0},
                           "give either fov_deg or fx, fy, cx, cy")):
        wrong = json.loads(json.dumps(base))
        wrong["camera"].update(bad)
        with pytest.raises(ValueError, match=fragment):
            aos.simulate(wrong)
    missing = json.loads(json.dumps(explicit))
    del missing["camera"]["cy"]
    with pytest.raises(ValueError, match=r"/camera/cy: missing"):
        aos.simulate(missing)


def test_the_scenes_ground_as_a_dem_is_the_simulated_ground(tmp_path: Path) -> None:
    # A 1.5 m step and a slope on a 0.25 m grid over [-8, 8]^2: ground_heightfield's pixel
    # centres are the simulator's grid vertices, so the DEM's depth from the truth camera is the
    # simulator's own truth depth (Embree in float32: within 1e-4 m), and a render on it
    # (written and read back as a GeoTIFF) is in focus where a plane through the middle is not.
    scene = aos.parse_scene(json.dumps({
        "ground": {"slope": [0.0, 0.0625], "cell_size": 0.25, "extent": [-8, -8, 8, 8],
                   "steps": [{"point": [0.0, 0.0], "direction": [1, 0], "height": 1.5}],
                   "texture": {"type": "noise", "square": 0.5}},
        "camera": {"width": 96, "height": 96, "fov_deg": 50},
        "sampling": {"altitude": 15, "grid": 5, "aperture": {"diameter": 8}},
        "truth": {"width": 48, "height": 48, "fov_deg": 30, "blocked_fraction": False},
    }))
    dem = aos.ground_heightfield(scene)
    assert (dem.width, dem.height) == (65, 65)
    assert dem.geotransform == (-8.125, 0.25, 0.0, 8.125, 0.0, -0.25)
    assert dem.heights[0, 64] == np.float32(1.5 + 0.0625 * 8)  # row 0 is y = 8; x = 8 is stepped
    path = tmp_path / "ground.tif"
    dem.write(str(path))
    assert aos.Heightfield.read(str(path)) == dem
    assert aos.ground_heightfield(scene, [0, 0, 1, 1]).width == 5

    result = aos.simulate(scene)
    truth = result.truth
    camera = truth.camera
    surface = aos.FocalSurface.read(str(path))
    depth = surface.depth_for(result.light_field, camera, truth.cam_from_world)
    assert np.abs(depth - truth.depth).max() < 1e-4
    options = dict(cam_from_world=truth.cam_from_world, fov_deg=camera.fov_x_deg(), width=48,
                   height=48)
    on_dem = aos.render_integral(result.light_field, focal_surface=surface, **options)
    on_depth = aos.render_integral_on_depth(result.light_field, depth, **options)
    np.testing.assert_array_equal(on_dem.image, on_depth.integral.image)
    on_plane = aos.render_integral(result.light_field, focal_surface=aos.Plane.at_height(0.75),
                                   **options)
    psnr = [aos.compare_images(r.image, truth.ground).psnr_db for r in (on_dem, on_plane)]
    assert psnr[0] > psnr[1] + 6.0, psnr  # measured: 36.7 dB against 24.6 dB

    with pytest.raises(ValueError, match="/ground/extent"):
        aos.ground_heightfield(aos.parse_scene(json.dumps({"ground": {"steps": [
            {"point": [0, 0], "direction": [1, 0], "height": 1.0}]}})))
