#!/usr/bin/env python3
"""Live integration's speed and memory (issue 35's goals, checked here, never in the tests).

1. Update time on F0 replayed in flight order (382 thermal frames of 640 x 512, 512 x 512 output
   from the newest view, the plane z = +21, window 30, rx-local, GeoJSON and an 8-bit image
   written every update): `aos-render live --replay`'s own report (update = add, drop, render,
   detect, write). Goal p50 <= 50 ms, p95 <= 100 ms. The same with --detect=false beside it.
2. Latency in a watched folder: a simulated thermal flight (640 x 512 frames, a telemetry CSV)
   renamed into a folder at --fps; `aos-render live FOLDER --view`, and the live page open in
   headless Chromium. For each frame: rename -> the server's state names it (its GeoJSON and
   image were written before), and rename -> the page shows it.
3. Memory: a 2,000-frame replay (F0's frames listed over and over, each view its own name):
   the process's resident size sampled through the run; flat means bounded by the window.

Prints the CPU line first; figures are this host's. Usage:
    python3 tools/bench_live.py [--fps 5] [--frames 60] [--skip-memory]
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

import aos

ROOT = Path(__file__).resolve().parents[1]
F0 = ROOT.parent / "shared" / "data" / "jku-f0"
F0_FOV_DEG = 50.815436217896945


def cpu_line() -> str:
    return next((line.split(":", 1)[1].strip() for line in
                 Path("/proc/cpuinfo").read_text().splitlines() if line.startswith("model name")),
                platform.processor())


def percentiles(values: list[float]) -> str:
    if not values:
        return "none"
    a = np.array(values)
    return f"p50 {np.percentile(a, 50):.0f} ms, p95 {np.percentile(a, 95):.0f} ms (n = {len(a)})"


def replay_f0(folder: Path) -> None:
    for detect in ("true", "false"):
        out = subprocess.run(
            ["aos-render", "live", "--replay", str(F0 / "poses" / "poses.json"),
             "--frames-fov-deg", str(F0_FOV_DEG), "--focal-height", "21", "--width", "512",
             "--height", "512", "--fov-deg", str(F0_FOV_DEG), "--geojson",
             str(folder / f"f0-{detect}.geojson"), "--image", str(folder / f"f0-{detect}.png"),
             f"--detect={detect}", "--json", "--force"],
            capture_output=True, text=True, timeout=1200)
        if out.returncode != 0:
            raise SystemExit(out.stderr[-1000:])
        report = json.loads(out.stdout)
        print(f"F0 replay, detect={detect}: update p50 {report['update_ms_p50']:.1f} ms, "
              f"p95 {report['update_ms_p95']:.1f} ms over {report['frames']} frames; "
              f"{report['tracks']} tracks" + ("  (goal p50 <= 50, p95 <= 100)"
                                                if detect == "true" else ""))


def simulated_flight(folder: Path) -> tuple[list[Path], str]:
    """A thermal 7 x 7 flight of 640 x 512 frames over the default scene's person, written as
    PNG with a telemetry CSV (nadir, image up at north, on zone 33's central meridian)."""
    from rasterio.warp import transform

    scene = json.loads((ROOT / "scenes" / "forest_person.json").read_text())
    scene["camera"].update(width=640, height=512, fov_deg=50.0, channels=1)
    scene["sampling"]["grid"] = 7
    scene["effects"] = {"thermal": {"ground": 0.35, "targets": 0.9, "leaves": 0.5,
                                    "trunks": 0.45, "texture_contrast": 0.15},
                        "sensor_noise": {"sigma": 0.01}}
    light_field = aos.simulate(scene).light_field
    origin = np.array([500000.0, 5300000.0, 0.0])
    frames, rows = [], []
    for i, view in enumerate(light_field.views):
        centre = np.array(view.cam_from_world.center) + origin
        (lon,), (lat,) = transform("EPSG:32633", "EPSG:4326", [centre[0]], [centre[1]])
        name = f"frame_{i:04d}.png"
        path = folder / name
        aos.write_image(str(path), view.image)
        frames.append(path)
        rows.append(f"{name},{lat:.10f},{lon:.10f},{centre[2]:.4f},0,-90,0\n")
    return frames, "frame,lat,lon,alt,yaw,pitch,roll\n" + "".join(rows)


def folder_latency(folder: Path, fps: float, count: int) -> None:
    source = folder / "source"
    source.mkdir()
    frames, log = simulated_flight(source)
    frames = frames[:count]
    (folder / "log.csv").write_text(log)
    watched = folder / "watched"
    watched.mkdir()
    process = subprocess.Popen(
        ["aos-render", "live", str(watched), "--telemetry-file", str(folder / "log.csv"),
         "--frames-fov-deg", "50", "--focal-height", "0", "--width", "512", "--height", "512",
         "--geojson", str(folder / "tracks.geojson"), "--view", "--no-browser",
         "--idle-exit-s", "4"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    errors: list[str] = []  # stderr, drained as it comes (the page's URL is among its lines)
    threading.Thread(target=lambda: [errors.append(line) for line in process.stderr],
                     daemon=True).start()
    url = ""
    deadline = time.monotonic() + 60
    while not url and time.monotonic() < deadline:
        url = next((line.strip() for line in errors if line.strip().startswith("http://")), "")
        time.sleep(0.05)
    if not url:
        process.kill()
        raise SystemExit("live --view printed no URL: " + "".join(errors)[-800:])
    renamed: dict[str, float] = {}
    served: dict[str, float] = {}
    base, token = url.split("?token=")

    def follow_server() -> None:
        import urllib.request

        after = 0
        while process.poll() is None:
            try:
                body = urllib.request.urlopen(f"{base}api/live?after={after}&token={token}",
                                              timeout=15).read()
            except OSError:
                return
            if not body:
                continue
            state = json.loads(body)
            if state["update"] > after:
                served.setdefault(state["frame"], time.time())
                after = state["update"]

    shown: list[Any] = []
    driver = None
    try:
        from selenium import webdriver

        options = webdriver.ChromeOptions()
        options.binary_location = shutil.which("chromium") or "chromium"
        for argument in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage",
                         "--disable-gpu", "--window-size=1280,900"):
            options.add_argument(argument)
        driver = webdriver.Chrome(options=options, service=webdriver.ChromeService(
            executable_path=shutil.which("chromedriver")))
        driver.get(url)
    except Exception as error:  # noqa: BLE001 - the browser part is optional
        print(f"(no headless Chromium: {type(error).__name__}; the page latency is not measured)")
    follower = threading.Thread(target=follow_server, daemon=True)
    follower.start()
    time.sleep(1.0)
    for path in frames:
        temporary = watched / f".{path.name}.part"
        shutil.copyfile(path, temporary)
        temporary.rename(watched / path.name)
        renamed[path.name] = time.time()
        time.sleep(1.0 / fps)
    time.sleep(2.0)
    if driver is not None:
        shown = driver.execute_script("return window.aosLive.history;")
        driver.quit()
    time.sleep(4.5)  # --idle-exit-s: the run ends, the page stays until SIGINT
    process.send_signal(signal.SIGINT)
    process.wait(timeout=60)
    time.sleep(0.2)
    stderr = "".join(errors)
    to_server = [1000 * (served[n] - t) for n, t in renamed.items() if n in served]
    print(f"folder at {fps:g} frames/s, {len(frames)} frames of 640 x 512: rename -> state "
          f"served (GeoJSON written before): {percentiles(to_server)}")
    if shown:
        to_page = [1000 * (at / 1000.0 - renamed[frame]) for _, frame, at in shown
                   if frame in renamed]
        print(f"  rename -> shown in headless Chromium: {percentiles(to_page)}; "
              f"{len(shown)} of {len(frames)} updates shown")
    report = [line for line in stderr.splitlines() if "frames integrated" in line]
    if report:
        print("  " + report[-1].strip())


def memory(folder: Path, frames: int) -> None:
    """Resident size through a replay of `frames` views (F0's, listed again and again)."""
    lf = aos.load_lightfield(str(F0 / "poses" / "poses.json"), fov_deg=F0_FOV_DEG,
                             load_images=False).light_field
    aos.write_lightfield(str(folder / "f0.json"), lf)  # views reference F0's frames
    spec = json.loads((folder / "f0.json").read_text())
    path = folder / "long.json"
    base_views = spec["views"]
    spec["views"] = []
    for i in range(frames):
        view = dict(base_views[i % len(base_views)])
        view["name"] = f"{i:05d}-{view.get('name', '')}"
        spec["views"].append(view)
    path.write_text(json.dumps(spec))
    process = subprocess.Popen(
        ["aos-render", "live", "--replay", str(path), "--focal-height", "21", "--width", "512",
         "--height", "512", "--fov-deg", str(F0_FOV_DEG), "--geojson",
         str(folder / "long.geojson"), "--json"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    samples = []
    start = time.monotonic()
    while process.poll() is None:
        try:
            status = Path(f"/proc/{process.pid}/status").read_text()
            rss = next(int(line.split()[1]) for line in status.splitlines()
                       if line.startswith("VmRSS:"))
            samples.append((time.monotonic() - start, rss / 1024.0))
        except (OSError, StopIteration):
            pass
        time.sleep(0.5)
    stdout, stderr = process.communicate()
    if process.returncode != 0:
        print("memory: the replay failed: " + stderr[-600:])
        return
    report = json.loads(stdout)
    n = len(samples)
    at = [samples[min(n - 1, int(f * n))][1] for f in (0.1, 0.25, 0.5, 0.75, 0.99)]
    print(f"memory over a {report['frames']}-frame replay ({samples[-1][0]:.0f} s): resident "
          + ", ".join(f"{v:.0f} MB" for v in at) + " at 10/25/50/75/99 % of the run; peak "
          f"{max(s[1] for s in samples):.0f} MB")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--fps", type=float, default=5.0)
    parser.add_argument("--frames", type=int, default=49)
    parser.add_argument("--memory-frames", type=int, default=2000)
    parser.add_argument("--skip-memory", action="store_true")
    args = parser.parse_args()
    print(f"CPU: {cpu_line()}")
    with tempfile.TemporaryDirectory(prefix="aos-bench-live-") as temporary:
        folder = Path(temporary)
        if (F0 / "poses" / "poses.json").exists():
            replay_f0(folder)
        else:
            print(f"F0 not found at {F0}: its replay skipped")
        folder_latency(folder, args.fps, args.frames)
        if not args.skip_memory and (F0 / "poses" / "poses.json").exists():
            memory(folder, args.memory_frames)
    return 0


if __name__ == "__main__":
    sys.exit(main())
