#!/usr/bin/env python3
"""Benchmark of distributed maps (aos.distributed, docs/distributed.md): a simulated survey is
generated once into a folder by the simulator (frames as PNG files, read from disk like real
data), then mapped on LocalClusters of 1, 2, ... worker processes (one thread each). Reports per
run: seconds, frames/s (frames of the survey / seconds), map megapixels/s, frame reads (cache
misses summed over the tasks) and the peak resident memory of each worker process (the
getrusage high-water mark of a fresh cluster), the tasks' summed time reading frames and
rendering, the CPU seconds of the client process (client, scheduler, nannies, writer) and of
each worker, and the speed-up against the first worker count's run of the same round (--repeats
rounds, interleaved) beside the most that run's CPU seconds allow on this machine's cores (base
seconds / (CPU seconds / cores): no schedule of the same work on C cores is faster).

    python3 tools/bench_distributed.py --frames 2000 --frame-width 1200 --area-ha 5 \\
        --pixel-size 0.05 --workers 1,2 --folder /tmp/survey-2000
    python3 tools/bench_distributed.py --frames 100 --frame-width 256 --area-ha 0.25 \\
        --pixel-size 0.05 --workers 1,2            # a quick run

The survey: a square grid of ceil(sqrt(frames)) x ceil(sqrt(frames)) nadir views over a square
of area-ha hectares, 4:3 frames of frame-width pixels with a 60 degree horizontal field of view,
flown at the altitude where a frame's footprint is `overlap` grid spacings wide (each ground
point then lies in about overlap^2 frames), over a noise-textured ground. A folder already
holding the same survey (same scene.json) is reused.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path

import aos
from aos import distributed
from host import cpu_line


def scene_for(args: argparse.Namespace) -> dict:
    grid = math.ceil(math.sqrt(args.frames))
    side = math.sqrt(args.area_ha * 10000.0)
    spacing = side / max(grid - 1, 1)
    footprint = args.overlap * spacing
    altitude = footprint / (2.0 * math.tan(math.radians(30.0)))
    height = args.frame_width * 3 // 4
    return {
        "ground": {"texture": {"type": "noise", "square": 0.5, "seed": 7}},
        "camera": {"width": args.frame_width, "height": height, "fov_deg": 60},
        "sampling": {"altitude": altitude, "grid": grid,
                     "aperture": {"shape": "square", "diameter": side}},
        "truth": {"width": 8, "height": 8, "blocked_fraction": False},
    }


def survey(args: argparse.Namespace) -> Path:
    folder = Path(args.folder) if args.folder else Path(tempfile.gettempdir()) / (
        f"aos-survey-{args.frames}-{args.frame_width}-{args.area_ha:g}ha")
    scene = scene_for(args)
    stamp = folder / "bench_scene.json"
    if stamp.exists() and json.loads(stamp.read_text()) == scene and \
            (folder / "lightfield.json").exists():
        print(f"survey: reusing {folder}", file=sys.stderr)
        return folder / "lightfield.json"
    if folder.exists() and any(folder.iterdir()):
        sys.exit(f"{folder}: exists and holds another survey; remove it or give --folder")
    started = time.perf_counter()
    aos.simulate(scene, folder)
    stamp.write_text(json.dumps(scene))
    print(f"survey: simulated {scene['sampling']['grid'] ** 2} frames into {folder} in "
          f"{time.perf_counter() - started:.0f} s", file=sys.stderr)
    return folder / "lightfield.json"


def peak_rss_bytes() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # Linux: KiB


def cpu_seconds() -> float:
    """CPU time (user + system) this process has used so far, all its threads."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=100, help="views (rounded up to a square)")
    parser.add_argument("--frame-width", type=int, default=256, help="pixels; height = 3/4")
    parser.add_argument("--area-ha", type=float, default=0.25, help="flown square, hectares")
    parser.add_argument("--overlap", type=float, default=3.0,
                        help="a frame's footprint in grid spacings")
    parser.add_argument("--pixel-size", type=float, default=0.05, help="map pixel, metres")
    parser.add_argument("--tile-size", type=int, default=512, help="map tile, pixels")
    parser.add_argument("--workers", default="1,2", help="worker counts to run, e.g. 1,2")
    parser.add_argument("--cache-mb", type=float,
                        default=aos.DistributedOptions().cache_mb,
                        help="frame cache per worker, MiB")
    parser.add_argument("--repeats", type=int, default=1,
                        help="rounds of every worker count, interleaved (0: only make the "
                        "survey)")
    parser.add_argument("--folder", default="", help="where the survey is (generated once)")
    parser.add_argument("--json", default="", help="also write the results here")
    args = parser.parse_args()

    path = survey(args)
    if args.repeats == 0:  # --repeats 0: only make (or check) the survey
        return 0
    poses = aos.load_lightfield(path, load_images=False).light_field
    frame = poses.views[0]
    probe = aos.load_lightfield(path, load_images=False).light_field
    aos._core._load_view_images(probe, [0], num_threads=1)
    frame_bytes = probe.image_bytes()  # one decoded frame (grey or colour, its bit depth)
    del probe
    options = aos.MapOptions(pixel_size=args.pixel_size, tile_size=args.tile_size)
    grid = aos._core._map_grid(poses, options)
    megapixels = grid["width"] * grid["height"] / 1e6
    print(f"survey: {len(poses)} frames of {frame.camera.width} x {frame.camera.height} "
          f"({len(poses) * frame_bytes / 2**30:.2f} GiB decoded); map {grid['width']} x "
          f"{grid['height']} pixels of {args.pixel_size} m ({megapixels:.1f} MP, "
          f"{grid['width'] * grid['height'] * args.pixel_size**2 / 1e4:.2f} ha)", file=sys.stderr)
    runs = []
    counts = [int(w) for w in args.workers.split(",")]
    with tempfile.TemporaryDirectory() as scratch:
        # Rounds of every worker count, interleaved (1, 2, 1, 2, ...): the machine's load
        # drifts, and hits both alike.
        for round_index in range(args.repeats):
            for workers in counts:
                with distributed.local_client(workers) as client:
                    # CPU of the workers and of this process (the client, the scheduler, the
                    # nannies and the writer) over the run: on a machine of C cores no run can
                    # take less than their sum / C.
                    workers_cpu = client.run(cpu_seconds)
                    client_cpu = cpu_seconds()
                    started = time.perf_counter()
                    result = distributed.render_map(
                        poses, options, path=Path(scratch) / f"map-{len(runs)}.tif",
                        client=client, cache_mb=args.cache_mb)
                    seconds = time.perf_counter() - started
                    client_cpu = cpu_seconds() - client_cpu
                    workers_cpu = [after - workers_cpu[address] for address, after in
                                   client.run(cpu_seconds).items()]
                    peaks = sorted(client.run(peak_rss_bytes).values())
                    client.cluster.close()
                run = {"round": round_index, "workers": workers, "seconds": round(seconds, 2),
                       "seconds_cog_write": round(result.seconds_write, 2),
                       "task_seconds_decode": round(result.seconds_decode, 2),
                       "task_seconds_render": round(result.seconds_render, 2),
                       "frames_per_s": round(len(poses) / seconds, 2),
                       "map_mp_per_s": round(megapixels / seconds, 3),
                       "cpu_s_client": round(client_cpu, 2),
                       "cpu_s_workers": sorted(round(c, 2) for c in workers_cpu),
                       "tiles": result.tiles, "frame_reads": result.frames_read,
                       "frames_shared": result.frames_shared,
                       "peak_worker_rss_mib": [round(p / 2**20) for p in peaks]}
                runs.append(run)
                print(json.dumps(run), file=sys.stderr)
    # Speed-up of each run against the first worker count's run of the same round.
    cores = len(os.sched_getaffinity(0))
    for run in runs:
        base = next(r for r in runs if r["round"] == run["round"] and r["workers"] == counts[0])
        run["speedup"] = round(base["seconds"] / run["seconds"], 2)
        # The most this run could have been sped up against the base on this machine's cores
        # with the CPU work it did: base seconds / (all its CPU seconds / cores).
        cpu = run["cpu_s_client"] + sum(run["cpu_s_workers"])
        run["cpu_bound_speedup"] = round(base["seconds"] / (cpu / cores), 2)
    summary = {}
    for workers in counts:
        mine = [r for r in runs if r["workers"] == workers]
        summary[workers] = {
            "median_seconds": statistics.median(r["seconds"] for r in mine),
            "median_speedup": statistics.median(r["speedup"] for r in mine),
            "peak_worker_rss_mib": max(max(r["peak_worker_rss_mib"]) for r in mine)}
        print(f"{workers} worker(s): median {summary[workers]['median_seconds']:.1f} s, "
              f"speed-up {summary[workers]['median_speedup']:.2f}x (rounds: "
              f"{', '.join(str(r['speedup']) for r in mine)}; at most "
              f"{', '.join(str(r['cpu_bound_speedup']) for r in mine)} with their CPU seconds "
              f"on {cores} cores), peak worker memory "
              f"{summary[workers]['peak_worker_rss_mib']} MiB", file=sys.stderr)
    report = {"frames": len(poses), "frame_size": [frame.camera.width, frame.camera.height],
              "map_size": [grid["width"], grid["height"]], "map_mp": round(megapixels, 2),
              "pixel_size": args.pixel_size, "tile_size": args.tile_size,
              "cache_mb": args.cache_mb, "frame_mib": round(frame_bytes / 2**20, 3),
              "runs": runs, "summary": summary}
    report["load_average"] = os.getloadavg()
    report["cpu"] = cpu_line()
    print(json.dumps(report, indent=1))
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
