"""Real flights in (issue 15): views by name, frame lookup ignoring case, poses without frames,
camera files for known lenses (`aos-render camera`), rectify --fill, and grey frames."""
from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import aos

EXE = shutil.which("aos-render")
needs_cli = pytest.mark.skipif(EXE is None, reason="aos-render is not on PATH")

# 3 x 3 RGB 8-bit views of 48 x 40 pixels, 3 m apart at 35 m, over a voxel volume.
RGB_SCENE = {
    "occluders": {"voxels": {"center": [0, 0, 11], "size": [20, 20, 6], "grid": [40, 40, 12],
                             "density": 0.6}},
    "camera": {"width": 48, "height": 40, "fov_deg": 50, "channels": 3},
    "sampling": {"altitude": 35, "grid": 3, "aperture": {"diameter": 6}},
    "truth": {"width": 8, "height": 8, "blocked_fraction": False},
}
RENDER = ["--fov-deg", "50", "--width", "40", "--height", "32", "--focal-height", "0"]


def run(*args: object) -> subprocess.CompletedProcess:
    return subprocess.run([EXE, *map(str, args)], capture_output=True, text=True, timeout=120)


def refused(result: subprocess.CompletedProcess, *fragments: str) -> str:
    """One error line containing every fragment, exit code non-zero."""
    assert result.returncode != 0, result.stdout
    lines = [line for line in result.stderr.splitlines() if line.startswith("aos-render: error:")]
    assert len(lines) == 1, result.stderr
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])
    return lines[0]


@pytest.fixture
def scene(tmp_path: Path) -> Path:
    """tmp/lf/lightfield.json + views/0000.png ... 0008.png, RGB."""
    light_field = aos.simulate(RGB_SCENE).light_field
    folder = tmp_path / "lf"
    folder.mkdir()
    aos.write_lightfield(str(folder / "lightfield.json"), light_field)
    return folder / "lightfield.json"


# --- Naming ----------------------------------------------------------------------------------

def test_find_view_by_name_stem_and_case(scene: Path) -> None:
    light_field = aos.load_lightfield(scene).light_field
    name = light_field.views[4].name  # "views/0004.png"
    assert aos.find_view(light_field, name) == 4
    assert aos.find_view(light_field, Path(name).name) == 4
    assert aos.find_view(light_field, Path(name).stem) == 4
    assert aos.find_view(light_field, Path(name).name.upper()) == 4
    with pytest.raises(ValueError, match=r"no view named \"0044\".*close: "):
        aos.find_view(light_field, "0044")


@needs_cli
def test_pose_view_takes_a_frame_name(scene: Path, tmp_path: Path) -> None:
    by_index = tmp_path / "index.tif"
    assert run("integral", scene, "--pose-view", "4", *RENDER, "-o", by_index).returncode == 0
    for name in ("0004", "0004.png", "views/0004.png", "0004.PNG"):
        out = tmp_path / f"name_{name.replace('/', '_')}.tif"
        result = run("integral", scene, "--pose-view", name, *RENDER, "-o", out)
        assert result.returncode == 0, result.stderr
        np.testing.assert_array_equal(aos.read_image(str(out)), aos.read_image(str(by_index)))
    # Unknown: one line naming the flag and close names; nothing written.
    out = tmp_path / "unknown.tif"
    message = refused(run("integral", scene, "--pose-view", "0044", *RENDER, "-o", out),
                      "--pose-view", "no view named \"0044\"", "close:")
    assert "view_0004 (view 4, file views/0004.png)" in message
    message = refused(run("integral", scene, "--pose-view", "view_4", *RENDER, "-o", out),
                      "--pose-view", "no view named \"view_4\"")
    assert not out.exists()
    # Ambiguous: two frames with the same stem in different folders.
    document = json.loads(scene.read_text())
    (scene.parent / "other").mkdir()
    shutil.copy(scene.parent / "views" / "0004.png", scene.parent / "views" / "DJI_1.JPG.png")
    shutil.copy(scene.parent / "views" / "0006.png", scene.parent / "other" / "DJI_1.JPG.png")
    document["views"][4]["image"] = "views/DJI_1.JPG.png"
    document["views"][6]["image"] = "other/DJI_1.JPG.png"
    scene.write_text(json.dumps(document))
    refused(run("integral", scene, "--pose-view", "DJI_1.JPG", *RENDER, "-o", out),
            "--pose-view", "ambiguous", "view_0004 (view 4, file views/DJI_1.JPG.png)",
            "view_0006 (view 6, file other/DJI_1.JPG.png)")
    assert not out.exists()
    # The full name is not.
    assert run("integral", scene, "--pose-view", "views/DJI_1.JPG.png", *RENDER, "-o",
               out).returncode == 0
    out.unlink()
    refused(run("integral", scene, "--pose-view", "-2", *RENDER, "-o", out), "--pose-view")
    refused(run("integral", scene, "--pose-view", "99", *RENDER, "-o", out), "--pose-view",
            "no view 99 (the light field has 9 views)", "no view named \"99\"")
    # Digits that are both an index and another view's name: refused, naming both.
    document["views"][2]["image"] = "views/0006.png"
    document["views"][6]["image"] = "views/0002.png"
    scene.write_text(json.dumps(document))
    refused(run("integral", scene, "--pose-view", "0006", *RENDER, "-o", out), "--pose-view",
            "ambiguous: view 6 by index, or view_0002 (view 2, file views/0006.png) by name")
    assert run("integral", scene, "--pose-view", "0006.png", *RENDER, "-o", out).returncode == 0


@needs_cli
def test_frames_found_ignoring_case(scene: Path, tmp_path: Path) -> None:
    expected = tmp_path / "expected.tif"
    assert run("integral", scene, "--pose-view", "4", *RENDER, "-o", expected).returncode == 0
    views = scene.parent / "views"
    for path in sorted(views.glob("*.png")):
        path.rename(path.with_suffix(".PNG"))
    out = tmp_path / "renamed.tif"
    result = run("integral", scene, "--pose-view", "4", *RENDER, "-o", out)
    assert result.returncode == 0, result.stderr
    assert "differs only in case" in result.stderr
    np.testing.assert_array_equal(aos.read_image(str(out)), aos.read_image(str(expected)))
    # Two files differing only in case: an error naming both, nothing written.
    shutil.copy(views / "0003.PNG", views / "0003.Png")
    refused(run("integral", scene, "--pose-view", "4", *RENDER, "-o", tmp_path / "x.tif"),
            "view 3", "0003.PNG", "0003.Png", "ignoring case")
    assert not (tmp_path / "x.tif").exists()


def test_poses_only_needs_no_frames_and_the_renderer_names_the_view(scene: Path) -> None:
    shutil.rmtree(scene.parent / "views")
    with pytest.raises(ValueError, match="views/0000.png"):
        aos.load_lightfield(scene)
    loaded = aos.load_lightfield(scene, load_images=False)
    light_field = loaded.light_field
    assert len(light_field.views) == 9
    assert light_field.views[3].name == "view_0003"  # as the simulator named it
    with pytest.raises(ValueError, match=r"view 0 \(view_0000\): image: no pixels"):
        aos.render_integral(light_field, pose_view=4, fov_deg=50, width=8, height=8)


# --- Known lenses without a checkerboard ------------------------------------------------------

@needs_cli
def test_camera_command_writes_a_validated_camera_file(tmp_path: Path) -> None:
    path = tmp_path / "camera.json"
    result = run("camera", "--model", "radtan", "--width", "640", "--height", "480", "--fx", "500",
                 "--fy", "501", "--cx", "320.5", "--cy", "240.5", "--k1", "-0.1", "--k2", "0.01",
                 "--p1", "0.001", "--p2", "-0.002", "--k3", "0.0005", "-o", path)
    assert result.returncode == 0, result.stderr
    camera = aos.read_camera_file(path)
    assert camera.model == "radtan" if isinstance(camera.model, str) else True
    assert (camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy) == (
        640, 480, 500.0, 501.0, 320.5, 240.5)
    assert list(camera.distortion) == [-0.1, 0.01, 0.001, -0.002, 0.0005]
    document = json.loads(path.read_text())
    assert document["format"] == "aos-camera" and document["model"] == "radtan"
    # Defaults: fy = fx, principal point at the centre; fisheye k1..k4 land in their slots.
    fisheye = tmp_path / "fisheye.json"
    result = run("camera", "--model", "fisheye", "--width", "64", "--height", "48", "--fx", "20",
                 "--k1", "0.01", "--k4", "0.001", "-o", fisheye)
    assert result.returncode == 0, result.stderr
    camera = aos.read_camera_file(fisheye)
    assert (camera.fy, camera.cx, camera.cy) == (20.0, 32.0, 24.0)
    assert list(camera.distortion) == [0.01, 0.0, 0.0, 0.001]  # fisheye k1..k4
    # An existing output needs --force.
    before = path.read_bytes()
    refused(run("camera", "--width", "64", "--height", "48", "--fx", "20", "-o", path),
            str(path), "--force")
    assert path.read_bytes() == before
    assert run("camera", "--width", "64", "--height", "48", "--fx", "20", "-o", path,
               "--force").returncode == 0
    assert aos.read_camera_file(path).width == 64


@needs_cli
def test_camera_command_refuses_bad_cameras_and_writes_nothing(tmp_path: Path) -> None:
    path = tmp_path / "camera.json"
    base = ["--width", "64", "--height", "48"]
    refused(run("camera", *base, "--fx", "-3", "-o", path), "--fx")
    refused(run("camera", *base, "--fx", "20", "--model", "radtan", "--k4", "0.1", "-o", path),
            "--k4", "radtan", "--k1, --k2, --p1, --p2, --k3")
    refused(run("camera", *base, "--fx", "20", "--k1", "0.1", "-o", path), "--k1", "pinhole")
    refused(run("camera", *base, "--fx", "20", "--model", "kannala", "-o", path), "--model")
    refused(run("camera", *base, "--fx", "20", "--model", "omnidir", "--xi", "-1", "-o", path),
            "--xi")
    # A radial distortion that folds inside the frame.
    refused(run("camera", *base, "--fx", "20", "--model", "radtan", "--k1", "-2", "-o", path),
            "--k1/--k2/--p1/--p2/--k3/--k4")
    missing = run("camera", "--height", "48", "--fx", "20", "-o", path)  # the parser's error
    assert missing.returncode == 2 and "--width is required" in missing.stderr
    assert list(tmp_path.iterdir()) == []


@needs_cli
def test_rectify_offers_fill_and_fills_with_black(tmp_path: Path) -> None:
    camera = tmp_path / "camera.json"
    assert run("camera", "--model", "radtan", "--width", "64", "--height", "48", "--fx", "50",
               "--k1", "-0.1", "-o", camera).returncode == 0
    frames = []
    for i in range(4):
        frame = tmp_path / f"f{i}.png"
        aos.write_image(str(frame), np.full((48, 64, 3), 100 + i, np.uint8))
        frames.append(frame)
    out = tmp_path / "wide"
    refused(run("rectify", *frames, "--camera", camera, "--rectified-fov-deg", "120", "-o", out),
            "does not cover", "--fill", "--rectified-fov-deg")
    assert not out.exists()
    result = run("rectify", *frames, "--camera", camera, "--rectified-fov-deg", "120", "--fill",
                 "--json", "-o", out)
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert 0 < report["filled_pixels"] < 64 * 48
    for i, frame in enumerate(frames):
        image = aos.read_image(str(out / frame.name))
        black = np.all(image == 0, axis=2)
        assert black.sum() == report["filled_pixels"]
        assert np.all(image[~black] == 100 + i)  # a constant frame stays constant where covered
        assert black[0, 0] and not black[24, 32]


# --- Grey -------------------------------------------------------------------------------------

def luma(rgb: np.ndarray) -> np.ndarray:
    """Rec. 601, computed independently of the library."""
    return 0.299 * rgb[..., 0] + 0.587 * rgb[..., 1] + 0.114 * rgb[..., 2]


def test_grey_load_gives_rec601_luminance(scene: Path) -> None:
    rgb = aos.load_lightfield(scene).light_field
    assert rgb.views[0].image.ndim == 3
    grey = aos.load_lightfield(scene, grey=True).light_field
    for view_rgb, view_grey in zip(rgb.views, grey.views):
        assert view_grey.image.ndim == 2 and view_grey.image.dtype == np.uint8
        # Rounded half away from zero (np.round would round half to even).
        np.testing.assert_array_equal(view_grey.image,
                                      np.floor(luma(view_rgb.image.astype(np.float64)) + 0.5))


@needs_cli
def test_grey_integral_and_metrics(scene: Path, tmp_path: Path) -> None:
    rgb_out, grey_out = tmp_path / "rgb.tif", tmp_path / "grey.tif"
    assert run("integral", scene, "--pose-view", "4", *RENDER, "-o", rgb_out).returncode == 0
    result = run("integral", scene, "--pose-view", "4", *RENDER, "--grey", "-o", grey_out)
    assert result.returncode == 0, result.stderr
    rgb, grey = aos.read_image(str(rgb_out)), aos.read_image(str(grey_out))
    assert rgb.ndim == 3 and grey.ndim == 2
    # Luminance is linear: the grey render is the RGB render's luminance, up to the rounding of
    # each view to 8 bits at load (at most half a step).
    assert np.max(np.abs(grey - luma(rgb))) <= 0.5 + 1e-3
    # metrics: a grey test against an RGB reference is refused, naming --grey ...
    refused(run("metrics", grey_out, rgb_out), "grey.tif", "rgb.tif", "--grey")
    # ... and compared as luminances with it.
    # (Float renders in 8-bit units: L = 255. Half a step of error at most: PSNR > 48 dB.)
    result = run("metrics", grey_out, rgb_out, "--grey", "--data-range", "255", "--json")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["psnr_db"] > 48
    python = aos.compare_images(grey, rgb, grey=True, data_range=255)
    assert python.psnr_db > 48
    assert "Rec. 601" in python.note
    # --grey is on every command that loads a light field.
    for command in ("integral", "stack", "allinfocus", "merge", "rectify"):
        assert "--grey" in run(command, "--help").stdout, command
