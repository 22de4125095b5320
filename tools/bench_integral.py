#!/usr/bin/env python3
"""Benchmark of the integral renderer on the JKU F0 case (382 views -> 512x512).

Prints, for aos and for a plain Python/OpenCV baseline measured in the same run
(cv2.warpPerspective of each view, then accumulation of values and coverage):
  - median render time over --repeats runs (after one warm-up run), and the speed-up ratio;
  - samples per second (view samples actually integrated, i.e. the sum of the count map);
  - agreement of the two images (mean absolute difference, grey levels);
  - memory: peak resident memory of a fresh process that loads the light field and renders once,
    minus its resident memory before loading, against the decoded image bytes plus the output.

Usage: python3 tools/bench_integral.py [--data ../shared/data/jku-f0] [--repeats 7]
Needs: pip install '.[bench]' (opencv-python-headless) for the baseline.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import aos

FOV_DEG = 50.815436217896945
ROOT = Path(__file__).resolve().parents[1]


def median_time(function, repeats):
    function()  # warm-up: page faults, thread start, caches
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return statistics.median(times), times


def opencv_baseline(cv2, images, poses, virtual_index, size, fov_deg):
    """The straightforward implementation: warp every view into the virtual camera with
    cv2.warpPerspective (bilinear, pixels outside the view marked by a second channel) and
    accumulate value and coverage in float64."""
    f = 0.5 * size / np.tan(np.radians(fov_deg) / 2)
    K = np.array([[f, 0, size / 2], [0, f, size / 2], [0, 0, 1.0]])
    R_v, t_v = poses[virtual_index]
    c = -R_v.T @ t_v
    n = np.array([0.0, 0.0, 1.0])
    h = -c[2]  # plane z = 0
    # OpenCV's pixel centres are at integer coordinates: shift by half a pixel on both sides.
    to_cv = np.array([[1, 0, -0.5], [0, 1, -0.5], [0, 0, 1.0]])
    from_cv = np.array([[1, 0, 0.5], [0, 1, 0.5], [0, 0, 1.0]])
    homographies = []
    for R, t in poses:
        tau = R @ (c - (-R.T @ t))
        H = K @ (h * R + np.outer(tau, n)) @ R_v.T @ np.linalg.inv(K)  # output px -> view px
        homographies.append(to_cv @ (np.sign(h) * H) @ from_cv)

    def render():
        total = np.zeros((size, size), np.float64)
        count = np.zeros((size, size), np.float64)
        for image, H in zip(images, homographies):
            warped = cv2.warpPerspective(image, H, (size, size),
                                         flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                         borderMode=cv2.BORDER_CONSTANT, borderValue=0)
            total += warped[..., 0]
            count += warped[..., 1] > 0.5
        return np.where(count > 0, total / np.maximum(count, 1), 0.0)

    return render


MEMORY_PROBE = r"""
import json, sys
def rss_kib(field):
    for line in open('/proc/self/status'):
        if line.startswith(field):
            return int(line.split()[1])
import numpy as np, aos
before = rss_kib('VmRSS:')
loaded = aos.load_lightfield(sys.argv[1], fov_deg=float(sys.argv[2]))
lf = loaded.light_field
result = aos.render_integral(lf, pose_view=191, fov_deg=float(sys.argv[2]), width=512, height=512)
peak = rss_kib('VmHWM:')
out_bytes = result.image.nbytes + result.count.nbytes
print(json.dumps({'before_kib': before, 'peak_kib': peak, 'image_bytes': lf.image_bytes(),
                  'output_bytes': out_bytes}))
"""


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=str(ROOT.parent / "shared" / "data" / "jku-f0"))
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    poses_path = Path(args.data) / "poses" / "poses.json"
    if not poses_path.exists():
        print(f"bench_integral: no F0 data at {args.data}; nothing measured")
        return 0

    print(f"aos {aos.__version__}, {os.cpu_count()} cores; F0: {poses_path}")
    loaded = aos.load_lightfield(str(poses_path), fov_deg=FOV_DEG)
    light_field = loaded.light_field
    options = aos.IntegralOptions(pose_view=191, fov_deg=FOV_DEG, width=512, height=512,
                                  focal_plane=aos.Plane.at_height(0.0))
    result = aos.render_integral(light_field, options)
    aos_median, aos_times = median_time(lambda: aos.render_integral(light_field, options), args.repeats)
    samples = int(result.samples)
    print(f"aos:      median {aos_median * 1e3:7.1f} ms  (runs: "
          f"{', '.join(f'{t * 1e3:.0f}' for t in aos_times)} ms)  "
          f"{samples / aos_median / 1e6:7.1f} M samples/s  ({samples} samples)")

    try:
        import cv2
    except ImportError:
        print("baseline: opencv-python-headless not installed (pip install '.[bench]'); no ratio")
        cv2 = None
    if cv2 is not None:
        raw = json.loads(poses_path.read_text())["images"]
        poses = []
        for entry in raw:
            m = np.array([[float(v) for v in row] for row in entry["M3x4"]])
            poses.append((m[:, :3], m[:, 3]))
        # Value and coverage as two float32 channels, decoded once (not timed).
        images = []
        for view in light_field.views:
            image = view.image.astype(np.float32)
            images.append(np.dstack([image, np.ones_like(image)]))
        render = opencv_baseline(cv2, images, poses, 191, 512, FOV_DEG)
        baseline_image = render()
        base_median, base_times = median_time(render, args.repeats)
        print(f"baseline: median {base_median * 1e3:7.1f} ms  (runs: "
              f"{', '.join(f'{t * 1e3:.0f}' for t in base_times)} ms)  "
              f"cv2.warpPerspective + numpy accumulation, OpenCV threads: {cv2.getNumThreads()}")
        mad = float(np.mean(np.abs(baseline_image - result.image)))
        print(f"speed-up: {base_median / aos_median:.1f}x (target >= 6x)   "
              f"images agree to {mad:.3f} grey levels mean absolute difference")

    probe = subprocess.run([sys.executable, "-c", MEMORY_PROBE, str(poses_path), str(FOV_DEG)],
                           capture_output=True, text=True, check=True)
    memory = json.loads(probe.stdout)
    held = (memory["peak_kib"] - memory["before_kib"]) * 1024
    budget = memory["image_bytes"] + memory["output_bytes"]
    print(f"memory:   {held / 2**20:.1f} MiB held at peak (VmHWM after load+render minus VmRSS "
          f"before load, fresh process) vs {memory['image_bytes'] / 2**20:.1f} MiB decoded frames + "
          f"{memory['output_bytes'] / 2**20:.1f} MiB output = {held / budget:.2f}x (target < 1.5x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
