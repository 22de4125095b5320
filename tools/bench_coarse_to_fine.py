#!/usr/bin/env python3
"""Benchmark of coarse-to-fine all-in-focus (AllInFocusOptions.coarse_to_fine) against the full
100-slice stack, measured interleaved in one run (full, coarse-to-fine, full, ...), so load from
elsewhere hits both alike.

For improved and robust it prints, per case, the wall and CPU (process) times of the whole
aos.all_in_focus call for the full stack and for coarse_to_fine, their ratios, the fraction of
full-resolution slice pixels rendered, and:
  - on the merge study's scenes (tools/merge_study.py's study_scene: voxels and trees, with
    truth): PSNR against the truth (the occluder-free ground) and the study's banding measure,
    for both;
  - on the JKU F0 light field (no truth): PSNR of the coarse-to-fine image against the full
    stack's, and the fraction of pixels whose merged slice moved by more than one slice.

With --threads 1 the CPU times measure the work alone: on a shared machine two threads wait at
every barrier for a peer the scheduler has parked, which loads both paths by a different amount
(the load average at the start and end is printed with the tables).

Usage: python3 tools/bench_coarse_to_fine.py [--repeats 1] [--factor 4] [--size 256]
                                             [--seeds 1] [--data ../shared/data/jku-f0]
                                             [--skip-f0] [--skip-scenes] [--threads -1]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

import aos
from host import cpu_line

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tools"))
import merge_study  # noqa: E402

F0_FOV_DEG = 50.815436217896945
METHODS = ("improved", "robust")


def timed(call: Callable[[], Any]) -> tuple[Any, float, float]:
    wall, cpu = time.perf_counter(), time.process_time()
    result = call()
    return result, time.perf_counter() - wall, time.process_time() - cpu


def compare(run: Callable[[int], Any], repeats: int, factor: int) -> dict[str, Any]:
    """Interleaved runs of the full stack (0) and coarse_to_fine=factor; medians."""
    results: dict[int, Any] = {}
    walls: dict[int, list[float]] = {0: [], factor: []}
    cpus: dict[int, list[float]] = {0: [], factor: []}
    for _ in range(repeats):
        for knob in (0, factor):
            result, wall, cpu = timed(lambda: run(knob))
            results[knob] = result
            walls[knob].append(wall)
            cpus[knob].append(cpu)
    return {"full": results[0], "c2f": results[factor],
            "wall": (statistics.median(walls[0]), statistics.median(walls[factor])),
            "cpu": (statistics.median(cpus[0]), statistics.median(cpus[factor]))}


def psnr(image: np.ndarray, reference: np.ndarray) -> float:
    return aos.compare_images(image, reference, data_range=255.0).psnr_db


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--factor", type=int, default=4)
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--seeds", type=int, default=1)
    parser.add_argument("--slices", type=int, default=100)
    parser.add_argument("--data", default=str(ROOT.parent / "shared" / "data" / "jku-f0"))
    parser.add_argument("--skip-f0", action="store_true")
    parser.add_argument("--skip-scenes", action="store_true")
    parser.add_argument("--threads", type=int, default=-1,
                        help="num_threads of every all_in_focus call (-1: all cores)")
    args = parser.parse_args()
    f = args.factor
    print(f"coarse_to_fine={f} against the full {args.slices}-slice stack; times are medians of "
          f"{args.repeats} interleaved runs of the whole all_in_focus call (wall / CPU s), "
          f"num_threads {args.threads}; load average {os.getloadavg()[0]:.1f} at the start; "
          f"{cpu_line()}")
    print("| scene | method | full wall s | c2f wall s | wall ratio | full CPU s | c2f CPU s | "
          "CPU ratio | rendered | PSNR full dB | PSNR c2f dB | banding full | banding c2f |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for occluders in () if args.skip_scenes else ("voxels", "trees"):
        for seed in range(1, args.seeds + 1):
            simulation = aos.simulate(merge_study.study_scene(seed, args.size, occluders))
            truth, light_field = simulation.truth, simulation.light_field
            camera = merge_study.camera_options(truth, args.size)
            true_depth = np.asarray(truth.depth).astype(np.float32)
            ground = np.asarray(truth.ground).astype(np.float32)
            for method in METHODS:
                def run(knob: int) -> Any:
                    return aos.all_in_focus(
                        light_field, method=method, slices=args.slices,
                        first_plane=aos.Plane.at_height(merge_study.FIRST_HEIGHT),
                        last_plane=aos.Plane.at_height(merge_study.LAST_HEIGHT),
                        coarse_to_fine=knob, num_threads=args.threads, **camera)
                c = compare(run, args.repeats, f)
                full, fine = c["full"], c["c2f"]
                print(f"| {occluders} seed {seed} | {method} | {c['wall'][0]:.2f} | "
                      f"{c['wall'][1]:.2f} | {c['wall'][0] / c['wall'][1]:.2f} | "
                      f"{c['cpu'][0]:.2f} | {c['cpu'][1]:.2f} | {c['cpu'][0] / c['cpu'][1]:.2f} | "
                      f"{fine.rendered_fraction:.3f} | "
                      f"{psnr(np.asarray(full.image), ground):.3f} | "
                      f"{psnr(np.asarray(fine.image), ground):.3f} | "
                      f"{merge_study.banding(np.asarray(full.depth), true_depth):.4f} | "
                      f"{merge_study.banding(np.asarray(fine.depth), true_depth):.4f} |",
                      flush=True)
    poses = Path(args.data) / "poses" / "poses.json"
    if args.skip_f0 or not poses.exists():
        print(f"load average {os.getloadavg()[0]:.1f} at the end")
        print(f"F0: not measured ({'skipped' if args.skip_f0 else 'no data at ' + args.data})")
        return 0
    light_field = aos.load_lightfield(str(poses), fov_deg=F0_FOV_DEG).light_field
    print()
    print("| F0 (382 views, 512^2, 100 slices) | method | full wall s | c2f wall s | wall ratio | "
          "full CPU s | c2f CPU s | CPU ratio | rendered | PSNR c2f vs full dB | "
          "slice moved > 1 |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for method in METHODS:
        def run_f0(knob: int) -> Any:
            # The F0 frame has z pointing down: the slices run from z = 0 up 15 m (z = 0 is
            # 26.7 m below the camera, above the ground near z = +20: docs/benchmarks.md).
            return aos.all_in_focus(light_field, method=method, pose_view=191,
                                    fov_deg=F0_FOV_DEG, width=512, height=512,
                                    slices=args.slices, first_plane=aos.Plane.at_height(0.0),
                                    last_plane=aos.Plane.at_height(-15.0), coarse_to_fine=knob,
                                    num_threads=args.threads)
        c = compare(run_f0, args.repeats, f)
        full, fine = c["full"], c["c2f"]
        moved = float(np.mean(np.abs(np.asarray(fine.slice) - np.asarray(full.slice)) > 1.0))
        print(f"| F0 | {method} | {c['wall'][0]:.2f} | {c['wall'][1]:.2f} | "
              f"{c['wall'][0] / c['wall'][1]:.2f} | {c['cpu'][0]:.2f} | {c['cpu'][1]:.2f} | "
              f"{c['cpu'][0] / c['cpu'][1]:.2f} | {fine.rendered_fraction:.3f} | "
              f"{psnr(np.asarray(fine.image), np.asarray(full.image)):.2f} | {moved:.3f} |",
              flush=True)
    print(f"load average {os.getloadavg()[0]:.1f} at the end")
    return 0


if __name__ == "__main__":
    sys.exit(main())
