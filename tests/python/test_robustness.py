"""Never lose data, never hang, never eat the machine (issue 13): each failure the fuzz campaign
found, as a test that failed on the code before the fix.

Every bad input must give exit code != 0 with one error line naming the file (and the key path for
JSON), no output and no leftover temporary file, and inputs byte-for-byte unchanged. Bad values of
options exit with 2, like unknown flags. Python raises ValueError for every bad input.
"""
from __future__ import annotations

import json
import os
import resource
import shutil
import signal
import struct
import subprocess
import sys
import time
import zlib
from pathlib import Path

import numpy as np
import pytest

import aos
from conftest import write_colmap_text_model

EXE = shutil.which("aos-render")
pytestmark = pytest.mark.skipif(EXE is None, reason="aos-render is not on PATH (pip install .)")

# 3 x 3 grey 8-bit views of 32 x 24 pixels from 20 m.
TINY_SCENE = {
    "occluders": {"voxels": {"center": [0, 0, 8], "size": [10, 10, 4], "grid": [10, 10, 4],
                             "density": 0.3}},
    "camera": {"width": 32, "height": 24, "fov_deg": 50},
    "sampling": {"altitude": 20, "grid": 3, "aperture": {"diameter": 4}},
    "truth": {"width": 8, "height": 8, "blocked_fraction": False},
}
CAMERA = ["--pose-view", "4", "--fov-deg", "50", "--width", "32", "--height", "24"]


def run(*args: str | Path, timeout: float = 60, env: dict | None = None,
        preexec=None) -> subprocess.CompletedProcess:
    return subprocess.run([EXE, *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env=env, preexec_fn=preexec, errors="replace")


def snapshot(folder: Path) -> dict[str, tuple[bytes, int]]:
    """Every file below `folder` with its bytes and modification time."""
    return {str(p.relative_to(folder)): (p.read_bytes(), p.stat().st_mtime_ns)
            for p in sorted(folder.rglob("*")) if p.is_file()}


def assert_refused(result: subprocess.CompletedProcess, *names: str, code: int = 1) -> str:
    """Exit code `code`, exactly one stderr line (the error), naming each of `names`."""
    assert result.returncode == code, (result.returncode, result.stdout, result.stderr)
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    errors = [line for line in lines if "error" in line]
    assert len(errors) == 1 and lines[-1] == errors[0], result.stderr
    for name in names:
        assert name in errors[0], (name, errors[0])
    return errors[0]


def no_leftovers(folder: Path, allowed: set[str]) -> None:
    """Nothing in `folder` but the `allowed` entries (no outputs, no hidden temporary files)."""
    assert {p.name for p in folder.iterdir()} <= allowed, sorted(p.name for p in folder.iterdir())


@pytest.fixture(scope="module")
def light_field(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("robust") / "lf"
    folder.mkdir()
    aos.write_lightfield(str(folder / "lightfield.json"), aos.simulate(TINY_SCENE).light_field)
    return folder / "lightfield.json"


# ---------------------------------------------------------------------------------------------
# Data loss: an output that is one of the inputs, for every command.

def write_colmap_binary_model(light_field: Path, model: Path) -> None:
    lf = json.loads(light_field.read_text())
    camera = next(iter(lf["cameras"].values()))
    model.mkdir()
    (model / "cameras.bin").write_bytes(
        struct.pack("<QIiQQ4d", 1, 1, 1, camera["width"], camera["height"], camera["fx"],
                    camera["fy"], camera["cx"], camera["cy"]))
    images = struct.pack("<Q", len(lf["views"]))
    for i, view in enumerate(lf["views"], start=1):
        t = view["cam_from_world"]["translation"]
        images += struct.pack("<I7dI", i, 0, 1, 0, 0, *t, 1)
        images += Path(view["image"]).name.encode() + b"\0" + struct.pack("<Q", 0)
    (model / "images.bin").write_bytes(images)
    (model / "points3D.bin").write_bytes(struct.pack("<Q", 0))


@pytest.mark.parametrize("kind", ["txt", "bin"])
def test_import_colmap_never_writes_over_its_model(light_field: Path, tmp_path: Path,
                                                   kind: str) -> None:
    model = tmp_path / "model"
    (write_colmap_text_model if kind == "txt" else write_colmap_binary_model)(light_field, model)
    images = light_field.parent / "views"
    ok = run("import-colmap", model, "--images-dir", images, "-o", tmp_path / "lf.json")
    assert ok.returncode == 0, ok.stderr
    before = snapshot(model)
    frames_before = snapshot(images)
    # The model's files, a symbolic link and a hard link to one of them, and a frame.
    (tmp_path / "link.json").symlink_to(model / f"images.{kind}")
    os.link(model / f"cameras.{kind}", tmp_path / "hard.json")
    targets = [model / f"{name}.{kind}" for name in ("cameras", "images", "points3D")]
    targets += [tmp_path / "link.json", tmp_path / "hard.json", images / "0000.png"]
    for target in targets:
        result = run("import-colmap", model, "--images-dir", images, "-o", target)
        assert_refused(result, str(target), "input")
    assert snapshot(model) == before and snapshot(images) == frames_before


def test_poses_and_calibrate_refuse_an_input_as_output(light_field: Path, tmp_path: Path) -> None:
    frames = light_field.parent / "views"
    before = snapshot(frames)
    positions = tmp_path / "positions.csv"
    positions.write_text("name,x,y,z\n0000.png,0,0,0\n")
    for target in (frames / "0003.png", positions):
        result = run("poses", frames, "--positions-file", positions, "-o", target)
        assert_refused(result, str(target), "input")
    result = run("calibrate", frames / "0000.png", frames / "0001.png", "-o", frames / "0001.png")
    assert_refused(result, "0001.png", "input")
    assert snapshot(frames) == before and positions.read_text().startswith("name,x,y,z")


# ---------------------------------------------------------------------------------------------
# Hangs and signals: regular files only, bounded reads, SIGTERM/SIGINT at every stage.

def test_fifo_and_devices_are_refused_at_once(light_field: Path, tmp_path: Path) -> None:
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    out = tmp_path / "out.png"
    for source in (fifo, Path("/dev/zero"), tmp_path):
        result = run("integral", source, *CAMERA, "-o", out, timeout=20)
        message = assert_refused(result, str(source))
        assert "regular file" in message or "folder" in message
    result = run("metrics", "/dev/zero", "/dev/zero", timeout=20)
    assert_refused(result, "/dev/zero", "regular file")
    # A frame of the light field that is a FIFO.
    folder = tmp_path / "lf"
    shutil.copytree(light_field.parent, folder)
    (folder / "views" / "0002.png").unlink()
    os.mkfifo(folder / "views" / "0002.png")
    result = run("integral", folder / "lightfield.json", *CAMERA, "-o", out, timeout=20)
    assert_refused(result, "0002.png", "FIFO")
    assert not out.exists()
    with pytest.raises(ValueError, match="FIFO"):
        aos.load_lightfield(str(fifo))
    with pytest.raises(ValueError, match="regular file"):
        aos.read_image("/dev/zero")


F0 = Path(__file__).resolve().parents[3] / "shared" / "data" / "jku-f0" / "poses" / "poses.json"


@pytest.mark.skipif(not F0.exists(), reason="the F0 light field is not in ../shared/data")
@pytest.mark.parametrize("signal_number", [signal.SIGTERM, signal.SIGINT])
def test_signal_while_loading_stops_at_once(tmp_path: Path, signal_number: int) -> None:
    out = tmp_path / "f0.png"
    process = subprocess.Popen(
        [EXE, "integral", str(F0), "--frames-fov-deg", "50.815436217896945", "--pose-view", "191",
         "--focal-height", "21", "-o", str(out), "--threads", "1"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        # A process started in the background inherits SIGINT ignored; restore the default.
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        # Signal once it reads the frames (loading 382 thermal frames on one thread takes about a
        # second or more), however slowly it started.
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and process.poll() is None:
            try:
                open_files = [os.readlink(f"/proc/{process.pid}/fd/{fd}")
                              for fd in os.listdir(f"/proc/{process.pid}/fd")]
            except OSError:
                open_files = []
            if any("jku-f0/images" in name for name in open_files):
                break
            time.sleep(0.005)
        process.send_signal(signal_number)
        _, stderr = process.communicate(timeout=10)
    finally:
        process.kill()
    assert process.returncode == 128 + signal_number, stderr  # 143 SIGTERM, 130 SIGINT
    assert "interrupted" in stderr
    no_leftovers(tmp_path, set())


# ---------------------------------------------------------------------------------------------
# Memory: estimated before allocating, refused with the options and the figure.

def test_output_larger_than_memory_is_refused(light_field: Path, tmp_path: Path) -> None:
    out = tmp_path / "big.exr"
    result = run("integral", light_field, "--pose-view", "4", "--width", "65536", "--height",
                 "65536", "-o", out, timeout=60,
                 preexec=lambda: resource.setrlimit(resource.RLIMIT_AS, (6 << 30, 6 << 30)))
    message = assert_refused(result, "--width", code=2)
    assert "GiB" in message and "65536" in message
    # The documented limit: AOS_MEMORY_LIMIT_MB (4096 x 4096 needs 128 MiB for image and count).
    env = dict(os.environ, AOS_MEMORY_LIMIT_MB="64")
    result = run("integral", light_field, "--pose-view", "4", "--width", "4096", "--height",
                 "4096", "-o", out, env=env)
    message = assert_refused(result, "--width", "AOS_MEMORY_LIMIT_MB", code=2)
    assert "128 MiB" in message
    # A focal stack keeps every slice; a simulation every view.
    result = run("stack", light_field, "--pose-view", "4", "--width", "1024", "--height", "1024",
                 "--slices", "100", "-o", tmp_path / "stack", env=env)
    message = assert_refused(result, "--slices", code=2)
    assert "800 MiB" in message, message
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps({"camera": {"width": 2000, "height": 1500},
                                 "sampling": {"grid": 30}}))
    message = assert_refused(run("simulate", scene, "-o", tmp_path / "sim", env=env),
                             "scene.json", "900 views of 2000 x 1500")
    assert "2.5 GiB" in message, message
    scene.unlink()
    env["AOS_MEMORY_LIMIT_MB"] = "lots"
    assert_refused(run("integral", light_field, *CAMERA, "-o", out, env=env), "AOS_MEMORY_LIMIT_MB")
    no_leftovers(tmp_path, set())


def png_chunk(kind: bytes, data: bytes) -> bytes:
    return (struct.pack(">I", len(data)) + kind + data +
            struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))


def forged_png(width: int, height: int) -> bytes:
    """A well-formed PNG header (valid CRCs) claiming width x height grey pixels, no pixels."""
    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", header) +
            png_chunk(b"IDAT", zlib.compress(b"")) + png_chunk(b"IEND", b""))


def forged_tiff(width: int, height: int, data: bytes, claimed_bytes: int) -> bytes:
    """An uncompressed float32 grey TIFF of width x height in one strip that claims
    `claimed_bytes` of pixel data but holds `data`."""
    entries = [(256, 4, 1, width), (257, 4, 1, height), (258, 3, 1, 32), (259, 3, 1, 1),
               (262, 3, 1, 1), (273, 4, 1, 0), (277, 3, 1, 1), (278, 4, 1, height),
               (279, 4, 1, claimed_bytes), (339, 3, 1, 3)]
    ifd_size = 2 + 12 * len(entries) + 4
    data_offset = 8 + ifd_size
    body = struct.pack("<H", len(entries))
    for tag, kind, count, value in entries:
        value = data_offset if tag == 273 else value
        packed = struct.pack("<I", value) if kind == 4 else struct.pack("<HH", value, 0)
        body += struct.pack("<HHI", tag, kind, count) + packed
    body += struct.pack("<I", 0)
    return b"II*\x00" + struct.pack("<I", 8) + body + data


def test_image_headers_that_lie_are_refused_before_decoding(tmp_path: Path) -> None:
    png = tmp_path / "huge.png"
    png.write_bytes(forged_png(46340, 46340))
    tiff = tmp_path / "huge.tif"
    tiff.write_bytes(forged_tiff(30000, 30000, b"\0" * 64, 30000 * 30000 * 4))
    assert len(png.read_bytes()) < 100 and len(tiff.read_bytes()) < 300
    small = tmp_path / "small.png"
    aos.write_image(str(small), np.zeros((8, 8), np.uint8))
    for image in (png, tiff):
        # 1 GiB of address space is far less than either image would take decoded.
        result = run("metrics", image, small,
                     preexec=lambda: resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30)))
        message = assert_refused(result, str(image))
        assert "header claims" in message, message
        with pytest.raises(ValueError, match="header claims"):
            aos.read_image(str(image))


# ---------------------------------------------------------------------------------------------
# Accepted but wrong.

def test_truncated_tiff_is_an_error_not_junk(light_field: Path, tmp_path: Path) -> None:
    # A 32 x 32 float TIFF holding 16 of its 1024 pixels.
    truncated = tmp_path / "truncated.tif"
    truncated.write_bytes(forged_tiff(32, 32, np.ones(16, np.float32).tobytes(), 32 * 32 * 4))
    with pytest.raises(ValueError, match="truncated.tif"):
        aos.read_image(str(truncated))
    small = tmp_path / "ok.tif"
    aos.write_image(str(small), np.ones((32, 32), np.float32))
    assert_refused(run("metrics", truncated, small), "truncated.tif")
    # A truncated slice of a focal stack.
    stack = tmp_path / "stack"
    result = run("stack", light_field, *CAMERA, "--slices", "3", "-q", "-o", stack)
    assert result.returncode == 0, result.stderr
    slice_file = stack / "slice_0001.tif"
    assert slice_file.exists(), sorted(p.name for p in stack.iterdir())
    slice_file.write_bytes(slice_file.read_bytes()[: slice_file.stat().st_size // 2])
    result = run("merge", stack, "-o", tmp_path / "merged")
    assert_refused(result, "slice_0001.tif")
    assert not (tmp_path / "merged").exists()


def test_merge_names_the_stack_json_that_names_a_missing_slice(light_field: Path,
                                                               tmp_path: Path) -> None:
    stack = tmp_path / "stack"
    result = run("stack", light_field, *CAMERA, "--slices", "3", "-q", "-o", stack)
    assert result.returncode == 0, result.stderr
    (stack / "slice_0002.tif").unlink()
    result = run("merge", stack, "-o", tmp_path / "merged")
    message = assert_refused(result, "stack.json", "/slices/2/image", "slice_0002.tif")
    assert message.index("stack.json") < message.index("slice_0002.tif"), message
    with pytest.raises(ValueError, match=r"stack\.json: /slices/2/image: .*slice_0002\.tif"):
        aos.read_focal_stack(str(stack))
    assert not (tmp_path / "merged").exists()


def test_output_formats_are_refused_before_rendering(light_field: Path, tmp_path: Path) -> None:
    # An image output no writer takes (or a map that is not a .tif name) is refused before any
    # rendering: nothing rendered ("integrated ..." comes after the render), nothing written.
    cases = [
        (["integral", light_field, *CAMERA, "-o", tmp_path / "a.xyz"], "a.xyz", "extension .xyz"),
        (["integral", light_field, *CAMERA, "-o", tmp_path / "noext"], "noext", "no file extension"),
        (["integral", light_field, *CAMERA, "-o", tmp_path / "a.tif", "--count",
          tmp_path / "c.xyz"], "c.xyz", "extension .xyz"),
        (["integral", light_field, *CAMERA, "-o", tmp_path / "a.exr", "--sample-type", "uint8"],
         "a.exr", "EXR files hold float samples"),
        (["map", light_field, "--pixel-size", "0.5", "-o", tmp_path / "map.png"], "map.png",
         "Cloud-Optimised GeoTIFF"),
    ]
    for args, name, why in cases:
        result = run(*args)
        assert result.returncode in (1, 2), (args, result.stderr)
        message = [line for line in result.stderr.splitlines() if "error" in line]
        assert len(message) == 1 and name in message[0] and why in message[0], result.stderr
        assert "integrated" not in result.stderr and "map:" not in result.stderr, result.stderr
        no_leftovers(tmp_path, set())
    result = run("map", light_field, "--pixel-size", "0.5", "-o", tmp_path / "map.png")
    assert result.returncode == 2 and "--output" in result.stderr, result.stderr
    lf = aos.load_lightfield(str(light_field)).light_field
    with pytest.raises(ValueError, match=r"map\.png: a map is written as a Cloud-Optimised GeoTIFF"):
        aos.render_map(lf, pixel_size=0.5, path=tmp_path / "map.png")
    with pytest.raises(ValueError, match=r"a\.xyz: no image format has the extension \.xyz"):
        aos.write_image(str(tmp_path / "a.xyz"), np.zeros((4, 4), np.uint8))
    no_leftovers(tmp_path, set())


def test_truncated_jpeg_is_an_error_not_grey(tmp_path: Path) -> None:
    # A JPEG without its end-of-image marker: libjpeg decodes this one (a gradient, whose last
    # scan data ends before the decoder looks past it) without a word; OpenImageIO catches
    # other cuts ("Premature end of JPEG file"), not this one.
    y, x = np.mgrid[0:48, 0:64]
    whole = tmp_path / "whole.jpg"
    aos.write_image(str(whole), ((x + y) % 256).astype(np.uint8))
    data = whole.read_bytes()
    assert data[-2:] == b"\xff\xd9"
    truncated = tmp_path / "truncated.jpg"
    for cut in (2, len(data) // 3):
        truncated.write_bytes(data[:-cut])
        with pytest.raises(ValueError, match="truncated.jpg: truncated JPEG"):
            aos.read_image(str(truncated))
    truncated.write_bytes(data[:-2])
    assert_refused(run("metrics", truncated, whole), "truncated.jpg", "truncated JPEG")
    camera = tmp_path / "camera.json"
    camera.write_text(json.dumps({"format": "aos-camera", "version": 1, "model": "fisheye",
                                  "width": 64, "height": 48, "fx": 24, "fy": 24, "cx": 32,
                                  "cy": 24, "distortion": [0, 0, 0, 0]}))
    out = tmp_path / "rectified"
    result = run("rectify", truncated, "--camera", camera, "--rectified-fov-deg", "60", "-o", out)
    assert_refused(result, "truncated.jpg", "truncated JPEG")
    assert not out.exists()
    result = run("rectify", whole, "--camera", camera, "--rectified-fov-deg", "60", "-o", out)
    assert result.returncode == 0, result.stderr


def test_rectify_refuses_non_finite_frames(tmp_path: Path) -> None:
    camera = tmp_path / "camera.json"
    camera.write_text(json.dumps({"format": "aos-camera", "version": 1, "model": "fisheye",
                                  "width": 32, "height": 24, "fx": 12, "fy": 12, "cx": 16,
                                  "cy": 12, "distortion": [0, 0, 0, 0]}))
    for bad in (np.nan, np.inf):
        frame = tmp_path / "frame.tif"
        pixels = np.full((24, 32), 0.5, np.float32)
        pixels[5, 7] = bad
        aos.write_image(str(frame), pixels)
        out = tmp_path / "rectified"
        result = run("rectify", frame, "--camera", camera, "--rectified-fov-deg", "60", "-o", out)
        message = assert_refused(result, "frame.tif")
        assert "(7, 5)" in message and ("NaN" in message or "infinite" in message)
        assert not out.exists()


def test_bad_values_of_options_exit_2(light_field: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    for grid in ("0", "-3"):
        result = run("simulate", "--grid", grid, "-o", out)
        assert result.returncode == 2 and "--grid" in result.stderr, result.stderr
    result = run("integral", light_field, "--pose-view", "-1", "-o", tmp_path / "a.png")
    assert result.returncode == 2 and "--pose-view" in result.stderr, result.stderr
    for args in (["--width", "-5"], ["--view-indices", "5:2"], ["--range", "3,1"],
                 ["--aperture-radius", "x"]):
        result = run("integral", light_field, "--pose-view", "4", *args, "-o", tmp_path / "a.png")
        assert_refused(result, args[0], code=2)
    result = run("allinfocus", light_field, *CAMERA, "--method", "foo", "-o", out)
    assert_refused(result, "--method", code=2)
    no_leftovers(tmp_path, set())


# ---------------------------------------------------------------------------------------------
# Errors that say where.

def test_json_errors_name_the_file_and_key(light_field: Path, tmp_path: Path) -> None:
    lf = json.loads(light_field.read_text())
    text = json.dumps(lf, indent=1).replace('"translation": [', '"translation": [1e999, ', 1)
    overflow = light_field.parent / "overflow.json"
    overflow.write_text(text)
    message = assert_refused(run("integral", overflow, *CAMERA, "-o", tmp_path / "a.png"),
                             "overflow.json", "/views/0/cam_from_world/translation/0")
    assert "[json.exception" not in message
    with pytest.raises(ValueError, match="overflow.json: /views/0/cam_from_world/translation"):
        aos.load_lightfield(str(overflow))

    camera = tmp_path / "camera.json"
    camera.write_text(json.dumps({"format": 7, "version": 1}))
    message = assert_refused(run("rectify", light_field.parent / "views" / "0000.png",
                                 "--camera", camera, "-o", tmp_path / "r"), "camera.json", "format")
    assert "[json.exception" not in message
    camera.write_text('{"format": "aos-camera", "version": 1, "model": "pinhole", '
                      '"width": 1e999}')
    with pytest.raises(ValueError, match="camera.json: /width"):
        aos.read_camera_file(str(camera))

    scene = tmp_path / "scene.json"
    scene.write_text('{"sampling": {"grid": 1e999}}')
    assert_refused(run("simulate", scene, "-o", tmp_path / "s"), "scene.json", "/sampling/grid")
    scene.write_text('{"sampling": {"grid": "three"}}')
    assert_refused(run("simulate", scene, "-o", tmp_path / "s"), "scene.json", "grid")
    no_leftovers(tmp_path, {"camera.json", "scene.json"})


def test_invalid_utf8_raises_value_error(light_field: Path, tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_bytes(b'{"format": "aos-lightfield", "version": 1, "na\xffme": 1}')
    with pytest.raises(ValueError, match="bad.json"):
        aos.load_lightfield(str(bad))
    bad.write_bytes(b'{"format": "aos-camera", "model": "pin\xc3\x28hole"}')
    with pytest.raises(ValueError, match="bad.json"):
        aos.read_camera_file(str(bad))
    with pytest.raises(ValueError, match="bad.json"):
        aos.load_scene(str(bad))
    assert_refused(run("integral", bad, *CAMERA, "-o", tmp_path / "a.png"), "bad.json")
    # A COLMAP model naming a frame in invalid UTF-8.
    model = tmp_path / "model"
    write_colmap_text_model(light_field, model)
    images = (model / "images.txt").read_bytes().replace(b"0000.png", b"00\xff0.png", 1)
    (model / "images.txt").write_bytes(images)
    with pytest.raises(ValueError, match="UTF-8"):
        aos.import_colmap(str(model), str(light_field.parent / "views"))


def test_damaged_png_gives_one_line(light_field: Path, tmp_path: Path) -> None:
    png = bytearray((light_field.parent / "views" / "0000.png").read_bytes())
    for position in (12, 40, len(png) // 2, len(png) - 6):
        damaged = tmp_path / "damaged.png"
        mutated = png.copy()
        mutated[position] ^= 0x5A
        damaged.write_bytes(bytes(mutated))
        assert_refused(run("metrics", damaged, light_field.parent / "views" / "0001.png"),
                       "damaged.png")
    damaged.write_bytes(bytes(png[:100]))
    assert_refused(run("metrics", damaged, damaged), "damaged.png")


def test_write_failure_names_the_users_path(light_field: Path, tmp_path: Path) -> None:
    """A full disk (here: a file-size limit of 300 bytes) while writing: the error names -o."""
    def small_files() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (300, 300))

    out = tmp_path / "out"
    out.mkdir()
    for name in ("image.png", "image.tif", "image.exr"):
        result = run("integral", light_field, *CAMERA, "-o", out / name, preexec=small_files)
        message = assert_refused(result, str(out / name))
        assert ".tmp" not in message, message
    result = run("allinfocus", light_field, *CAMERA, "--slices", "2", "-o", out / "aif",
                 preexec=small_files)
    message = assert_refused(result, str(out / "aif"))
    assert ".partial" not in message, message
    no_leftovers(out, set())


def test_python_raises_value_error_for_library_errors(tmp_path: Path) -> None:
    """The bindings turn the JSON library's and the filesystem's exceptions into ValueError."""
    with pytest.raises(ValueError, match="<dict>"):
        aos.simulate({"sampling": {"grid": float("nan")}})
    with pytest.raises(ValueError, match="not valid JSON"):
        aos.parse_scene('{"seed": 1e999}', "inline")


def test_sixteen_bit_frames_give_sixteen_bit_pngs(tmp_path: Path) -> None:
    """One rule for float -> integer samples (image_io.h): renders keep the views' units and, to
    PNG, their depth; the CLI wrote 8-bit PNGs of 16-bit thermal frames."""
    from conftest import build_lightfield

    folder = tmp_path / "lf"
    folder.mkdir()
    lf = build_lightfield(dtype=np.uint16, value=40001.0)
    aos.write_lightfield(str(folder / "lightfield.json"), lf)
    out = tmp_path / "integral.png"
    result = run("integral", folder / "lightfield.json", "--pose-view", "4", "--width", "16",
                 "--height", "12", "--fov-deg", "30", "-o", out)
    assert result.returncode == 0, result.stderr
    image = aos.read_image(str(out))
    assert image.dtype == np.uint16 and np.all(image == 40001), (image.dtype, image.max())
    # Python's write_image follows the same rule, with the units stated.
    floats = np.full((4, 5), 40001.0, np.float32)
    aos.write_image(str(tmp_path / "a.png"), floats, units="uint16")
    back = aos.read_image(str(tmp_path / "a.png"))
    assert back.dtype == np.uint16 and np.all(back == 40001)
    aos.write_image(str(tmp_path / "b.png"), np.full((4, 5), 0.5, np.float32), units="float32")
    back = aos.read_image(str(tmp_path / "b.png"))
    assert back.dtype == np.uint16 and np.all(back == 32768)
    aos.write_image(str(tmp_path / "c.png"), np.full((4, 5), 100.0, np.float32))
    back = aos.read_image(str(tmp_path / "c.png"))
    assert back.dtype == np.uint8 and np.all(back == 100)


def test_positions_in_degrees_are_projected_not_read_as_metres(light_field: Path,
                                                                tmp_path: Path) -> None:
    """A name,lat,lon,alt file was read as metres (origin "48.300 14.300", exit 0)."""
    model = tmp_path / "model"
    write_colmap_text_model(light_field, model)
    lf = json.loads(light_field.read_text())
    lat0, lon0 = 48.3, 14.3
    lines = ["name,lat,lon,alt"]
    for view in lf["views"]:
        rotation = np.array(view["cam_from_world"]["rotation"])
        centre = -rotation.T @ np.array(view["cam_from_world"]["translation"])
        lat = lat0 + centre[1] / 111_200.0
        lon = lon0 + centre[0] / (111_320.0 * np.cos(np.radians(lat0)))
        lines.append(f"{Path(view['image']).name},{lat:.9f},{lon:.9f},{300 + centre[2]:.3f}")
    positions = tmp_path / "gps.csv"
    positions.write_text("\n".join(lines) + "\n")
    images = light_field.parent / "views"
    out = tmp_path / "lf.json"
    result = run("import-colmap", model, "--images-dir", images, "--positions-file", positions, "-o", out)
    assert result.returncode == 0, result.stderr
    assert "UTM 33N" in result.stdout, result.stdout
    origin = json.loads(out.read_text())["origin"]
    assert 400_000 < origin[0] < 600_000 and 5_300_000 < origin[1] < 5_400_000, origin
    # The same numbers without a header are evidently degrees: refused, not read as metres.
    positions.write_text("\n".join(lines[1:]) + "\n")
    message = assert_refused(run("import-colmap", model, "--images-dir", images, "--positions-file",
                                 positions, "-o", tmp_path / "lf2.json"), "gps.csv")
    assert "look like degrees" in message
    # ... unless the CRS is stated (x = longitude, y = latitude in EPSG:4326's GIS order).
    swapped = ["name,x,y,z"] + [
        ",".join([f[0], f[2], f[1], f[3]]) for f in (line.split(",") for line in lines[1:])]
    positions.write_text("\n".join(swapped) + "\n")
    result = run("import-colmap", model, "--images-dir", images, "--positions-file", positions,
                 "--positions-crs", "EPSG:4326", "-o", tmp_path / "lf3.json")
    assert result.returncode == 0, result.stderr
    origin3 = json.loads((tmp_path / "lf3.json").read_text())["origin"]
    assert np.allclose(origin3, origin, atol=1e-6)


def test_light_field_files_refuse_unknown_keys(light_field: Path, tmp_path: Path) -> None:
    """A misspelled "orgin" was ignored (origin silently 0) while the camera and scene readers
    refused unknown keys. Every format reads cameras, poses and the pose record with one codec
    now, which refuses unknown keys naming the file and the key's JSON pointer."""
    lf = json.loads(light_field.read_text())
    camera_id = next(iter(lf["cameras"]))
    cases = [("orgin", lambda d: d.__setitem__("orgin", [1.0, 2.0, 3.0]), "/orgin: unknown key"),
             ("view", lambda d: d["views"][2].__setitem__("exposure", 1),
              "/views/2/exposure: unknown key"),
             ("camera", lambda d: d["cameras"][camera_id].__setitem__("k1", 0.1),
              f"/cameras/{camera_id}/k1: unknown key"),
             ("pose", lambda d: d["views"][0]["cam_from_world"].__setitem__("scale", 2),
              r"/views/0/cam_from_world/scale \(view 0: views/0000\.png\): unknown key"),
             ("pose_source", lambda d: d.__setitem__("pose_source", {"method": "colmap",
                                                                     "median_dept": 3}),
              "/pose_source/median_dept: unknown key")]
    for name, mutate, expected in cases:
        document = json.loads(json.dumps(lf))
        mutate(document)
        bad = light_field.parent / f"bad_{name}.json"
        bad.write_text(json.dumps(document))
        with pytest.raises(ValueError, match=f"bad_{name}.json: {expected}"):
            aos.load_lightfield(str(bad))
        bad.unlink()
    # The camera file: the same rule and the same fields (fov_deg for a pinhole included).
    camera = dict(lf["cameras"][camera_id], format="aos-camera", version=1)
    path = tmp_path / "camera.json"
    path.write_text(json.dumps(dict(camera, fxx=1)))
    with pytest.raises(ValueError, match="camera.json: /fxx: unknown key"):
        aos.read_camera_file(path)
    path.write_text(json.dumps(camera))
    loaded = aos.load_lightfield(str(light_field), load_images=False).light_field
    assert aos.read_camera_file(path) == loaded.views[0].camera


def test_truth_camera_reads_as_a_camera_file(tmp_path: Path) -> None:
    # truth/truth.json writes its camera and pose with the shared codec: the camera reads in a
    # camera file (it carried fov_deg beside fx, fy, cx, cy, which no reader accepts).
    simulation = aos.simulate({"sampling": {"grid": 1}, "camera": {"width": 16, "height": 12},
                               "truth": {"width": 16, "height": 12}})
    summary = json.loads(simulation.summary_json())
    path = tmp_path / "camera.json"
    path.write_text(json.dumps(dict(summary["truth_camera"], format="aos-camera", version=1)))
    camera = aos.read_camera_file(path)
    assert camera.pinhole() == simulation.truth.camera
    assert summary["truth_fov_deg"] == pytest.approx(simulation.truth.camera.fov_x_deg())


# ---------------------------------------------------------------------------------------------
# Found by the libFuzzer campaign (tests/fuzz, tools/run_sanitizers.sh --fuzz-only).

def test_huge_lens_frames_are_refused_not_walked() -> None:
    # A radtan lens with tangential terms checks its frame's border; it used to visit every
    # border pixel, so a camera claiming 2^31 pixels across hung (camera files allow any int).
    with pytest.raises(ValueError, match="at most 65536"):
        aos.LensCamera(aos.LensModel.radtan, 2**31 - 1, 480, 500, 500, 320, 240,
                       distortion=[0.01, 0, 0.001, 0.001, 0])
    with pytest.raises(ValueError, match="at most 65536"):
        aos.PinholeCamera(70000, 480, 500, 500, 320, 240).check("camera")
    start = time.monotonic()
    lens = aos.LensCamera(aos.LensModel.radtan, 65536, 65536, 40000, 40000, 32768, 32768,
                          distortion=[0.01, 0, 0.001, 0.001, 0])
    assert lens.width == 65536 and time.monotonic() - start < 30  # a bound against hanging


def test_integer_images_count_their_conversion_buffer(tmp_path: Path) -> None:
    # uint32 samples are read natively and converted to float: 16 MiB of floats plus 16 MiB of
    # uint32 are in memory at once, over a 24 MiB limit (the check counted the floats only).
    path = tmp_path / "counts.tif"
    aos.write_image(str(path), np.arange(2048 * 2048, dtype=np.uint32).reshape(2048, 2048))
    code = ("import aos, sys\n"
            "try:\n    aos.read_image(sys.argv[1])\n"
            "except ValueError as error:\n    print(error)\n")
    env = dict(os.environ, AOS_MEMORY_LIMIT_MB="24")
    out = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True,
                         text=True, env=env, timeout=60)
    assert "counts.tif" in out.stdout and "32 MiB" in out.stdout, out
    env["AOS_MEMORY_LIMIT_MB"] = "40"
    out = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True,
                         text=True, env=env, timeout=60)
    assert out.returncode == 0 and out.stdout == "", out


def test_focal_stack_is_refused_before_its_slices_are_decoded(tmp_path: Path) -> None:
    # 100 slices of 512 x 512 (every one the same two small files): each file fits the limit, the
    # stack (100 x 512 x 512 x 8 bytes = 200 MiB) does not.
    folder = tmp_path / "stack"
    folder.mkdir()
    aos.write_image(str(folder / "image.tif"), np.ones((512, 512), np.float32))
    aos.write_image(str(folder / "count.tif"), np.ones((512, 512), np.uint32))
    stack = {"format": "aos-focal-stack", "version": 1,
             "camera": {"width": 512, "height": 512, "fx": 400, "fy": 400, "cx": 256, "cy": 256},
             "cam_from_world": {"rotation": [[1, 0, 0], [0, -1, 0], [0, 0, -1]],
                                "translation": [0, 0, 30]},
             "slices": [{"plane": {"point": [0, 0, i * 0.1], "normal": [0, 0, 1]},
                         "image": "image.tif", "count": "count.tif"} for i in range(100)]}
    (folder / "stack.json").write_text(json.dumps(stack))
    before = snapshot(tmp_path)
    env = dict(os.environ, AOS_MEMORY_LIMIT_MB="64")
    result = run("merge", folder, "-o", tmp_path / "merged", env=env)
    message = assert_refused(result, "stack.json", "100 slices of 512x512")
    assert "200 MiB" in message, message
    assert snapshot(tmp_path) == before


def test_exr_attribute_sizes_past_the_end_are_refused(tmp_path: Path) -> None:
    # 24 bytes: magic, version 2, and a string attribute declaring 2 GiB (OpenEXR allocated it).
    exr = tmp_path / "forged.exr"
    exr.write_bytes(b"\x76\x2f\x31\x01" + struct.pack("<I", 2) + b"a\0string\0" +
                    struct.pack("<i", 0x7FFFFFF0) + b"xx")
    small = tmp_path / "small.png"
    aos.write_image(str(small), np.zeros((8, 8), np.uint8))
    result = run("metrics", exr, small,
                 preexec=lambda: resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30)))
    message = assert_refused(result, str(exr), "damaged OpenEXR file")
    assert "past the end" in message, message
    with pytest.raises(ValueError, match="damaged OpenEXR file"):
        aos.read_image(str(exr))
    # A real EXR still reads.
    good = tmp_path / "good.exr"
    values = np.linspace(0, 1, 64, dtype=np.float32).reshape(8, 8)
    aos.write_image(str(good), values)
    np.testing.assert_array_equal(aos.read_image(str(good)), values)


def test_four_channel_tiffs_read_the_same_in_other_programs(tmp_path: Path) -> None:
    # Only PNGs are written with OpenImageIO's "unassociated alpha" hint: in a TIFF it tags the
    # last channel as alpha, and other programs (oiiotool, OpenImageIO's defaults) then multiply
    # the others by it.
    oiiotool = shutil.which("oiiotool")
    if oiiotool is None:
        pytest.skip("oiiotool (openimageio-tools) is not installed")
    values = np.array([[[0.8, 0.6, 0.4, 0.5]]], np.float32).repeat(4, 0).repeat(4, 1)
    path = tmp_path / "rgba.tif"
    aos.write_image(str(path), values)
    copy = tmp_path / "copy.exr"
    done = subprocess.run([oiiotool, str(path), "-o", str(copy)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    np.testing.assert_allclose(aos.read_image(str(copy)), values, rtol=1e-6)


@pytest.mark.parametrize("suffix", [".png", ".tif"])
def test_two_and_four_channel_images_read_back_as_written(tmp_path: Path, suffix: str) -> None:
    # The last channel is data, not alpha to multiply the others by (the writer used to refuse
    # a 4-channel PNG, blaming the disk, because the read-back was premultiplied).
    rng = np.random.default_rng(7)
    for channels in (2, 4):
        values = rng.integers(0, 256, (6, 5, channels), dtype=np.uint8)
        values[0, 0, -1] = 0
        path = tmp_path / f"c{channels}{suffix}"
        aos.write_image(str(path), values)
        np.testing.assert_array_equal(aos.read_image(str(path)), values)


# ---------------------------------------------------------------------------------------------
# Found by tools/fuzz.py (tests/python/test_fuzz.py runs a seeded campaign).

def corrupt_first_chunk_data(png: bytes, kind: bytes, offset: int) -> bytes:
    """`png` with one byte of its first `kind` chunk's data flipped and the CRC fixed."""
    position = 8
    while True:
        length, name = struct.unpack(">I4s", png[position:position + 8])
        if name == kind:
            data = bytearray(png[position + 8:position + 8 + length])
            data[offset] ^= 0xFF
            return (png[:position] + png_chunk(kind, bytes(data)) +
                    png[position + 12 + length:])
        position += 12 + length


def test_damaged_pixel_data_gives_one_error_line(light_field: Path, tmp_path: Path) -> None:
    # libpng printed its own "libpng error: ..." line before ours when the zlib stream of IDAT
    # (CRC valid) or the IHDR values were bad; a damaged deflate strip of a TIFF read as zeros.
    rng = np.random.default_rng(3)
    good_png = tmp_path / "good.png"
    aos.write_image(str(good_png), rng.integers(0, 255, (32, 32), dtype=np.uint8))
    png = good_png.read_bytes()
    cases = {"idat.png": corrupt_first_chunk_data(png, b"IDAT", 20),
             "ihdr.png": corrupt_first_chunk_data(png, b"IHDR", 9),   # bit depth 8 -> 247
             # The signature's last bytes altered (a text-mode transfer; fuzz seed 3 case 158).
             "signature.png": png[:7] + b"0" + png[8:],
             "cut.png": png[:6]}
    good_tif = tmp_path / "good.tif"
    aos.write_image(str(good_tif), rng.integers(0, 60000, (32, 32), dtype=np.uint16))
    tif = bytearray(good_tif.read_bytes())
    offset = struct.unpack("<I", tif[4:8])[0]
    entries = {struct.unpack("<H", tif[offset + 2 + 12 * i:offset + 4 + 12 * i])[0]: offset + 2 + 12 * i
               for i in range(struct.unpack("<H", tif[offset:offset + 2])[0])}
    assert struct.unpack("<H", tif[entries[259] + 8:entries[259] + 10])[0] == 8   # deflate
    strip = struct.unpack("<I", tif[entries[273] + 8:entries[273] + 12])[0]
    tif[strip + 30:strip + 34] = b"\xff\x00\xff\x00"
    cases["strip.tif"] = bytes(tif)
    for name, data in cases.items():
        path = tmp_path / name
        path.write_bytes(data)
        reference = good_tif if name.endswith(".tif") else good_png
        message = assert_refused(run("metrics", path, reference), str(path))
        assert "libpng" not in message, message
        with pytest.raises(ValueError, match=name):
            aos.read_image(str(path))


@pytest.mark.parametrize("kind", ["txt", "bin"])
def test_a_special_file_in_a_colmap_model_is_named(light_field: Path, tmp_path: Path,
                                                   kind: str) -> None:
    # A FIFO or a link to /dev/zero in place of one model file made the folder "not a COLMAP
    # sparse model"; the error names the file.
    model = tmp_path / "model"
    (write_colmap_text_model if kind == "txt" else write_colmap_binary_model)(light_field, model)
    (model / f"images.{kind}").unlink()
    os.mkfifo(model / f"images.{kind}")
    (model / f"points3D.{kind}").unlink()
    (model / f"points3D.{kind}").symlink_to("/dev/zero")
    result = run("import-colmap", model, "--images-dir", light_field.parent / "views", "-o",
                 tmp_path / "lf.json", timeout=30)
    message = assert_refused(result, f"images.{kind}")
    assert "FIFO" in message, message
    no_leftovers(tmp_path, {"model"})


def test_deeply_nested_json_is_refused_not_a_crash(light_field: Path, tmp_path: Path) -> None:
    # 100000 nested arrays in a view's "image" crashed integral with SIGSEGV (stack overflow).
    lf = json.loads(light_field.read_text())
    text = json.dumps(lf).replace('"image": "views/0003.png"', '"image": ' + "[" * 100000 +
                                  "]" * 100000, 1)
    assert text.count("[") > 100000
    deep = light_field.parent / "deep.json"
    deep.write_text(text)
    try:
        message = assert_refused(run("integral", deep, *CAMERA, "-o", tmp_path / "a.png"),
                                 "deep.json", "/views/3/image/0/0")
        assert "nested deeper than 256 levels" in message and len(message) < 300, message
        with pytest.raises(ValueError, match="nested deeper than 256"):
            aos.load_lightfield(str(deep))
    finally:
        deep.unlink()
    no_leftovers(tmp_path, set())


def test_stack_and_model_errors_name_the_file_at_fault(light_field: Path, tmp_path: Path) -> None:
    # A stack slice with values that overflow the merge's float32 focus measures wrote NaN
    # confidences (exit 0); a wrong count file and a COLMAP camera of the wrong size were blamed
    # on stack.json / images.bin; a camera file whose lens cannot cover the view was not named.
    folder = tmp_path / "stack"
    done = run("stack", light_field, *CAMERA, "--first-plane", "-1", "--last-plane", "1",
               "--slices", "2", "-q", "-o", folder)
    assert done.returncode == 0, done.stderr
    meta = json.loads((folder / "stack.json").read_text())
    slice_file = folder / meta["slices"][1]["image"]
    count_file = folder / meta["slices"][0]["count"]
    values = aos.read_image(str(slice_file))
    values[3, 4] = 3e20
    slice_file.unlink()
    aos.write_image(str(slice_file), values)
    message = assert_refused(run("merge", folder, "-o", tmp_path / "m"), slice_file.name,
                             "beyond +-1e15")
    with pytest.raises(ValueError, match=slice_file.name):
        aos.read_focal_stack(str(folder))
    values[3, 4] = 0
    slice_file.unlink()
    aos.write_image(str(slice_file), values)
    count_file.unlink()
    aos.write_image(str(count_file), np.ones((24, 32), np.uint16))
    assert_refused(run("merge", folder, "-o", tmp_path / "m"), count_file.name, "32-bit counts")

    model = tmp_path / "model"
    write_colmap_text_model(light_field, model)
    cameras = (model / "cameras.txt").read_text()
    (model / "cameras.txt").write_text(cameras.replace(" 32 24 ", " 64 24 "))
    assert (model / "cameras.txt").read_text() != cameras
    assert_refused(run("import-colmap", model, "--images-dir", light_field.parent / "views", "-o",
                       tmp_path / "lf.json"), "cameras.txt", "64x24")

    camera = tmp_path / "camera.json"
    camera.write_text(json.dumps({"format": "aos-camera", "version": 1, "model": "pinhole",
                                  "width": 32, "height": 24, "fx": 30, "fy": 30, "cx": -200,
                                  "cy": 12}))
    result = run("rectify", light_field.parent / "views" / "0000.png", "--camera", camera,
                 "--rectified-fov-deg", "40", "-o", tmp_path / "r")
    assert_refused(result, "camera.json", "does not cover", code=2)
    no_leftovers(tmp_path, {"stack", "model", "camera.json"})


def test_positions_with_invalid_utf8_and_mismatched_metrics_are_named(tmp_path: Path) -> None:
    # Found by a 3000-case run of tools/fuzz.py: a positions CSV with a byte 0xff in a name raised
    # UnicodeDecodeError in Python; metrics of two images of different sizes named neither file.
    positions = tmp_path / "positions.csv"
    positions.write_bytes(b"name,x,y,z\n\xffa.png,1,2,3\n")
    with pytest.raises(ValueError, match=r"positions.csv: line 2: not valid UTF-8"):
        aos.read_positions(str(positions))
    small, tall = tmp_path / "small.png", tmp_path / "tall.png"
    aos.write_image(str(small), np.zeros((8, 8), np.uint8))
    aos.write_image(str(tall), np.zeros((16, 8), np.uint8))
    message = assert_refused(run("metrics", tall, small), str(tall), str(small))
    assert "8x16x1" in message, message
