"""The aos-render executable: success paths, and every kind of bad input giving one clear line,
a non-zero exit code and no output file (nor a leftover temporary file), inputs untouched."""
from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import aos
from conftest import write_colmap_text_model

EXE = shutil.which("aos-render")
pytestmark = pytest.mark.skipif(EXE is None, reason="aos-render is not on PATH (pip install .)")


# 3 x 3 grey 8-bit views of 48 x 40 pixels, 3 m apart at 35 m, over a voxel volume.
SMALL_SCENE = {
    "occluders": {"voxels": {"center": [0, 0, 11], "size": [20, 20, 6], "grid": [40, 40, 12],
                             "density": 0.6}},
    "camera": {"width": 48, "height": 40, "fov_deg": 50},
    "sampling": {"altitude": 35, "grid": 3, "aperture": {"diameter": 6}},
    "truth": {"width": 8, "height": 8, "blocked_fraction": False},
}


def run(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([EXE, *args], capture_output=True, text=True, cwd=cwd, timeout=120)


@pytest.fixture
def scene(tmp_path: Path) -> Path:
    """A small simulated light field in the aos format: tmp/lf/lightfield.json + views/."""
    light_field = aos.simulate(SMALL_SCENE).light_field
    folder = tmp_path / "lf"
    folder.mkdir()
    aos.write_lightfield(str(folder / "lightfield.json"), light_field)
    return folder / "lightfield.json"


def snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


BASE = ["--pose-view", "4", "--fov-deg", "50", "--width", "40", "--height", "32"]


def test_version_and_help() -> None:
    result = run("--version")
    assert result.returncode == 0 and result.stdout.strip() == f"aos-render {aos.__version__}"
    for command in ("integral", "demo"):
        result = run(command, "--help")
        assert result.returncode == 0 and "--" in result.stdout
    assert run().returncode != 0  # a subcommand is required


def test_integral_writes_image_and_count(scene: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    result = run("integral", str(scene), *BASE, "-o", str(out / "z0.exr"), "--count", str(out / "n.tif"))
    assert result.returncode == 0, result.stderr
    assert "wrote" in result.stdout
    image = aos.read_image(str(out / "z0.exr"))
    count = aos.read_image(str(out / "n.tif"))
    expected = aos.render_integral(aos.load_lightfield(str(scene)).light_field, pose_view=4, fov_deg=50,
                                   width=40, height=32)
    np.testing.assert_array_equal(image, expected.image)
    np.testing.assert_array_equal(count, expected.count)
    # 8-bit PNG with the stated normalisation (the views' own 0..255 range).
    result = run("integral", str(scene), *BASE, "-o", str(out / "z0.png"))
    assert result.returncode == 0 and "values 0..255 mapped to 0..255" in result.stdout
    png = aos.read_image(str(out / "z0.png"))
    assert png.dtype == np.uint8
    assert np.max(np.abs(png.astype(float) - np.clip(np.round(expected.image), 0, 255))) <= 0
    assert sorted(p.name for p in out.iterdir()) == ["n.tif", "z0.exr", "z0.png"]


def test_look_at_and_tilted_plane_and_view_selection(scene: Path, tmp_path: Path) -> None:
    out = tmp_path / "o.tif"
    result = run("integral", str(scene), "--look-at", "0.5,0,35,0,0,0,0,1,0", "--fov-deg", "40", "--width",
                 "30", "--height", "20", "--focal-plane", "0,0,1,0.1,0,1", "--view-indices", "0:4,8",
                 "--aperture-radius", "5", "-o", str(out))
    assert result.returncode == 0, result.stderr
    assert "of 5 selected views" in result.stderr
    assert aos.read_image(str(out)).shape == (20, 30)


def test_demo_runs_on_the_default_scene(tmp_path: Path) -> None:
    result = run("demo", "-o", str(tmp_path / "demo"), "--grid", "3", "-q")
    assert result.returncode == 0, result.stderr
    names = {p.name for p in (tmp_path / "demo").iterdir()}
    assert {"lightfield.json", "lightfield_true.json", "scene.json", "views", "truth",
            "integral_ground.png", "single_view.png", "integral_occluders.png",
            "all_in_focus.png", "demo.json", "index.html"} <= names
    loaded = aos.load_lightfield(str(tmp_path / "demo" / "lightfield.json"))
    assert len(loaded.light_field) == 9
    assert loaded.light_field.views[0].image.shape[2] == 3  # the default scene is in colour
    assert "against the ground truth" in result.stdout and "target stands out" in result.stdout
    summary = json.loads((tmp_path / "demo" / "demo.json").read_text())
    assert summary["views"] == 9 and len(summary["renders"]) == 4
    for name in ("single_view", "integral_ground"):
        assert f"{name}.png" in (tmp_path / "demo" / "index.html").read_text()
    # Nothing is overwritten: a second run into the same folder is refused.
    again = run("demo", "-o", str(tmp_path / "demo"), "--grid", "3", "-q")
    assert again.returncode == 1 and "not an empty folder" in again.stderr


def assert_clean_failure(result: subprocess.CompletedProcess, *fragments: str) -> None:
    assert result.returncode != 0
    lines = [line for line in result.stderr.splitlines() if line.startswith("aos-render: error:")]
    assert len(lines) == 1, result.stderr
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])


def corrupt(scene: Path, edit) -> None:
    document = json.loads(scene.read_text())
    edit(document)
    scene.write_text(json.dumps(document))


@pytest.mark.parametrize("case", ["missing image", "unreadable image", "size mismatch", "non-orthonormal",
                                  "nan in jku pose", "empty selection", "plane behind", "plane parallel",
                                  "fov negative", "fov 180", "output is an input", "output is the light field",
                                  "count format", "count is the output", "views out of range"])
def test_bad_input_fails_cleanly(case: str, scene: Path, tmp_path: Path) -> None:
    folder = scene.parent
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    output = out_dir / "result.png"
    count = out_dir / "count.tif"
    args = ["integral", str(scene), *BASE]
    expect: tuple[str, ...]
    view_file = folder / json.loads(scene.read_text())["views"][2]["image"]
    if case == "missing image":
        view_file.unlink()
        expect = (view_file.name, "not found")
    elif case == "unreadable image":
        view_file.write_bytes(b"this is not a png")
        expect = (view_file.name, "cannot")
    elif case == "size mismatch":
        aos.write_image(str(view_file), np.zeros((10, 12), np.uint8))
        expect = ("lightfield.json", "view 2", "12x10", "camera")
    elif case == "non-orthonormal":
        corrupt(scene, lambda d: d["views"][1]["cam_from_world"]["rotation"][0].__setitem__(1, 0.3))
        expect = ("lightfield.json", "view 1", "cam_from_world", "orthonormal")
    elif case == "nan in jku pose":
        poses = {"images": [{"imagefile": v["image"].split("/")[-1], "M3x4": [[1, 0, 0, 0], [0, -1, 0, 0], [0, 0, -1, 35]]}
                            for v in json.loads(scene.read_text())["views"]]}
        poses["images"][3]["M3x4"][1][2] = "nan"
        jku = folder / "views" / "poses.json"
        jku.write_text(json.dumps(poses))
        args = ["integral", str(jku), "--frames-fov-deg", "50", "--images-dir", str(folder / "views"), *BASE]
        expect = ("poses.json", "image 3", "M3x4", "nan")
    elif case == "empty selection":
        args += ["--view-indices", "5:5"]
        expect = ("--view-indices", "empty")
    elif case == "plane behind":
        args += ["--focal-height", "100"]
        expect = ("focal_surface", "behind")
    elif case == "plane parallel":  # through the camera centre: its rays run along it
        args += ["--focal-plane", "0,0,35,0.3,0,1"]
        expect = ("focal_surface", "parallel", "--focal-surface/--focal-height/--focal-plane/--focal-distance")
    elif case == "fov negative":  # 0 means the pose view's; below 0 is refused
        args[args.index("--fov-deg") + 1] = "-5"
        expect = ("fov_deg",)
    elif case == "fov 180":
        args[args.index("--fov-deg") + 1] = "180"
        expect = ("fov_deg", "180")
    elif case == "output is an input":
        output = view_file
        expect = (view_file.name, "input")
    elif case == "output is the light field":
        output = scene
        expect = ("lightfield.json", "input")
    elif case == "count format":  # found before any work, and no image is left behind
        count = out_dir / "count.jpg"
        expect = ("count.jpg", "8-bit")
    elif case == "count is the output":
        output = out_dir / "same.tif"
        count = out_dir / ".." / "out" / "same.tif"
        expect = ("same file",)
    elif case == "views out of range":
        args += ["--view-indices", "0:2000000000"]
        expect = ("--view-indices", "outside")
    before_inputs = snapshot(folder)
    result = run(*args, "-o", str(output), "--count", str(count))
    assert_clean_failure(result, *expect)
    assert list(out_dir.iterdir()) == [], "no output and no temporary file may be left"
    assert snapshot(folder) == before_inputs, "inputs must never be modified"


def test_metrics_subcommand_matches_python(tmp_path: Path) -> None:
    rng = np.random.default_rng(8)
    reference = rng.integers(0, 256, (40, 50)).astype(np.uint8)
    test = np.clip(reference.astype(int) + rng.integers(-9, 10, reference.shape), 0, 255).astype(np.uint8)
    aos.write_image(str(tmp_path / "t.png"), test)
    aos.write_image(str(tmp_path / "r.png"), reference)
    result = run("metrics", str(tmp_path / "t.png"), str(tmp_path / "r.png"), "--json")
    assert result.returncode == 0, result.stderr
    printed = json.loads(result.stdout)
    expected = aos.compare_images(test, reference)
    assert printed["psnr_db"] == pytest.approx(expected.psnr_db, rel=1e-9)
    assert printed["ssim"] == pytest.approx(expected.ssim, rel=1e-9)
    text = run("metrics", str(tmp_path / "t.png"), str(tmp_path / "r.png"))
    assert text.returncode == 0 and text.stdout.startswith("PSNR ")
    bad = run("metrics", str(tmp_path / "t.png"), str(tmp_path / "missing.png"))
    assert_clean_failure(bad, "missing.png", "not found")


def test_quiet_means_quiet_on_every_command(scene: Path, tmp_path: Path) -> None:
    """-q printed "wrote ..." lines; now every command takes -q, and with it a successful run
    prints nothing but its result (metrics, resolution)."""
    for command in ("integral", "stack", "merge", "allinfocus", "simulate", "demo", "metrics",
                    "resolution", "rectify", "calibrate", "poses", "import-colmap"):
        assert "--quiet" in run(command, "--help").stdout, command
    out = tmp_path / "out"
    runs = [("integral", str(scene), *BASE, "-o", str(out / "a.png"), "--count",
             str(out / "c.tif")),
            ("stack", str(scene), *BASE, "--slices", "2", "-o", str(out / "stack")),
            ("merge", str(out / "stack"), "-o", str(out / "merged")),
            ("allinfocus", str(scene), *BASE, "--slices", "2", "-o", str(out / "aif")),
            ("simulate", "--grid", "2", "-o", str(out / "sim"))]
    out.mkdir()
    for args in runs:
        loud = run(*args[:-1], args[-1] + "_loud") if args[0] != "integral" else None
        if loud is not None:
            assert loud.returncode == 0 and "wrote" in loud.stdout, loud.stderr
        done = run(*args, "-q")
        assert done.returncode == 0, done.stderr
        assert done.stdout == "" and done.stderr == "", (args[0], done.stdout, done.stderr)


def test_json_report_on_every_command(scene: Path, tmp_path: Path) -> None:
    """--json: the command's report as one JSON object on stdout and nothing else there (no
    'wrote' lines), with what it wrote and its figures; the text report without it."""
    out = tmp_path / "out"
    out.mkdir()
    runs = [("integral", str(scene), *BASE, "-o", str(out / "a.png"), "--count",
             str(out / "c.tif")),
            ("stack", str(scene), *BASE, "--slices", "2", "-o", str(out / "stack")),
            ("merge", str(out / "stack"), "-o", str(out / "merged")),
            ("allinfocus", str(scene), *BASE, "--slices", "2", "-o", str(out / "aif")),
            ("simulate", "--grid", "2", "-o", str(out / "sim")),
            ("metrics", str(out / "a.png"), str(out / "a.png")),
            ("resolution", "--width", "64", "--height", "48", "--lens-fov-deg", "60")]
    reports = {}
    for args in runs:
        done = run(*args, "--json")
        assert done.returncode == 0, done.stderr
        lines = done.stdout.splitlines()
        assert len(lines) == 1, (args[0], done.stdout)
        reports[args[0]] = json.loads(lines[0])
        assert reports[args[0]]["command"] == args[0]
    integral = reports["integral"]
    assert integral["output"] == str(out / "a.png") and integral["count"] == str(out / "c.tif")
    assert (integral["width"], integral["height"], integral["sample_type"]) == (40, 32, "uint8")
    assert integral["views_used"] == 9 and integral["range"] == [0, 255]
    assert reports["stack"]["slices"] == 2 and (out / "stack" / "stack.json").exists()
    assert "depth.tif" in reports["allinfocus"]["files"]
    assert reports["metrics"]["psnr_db"] is None and reports["metrics"]["ssim"] == 1.0
    assert reports["simulate"]["views"] == 4
    # --threads is checked on every command (here one without a thread count of its own).
    bad = run("resolution", "--width", "64", "--height", "48", "--lens-fov-deg", "60",
              "--threads", "0")
    assert bad.returncode == 2 and "--threads" in bad.stderr, bad.stderr


def test_errors_name_the_flag_that_set_the_field(scene: Path, tmp_path: Path) -> None:
    """An Options::Check() error names the flag bound to its field: the loader's fov_deg is
    --frames-fov-deg (not the virtual camera's --fov-deg), and an error about two fields names
    both flags."""
    folder = scene.parent
    poses = {"images": [{"imagefile": v["image"].split("/")[-1],
                         "M3x4": [[1, 0, 0, 0], [0, -1, 0, 0], [0, 0, -1, 35]]}
                        for v in json.loads(scene.read_text())["views"]]}
    jku = folder / "views" / "poses.json"
    jku.write_text(json.dumps(poses))
    for command in ("integral", "stack", "allinfocus"):
        output = tmp_path / (command + (".png" if command == "integral" else ""))
        frames = run(command, str(jku), "--frames-fov-deg", "190", "--images-dir",
                     str(folder / "views"), "--pose-view", "0", "-o", str(output))
        assert frames.returncode == 2 and frames.stderr.strip().endswith(
            "[option --frames-fov-deg]"), (command, frames.stderr)
        camera = run(command, str(scene), "--pose-view", "0", "--fov-deg", "190", "-o",
                     str(output))
        assert camera.returncode == 2 and camera.stderr.strip().endswith("[option --fov-deg]"), \
            (command, camera.stderr)
        assert not output.exists()
    both = run("rectify", "--lightfield", str(scene), "--width", "-3", "-o", str(tmp_path / "r"))
    assert both.returncode == 2 and "[option --width/--height]" in both.stderr, both.stderr
    bad = run("stack", str(scene), "--pose-view", "0", "--slices", "abc", "-o",
              str(tmp_path / "s"))
    assert bad.returncode == 2 and bad.stderr.splitlines() == [
        'aos-render: error: slices: "abc" is not a number [option --slices]'], bad.stderr


def test_defaults_from_the_data_and_focus_by_distance(scene: Path, tmp_path: Path) -> None:
    """--pose-view K takes view K's field of view and size unless given; --look-at works for a
    straight-down camera without an up vector; --focal-distance D focuses D metres in front."""
    out = tmp_path / "view.tif"
    done = run("integral", str(scene), "--pose-view", "4", "-o", str(out))
    assert done.returncode == 0, done.stderr
    assert aos.read_image(str(out)).shape == (40, 48)  # the views are 48 x 40
    done = run("integral", str(scene), "--pose-view", "4", "--width", "24", "-o",
               str(tmp_path / "narrow.tif"))
    assert aos.read_image(str(tmp_path / "narrow.tif")).shape == (40, 24)
    # Straight down from 35 m over the ground (z = 0), no up vector.
    look = ["--look-at", "0,0,35,0,0,0", "--fov-deg", "50", "--width", "40", "--height", "32"]
    done = run("integral", str(scene), *look, "--focal-height", "0", "-o",
               str(tmp_path / "height.tif"))
    assert done.returncode == 0, done.stderr
    # Focus 35 m in front of that camera = the ground plane, perpendicular or horizontal.
    for extra in ([], ["--horizontal"]):
        done = run("integral", str(scene), *look, "--focal-distance", "35", *extra, "-o",
                   str(tmp_path / "distance.tif"))
        assert done.returncode == 0, done.stderr
        np.testing.assert_allclose(aos.read_image(str(tmp_path / "distance.tif")),
                                   aos.read_image(str(tmp_path / "height.tif")), atol=1e-4)
        (tmp_path / "distance.tif").unlink()
    assert run("integral", str(scene), *look, "--focal-distance", "-3", "-o",
               str(tmp_path / "x.tif")).returncode == 2
    pose = aos.look_at((0.0, 0.0, 35.0), (0.0, 0.0, 0.0))
    plane = aos.Plane.in_front_of(pose, 35.0)
    np.testing.assert_allclose(plane.point, (0.0, 0.0, 0.0), atol=1e-12)


def test_existing_output_files_need_force(scene: Path, tmp_path: Path) -> None:
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    image, count = out_dir / "a.png", out_dir / "a_count.png"
    first = run("integral", str(scene), *BASE, "-o", str(image), "--count", str(count), "-q")
    assert first.returncode == 0, first.stderr
    written = image.read_bytes(), count.read_bytes()
    # Without --force an existing output (image or count) is refused before any work, untouched.
    for args in (["-o", str(image)], ["-o", str(out_dir / "b.png"), "--count", str(count)]):
        again = run("integral", str(scene), *BASE, *args, "--focal-height", "3")
        assert again.returncode == 1, again.stderr
        assert "exists; give --force to replace it" in again.stderr
    assert (image.read_bytes(), count.read_bytes()) == written
    assert sorted(p.name for p in out_dir.iterdir()) == ["a.png", "a_count.png"]
    # With --force both are replaced by the new render.
    forced = run("integral", str(scene), *BASE, "-o", str(image), "--count", str(count),
                 "--focal-height", "3", "--force", "-q")
    assert forced.returncode == 0, forced.stderr
    assert image.read_bytes() != written[0]
    # --force never lets an output replace an input, and a folder is not a file.
    refused = run("integral", str(scene), *BASE, "-o", str(scene), "--force")
    assert refused.returncode == 1 and "input" in refused.stderr
    refused = run("integral", str(scene), *BASE, "-o", str(out_dir), "--force")
    assert refused.returncode != 0 and str(out_dir) in refused.stderr


def test_import_colmap_images_dir_and_its_deprecated_alias(scene: Path, tmp_path: Path) -> None:
    model = tmp_path / "model"
    write_colmap_text_model(scene, model)
    views = str(scene.parent / "views")
    done = run("import-colmap", str(model), "--images-dir", views, "-o", str(tmp_path / "a.json"))
    assert done.returncode == 0 and "deprecated" not in done.stderr, done.stderr
    old = run("import-colmap", str(model), "--images", views, "-o", str(tmp_path / "b.json"))
    assert old.returncode == 0 and "warning: --images is deprecated; use --images-dir" in old.stderr
    assert (tmp_path / "a.json").read_text() == (tmp_path / "b.json").read_text()
    both = run("import-colmap", str(model), "--images", views, "--images-dir", views, "-o",
               str(tmp_path / "c.json"))
    assert both.returncode == 2 and "--images-dir" in both.stderr
    missing = run("import-colmap", str(model), "-o", str(tmp_path / "c.json"))
    assert missing.returncode == 2 and "--images-dir is required" in missing.stderr


def test_renamed_flags_keep_their_old_spelling_with_a_warning(tmp_path: Path) -> None:
    # Flags named by what they describe (docs/vocabulary.md); the old spellings work for one
    # release and say what replaced them.
    common = ["resolution", "--width", "640", "--height", "480", "--distance-m", "30"]
    new = run(*common, "--lens-fov-deg", "60", "--json")
    old = run(*common, "--fov-deg", "60", "--json")
    assert new.returncode == old.returncode == 0 and new.stdout == old.stdout, old.stderr
    assert new.stderr == "" and old.stderr == "warning: --fov-deg is deprecated; use --lens-fov-deg\n"
    image = tmp_path / "a.png"
    aos.write_image(str(image), (np.arange(64 * 48) % 251).astype(np.uint8).reshape(48, 64))
    new = run("metrics", str(image), str(image), "--ssim-window-radius", "3", "--json")
    old = run("metrics", str(image), str(image), "--window-radius", "3", "--json")
    assert new.stdout == old.stdout and "ssim" in new.stdout
    assert "warning: --window-radius is deprecated; use --ssim-window-radius" in old.stderr
    for command, old_flag, new_flag in [("poses", "--fov-deg", "--frames-fov-deg"),
                                        ("rectify", "--fov-deg", "--rectified-fov-deg")]:
        text = run(command, "--help").stdout
        assert f"{new_flag},{old_flag}" in text, command


def test_every_field_flag_comes_from_its_table_row() -> None:
    # The field tables (util/option_fields.h) give every field of a struct that has one its
    # flag: the field's name in kebab case (or the row's own flag), its help and its default.
    # Other spellings are shorthands beside it, never instead of it (docs/vocabulary.md).
    bindings = json.loads(run("flags").stdout)
    by_source: dict[str, list[dict[str, str]]] = {}
    for binding in bindings:
        by_source.setdefault(binding["source"], []).append(binding)
    assert set(by_source) == {"table", "shorthand"}, {b["flag"] for b in by_source.get("hand", [])}
    table = {(b["command"], b["field"]): b["flag"] for b in by_source["table"]}
    for shorthand in by_source["shorthand"]:
        assert (shorthand["command"], shorthand["field"]) in table, shorthand
    assert table[("integral", "view_indices")] == "--view-indices"
    assert table[("integral", "focal_surface")] == "--focal-surface"
    assert table[("stack", "ground_plane")] == "--ground-plane"
    assert table[("view", "viewer.open_browser")] == "--open-browser"
    assert table[("calibrate", "pattern_rows")] == "--pattern-rows"
    assert table[("allinfocus", "merge.num_threads")] == "--threads"
    assert table[("poses", "fov_deg")] == "--frames-fov-deg"  # the row names its flag
    assert table[("camera", "distortion")] == "--distortion"  # LensCamera's table


def test_focal_surface_takes_a_height_a_plane_or_a_file_and_views_its_old_spelling(
        scene: Path, tmp_path: Path) -> None:
    lf = aos.load_lightfield(str(scene)).light_field
    expected = aos.render_integral(lf, pose_view=4, fov_deg=50, width=40, height=32,
                                   focal_surface=3.0, view_indices=[0, 1, 2, 5])
    outputs = []
    for i, args in enumerate([["--focal-surface", "3", "--view-indices", "0:3,5"],
                              ["--focal-height", "3", "--view-indices", "0:3,5"],
                              ["--focal-surface", "0,0,3,0,0,1", "--views", "0:3,5"]]):
        out = tmp_path / f"{i}.tif"
        result = run("integral", str(scene), *BASE, *args, "-o", str(out))
        assert result.returncode == 0, result.stderr
        assert ("deprecated" in result.stderr) == ("--views" in args), result.stderr
        outputs.append(aos.read_image(str(out)))
    for image in outputs:
        np.testing.assert_array_equal(image, expected.image)
    assert "warning: --views is deprecated; use --view-indices" in result.stderr
    # A file that is not there is named as a file; two spellings of the field exclude each other.
    missing = run("integral", str(scene), *BASE, "--focal-surface", str(tmp_path / "dem.tif"),
                  "-o", str(tmp_path / "x.tif"))
    assert missing.returncode != 0 and "dem.tif" in missing.stderr
    both = run("integral", str(scene), *BASE, "--focal-surface", "3", "--focal-height", "3",
               "-o", str(tmp_path / "y.tif"))
    assert both.returncode == 2 and "--focal-height" in both.stderr
    assert not (tmp_path / "x.tif").exists() and not (tmp_path / "y.tif").exists()


def test_the_new_table_flags_and_their_shorthands_exclude_each_other(scene: Path,
                                                                      tmp_path: Path) -> None:
    # Flags named after their fields, beside the older spellings that set the same field.
    for args, flag in [(["calibrate", "x.png", "--pattern", "9x6", "--pattern-columns", "9",
                         "-o", "c.json"], "--pattern"),
                       (["view", str(scene), "--browser", "--open-browser", "false"],
                        "--browser"),
                       (["camera", "--width", "64", "--height", "48", "--fx", "50",
                         "--distortion", "0.1", "--k1", "0.1", "-o", "c.json"], "--distortion"),
                       (["stack", str(scene), "--pose-view", "4", "--ground-plane", "0",
                         "--first-plane", "1", "-o", "s"], "--ground-plane")]:
        result = run(*args, cwd=tmp_path)
        assert result.returncode == 2 and "excludes" in result.stderr and flag in result.stderr, \
            (args, result.stderr)
    # camera --distortion: the model's own coefficients only; the file is what --k1 .. write.
    base = ["camera", "--model", "radtan", "--width", "64", "--height", "48", "--fx", "50"]
    assert run(*base, "--distortion", "0.1,-0.02", "-o", str(tmp_path / "a.json")).returncode == 0
    assert run(*base, "--k1", "0.1", "--k2", "-0.02", "-o", str(tmp_path / "b.json")).returncode == 0
    assert (tmp_path / "a.json").read_text() == (tmp_path / "b.json").read_text()
    pinhole = run("camera", "--width", "64", "--height", "48", "--fx", "50", "--distortion", "0.1",
                  "-o", str(tmp_path / "p.json"))
    assert pinhole.returncode == 2 and "pinhole model has no distortion" in pinhole.stderr
    assert not (tmp_path / "p.json").exists()
    # stack --ground-plane with offsets: planes parallel to it (as --ground gives them).
    out = tmp_path / "stack"
    result = run("stack", str(scene), *BASE, "--ground-plane", "0,0,0,0,0,1", "--first-offset",
                 "0", "--last-offset", "2", "--slices", "3", "-o", str(out), "-q")
    assert result.returncode == 0, result.stderr
    heights = [s["plane"]["point"][2] for s in json.loads((out / "stack.json").read_text())["slices"]]
    assert heights == [0.0, 1.0, 2.0]
    # A stack's --focal-surface is a terrain file, not a plane (which it would ignore).
    plane = run("stack", str(scene), *BASE, "--focal-surface", "0", "-o", str(tmp_path / "t"))
    assert plane.returncode == 2 and "--first-plane/--last-plane" in plane.stderr
