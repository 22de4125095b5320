"""Poses from frames with COLMAP (aos-render poses, aos.estimate_poses): a simulated flight with
known poses goes through the whole pipeline, is geo-referenced at UTM coordinates, and is
compared with the truth; frames COLMAP cannot register are listed. Skipped without COLMAP."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import aos

pytestmark = pytest.mark.skipif(shutil.which("colmap") is None, reason="COLMAP is not installed")

UTM = np.array([512000.0, 5300000.0, 300.0])  # added to the simulator's frame
FOV = 60.0


def flight_scene(grid: int = 4) -> dict:
    # 16 frames of 512 x 384 from 20 m, 3 m apart (about 85 % overlap), over textured ground
    # with a few trees: SIFT needs texture, and the trees give the scene relief.
    return {"seed": 5,
            "ground": {"texture": {"type": "noise", "square": 0.25, "colors": [0.1, 0.9]}},
            "occluders": {"trees": {"per_hectare": 80, "leaves_per_tree": 300}},
            "camera": {"width": 512, "height": 384, "fov_deg": FOV},
            "sampling": {"altitude": 20.0, "grid": grid, "aperture": {"diameter": 3.0 * (grid - 1)}},
            "truth": {"width": 96, "height": 96, "fov_deg": 40.0}}


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    """The simulated flight, its positions file, and `aos-render poses` run on it once."""
    root = tmp_path_factory.mktemp("flight")
    simulation = aos.simulate(flight_scene(), root / "sim")
    frames = root / "sim" / "views"
    # Two frames COLMAP cannot register (no texture), same size as the others.
    blank = np.full((384, 512), 128, np.uint8)
    aos.write_image(str(frames / "9998.png"), blank)
    aos.write_image(str(frames / "9999.png"), blank)
    lines = ["name,x,y,z"]
    for k, pose in enumerate(simulation.true_cam_from_world):
        c = pose.center + UTM
        lines.append(f"{k:04d}.png,{c[0]:.4f},{c[1]:.4f},{c[2]:.4f}")
    (root / "gps.csv").write_text("\n".join(lines) + "\n")
    # The known camera (as `aos-render calibrate` would give it). Self-calibrating the focal
    # length is ill-posed for nadir views of nearly flat ground: COLMAP then converges to
    # f = 443 px or f = 960 px with the same reprojection error, run to run (docs/poses.md).
    camera = simulation.light_field.views[0].camera
    aos.write_camera_file(root / "camera.json",
                          aos.LensCamera(aos.LensModel.pinhole, camera.width, camera.height,
                                         camera.fx, camera.fy, camera.cx, camera.cy))
    before = {p.name: p.read_bytes() for p in frames.iterdir()}
    done = subprocess.run(["aos-render", "poses", str(frames), "-o", str(root / "poses.json"),
                           "--positions-file", str(root / "gps.csv"), "--camera-file",
                           str(root / "camera.json"), "--max-num-features", "1024", "--sequential-overlap", "4",
                           "--workspace", str(root / "ws"),
                           "--points-output", str(root / "points.ply")],
                          capture_output=True, text=True)
    after = {p.name: p.read_bytes() for p in frames.iterdir()}
    return {"root": root, "simulation": simulation, "done": done, "unchanged": before == after}


def rotation_error_deg(a: np.ndarray, b: np.ndarray) -> float:
    cos = (np.trace(a @ b.T) - 1.0) / 2.0
    return math.degrees(math.acos(max(-1.0, min(1.0, cos))))


def test_poses_match_the_truth_after_geo_referencing(flight) -> None:
    done = flight["done"]
    assert done.returncode == 0, done.stderr
    assert flight["unchanged"]  # the frames were never modified
    # The blank frames are named as unregistered, and the rest is usable.
    assert "2 of 18 frames were not registered: 9998.png, 9999.png" in done.stderr
    assert "geo-referenced by 16 positions" in done.stdout
    loaded = aos.load_lightfield(str(flight["root"] / "poses.json"), load_images=False)
    light_field = loaded.light_field
    assert len(light_field) == 16
    source = light_field.pose_source
    assert source.method == "colmap" and source.georeferenced
    assert source.unregistered == ["9998.png", "9999.png"]
    assert 0.0 < source.mean_reprojection_error_px < 1.0
    # e = error_px x depth / f: about 20 m depth; f held at the known 443 px.
    assert source.median_depth == pytest.approx(20.0, rel=0.1)
    f = light_field.views[0].camera.fx
    assert f == pytest.approx(256.0 / math.tan(math.radians(FOV / 2)), rel=1e-9)
    assert source.pose_error == pytest.approx(source.mean_reprojection_error_px * source.median_depth / f,
                                              rel=1e-6)
    # The origin holds the UTM-sized mean in double; poses are small numbers about it.
    origin = np.asarray(light_field.origin)
    assert np.all(np.abs(origin - UTM) < 25.0)  # the centres' mean: 20 m up, about (0, 0)
    truth = flight["simulation"].true_cam_from_world
    centre_errors, rotation_errors = [], []
    for view in light_field.views:
        k = int(Path(view.name).stem)
        true_centre = truth[k].center + UTM
        centre_errors.append(np.linalg.norm(view.cam_from_world.center + origin - true_centre))
        rotation_errors.append(rotation_error_deg(np.asarray(view.cam_from_world.rotation),
                                                  np.asarray(truth[k].rotation)))
    # The target for a 20 m flight: centimetres and tenths of a degree.
    print(f"centre error max {max(centre_errors) * 100:.2f} cm, rotation error max "
          f"{max(rotation_errors):.3f} deg")
    assert max(centre_errors) < 0.05
    assert max(rotation_errors) < 0.2


def test_ground_from_the_reconstructed_points_is_the_true_ground(flight) -> None:
    """`aos-render ground` on the points COLMAP reconstructed of the simulated forest: the true
    ground is flat at the simulator's z = 0, i.e. UTM[2] in the world frame."""
    rasterio = pytest.importorskip("rasterio")
    assert flight["done"].returncode == 0, flight["done"].stderr
    root = flight["root"]
    done = subprocess.run(["aos-render", "ground", str(root / "poses.json"), "--points",
                           str(root / "points.ply"), "-o", str(root / "ground.tif"),
                           "--cell-size-m", "3", "--json"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["up"] == "+z"
    with rasterio.open(root / "ground.tif") as dem:
        heights = dem.read(1)
    # Measured cells and fill alike: within 0.25 m of the true ground (pose error is about a
    # centimetre; SIFT points on the textured ground scatter by a few centimetres; the 0.1
    # quantile keeps the lower envelope), and the plane is level within a degree.
    print(f"ground DEM error max {np.abs(heights - UTM[2]).max():.3f} m")
    assert np.abs(heights - UTM[2]).max() < 0.25
    normal = np.asarray(report["plane_normal"])
    assert normal[2] > math.cos(math.radians(1.0))
    # The flight was 20 m above the ground.
    assert report["height_above_ground_m"]["median"] == pytest.approx(20.0, abs=0.25)


def test_integral_from_recovered_poses_matches_the_true_one(flight) -> None:
    assert flight["done"].returncode == 0, flight["done"].stderr
    simulation = flight["simulation"]
    recovered = aos.load_lightfield(str(flight["root"] / "poses.json")).light_field
    origin = np.asarray(recovered.origin)
    truth = simulation.truth
    # The truth camera and the ground plane, expressed in the recovered light field's frame
    # (local = simulator frame + UTM - origin).
    shift = UTM - origin
    pose = truth.cam_from_world
    rotation = np.asarray(pose.rotation)
    moved = aos.Rigid3d(rotation, np.asarray(pose.translation) - rotation @ shift)
    common = dict(fov_deg=40.0, width=96, height=96, aperture_radius=math.inf)
    true_image = aos.render_integral(simulation.light_field, cam_from_world=pose,
                                     focal_surface=aos.Plane.at_height(0.0), **common).image
    recovered_image = aos.render_integral(recovered, cam_from_world=moved,
                                          focal_surface=aos.Plane.at_height(shift[2]), **common).image
    mask = np.ones(true_image.shape, np.uint8)
    psnr = aos.compare_images(recovered_image, true_image, mask, data_range=255.0).psnr_db
    print(f"integral from recovered poses vs true poses: {psnr:.1f} dB")
    assert psnr > 30.0


def test_python_api_and_bad_input(flight, tmp_path) -> None:
    with pytest.raises(ValueError, match="not a folder of frames"):
        aos.estimate_poses(tmp_path / "missing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="no readable frames"):
        aos.estimate_poses(tmp_path / "empty")
    with pytest.raises(ValueError, match=r"colmap: \"/nonexistent/colmap\" not found"):
        aos.estimate_poses(flight["root"] / "sim" / "views", colmap="/nonexistent/colmap")
    with pytest.raises(ValueError, match="matcher"):
        aos.estimate_poses(tmp_path, matcher="vocab")
    with pytest.raises(ValueError, match="only 0 frames carry EXIF GPS positions"):
        aos.estimate_poses(flight["root"] / "sim" / "views", exif_positions=True)
    with pytest.raises(TypeError, match="unexpected keyword argument 'overlap'"):
        aos.estimate_poses(tmp_path, overlap=3)
    # The CLI names its flags, exits 1, and writes nothing.
    done = subprocess.run(["aos-render", "poses", str(tmp_path / "empty"), "-o",
                           str(tmp_path / "out.json")], capture_output=True, text=True)
    assert done.returncode == 1 and "no readable frames" in done.stderr
    assert not (tmp_path / "out.json").exists()
    done = subprocess.run(["aos-render", "poses", str(tmp_path / "empty"), "-o",
                           str(tmp_path / "out.json"), "--matcher", "vocab"],
                          capture_output=True, text=True)
    assert done.returncode == 2 and "--matcher" in done.stderr
    # The kept workspace holds COLMAP's model, which import_colmap (and the CLI) read back,
    # geo-referenced the same way.
    model = flight["root"] / "ws" / "sparse" / "0"
    frames = flight["root"] / "sim" / "views"
    imported = aos.import_colmap(model, frames, positions_file=str(flight["root"] / "gps.csv"))
    assert len(imported.registered) == 16
    assert imported.unregistered == ["9998.png", "9999.png"]
    assert imported.georeferenced and imported.light_field.pose_source.pose_error > 0
    done = subprocess.run(["aos-render", "import-colmap", str(model), "--images-dir", str(frames),
                           "--positions-file", str(flight["root"] / "gps.csv"), "-o",
                           str(tmp_path / "imported.json")], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "16 of 18 frames registered" in done.stdout
    assert "2 of 18 frames were not registered" in done.stderr
    again = aos.load_lightfield(str(tmp_path / "imported.json"), load_images=False).light_field
    original = aos.load_lightfield(str(flight["root"] / "poses.json"), load_images=False).light_field
    np.testing.assert_allclose(np.asarray(again.origin), np.asarray(original.origin), atol=1e-9)
    for a, b in zip(again.views, original.views):
        np.testing.assert_allclose(a.cam_from_world.center, b.cam_from_world.center, atol=1e-9)
    positions = aos.read_positions(str(flight["root"] / "gps.csv"))
    assert len(positions) == 16 and positions["0000.png"][0] > 500000.0
    report = json.loads((flight["root"] / "poses.json").read_text())["pose_source"]
    assert report["georeferenced"] is True


def test_exhaustive_matching_with_real_colmap(flight, tmp_path) -> None:
    # Exhaustive matching matches all pairs and registers the flight. (Spatial matching, whose
    # pairs come from the positions written into COLMAP's database as priors, is the quick
    # preset's: test_quick_preset_with_real_colmap.)
    frames = flight["root"] / "sim" / "views"
    gps = str(flight["root"] / "gps.csv")
    camera = str(flight["root"] / "camera.json")
    stages = []
    exhaustive = aos.estimate_poses(frames, matcher="exhaustive", positions_file=gps,
                                    camera_file=camera, max_num_features=1024,
                                    progress=lambda stage, done, total: stages.append(stage))
    assert len(exhaustive.registered) == 16 and exhaustive.georeference_rms_m < 0.05
    assert {"features", "matching", "mapping", "import"} <= set(stages)


def test_quick_preset_with_real_colmap(flight, tmp_path) -> None:
    # preset="quick" with positions matches spatially (the warning about frames without a
    # position prior comes from spatial matching only) and still registers the flight.
    frames = flight["root"] / "sim" / "views"
    gps = str(flight["root"] / "gps.csv")
    quick = aos.estimate_poses(frames, preset="quick", positions_file=gps,
                               camera_file=str(flight["root"] / "camera.json"))
    assert len(quick.registered) == 16 and quick.georeferenced
    assert quick.georeference_rms_m < 0.05
    assert any("2 of 18 frames have no position prior; spatial matching cannot match" in w
               for w in quick.warnings)
    with pytest.raises(ValueError, match="preset"):
        aos.estimate_poses(frames, preset="fast")
    done = subprocess.run(["aos-render", "poses", str(frames), "-o", str(tmp_path / "q.json"),
                           "--preset", "slow"], capture_output=True, text=True)
    assert done.returncode == 2 and "--preset" in done.stderr


def test_scene_scale_is_checked_against_the_flight_height(flight, tmp_path) -> None:
    # The flight's kept COLMAP model (known camera, so its scale is right: median depth about
    # 20 m) imported with a stated flight height.
    model = flight["root"] / "ws" / "sparse" / "0"
    frames = flight["root"] / "sim" / "views"
    gps = str(flight["root"] / "gps.csv")
    right = aos.import_colmap(model, frames, positions_file=gps, flight_height_m=20.0)
    assert not right.implausible
    assert abs(right.scale_deviation) < 0.15
    assert right.scale_deviation == pytest.approx(right.median_depth / 20.0 - 1.0, rel=1e-12)
    assert not any("scene scale" in w for w in right.warnings)
    unchecked = aos.import_colmap(model, frames, positions_file=gps)
    assert math.isnan(unchecked.scale_deviation)
    # A 14 m flight that reads about 20 m deep: refused, or kept loudly with the fields set.
    with pytest.raises(ValueError, match=r"IMPLAUSIBLE scene scale: the views' median depth came "
                                         r"out at .* m but the flight height is 14 m"):
        aos.import_colmap(model, frames, positions_file=gps, flight_height_m=14.0)
    kept = aos.import_colmap(model, frames, positions_file=gps, flight_height_m=14.0,
                             allow_implausible=True)
    assert kept.implausible
    assert kept.scale_deviation == pytest.approx(kept.median_depth / 14.0 - 1.0, rel=1e-12)
    assert kept.scale_deviation > 0.15
    assert any(w.startswith("IMPLAUSIBLE scene scale") for w in kept.warnings)
    # Without positions the units are arbitrary: a flight height is refused.
    with pytest.raises(ValueError, match="flight_height_m: checks a geo-referenced model's scale"):
        aos.import_colmap(model, frames, flight_height_m=20.0)
    # The CLI: refused (exit 1, nothing written), kept with --allow-implausible (warning on
    # stderr), and a flight height without positions names its flag (exit 2).
    command = ["aos-render", "import-colmap", str(model), "--images-dir", str(frames),
               "--positions-file", gps, "--flight-height-m", "14"]
    done = subprocess.run(command + ["-o", str(tmp_path / "a.json")], capture_output=True,
                          text=True)
    assert done.returncode == 1 and "IMPLAUSIBLE scene scale" in done.stderr
    assert "--allow-implausible" in done.stderr
    assert not (tmp_path / "a.json").exists()
    done = subprocess.run(command + ["--allow-implausible", "-o", str(tmp_path / "b.json")],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "warning: IMPLAUSIBLE scene scale" in done.stderr
    done = subprocess.run(["aos-render", "import-colmap", str(model), "--images-dir",
                           str(frames), "--flight-height-m", "20", "-o",
                           str(tmp_path / "c.json")], capture_output=True, text=True)
    assert done.returncode == 2 and "--flight-height-m" in done.stderr
