#!/usr/bin/env python3
"""Benchmark of focal stacks and all-in-focus merging.

Prints, in one run on this machine:
  1. merge time per method (median of --repeats) against the number of slices N and the image
     size, on stacks rendered from a simulated scene (not timed), with the ratio of each method to
     sobel, the paper's baseline, measured in the same run (target: improved within 3x);
     robust's time is split into the merge proper and the re-integration of the rays;
  2. the JKU F0 light field (382 views, 512 x 512): 100 slices rendered and merged end to end
     with aos.all_in_focus (decoding the frames is reported apart); target under 10 s;
  3. F0 robust with the AVX2 variance kernel against the scalar variance kernel it replaced
     (aos._core._set_simd_kernels(variance=False)), interleaved, with the outputs compared
     (target: <= 5 s and >= 3x).

Usage: python3 tools/bench_merge.py [--repeats 3] [--data ../shared/data/jku-f0]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import aos

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tools"))
import merge_study  # noqa: E402

F0_FOV_DEG = 50.815436217896945
TARGET_F0_SECONDS = 10.0


def merge_times(size: int, slices: int, repeats: int) -> dict[str, tuple[float, float]]:
    simulation = aos.simulate(merge_study.study_scene(1, min(size, 256), "voxels"))
    camera = merge_study.camera_options(simulation.truth, size)
    stack = aos.render_focal_stack(simulation.light_field,
                                   first_plane=aos.Plane.at_height(merge_study.FIRST_HEIGHT),
                                   last_plane=aos.Plane.at_height(merge_study.LAST_HEIGHT),
                                   slices=slices, variance=True, **camera)
    times: dict[str, list[tuple[float, float]]] = {m: [] for m in merge_study.METHODS}
    for _ in range(repeats):  # interleaved, so load from elsewhere hits every method alike
        for method in merge_study.METHODS:
            result = aos.merge_focal_stack(stack, method=method, light_field=simulation.light_field)
            times[method].append((result.seconds_merge, result.seconds_render))
    return {m: (statistics.median(t[0] for t in v), statistics.median(t[1] for t in v))
            for m, v in times.items()}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--data", default=str(ROOT.parent / "shared" / "data" / "jku-f0"))
    args = parser.parse_args()

    print("merge time (median of %d), ms; ratio to sobel in the same run:" % args.repeats)
    print(f"  {'size':>5} {'N':>4} {'sobel':>8} {'improved':>9} {'x sobel':>8} "
          f"{'robust':>8} {'x sobel':>8} {'+ re-integration':>17}")
    for size in (256, 512):
        for slices in (25, 50, 100):
            t = merge_times(size, slices, args.repeats)
            sobel = t["sobel"][0]
            print(f"  {size:>5} {slices:>4} {1e3 * sobel:8.1f} {1e3 * t['improved'][0]:9.1f} "
                  f"{t['improved'][0] / sobel:8.2f} {1e3 * t['robust'][0]:8.1f} "
                  f"{t['robust'][0] / sobel:8.2f} {1e3 * t['robust'][1]:14.1f} ms", flush=True)

    poses = Path(args.data) / "poses" / "poses.json"
    if not poses.exists():
        print(f"F0: no data at {args.data}; end-to-end case not measured")
        return 0
    start = time.perf_counter()
    light_field = aos.load_lightfield(str(poses), fov_deg=F0_FOV_DEG).light_field
    load = time.perf_counter() - start
    print(f"F0: {len(light_field.views)} views decoded in {load:.2f} s (not counted below)")
    # The F0 frame has z pointing down: the ground is near z = 0, the cameras at z = -26..-58;
    # the slices run from the ground up to 15 m above it.
    for method in ("sobel", "improved", "robust"):
        start = time.perf_counter()
        result = aos.all_in_focus(light_field, method=method, pose_view=191, fov_deg=F0_FOV_DEG,
                                  width=512, height=512, slices=100,
                                  first_plane=aos.Plane.at_height(0.0),
                                  last_plane=aos.Plane.at_height(-15.0))
        wall = time.perf_counter() - start
        print(f"  {method:9s} 100 slices of 512x512 from 382 views, end to end {wall:5.2f} s "
              f"(render {result.seconds_render:.2f} s, merge {result.seconds_merge:.2f} s; "
              f"{wall / TARGET_F0_SECONDS:.2f} x the {TARGET_F0_SECONDS:.0f} s target)", flush=True)
    robust_against_scalar_variance(light_field, args.repeats)
    return 0


def robust_against_scalar_variance(light_field, repeats: int) -> None:
    """robust on F0 with the AVX2 variance kernel against the same run with the scalar variance
    kernel (what robust ran before the AVX2 one existed), interleaved; the outputs compared."""
    def run():
        start = time.perf_counter()
        result = aos.all_in_focus(light_field, method="robust", pose_view=191,
                                  fov_deg=F0_FOV_DEG, width=512, height=512, slices=100,
                                  first_plane=aos.Plane.at_height(0.0),
                                  last_plane=aos.Plane.at_height(-15.0))
        return time.perf_counter() - start, result

    times = {"simd": [], "scalar": []}
    results = {}
    for _ in range(max(1, repeats)):
        for name in ("scalar", "simd"):
            aos._core._set_simd_kernels(enabled=True, variance=name == "simd")
            try:
                wall, results[name] = run()
            finally:
                aos._core._set_simd_kernels(enabled=True, variance=True)
            times[name].append(wall)
    ratios = [b / a for a, b in zip(times["simd"], times["scalar"])]
    simd, scalar = results["simd"], results["scalar"]
    import numpy as np
    difference = np.abs(simd.image.astype(np.float64) - scalar.image)
    # The slice map holds refined (fractional) positions: count the pixels that moved by more
    # than half a slice, i.e. that chose another slice, not a rounding of the same one.
    slice_moved = float(np.mean(np.abs(simd.slice - scalar.slice) > 0.5))
    moved = np.abs(simd.slice.astype(np.float64) - scalar.slice)
    slice_jitter = float(np.max(moved[moved <= 0.5], initial=0.0))
    moved_1e3 = float(np.mean(moved > 1e-3))
    image_over_1 = float(np.mean(np.abs(simd.image.astype(np.float64) - scalar.image) > 1.0))
    peak = float(scalar.image.max())
    mse = float(np.mean(difference ** 2))
    psnr = float("inf") if mse == 0 else 10 * np.log10(peak ** 2 / mse)
    print(f"F0 robust, 100 slices, interleaved ({len(ratios)} rounds): AVX2 variance kernel "
          f"median {statistics.median(times['simd']):.2f} s, scalar variance kernel (before) "
          f"{statistics.median(times['scalar']):.2f} s: {statistics.median(ratios):.2f}x faster "
          f"(per-round {min(ratios):.2f}..{max(ratios):.2f}); target <= 5 s and >= 3x")
    print(f"  render {simd.seconds_render:.2f} s + merge {simd.seconds_merge:.2f} s (AVX2) against "
          f"{scalar.seconds_render:.2f} s + {scalar.seconds_merge:.2f} s (scalar)")
    print(f"  outputs: {slice_moved:.2e} of the pixels chose another slice (refined position moved "
          f"> 0.5; the others by <= {slice_jitter:.2g} slices, {moved_1e3:.2e} of them by more "
          f"than 1e-3); {image_over_1:.2e} of the pixels differ by more than 1 grey level; "
          f"image max abs "
          f"difference {difference.max():.4g}, mean {difference.mean():.3g} grey levels; PSNR of "
          f"one against the other {psnr:.1f} dB (peak {peak:.1f})", flush=True)


if __name__ == "__main__":
    sys.exit(main())
