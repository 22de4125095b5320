#!/usr/bin/env python3
"""Detection speed (issue 34's goals, checked here, never in the tests):

- RX on a 512 x 512 integral image: <= 20 ms (grey: F0's integral; RGB: a random 3-channel image);
  local RX beside it;
- anomaly imaging on F0 (382 views, 512 x 512, the ground plane z = +21): <= 2 x the integral's
  render time, measured interleaved in the same run.

Prints the CPU line and the best of --repeat runs (interleaved), and the ratio.
Usage: python3 tools/bench_detect.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np

import aos

F0 = Path(__file__).resolve().parents[2] / "shared" / "data" / "jku-f0"
F0_FOV_DEG = 50.815436217896945


def best(function, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    cpu = next((line.split(":", 1)[1].strip() for line in
                Path("/proc/cpuinfo").read_text().splitlines() if line.startswith("model name")),
               platform.processor())
    print(f"CPU: {cpu}")
    if not (F0 / "poses" / "poses.json").exists():
        print(f"F0 not found at {F0}: skipped")
        return 0
    lf = aos.load_lightfield(str(F0 / "poses" / "poses.json"), fov_deg=F0_FOV_DEG).light_field
    integral = aos.render_integral(lf, pose_view=191, focal_surface=21.0)
    grey = integral.image
    rgb = np.random.default_rng(1).normal(100.0, 10.0, (512, 512, 3)).astype(np.float32)
    for name, image in (("grey (F0)", grey), ("RGB", rgb)):
        for detector in ("rx", "rx-local"):
            options = aos.DetectOptions(detector=detector)
            aos.anomaly_scores(image, None, options)  # warm up
            seconds = best(lambda: aos.anomaly_scores(image, None, options), args.repeat)
            goal = "  (goal <= 20 ms)" if detector == "rx" else ""
            print(f"{detector:9s} on a 512 x 512 {name:9s}: {1000 * seconds:7.1f} ms{goal}")
    render, imaging = [], []
    for _ in range(args.repeat):  # interleaved: drift hits both alike
        render.append(best(lambda: aos.render_integral(lf, pose_view=191, focal_surface=21.0), 1))
        imaging.append(best(lambda: aos.detect(lf, pose_view=191, focal_surface=21.0,
                                               detector="anomaly-imaging"), 1))
    print(f"F0 integral: {1000 * min(render):.0f} ms; anomaly imaging (detect): "
          f"{1000 * min(imaging):.0f} ms; ratio {min(imaging) / min(render):.1f} (goal <= 2)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
