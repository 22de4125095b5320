"""aos-render checks every flag before it loads anything: a bad flag on a light field whose frames
cannot be decoded is refused naming the flag, not the frames (which the loader would name), so
the command returned before decoding a frame. Before this, a bad --aperture-radius was refused
only after every frame had been read (F0: about a second of decoding)."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

import aos

EXE = shutil.which("aos-render")
pytestmark = pytest.mark.skipif(EXE is None, reason="aos-render is not on PATH (pip install .)")

SCENE = {
    "ground": {"texture": {"type": "noise", "square": 1.0, "colors": [0.2, 0.8]}},
    "camera": {"width": 32, "height": 24, "fov_deg": 50},
    "sampling": {"altitude": 35, "grid": 2, "aperture": {"diameter": 4}},
    "truth": {"width": 8, "height": 8, "blocked_fraction": False},
}


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([EXE, *args], capture_output=True, text=True, timeout=120)


@pytest.fixture(scope="module")
def undecodable(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A light field whose every frame is junk: loading it fails naming a frame."""
    folder = tmp_path_factory.mktemp("undecodable")
    aos.write_lightfield(str(folder / "lightfield.json"), aos.simulate(SCENE).light_field)
    frames = sorted((folder / "views").iterdir())
    assert frames
    for frame in frames:
        frame.write_bytes(b"not an image")
    return folder / "lightfield.json"


def test_loading_the_fixture_fails_naming_a_frame(undecodable: Path, tmp_path: Path) -> None:
    """The guard of the cases below: with good flags the command gets to the frames and fails
    there, so a failure naming the flag (and no frame) means it stopped before loading."""
    result = run("integral", str(undecodable), "--pose-view", "0", "-o", str(tmp_path / "o.png"))
    assert result.returncode == 1
    assert "views/0000.png" in result.stderr and "cannot read image" in result.stderr


CASES = {
    "integral aperture": (["integral", "--pose-view", "0", "--aperture-radius", "-1"], "--aperture-radius"),
    "integral view angle": (["integral", "--pose-view", "0", "--min-view-angle-deg", "95"],
                            "--min-view-angle-deg"),
    "integral width": (["integral", "--pose-view", "0", "--width", "70000"], "--width"),
    "integral no camera": (["integral"], "--pose-view, --look-at or --cam-from-world"),
    "integral bad look-at": (["integral", "--look-at", "0,0,35,0,0"], "--look-at"),
    "integral frames fov": (["integral", "--pose-view", "0", "--frames-fov-deg", "200"], "--frames-fov-deg"),
    "integral threads": (["integral", "--pose-view", "0", "--threads", "-3"], "--threads"),
    "stack aperture": (["stack", "--pose-view", "0", "--aperture-radius", "-1"], "--aperture-radius"),
    "stack slices": (["stack", "--pose-view", "0", "--slices", "0"], "--slices"),
    "stack ground file": (["stack", "--pose-view", "0", "--ground", "/nonexistent/ground.ply"],
                          "/nonexistent/ground.ply"),
    "allinfocus aperture": (["allinfocus", "--pose-view", "0", "--aperture-radius", "-1"], "--aperture-radius"),
    "allinfocus robust pinhole": (["allinfocus", "--pose-view", "0", "--aperture-radius", "0",
                                   "--method", "robust"], "--aperture-radius"),
    "map aperture": (["map", "--width", "64", "--aperture-radius", "-1"], "--aperture-radius"),
    "view aperture": (["view", "--pose-view", "0", "--aperture-radius", "-1", "--no-browser"],
                      "--aperture-radius"),
    # Flags naming views: checked against the poses alone (4 views), before any frame.
    "integral views range": (["integral", "--pose-view", "0", "--view-indices", "0:9"], "--view-indices: index 9 is outside"),
    "integral pose view range": (["integral", "--pose-view", "7"], "--pose-view: no view 7"),
    "stack views range": (["stack", "--pose-view", "0", "--view-indices", "5"], "--view-indices: index 5 is outside"),
    "allinfocus views range": (["allinfocus", "--pose-view", "0", "--view-indices", "2,4"],
                               "--view-indices: index 4 is outside"),
    "map views range": (["map", "--width", "64", "--view-indices", "1:5"], "--view-indices: index 5 is outside"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_flag_is_refused_before_loading(case: str, undecodable: Path, tmp_path: Path) -> None:
    args, flag = CASES[case]
    command, *flags = args
    output = {"integral": ["-o", str(tmp_path / "o.png")], "stack": ["-o", str(tmp_path / "stack")],
              "allinfocus": ["-o", str(tmp_path / "aif")], "map": ["-o", str(tmp_path / "m.tif")],
              "view": []}[command]
    result = run(command, str(undecodable), *flags, *output)
    assert result.returncode != 0, result.stdout
    errors = [line for line in result.stderr.splitlines() if line.startswith("aos-render: error:")]
    assert len(errors) == 1, result.stderr
    assert flag in errors[0], errors[0]
    assert "cannot read image" not in errors[0], errors[0]
    # (--pose-view's message lists the view names, which are frame paths.)
    assert "views/" not in errors[0] or "--pose-view" in flag, errors[0]
    assert not any(tmp_path.iterdir())  # nothing written


def test_merge_checks_flags_before_reading_the_stack(tmp_path: Path) -> None:
    """merge refuses a bad flag before it reads the stack (here a folder that does not exist)."""
    result = run("merge", str(tmp_path / "no-stack"), "--window-radius", "99", "-o", str(tmp_path / "out"))
    assert result.returncode != 0
    assert "--window-radius" in result.stderr and "no-stack" not in result.stderr, result.stderr


def test_metrics_and_calibrate_check_flags_before_reading_images(tmp_path: Path) -> None:
    """The images named here do not exist: a bad flag must be what is reported."""
    junk = tmp_path / "junk.png"
    junk.write_bytes(b"not an image")
    result = run("metrics", str(junk), str(junk), "--ssim-window-radius", "0")
    assert result.returncode != 0
    assert "--ssim-window-radius" in result.stderr and "junk.png" not in result.stderr, result.stderr
    result = run("calibrate", str(junk), "--square-size-m", "-1", "-o", str(tmp_path / "camera.json"))
    assert result.returncode != 0
    assert "--square-size-m" in result.stderr and "junk.png" not in result.stderr, result.stderr
    assert not (tmp_path / "camera.json").exists()
