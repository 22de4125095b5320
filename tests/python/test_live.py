"""Live, in-flight integration (aos-render live, aos.LiveIntegrator, docs/live.md): a replayed
simulated flight equals the batch render of its window at every step and finds the hidden person
before the flight ends; a watched folder takes frames only once complete and skips a corrupt
one with one warning."""

from __future__ import annotations

import json
import os
import math
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import aos

ROOT = Path(__file__).resolve().parents[2]


def test_replay_equals_the_batch_render_at_every_step_and_finds_the_person(
        forest: aos.LightField) -> None:
    window = 30
    live = aos.LiveIntegrator(forest, aos.IntegralOptions(focal_surface=0.0),
                              aos.DetectOptions(), aos.LiveOptions(window_frames=window))
    found_at = None
    for i, view in enumerate(forest.views):
        dropped = live.add_view(view)
        first = max(0, i - window + 1)
        assert dropped == ([forest.views[first - 1].name] if first > 0 else [])
        batch = aos.render_integral(forest, focal_surface=0.0, pose_view=i,
                                    view_indices=list(range(first, i + 1)))
        np.testing.assert_array_equal(live.image, batch.image)
        np.testing.assert_array_equal(live.count, batch.count)
        near = [t for t in live.tracks
                if math.hypot(t.detection.local[0], t.detection.local[1]) < 0.5]
        if near and found_at is None:
            found_at = i
    assert found_at is not None and found_at < len(forest) - 1, found_at
    # The person is one track, seen by many updates; its file carries the sightings.
    person = [t for t in live.tracks if math.hypot(t.detection.local[0], t.detection.local[1]) < 0.5]
    assert len(person) == 1 and person[0].sightings >= 5, person
    assert live.updates == len(forest) and len(live.window) == window
    assert "LiveIntegrator(window=30/30" in repr(live)


def test_python_add_remove_and_bad_input(forest: aos.LightField) -> None:
    live = aos.LiveIntegrator(forest, aos.IntegralOptions(focal_surface=0.0),
                              aos.DetectOptions(), aos.LiveOptions(window_frames=3, detect=False))
    v = forest.views[0]
    live.add(v.image, v.camera, v.cam_from_world, "a")
    live.add(forest.views[1].image, v.camera, forest.views[1].cam_from_world, "b")
    assert live.remove("a") and not live.remove("a")
    assert [w.name for w in live.window.views] == ["b"]
    with pytest.raises(ValueError, match="name: already in the window"):
        live.add(v.image, v.camera, v.cam_from_world, "b")
    with pytest.raises(ValueError, match="window_frames"):
        aos.LiveOptions(window_frames=0).check()
    with pytest.raises(ValueError, match="view_indices"):
        aos.LiveIntegrator(forest, aos.IntegralOptions(view_indices=[0]))


def run_live(*args: str, timeout: float = 120) -> subprocess.Popen[str]:
    return subprocess.Popen(["aos-render", "live", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def test_cli_replay_writes_complete_tracks(forest: aos.LightField, tmp_path: Path) -> None:
    path = tmp_path / "lf.json"
    aos.write_lightfield(str(path), forest)
    out = subprocess.run(["aos-render", "live", "--replay", str(path), "--focal-height", "0",
                          "--geojson", str(tmp_path / "tracks.geojson"), "--csv",
                          str(tmp_path / "tracks.csv"), "--image", str(tmp_path / "live.png"),
                          "--json"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-800:]
    report = json.loads(out.stdout)
    assert report["frames"] == len(forest) and report["skipped"] == 0
    tracks = json.loads((tmp_path / "tracks.geojson").read_text())["features"]
    person = [f for f in tracks
              if math.hypot(f["properties"]["local"][0], f["properties"]["local"][1]) < 0.5]
    assert len(person) == 1 and person[0]["properties"]["sightings"] >= 5
    lon, lat = person[0]["geometry"]["coordinates"]
    assert 14.99 < lon < 15.01 and 47.8 < lat < 47.9
    assert (tmp_path / "live.png").stat().st_size > 0
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "lf.json", "live.png", "tracks.csv", "tracks.geojson", "views"]


def test_cli_folder_takes_complete_frames_and_skips_a_corrupt_one(tmp_path: Path) -> None:
    """Frames arrive by rename, one is written in two halves 50 ms apart (never read half), one
    is corrupt (skipped with one warning, the run goes on)."""
    frames = tmp_path / "frames"
    frames.mkdir()
    names = [f"f{i:02d}.png" for i in range(8)]
    rows = [f"{name},{48.0 + 2e-5 * i:.10f},15.0,30.0,0,-90,0\n" for i, name in enumerate(names)]
    (tmp_path / "log.csv").write_text("frame,lat,lon,alt,yaw,pitch,roll\n" + "".join(rows))
    rng = np.random.default_rng(3)
    encoded = {}
    for name in names:
        aos.write_image(str(tmp_path / name), rng.integers(0, 255, (48, 64), dtype=np.uint8))
        encoded[name] = (tmp_path / name).read_bytes()
    process = run_live(str(frames), "--telemetry-file", str(tmp_path / "log.csv"),
                       "--frames-fov-deg", "50", "--focal-height", "0", "--detect=false",
                       "--window-frames", "4", "--image", str(tmp_path / "live.png"),
                       "--geojson", str(tmp_path / "tracks.geojson"), "--idle-exit-s", "3",
                       "--json")
    try:
        for i, name in enumerate(names):
            data = encoded[name]
            if i == 3:  # written in place in two halves
                with open(frames / name, "wb") as f:
                    f.write(data[: len(data) // 2])
                    f.flush()
                    time.sleep(0.05)
                    f.write(data[len(data) // 2:])
            elif i == 5:  # corrupt: a PNG signature and garbage
                (frames / name).write_bytes(data[:16] + b"\0" * 200)
            else:
                (frames / f".{name}.part").write_bytes(data)
                (frames / f".{name}.part").rename(frames / name)
            time.sleep(0.3)
        stdout, stderr = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 0, stderr[-800:]
    report = json.loads(stdout)
    assert report["frames"] == 7 and report["skipped"] == 1, (report, stderr[-800:])
    warnings = [line for line in stderr.splitlines() if "skipped" in line]
    assert len(warnings) == 1 and "f05.png" in warnings[0], stderr[-800:]
    assert "f03.png" not in stderr
    image = aos.read_image(str(tmp_path / "live.png"))
    assert image.shape[:2] == (48, 64)


def test_cli_view_serves_the_live_page_and_stops_with_it(forest: aos.LightField,
                                                         tmp_path: Path) -> None:
    """`live --view`: the page's server (a child process) serves the updates on 127.0.0.1 with
    its token; after the replay it keeps the last update until SIGINT, then both end (exit 0:
    the run was complete) and the state folder is gone."""
    import signal
    import urllib.request

    path = tmp_path / "lf.json"
    aos.write_lightfield(str(path), forest)
    # Its temporary folders in a folder of this test's ($TMPDIR): another run's live page on
    # the same machine cannot make them look left behind.
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    process = subprocess.Popen(
        ["aos-render", "live", "--replay", str(path), "--focal-height", "0", "--geojson",
         str(tmp_path / "tracks.geojson"), "--view", "--no-browser", "--fps", "40"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env=dict(os.environ, TMPDIR=str(temporary)))
    import queue

    lines: "queue.Queue[str]" = queue.Queue()
    threading.Thread(target=lambda: [lines.put(line) for line in process.stderr],
                     daemon=True).start()
    try:
        url = ""
        deadline = time.monotonic() + 60
        while not url:  # the page's URL comes on stderr (stdout is the --json report's)
            line = lines.get(timeout=max(0.1, deadline - time.monotonic())).strip()
            url = line if line.startswith("http://") else ""
        assert url.startswith("http://127.0.0.1:") and "token=" in url, url
        base, token = url.split("?token=")
        state = json.loads(urllib.request.urlopen(f"{base}api/live?after=0&token={token}",
                                                  timeout=20).read())
        assert state["update"] >= 1 and state["width"] == 128
        png = urllib.request.urlopen(f"{base}api/live/image?token={token}", timeout=20).read()
        assert png[:4] == b"\x89PNG"
        try:
            urllib.request.urlopen(f"{base}api/live?after=0", timeout=20)
            raise AssertionError("served without its token")
        except urllib.error.HTTPError as error:
            assert error.code == 403
        deadline = time.monotonic() + 60
        while json.loads(urllib.request.urlopen(
                f"{base}api/live?after=0&token={token}", timeout=20).read())["update"] < len(forest):
            assert time.monotonic() < deadline
            time.sleep(0.2)
        time.sleep(0.5)
        assert process.poll() is None  # the page stays up after the run
        process.send_signal(signal.SIGINT)
        process.wait(timeout=10)
    finally:
        if process.poll() is None:
            process.kill()
    time.sleep(0.2)
    stderr = "".join(iter(lambda: lines.get_nowait() if not lines.empty() else "", ""))
    assert process.returncode == 0, stderr[-800:]
    assert "the run ended" in stderr or "aos live page: stopped" in stderr, stderr[-800:]
    assert not list(temporary.iterdir())  # the state folder went
    features = json.loads((tmp_path / "tracks.geojson").read_text())["features"]
    assert features


def test_cli_folder_resume_carries_the_tracks_and_passes_over_the_backlog(tmp_path: Path) -> None:
    """A restart with --resume: the tracks of the earlier run's GeoJSON are kept (rewritten with
    the new run's), and of the frames already in the folder only the newest window is
    integrated."""
    frames = tmp_path / "frames"
    frames.mkdir()
    names = [f"f{i:02d}.png" for i in range(7)]
    rows = [f"{name},{48.0 + 2e-5 * i:.10f},15.0,30.0,0,-90,0\n" for i, name in enumerate(names)]
    (tmp_path / "log.csv").write_text("frame,lat,lon,alt,yaw,pitch,roll\n" + "".join(rows))
    rng = np.random.default_rng(4)
    for name in names:
        aos.write_image(str(frames / name), rng.integers(0, 255, (48, 64), dtype=np.uint8))
    earlier = {"type": "FeatureCollection", "features": [{
        "type": "Feature", "id": 1, "geometry": {"type": "Point", "coordinates": [15.0, 48.0]},
        "properties": {"pixel_x": 10.0, "pixel_y": 12.0, "area_px": 9, "peak_score": 1234.5,
                       "mean_score": 300.0, "world": [500000.0, 5316666.0, 0.0],
                       "local": [1.0, 2.0, 0.0], "crs": "EPSG:32633", "views": [],
                       "sightings": 7, "first_seen": "a.png", "last_seen": "b.png"}}]}
    tracks = tmp_path / "tracks.geojson"
    tracks.write_text(json.dumps(earlier))
    refused = subprocess.run(["aos-render", "live", str(frames), "--telemetry-file",
                              str(tmp_path / "log.csv"), "--frames-fov-deg", "50",
                              "--geojson", str(tracks), "--idle-exit-s", "1"],
                             capture_output=True, text=True, timeout=60)
    assert refused.returncode != 0 and "exists" in refused.stderr  # no --resume: not replaced
    out = subprocess.run(["aos-render", "live", str(frames), "--telemetry-file",
                          str(tmp_path / "log.csv"), "--frames-fov-deg", "50", "--focal-height",
                          "0", "--window-frames", "3", "--geojson", str(tracks), "--resume",
                          "--idle-exit-s", "1.5", "--json"],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr[-800:]
    report = json.loads(out.stdout)
    assert report["passed_over"] == 4 and report["frames"] == 3, report
    features = json.loads(tracks.read_text())["features"]
    carried = [f for f in features if f["properties"].get("first_seen") == "a.png"]
    assert len(carried) == 1 and carried[0]["properties"]["sightings"] == 7
    assert carried[0]["properties"]["peak_score"] == 1234.5


def test_cli_folder_finds_the_person_before_the_flight_ends(forest: aos.LightField,
                                                            tmp_path: Path) -> None:
    """The simulated flight's frames arrive one by one in a folder, posed by a telemetry log
    whose rows come a little after their frames (the log lags): every frame lands where it was
    taken (the live page's flight path against the truth, 1 cm), and the hidden person is a track
    at its true position before the last frame. The flight is centred on UTM 500050 E,
    5300050 N: its frames straddle the 100 m lines each frame's own import rounds its origin to,
    so frames posed in different local frames must be moved into the flight's exactly."""
    import copy
    import queue
    import signal
    import urllib.request

    from rasterio.warp import transform

    forest = copy.copy(forest)
    forest.origin = (500050.0, 5300050.0, 300.0)  # the log's heights: 300 m + local
    frames = tmp_path / "frames"
    frames.mkdir()
    log = tmp_path / "log.csv"
    log.write_text("frame,lat,lon,alt,yaw,pitch,roll\n")
    process = run_live(str(frames), "--telemetry-file", str(log), "--frames-fov-deg",
                       f"{forest.views[0].camera.pinhole().fov_x_deg():.10f}", "--focal-height",
                       "300", "--geojson", str(tmp_path / "tracks.geojson"), "--idle-exit-s", "2",
                       "--view", "--no-browser", "--json")
    lines: "queue.Queue[str]" = queue.Queue()
    threading.Thread(target=lambda: [lines.put(line) for line in process.stderr],
                     daemon=True).start()
    names = []
    try:
        url = ""
        deadline = time.monotonic() + 60
        while not url:
            line = lines.get(timeout=max(0.1, deadline - time.monotonic())).strip()
            url = line if line.startswith("http://") else ""
        base, token = url.split("?token=")
        for i, view in enumerate(forest.views):
            centre = np.array(view.cam_from_world.center) + np.array(forest.origin)
            (lon,), (lat,) = transform("EPSG:32633", "EPSG:4326", [centre[0]], [centre[1]])
            name = f"frame_{i:03d}.png"
            aos.write_image(str(tmp_path / name), view.image)
            (tmp_path / name).rename(frames / name)
            names.append(name)
            time.sleep(0.05)
            with open(log, "a") as f:  # the row after its frame
                f.write(f"{name},{lat:.10f},{lon:.10f},{centre[2]:.4f},0,-90,0\n")
            time.sleep(0.05)
        deadline = time.monotonic() + 60
        while True:
            state = json.loads(urllib.request.urlopen(f"{base}api/live?after=0&token={token}",
                                                      timeout=20).read())
            if state["update"] >= len(forest) or time.monotonic() > deadline:
                break
            time.sleep(0.2)
        time.sleep(3.5)  # --idle-exit-s 2 after the last frame: the run is over, the page stays
        process.send_signal(signal.SIGINT)  # the page, kept up after the run, stops: exit 0
        stdout, _ = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 0
    report = json.loads(stdout)
    assert report["frames"] == len(forest) and report["skipped"] == 0, report
    # Every frame where it was taken: the page's path (local to the run's origin) against the
    # simulated poses (local to the flight's).
    truth = [np.array(v.cam_from_world.center) + np.array(forest.origin) for v in forest.views]
    placed = [np.array(p + [0.0])[:2] + np.array(state["origin"][:2]) for p in state["path"]]
    assert len(placed) == len(truth)
    assert max(np.hypot(*(p - t[:2])) for p, t in zip(placed, truth)) < 0.01
    features = json.loads((tmp_path / "tracks.geojson").read_text())["features"]
    person = [f for f in features
              if math.hypot(f["properties"]["world"][0] - 500050.0,
                            f["properties"]["world"][1] - 5300050.0) < 0.5]
    assert person, [f["properties"]["world"] for f in features]
    assert names.index(person[0]["properties"]["first_seen"]) < len(names) - 1


def test_cli_folder_needs_its_telemetry_named(tmp_path: Path) -> None:
    """A watched folder's poses come from --telemetry-file or --exif: neither (or both) is a
    usage error naming them, before anything is written."""
    (tmp_path / "frames").mkdir()
    for extra in ([], ["--exif", "--telemetry-file", str(tmp_path / "log.csv")]):
        (tmp_path / "log.csv").write_text("frame,lat,lon,alt,yaw,pitch,roll\n")
        out = subprocess.run(["aos-render", "live", str(tmp_path / "frames"), "--frames-fov-deg",
                              "50", "--geojson", str(tmp_path / "t.geojson"), *extra],
                             capture_output=True, text=True, timeout=60)
        assert out.returncode == 2 and "--telemetry-file" in out.stderr and "--exif" in out.stderr
        assert not (tmp_path / "t.geojson").exists()


def test_follow_map_is_the_batch_map_of_the_window_and_finds_the_person(
        forest: aos.LightField, tmp_path: Path) -> None:
    """follow 'map': each update is the orthographic map of a fixed area, equal to the batch
    map of the window's views; the person is a track at its place. The CLI takes --extent."""
    extent = [499990.0, 5299990.0, 500010.0, 5300010.0]
    map_options = aos.MapOptions(extent=extent, pixel_size=0.2, focal_surface=0.0)
    live = aos.LiveIntegrator(forest, map_options=map_options,
                              live_options=aos.LiveOptions(window_frames=20, follow="map"))
    assert "LiveIntegrator(window=0/20" in repr(live)
    for i, view in enumerate(forest.views):
        live.add_view(view)
        if i % 20 == 19:
            first = max(0, i - 19)
            batch = aos.render_map(forest, extent=extent, pixel_size=0.2, focal_surface=0.0,
                                   view_indices=list(range(first, i + 1)))
            np.testing.assert_array_equal(live.image, batch.image)
    assert live.image.shape[:2] == (100, 100)
    person = [t for t in live.tracks
              if math.hypot(t.detection.world[0] - 500000.0, t.detection.world[1] - 5300000.0) < 0.3]
    assert person and person[0].sightings >= 5, live.tracks[:3]
    with pytest.raises(ValueError, match="extent"):
        aos.LiveIntegrator(forest, map_options=aos.MapOptions(pixel_size=0.2),
                           live_options=aos.LiveOptions(follow="map"))
    path = tmp_path / "lf.json"
    aos.write_lightfield(str(path), forest)
    out = subprocess.run(["aos-render", "live", "--replay", str(path), "--follow", "map",
                          "--extent", *(str(v) for v in extent), "--pixel-size", "0.2",
                          "--focal-height", "0", "--geojson", str(tmp_path / "t.geojson"),
                          "--json"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-800:]
    features = json.loads((tmp_path / "t.geojson").read_text())["features"]
    assert any(math.hypot(f["properties"]["world"][0] - 500000.0,
                          f["properties"]["world"][1] - 5300000.0) < 0.3 for f in features)


def test_cli_folder_poses_frames_by_time_from_a_lagging_log(tmp_path: Path) -> None:
    """A log with a time column only (no frame names), its rows at another rate than the frames
    and written after them: frame i is at --time-offset-s + i * --frame-interval-s (as `poses`
    reads such a log) and lands where the log, interpolated between the rows around that time,
    puts it (the live page's path against the analytic flight, 1 cm); a frame before the log's
    first row is skipped with one warning, and the run goes on."""
    import queue
    import signal
    import urllib.request

    from rasterio.warp import transform

    frames = tmp_path / "frames"
    frames.mkdir()
    log = tmp_path / "log.csv"
    log.write_text("time,lat,lon,alt,yaw,pitch,roll\n")
    offset, interval, count = 100.0, 0.5, 10

    def at(t: float) -> tuple[float, float, float]:  # a straight line, 4 m/s north-east
        return 48.0 + 2.5e-5 * (t - offset), 15.0 + 3e-5 * (t - offset), 60.0 + 0.2 * (t - offset)

    # Rows every 0.35 s from 0.2 s after the first frame: frame 0 precedes them.
    row_times = [offset + 0.2 + 0.35 * k for k in range(int((count * interval + 1) / 0.35))]
    process = run_live(str(frames), "--telemetry-file", str(log), "--frame-interval-s",
                       str(interval), "--time-offset-s", str(offset), "--frames-fov-deg", "50",
                       "--focal-height", "0", "--detect=false", "--window-frames", "4",
                       "--geojson", str(tmp_path / "tracks.geojson"), "--idle-exit-s", "2",
                       "--view", "--no-browser", "--json")
    lines: "queue.Queue[str]" = queue.Queue()
    threading.Thread(target=lambda: [lines.put(line) for line in process.stderr],
                     daemon=True).start()
    rng = np.random.default_rng(5)
    stderr: list[str] = []
    try:
        url = ""
        deadline = time.monotonic() + 60
        while not url:
            line = lines.get(timeout=max(0.1, deadline - time.monotonic()))
            stderr.append(line)
            url = line.strip() if line.strip().startswith("http://") else ""
        base, token = url.split("?token=")
        written = 0
        for i in range(count):
            name = f"t{i:02d}.png"
            aos.write_image(str(tmp_path / name), rng.integers(0, 255, (48, 64), dtype=np.uint8))
            (tmp_path / name).rename(frames / name)
            time.sleep(0.1)
            # Then the rows up to just past this frame's time: the one after it comes with
            # the frame after (the log lags).
            t_frame = offset + i * interval
            with open(log, "a") as f:
                while written < len(row_times) and row_times[written] <= t_frame + 0.1:
                    lat, lon, alt = at(row_times[written])
                    f.write(f"{row_times[written]:.3f},{lat:.10f},{lon:.10f},{alt:.4f},"
                            "0,-90,0\n")
                    written += 1
            time.sleep(0.1)
        with open(log, "a") as f:
            for t in row_times[written:]:
                lat, lon, alt = at(t)
                f.write(f"{t:.3f},{lat:.10f},{lon:.10f},{alt:.4f},0,-90,0\n")
        deadline = time.monotonic() + 60
        while True:
            state = json.loads(urllib.request.urlopen(f"{base}api/live?after=0&token={token}",
                                                      timeout=20).read())
            if state["update"] >= count - 1 or time.monotonic() > deadline:
                break
            time.sleep(0.2)
        time.sleep(3.0)  # --idle-exit-s 2 after the last frame: the run is over, the page stays
        process.send_signal(signal.SIGINT)
        stdout, _ = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
    while not lines.empty():
        stderr.append(lines.get())
    assert process.returncode == 0, "".join(stderr)[-800:]
    report = json.loads(stdout)
    assert report["frames"] == count - 1 and report["skipped"] == 1, report
    warnings = [line for line in stderr if "skipped" in line]
    assert len(warnings) == 1 and "t00.png" in warnings[0] and "precedes" in warnings[0], warnings
    truth = []
    for i in range(1, count):
        lat, lon, alt = at(offset + i * interval)
        (x,), (y,) = transform("EPSG:4326", state["crs"], [lon], [lat])
        truth.append((x, y))
    placed = [np.array(p[:2]) + np.array(state["origin"][:2]) for p in state["path"]]
    assert len(placed) == len(truth)
    errors = [float(np.hypot(*(p - np.array(t)))) for p, t in zip(placed, truth)]
    assert max(errors) < 0.01, errors
