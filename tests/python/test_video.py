"""Real flights in as they come off the drone (issue 33), through the CLI and Python: a video with
DJI's SRT telemetry (`import-video`, aos.import_video), OpenDroneMap's geo.txt in and out
(`import-telemetry --telemetry-file geo.txt`, `export-odm`, aos.read_odm_geo/write_odm_geo), and
the summary every import prints. Positions are checked against rasterio's transform (GDAL/PROJ,
independent of aos). The C++ tests (video_test, telemetry_test) hold the analytic cases."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from rasterio.warp import transform as rasterio_transform

import aos
from avi_util import write_mjpeg_avi

FPS = 10


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["aos-render", *args], capture_output=True, text=True, timeout=120)


def flight(tmp_path: Path, frames: int = 40, gimbal: bool = True) -> tuple[Path, Path, list]:
    """A 64 x 48 grey video at 10 fps flying north 1 m per frame along zone 33's central meridian
    (15 E), 30 m above the take-off point, and its SRT (one block per frame)."""
    rng = np.random.default_rng(7)
    jpegs = []
    for k in range(frames):
        aos.write_image(str(tmp_path / "f.jpg"), rng.integers(0, 256, (48, 64), dtype=np.uint8))
        jpegs.append((tmp_path / "f.jpg").read_bytes())
    video = tmp_path / "DJI_0001.AVI"
    write_mjpeg_avi(video, jpegs, 64, 48, FPS)
    eastings = [500000.0] * frames
    northings = [5318000.0 + k for k in range(frames)]
    lons, lats = rasterio_transform("EPSG:32633", "EPSG:4326", eastings, northings)
    blocks = []
    for k in range(frames):
        start, end = k * 100, (k + 1) * 100
        angles = "[gb_yaw: 0.0 gb_pitch: -90.0 gb_roll: 0.0] " if gimbal else ""
        blocks.append(
            f"{k + 1}\n00:00:{start // 1000:02d},{start % 1000:03d} --> "
            f"00:00:{end // 1000:02d},{end % 1000:03d}\n<font size=\"28\">FrameCnt: {k + 1}, "
            f"DiffTime: 100ms\n2026-06-01 10:00:00.000\n[iso: 100] [latitude: {lats[k]:.9f}] "
            f"[longitude: {lons[k]:.9f}] [rel_alt: 30.000 abs_alt: 412.500] {angles}</font>\n")
    srt = tmp_path / "DJI_0001.SRT"
    srt.write_text("\n".join(blocks))
    return video, srt, list(zip(eastings, northings))


def test_cli_imports_a_video_with_its_srt_states_every_assumption_and_leaves_nothing_on_error(
        tmp_path: Path) -> None:
    video, srt, truth = flight(tmp_path)
    out = tmp_path / "out"
    done = run("import-video", str(video), "--srt", str(srt), "--frame-every-s", "0.5",
               "--frames-fov-deg", "60", "--altitude-reference", "takeoff",
               "--takeoff-height-m", "300", "-o", str(out), "--json")
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["video_frames"] == 40 and report["frames_taken"] == 8
    assert report["fps"] == pytest.approx(FPS)
    assert report["yaw_from"] == "SRT gimbal yaw"
    assert report["altitude_from"] == "SRT rel_alt (above the take-off point)"
    assert report["order"] == "time" and report["altitude_reference"] == "takeoff"
    assert report["takeoff_height_m"] == 300.0 and report["crs"] == "EPSG:32633"
    assert sorted(p.name for p in out.iterdir()) == ["frames", "lightfield.json", "telemetry.csv"]
    lf = aos.load_lightfield(str(out / "lightfield.json")).light_field
    assert len(lf) == 8 and lf.views[1].name == "000005.png"
    assert lf.views[0].image.shape[:2] == (48, 64)
    for i, view in enumerate(lf.views):
        centre = view.cam_from_world.center + lf.origin
        np.testing.assert_allclose(centre, [*truth[5 * i], 330.0], atol=1e-3)
    # The text report says where every number came from.
    text = run("import-video", str(video), "--srt", str(srt), "--frame-every-m", "10",
               "--frames-fov-deg", "60", "-o", str(tmp_path / "out2"))
    assert text.returncode == 0, text.stderr
    for words in ("4 of 40 frames taken (every 10 m of flight)", "yaw from the SRT gimbal yaw",
                  "order: capture time", "altitude: csv alt, taken as world heights"):
        assert words in text.stdout, text.stdout
    assert "rel_alt (above the take-off point) but altitude_reference is 'absolute'" in text.stderr
    # Errors: one line naming the file and the field; no output folder left.
    bad = tmp_path / "bad.srt"
    bad.write_text("1\n00:00:00,000 --> 00:00:00,100\n[latitude: 98.1] [longitude: 15.0]\n")
    failed = run("import-video", str(video), "--srt", str(bad), "--frames-fov-deg", "60",
                 "-o", str(tmp_path / "out3"))
    assert failed.returncode == 1
    assert "bad.srt: line 2: latitude: 98.1 is outside [-90, 90]" in failed.stderr
    (tmp_path / "g").mkdir()
    no_gimbal_video, no_gimbal_srt, _ = flight(tmp_path / "g", gimbal=False)
    failed = run("import-video", str(no_gimbal_video), "--srt", str(no_gimbal_srt),
                 "--frames-fov-deg", "60", "-o", str(tmp_path / "out3"))
    assert failed.returncode == 1 and "no gimbal angles" in failed.stderr, failed.stderr
    assert not (tmp_path / "out3").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out3")]


def test_python_import_video_takes_the_same_keywords(tmp_path: Path) -> None:
    video, srt, truth = flight(tmp_path, gimbal=False)
    result = aos.import_video(video, tmp_path / "out", srt_file=str(srt), frame_every_m=5.0,
                              fixed_pitch_deg=-90.0, fov_deg=60.0)
    assert result.frames.yaw_from == "direction of flight (course over ground)"
    assert len(result.frames.frames) == 8
    lf = result.telemetry.light_field
    assert result.light_field_path == str(tmp_path / "out" / "lightfield.json")
    # Flying north: yaw 0, image up (-camera y) at north.
    rotation = np.asarray(lf.views[3].cam_from_world.rotation)
    np.testing.assert_allclose(-rotation[1], [0, 1, 0], atol=1e-6)
    np.testing.assert_allclose(lf.views[3].cam_from_world.center + lf.origin,
                               [*truth[15], 30.0], atol=1e-3)
    with pytest.raises(TypeError, match="telemetry_file"):
        aos.import_video(video, tmp_path / "o2", srt_file=str(srt), telemetry_file="x.csv")


def test_odm_geo_txt_goes_out_and_comes_back_through_cli_and_python(tmp_path: Path) -> None:
    frames = tmp_path / "frames"
    frames.mkdir()
    rows = ["frame,lat,lon,alt,yaw,pitch,roll"]
    for k in range(5):
        aos.write_image(str(frames / f"{k + 1}.png"), np.zeros((6, 8), np.uint8))
        rows.append(f"{k + 1}.png,{48.0 + 1e-4 * k:.8f},15.3,{120 + k},{10 * k},-80,2")
    (tmp_path / "log.csv").write_text("\n".join(rows) + "\n")
    first = tmp_path / "lf.json"
    assert run("import-telemetry", str(frames), "--telemetry-file", str(tmp_path / "log.csv"),
               "--frames-fov-deg", "60", "-o", str(first)).returncode == 0
    geo = tmp_path / "geo.txt"
    done = run("export-odm", str(first), "-o", str(geo))
    assert done.returncode == 0, done.stderr
    lines = geo.read_text().splitlines()
    assert lines[0] == "EPSG:32633" and lines[1].startswith("1.png ")
    parsed = aos.read_odm_geo(str(geo))
    assert parsed.crs == "EPSG:32633" and len(parsed.entries) == 5
    # ODM's convention: pitch 0 = nadir, so the gimbal's -80 is 10.
    np.testing.assert_allclose(parsed.entries[2].yaw_pitch_roll_deg, (20.0, 10.0, 2.0), atol=1e-9)
    assert run("export-odm", str(first), "-o", str(geo)).returncode == 1  # exists: --force
    back = tmp_path / "back.json"
    done = run("import-telemetry", str(frames), "--telemetry-file", str(geo), "--frames-fov-deg",
               "60", "-o", str(back), "--json")
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["source"] == "odm"
    a = aos.load_lightfield(str(first), load_images=False).light_field
    b = aos.load_lightfield(str(back), load_images=False).light_field
    for va, vb in zip(a.views, b.views):
        assert va.name == vb.name
        np.testing.assert_allclose(va.cam_from_world.center + a.origin,
                                   vb.cam_from_world.center + b.origin, atol=1e-5)
        np.testing.assert_allclose(va.cam_from_world.rotation, vb.cam_from_world.rotation,
                                   atol=1e-9)
    aos.write_odm_geo(str(tmp_path / "py.txt"), a)
    assert (tmp_path / "py.txt").read_text() == geo.read_text()
