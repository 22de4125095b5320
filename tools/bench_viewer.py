#!/usr/bin/env python3
"""Benchmarks of the browser viewer (`aos-render view`, aos.view); docs/viewer.md has the figures.

    python3 tools/bench_viewer.py                 # render times + a drag in headless Chromium (F0)
    python3 tools/bench_viewer.py --load          # also 20 concurrent clients for 60 s
    python3 tools/bench_viewer.py --json out.json

1. Server render time of one full frame: F0 (382 views, 512 x 512, view 191's pose, focal
   plane z = 21) rendered `--renders` times through the viewer's Session (the C++ renderer, GIL
   released), p50/p95 of the render itself and of render + display mapping (RGBA).
2. A slider drag on the real page in headless Chromium (Debian chromium + chromium-driver,
   selenium): the focus slider is moved by input events at 60 Hz for `--drag-seconds` (a
   cosine sweep over +-`--sweep` metres about z = 21), as a pointer drag fires them; the page
   records performance.now() at each input event and when the image it caused is drawn on the
   canvas (window.aosStats). Reported: displayed updates per second during the drag (each the
   full-size image of every k-th view, k chosen by the server for its 20 ms share of a 33 ms frame), the
   views they used, the input-to-display latency p50/p95 of those updates, and the time from
   the last input to the image of every view; then the PSNR of such drag frames (the median k)
   against the image of every view, at 9 focal heights over the sweep.
3. With --load: `--clients` WebSocket clients (default 20) each render in a loop (send, wait for
   the frame; every 5th also a one-shot HTTP render) for `--load-seconds` (default 60) on F0 at
   preview and full size, after `--warmup-seconds` (default 5) of the same: errors, malformed
   responses, frames, and the server's RSS growth, which must stay under an eighth of the RGBA
   bytes sent (LEAK_FRACTION): a leak of one frame per update (1 MiB per full 512 x 512 frame,
   256 or 64 KiB per preview; about 400 MiB over a 60 s run) fails the run (exit 1).

Needs the F0 data (../shared/data/jku-f0, read in place; skipped with a message when absent)
and, for 2, selenium with chromium-driver. Machine load matters: the report prints the load
average; run it on a quiet machine for numbers to quote.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import os
import shutil
import statistics
import struct
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT.parent / "shared" / "data" / "jku-f0"
F0_FOV_DEG = 50.815436217896945
F0_POSE_VIEW = 191
F0_GROUND = 21.0
# The load run fails when RSS grows by more than this fraction of the RGBA bytes it sent: the
# bound a leak of one frame per update (or of the float image, the same size for 8-bit grey
# F0) would break by 8x. It is only meaningful when that fraction is well above the
# allocator's noise (a few tens of MiB), hence LEAK_MIN_BYTES.
LEAK_FRACTION = 1.0 / 8.0
LEAK_MIN_BYTES = 32 << 20


def percentile(values: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(values, dtype=float), q)) if values else float("nan")


def rss_bytes(pid: int | None = None) -> int:
    with open(f"/proc/{pid or 'self'}/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    return 0


def bench_renders(session: Any, count: int, focal_height: float = F0_GROUND) -> dict[str, Any]:
    from aos.viewer.session import Params

    render_ms, total_ms = [], []
    session.render(session.parse({}))  # warm-up
    for k in range(count):
        params = session.parse({"focal_height": focal_height + 0.01 * (k % 10)})
        start = time.perf_counter()
        frame = session.render(params)
        total_ms.append(1000.0 * (time.perf_counter() - start))
        render_ms.append(frame.info["render_ms"])
    assert isinstance(params, Params)
    return {"renders": count, "size": [frame.width, frame.height],
            "render_ms_p50": percentile(render_ms, 50), "render_ms_p95": percentile(render_ms, 95),
            "render_and_display_ms_p50": percentile(total_ms, 50),
            "render_and_display_ms_p95": percentile(total_ms, 95)}


def drag_psnr(session: Any, views: int, heights: list[float]) -> dict[str, Any]:
    """PSNR (peak 255, covered pixels of the exact image) of drag frames (a preview of `views`
    views, full size) against the exact image of every view, at `heights`."""
    saved = session.preview_view_count
    values, strides = [], []
    try:
        for height in heights:
            session.preview_view_count = views
            params = session.parse({"focal_height": height, "preview": True})
            subset, stride = session.preview_views(params)
            preview = session.render_raw(params, None, subset)
            exact = session.render_raw(session.parse({"focal_height": height}))
            covered = exact.count > 0
            error = np.mean((preview.image[covered].astype(np.float64)
                             - exact.image[covered].astype(np.float64)) ** 2)
            values.append(10.0 * math.log10(255.0 ** 2 / error) if error > 0 else math.inf)
            strides.append(stride)
    finally:
        session.preview_view_count = saved
    return {"views": views, "stride": max(strides), "psnr_db_min": min(values),
            "psnr_db_p50": percentile(values, 50)}


def bench_drag(viewer: Any, seconds: float, sweep: float) -> dict[str, Any]:
    from selenium import webdriver

    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    driver_path = shutil.which("chromedriver")
    if chromium is None or driver_path is None:
        return {"skipped": "chromium or chromedriver missing"}
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for argument in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage",
                     "--disable-gpu", "--window-size=1280,1000"):
        options.add_argument(argument)
    driver = webdriver.Chrome(options=options,
                              service=webdriver.ChromeService(executable_path=driver_path))
    try:
        driver.get(viewer.url)
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not driver.execute_script(
                "const s = window.aosStats; return s && s.lastFrame && !s.lastFrame.preview;"):
            time.sleep(0.1)
        driver.execute_script("""
            const seconds = arguments[0], sweep = arguments[1];
            const slider = document.getElementById('focal_height');
            const centre = Number(slider.value);
            const drag = window.aosDrag = {done: false, inputs: 0, t0: performance.now()};
            const timer = setInterval(() => {
              const t = (performance.now() - drag.t0) / 1000;
              if (t > seconds) {
                clearInterval(timer);
                drag.t1 = performance.now();
                slider.dispatchEvent(new Event('change', {bubbles: true}));
                drag.done = true;
                return;
              }
              slider.value = centre + sweep * Math.sin(2 * Math.PI * t / 4);
              slider.dispatchEvent(new Event('input', {bubbles: true}));
              drag.inputs += 1;
            }, 1000 / 60);""", seconds, sweep)
        while not driver.execute_script("return window.aosDrag.done;"):
            time.sleep(0.2)
        time.sleep(2.0)  # the final full frame
        drag = driver.execute_script("return window.aosDrag;")
        frames = driver.execute_script("return window.aosStats.frames;")
        during = [f for f in frames if drag["t0"] <= f["t"] <= drag["t1"] and f["preview"]]
        latencies = [f["latency_ms"] for f in during if f["latency_ms"] is not None]
        span_s = (drag["t1"] - drag["t0"]) / 1000.0
        # The image of every view after the last input (the change event at t1).
        rest = [f for f in frames if f["t"] > drag["t1"] and not f["preview"]]
        views = [f["views_used"] for f in during if f.get("views_used") is not None]
        strides = [f["view_stride"] for f in during if f.get("view_stride") is not None]
        return {"drag_seconds": span_s, "input_events": drag["inputs"],
                "rest_ms": rest[0]["t"] - drag["t1"] if rest else None,
                "full_frames_during": sum(1 for f in frames if drag["t0"] <= f["t"] <= drag["t1"]
                                          and not f["preview"]),
                "latency_ms_max": max(latencies) if latencies else None,
                "views_used_p50": percentile(views, 50) if views else None,
                "views_used_min": min(views) if views else None,
                "view_stride_p50": percentile(strides, 50) if strides else None,
                "input_events_per_s": drag["inputs"] / span_s,
                "updates": len(during), "updates_per_s": len(during) / span_s,
                "preview_sizes": {f"{w}x{h}": sum(1 for f in during
                                                   if (f["width"], f["height"]) == (w, h))
                                  for w, h in {(f["width"], f["height"]) for f in during}},
                "latency_ms_p50": percentile(latencies, 50),
                "latency_ms_p95": percentile(latencies, 95),
                "preview_render_ms_p50": percentile([f["render_ms"] for f in during], 50),
                "preview_render_ms_p95": percentile([f["render_ms"] for f in during], 95),
                "errors": driver.execute_script("return window.aosStats.errors;")}
    finally:
        driver.quit()


async def load(viewer: Any, clients: int, seconds: float) -> dict[str, Any]:
    import aiohttp

    base = f"http://127.0.0.1:{viewer.port}"
    counts = {"frames": 0, "http": 0, "errors": 0, "malformed": 0, "frame_bytes": 0}
    latencies: list[float] = []
    deadline = time.monotonic() + seconds

    def check(body: bytes) -> dict[str, Any]:
        length = struct.unpack("<I", body[:4])[0]
        header = json.loads(body[4:4 + length])
        if len(body) != 4 + length + header["width"] * header["height"] * 4:
            raise ValueError("frame size")
        return header

    async def page(index: int) -> None:
        async with aiohttp.ClientSession() as client:
            async with client.ws_connect(f"{base}/ws?token={viewer.token}",
                                         max_msg_size=64 << 20) as socket:
                k = 0
                while time.monotonic() < deadline:
                    k += 1
                    preview = k % 4 != 0
                    params = {"focal_height": F0_GROUND + (index + k) % 11 - 5,
                              "preview": preview, "aperture_radius": 5 + k % 10}
                    start = time.perf_counter()
                    await socket.send_str(json.dumps({"type": "render", "id": k,
                                                      "params": params}))
                    message = await socket.receive(timeout=300)
                    if message.type != aiohttp.WSMsgType.BINARY:
                        counts["errors"] += 1
                        continue
                    latencies.append(1000.0 * (time.perf_counter() - start))
                    try:
                        header = check(message.data)
                        sizes = (512,)  # previews too: full size, fewer views
                        if header["id"] != k or header["width"] not in sizes:
                            raise ValueError(header)
                        counts["frames"] += 1
                        counts["frame_bytes"] += header["width"] * header["height"] * 4
                    except (ValueError, KeyError):
                        counts["malformed"] += 1
                    if k % 5 == 0:
                        async with client.get(f"{base}/api/render", params={
                                "token": viewer.token, "preview": "true"}) as response:
                            body = await response.read()
                            if response.status != 200:
                                counts["errors"] += 1
                            else:
                                try:
                                    header = check(body)
                                    counts["http"] += 1
                                    counts["frame_bytes"] += header["width"] * header["height"] * 4
                                except (ValueError, KeyError):
                                    counts["malformed"] += 1

    rss = [rss_bytes()]

    async def sample() -> None:
        while time.monotonic() < deadline:
            await asyncio.sleep(5.0)
            rss.append(rss_bytes())

    await asyncio.gather(sample(), *(page(index) for index in range(clients)))
    rss.append(rss_bytes())
    growth = rss[-1] - rss[0]
    bound = LEAK_FRACTION * counts["frame_bytes"]
    return {**counts, "clients": clients, "seconds": seconds,
            "rss_growth_mib": growth / 2**20, "rss_bound_mib": bound / 2**20,
            "memory_flat": growth < bound if bound >= LEAK_MIN_BYTES else None,
            "round_trip_ms_p50": percentile(latencies, 50),
            "round_trip_ms_p95": percentile(latencies, 95),
            "rss_mib_start": rss[0] / 2**20, "rss_mib_end": rss[-1] / 2**20,
            "rss_mib_max": max(rss) / 2**20, "server_stats": dict(viewer.server.stats)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--threads", type=int, default=-1, help="render threads (-1 = all)")
    parser.add_argument("--renders", type=int, default=30)
    parser.add_argument("--drag-seconds", type=float, default=10.0)
    parser.add_argument("--sweep", type=float, default=8.0, help="metres about z = 21")
    parser.add_argument("--render-heights", type=float, nargs="+", default=[F0_GROUND],
                        help="focal heights of the full-render measurement: 21 = F0's ground "
                             "(57.7 M samples), 0 = the plane in mid air of bench_integral.py's "
                             "reference render (36.0 M samples)")
    parser.add_argument("--no-browser", action="store_true", help="skip the drag benchmark")
    parser.add_argument("--load", action="store_true", help="run the load test too")
    parser.add_argument("--clients", type=int, default=20)
    parser.add_argument("--load-seconds", type=float, default=60.0)
    parser.add_argument("--warmup-seconds", type=float, default=5.0,
                        help="load before the measured run (allocator pools, caches)")
    parser.add_argument("--json", type=Path, help="also write the results here")
    args = parser.parse_args()
    poses = args.data / "poses" / "poses.json"
    if not poses.exists():
        print(f"bench_viewer: {poses} not found (the F0 data); nothing measured")
        return 0
    import aos

    report: dict[str, Any] = {"machine": {"cpus": os.cpu_count(),
                                          "load_average": list(os.getloadavg())},
                              "threads": args.threads}
    start = time.perf_counter()
    light_field = aos.load_lightfield(str(poses), fov_deg=F0_FOV_DEG,
                                      num_threads=args.threads).light_field
    report["load_s"] = time.perf_counter() - start
    viewer = aos.view(light_field, pose_view=F0_POSE_VIEW, focal_surface=F0_GROUND,
                      width=512, height=512, num_threads=args.threads, open_browser=False,
                      source=str(poses))
    try:
        for height in args.render_heights:
            key = "render" if height == F0_GROUND else f"render_z{height:g}"
            report[key] = bench_renders(viewer.session, args.renders, height)
            print(f"server render, full 512x512 (F0, 382 views, plane z = {height:g}): p50 "
                  f"{report[key]['render_ms_p50']:.1f} ms, p95 "
                  f"{report[key]['render_ms_p95']:.1f} ms (with display mapping p50 "
                  f"{report[key]['render_and_display_ms_p50']:.1f} ms)", flush=True)
        if not args.no_browser:
            report["drag"] = drag = bench_drag(viewer, args.drag_seconds, args.sweep)
            if "skipped" not in drag:
                print(f"drag in headless Chromium: {drag['updates_per_s']:.1f} updates/s "
                      f"({drag['input_events_per_s']:.0f} input events/s, previews "
                      f"{drag['preview_sizes']}, views used p50 {drag['views_used_p50']} "
                      f"(min {drag['views_used_min']}; k = {drag['view_stride_p50']:g}), "
                      f"preview render p50 {drag['preview_render_ms_p50']:.1f} ms, p95 "
                      f"{drag['preview_render_ms_p95']:.1f} ms), input-to-display p50 "
                      f"{drag['latency_ms_p50']:.0f} ms, p95 {drag['latency_ms_p95']:.0f} ms, max "
                      f"{drag['latency_ms_max']:.0f} ms ({drag['full_frames_during']} images of "
                      f"every view during the drag); "
                      + (f"the image of every view {drag['rest_ms']:.0f} ms after the last input"
                         if drag["rest_ms"] is not None else "no image of every view after it"),
                      flush=True)
                if drag["views_used_p50"]:
                    views = int(round(drag["views_used_p50"]))
                    report["drag_psnr"] = quality = drag_psnr(
                        viewer.session, views,
                        [F0_GROUND + args.sweep * k / 4 for k in range(-4, 5)])
                    print(f"drag frames ({views} views, k = {quality['stride']}) against "
                          f"the exact image: PSNR p50 {quality['psnr_db_p50']:.1f} dB, min "
                          f"{quality['psnr_db_min']:.1f} dB over 9 focal heights", flush=True)
            else:
                print(f"drag: skipped ({drag['skipped']})")
        if args.load:
            if args.warmup_seconds > 0:
                asyncio.run(load(viewer, args.clients, args.warmup_seconds))
            report["load"] = result = asyncio.run(load(viewer, args.clients, args.load_seconds))
            print(f"load: {result['clients']} clients for {result['seconds']:.0f} s: "
                  f"{result['frames']} frames + {result['http']} HTTP renders, "
                  f"{result['errors']} errors, {result['malformed']} malformed; RSS "
                  f"{result['rss_mib_start']:.0f} -> {result['rss_mib_end']:.0f} MiB (max "
                  f"{result['rss_mib_max']:.0f}); round trip p50 "
                  f"{result['round_trip_ms_p50']:.0f} ms, p95 {result['round_trip_ms_p95']:.0f} ms",
                  flush=True)
            verdict = {True: "flat", False: "GROWING (a leak?)",
                       None: "not judged: too few frames for the bound"}[result["memory_flat"]]
            print(f"memory: RSS grew {result['rss_growth_mib']:.1f} MiB, bound "
                  f"{result['rss_bound_mib']:.1f} MiB (1/{1 / LEAK_FRACTION:.0f} of the "
                  f"{result['frame_bytes'] / 2**20:.0f} MiB of frames sent): {verdict}", flush=True)
    finally:
        viewer.stop()
    report["machine"]["load_average_end"] = list(os.getloadavg())
    print(f"load average at start {report['machine']['load_average'][0]:.1f}, at end "
          f"{report['machine']['load_average_end'][0]:.1f} ({report['machine']['cpus']} CPUs)")
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))
    if "load" in report and (report["load"]["errors"] or report["load"]["malformed"]
                             or report["load"]["memory_flat"] is False):
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
