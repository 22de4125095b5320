#!/usr/bin/env python3
"""Benchmark of the occlusion simulator (Embree 3 + OpenMP).

Prints, in one run on this machine:
  - primary rays per second (view rays / time of the views stage, median of --repeats) for
    the Appendix B voxel scene at 50 % density and for a forest of procedural trees, both with
    9 x 9 views of 512 x 512, and for the same camera over the bare ground (analytic plane, no
    Embree): the baseline whose ratio shows what tracing the occluders costs;
  - the wall time of the 27 x 27 x 512^2 voxel case (191 M primary rays), in memory;
  - memory of a 512^3 voxel grid at 90 % density: how much resident memory a fresh process
    gains while it builds and traces it (sampled every 2 ms), minus the same for density 0,
    against the 128 MiB one byte per cell would take.

Usage: python3 tools/bench_simulate.py [--repeats 3] [--skip-27]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from typing import Any

import aos

TARGET_RAYS_PER_SECOND = 10e6


def voxel_scene(grid: int, density: float = 0.5, size: int = 512, voxels: Any = 100) -> dict:
    return {
        "targets": [{"center": [0, 0], "size": [2.4, 0.8]}],
        "occluders": {"voxels": {"center": [0, 0, 6], "size": [10, 10, 10], "grid": voxels,
                                 "density": density}},
        "camera": {"width": size, "height": size, "fov_deg": 80},
        "sampling": {"altitude": 20, "aperture": {"diameter": 30}, "grid": grid},
        "truth": {"width": 64, "height": 64, "blocked_fraction": False},
    }


def forest_scene(grid: int) -> dict:
    return {
        "occluders": {"trees": {"area": [-25, -25, 25, 25], "per_hectare": 300,
                                "height": [8, 14], "leaves_per_tree": 1500}},
        "camera": {"width": 512, "height": 512, "fov_deg": 80},
        "sampling": {"altitude": 35, "aperture": {"diameter": 30}, "grid": grid},
        "truth": {"width": 64, "height": 64, "blocked_fraction": False},
    }


def ground_scene(grid: int) -> dict:
    scene = voxel_scene(grid)
    del scene["occluders"]
    return scene


def rays_per_second(scene: dict, repeats: int) -> tuple[float, dict]:
    rates, stats = [], {}
    for _ in range(repeats):
        stats = aos.simulate(scene).stats
        rates.append(stats["primary_rays"] / stats["seconds_views"])
    return statistics.median(rates), stats


MEMORY_PROBE = r"""
import json, os, sys, threading, time
import aos
density = float(sys.argv[1])
scene = {"occluders": {"voxels": {"center": [0, 0, 6], "size": [10, 10, 10], "grid": 512,
                                  "density": density}},
         "camera": {"width": 64, "height": 64, "fov_deg": 80},
         "sampling": {"altitude": 20, "aperture": {"diameter": 30}, "grid": 3},
         "truth": {"width": 64, "height": 64}}
page = os.sysconf("SC_PAGE_SIZE")
def rss():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * page
peak, done = [0], [False]
def sample():  # the GIL is released while simulating, so this thread keeps sampling
    while not done[0]:
        peak[0] = max(peak[0], rss())
        time.sleep(0.002)
before = rss()
thread = threading.Thread(target=sample)
thread.start()
stats = aos.simulate(scene).stats
done[0] = True
thread.join()
print(json.dumps({"peak": peak[0], "before": before, "voxels": stats["voxels"],
                  "occluder_bytes": stats["occluder_bytes"],
                  "seconds_geometry": stats["seconds_geometry"]}))
"""


def memory_probe(density: float) -> dict:
    output = subprocess.run([sys.executable, "-c", MEMORY_PROBE, str(density)], check=True,
                            capture_output=True, text=True).stdout
    return json.loads(output)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--skip-27", action="store_true", help="skip the 27x27 wall-time case")
    args = parser.parse_args()

    print("primary rays per second, 9x9 views of 512x512 (median of "
          f"{args.repeats}; target {TARGET_RAYS_PER_SECOND / 1e6:.0f} M rays/s):")
    base, _ = rays_per_second(ground_scene(9), args.repeats)
    print(f"  bare ground (baseline, no Embree)   {base / 1e6:6.1f} M rays/s")
    for name, scene in (("voxels, 50 % density (App. B)", voxel_scene(9)),
                        ("forest, 300 trees/ha", forest_scene(9))):
        rate, stats = rays_per_second(scene, args.repeats)
        geometry = (f"{stats['voxels']} voxels" if stats["voxels"] else
                    f"{stats['trees']} trees, {stats['leaf_quads']} leaves")
        print(f"  {name:35s} {rate / 1e6:6.1f} M rays/s  ({rate / base:.2f} x baseline, "
              f"{rate / TARGET_RAYS_PER_SECOND:.2f} x target; {geometry}, "
              f"BVH build {stats['seconds_geometry'] * 1e3:.0f} ms)")

    if not args.skip_27:
        start = time.perf_counter()
        result = aos.simulate(voxel_scene(27))
        wall = time.perf_counter() - start
        stats = result.stats
        print(f"27x27 x 512^2 voxel scene: {stats['primary_rays'] / 1e6:.0f} M primary rays, "
              f"views stage {stats['seconds_views']:.1f} s, whole simulate() {wall:.1f} s "
              f"({stats['primary_rays'] / stats['seconds_views'] / 1e6:.1f} M rays/s)")
        del result

    dense = memory_probe(0.9)
    empty = memory_probe(0.0)
    grow_dense = (dense["peak"] - dense["before"]) / 2 ** 20
    grow_empty = (empty["peak"] - empty["before"]) / 2 ** 20
    cells_mib = 512 ** 3 / 2 ** 20
    print(f"512^3 grid at 90 %: {dense['voxels']} occupied cells, occluder data "
          f"{dense['occluder_bytes'] / 2 ** 20:.1f} MiB; resident memory grows by "
          f"{grow_dense:.0f} MiB while simulating (3x3 views of 64x64), {grow_empty:.0f} MiB for "
          f"the same grid at density 0 (Embree device and threads): the grid costs "
          f"{grow_dense - grow_empty:.0f} MiB, {(grow_dense - grow_empty) / cells_mib:.2f} x the "
          f"{cells_mib:.0f} MiB of one byte per cell; generation + BVH "
          f"{dense['seconds_geometry']:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
