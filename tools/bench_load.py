#!/usr/bin/env python3
"""Loading a light field: decoding F0's 382 frames on one thread and on every core, against a
render of the loaded light field.

Interleaved rounds (aos on 1 thread, aos on all cores, one render), so that load from elsewhere
on a shared machine hits all alike; prints the median wall time of each and the CPU time (user +
system, all threads) of the loads: on a loaded machine the wall times swing with the load, the
CPU time far less (a load on an idle machine of C cores takes about CPU time / C).

Usage: python3 tools/bench_load.py [--poses /work/shared/data/jku-f0/poses/poses.json]
                                   [--fov-deg 50.815436217896945] [--rounds 5]
"""

from __future__ import annotations

import argparse
import math
import os
import resource
import statistics
import sys
import time
from pathlib import Path

import aos


def cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def timed(fn) -> tuple[float, float, object]:
    cpu, wall = cpu_seconds(), time.perf_counter()
    value = fn()
    return time.perf_counter() - wall, cpu_seconds() - cpu, value


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--poses", default="/work/shared/data/jku-f0/poses/poses.json")
    parser.add_argument("--fov-deg", type=float, default=50.815436217896945)
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    if not Path(args.poses).exists():
        print(f"{args.poses}: not found (the JKU F0 data set)", file=sys.stderr)
        return 1
    cores = os.cpu_count()
    samples: dict[str, list[float]] = {"aos 1 thread": [], f"aos all cores ({cores})": [],
                                       "cpu 1 thread": [], "cpu all cores": [], "render": []}
    light_field = None
    for _ in range(args.rounds):
        for threads, key, cpu_key in ((1, "aos 1 thread", "cpu 1 thread"),
                                      (-1, f"aos all cores ({cores})", "cpu all cores")):
            wall, cpu, loaded = timed(lambda: aos.load_lightfield(args.poses, fov_deg=args.fov_deg,
                                                                  num_threads=threads))
            samples[key].append(wall)
            samples[cpu_key].append(cpu)
            light_field = loaded.light_field
        wall, _, _ = timed(lambda: aos.render_integral(
            light_field, pose_view=len(light_field.views) // 2, aperture_radius=math.inf,
            focal_surface=aos.Plane.at_height(0.0)))
        samples["render"].append(wall)
    median = {key: statistics.median(values) for key, values in samples.items() if values}
    views = len(light_field.views)
    view = light_field.views[0]
    print(f"{args.poses}: {views} frames of {view.image.shape}, load average {os.getloadavg()[0]:.1f}, "
          f"{args.rounds} rounds, medians")
    for key, value in median.items():
        print(f"  {key:24s} {1000 * value:8.0f} ms" + (f"  ({1000 * value / views:.2f} ms a frame)"
                                                         if key != "render" else ""))
    all_key = f"aos all cores ({cores})"
    print(f"  parallel speed-up {median['aos 1 thread'] / median[all_key]:.2f}x on {cores} cores; "
          f"loading is {median[all_key] / median['render']:.1f}x a render")
    return 0


if __name__ == "__main__":
    sys.exit(main())
