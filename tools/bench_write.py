#!/usr/bin/env python3
"""Image writing speed: milliseconds per 512 x 512 RGB 8-bit PNG (aos.write_image) at zlib level 6
(the old default) and 1 (aos's), and the wall time of `aos-render rectify` of 90 such frames
through a radial-tangential lens on 1 thread and on all.

    python3 tools/bench_write.py [--frames 90] [--size 512] [--threads N]

The image is a simulated forest view's texture (smooth structure plus sensor-like noise), so the
PNG compressor sees what it sees in practice, not a constant or pure noise. Prints one JSON object.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

import aos


def texture(size: int, seed: int) -> np.ndarray:
    """A deterministic RGB 8-bit image with structure at several scales and a little noise."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:size, 0:size] / size
    base = np.zeros((size, size, 3))
    for k in range(1, 6):
        phase = rng.uniform(0, 2 * np.pi, 3)
        for c in range(3):
            base[..., c] += np.sin(2 * np.pi * (k * 3 * x + phase[c])) * np.cos(
                2 * np.pi * (k * 2 * y + phase[(c + 1) % 3])) / k
    base = (base - base.min()) / (base.max() - base.min())
    image = 40 + 170 * base + rng.normal(0, 4, base.shape)
    return np.clip(np.round(image), 0, 255).astype(np.uint8)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=90)
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--threads", type=int, default=-1, help="rectify --threads (-1: all)")
    args = parser.parse_args()
    exe = shutil.which("aos-render")
    result: dict[str, object] = {"size": args.size, "frames": args.frames, "cpus": os.cpu_count()}
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        image = texture(args.size, 1)
        for level in (6, 1):  # 6: zlib's default (OpenImageIO's, aos before), 1: aos's default
            times = []
            for i in range(args.repeats):
                start = time.perf_counter()
                aos.write_image(str(root / f"w{i}.png"), image, png_compression_level=level)
                times.append(1000 * (time.perf_counter() - start))
            result[f"write_png_level{level}_ms_median"] = round(statistics.median(times), 2)
            result[f"write_png_level{level}_bytes"] = (root / "w0.png").stat().st_size
        if exe is not None:
            frames = []
            for i in range(args.frames):
                frame = root / f"frame_{i:03d}.png"
                aos.write_image(str(frame), texture(args.size, 100 + i))
                frames.append(str(frame))
            camera = root / "camera.json"
            aos.write_camera_file(camera, aos.LensCamera(
                aos.LensModel.radtan, args.size, args.size, 0.9 * args.size, 0.9 * args.size,
                0.5 * args.size, 0.5 * args.size, [-0.05, 0.0, 0.0, 0.0, 0.0]))
            for threads in sorted({1, args.threads}):
                start = time.perf_counter()
                subprocess.run([exe, "rectify", *frames, "--camera", str(camera),
                                "--rectified-fov-deg", "50", "--threads", str(threads),
                                "-o", str(root / f"rectified{threads}"), "-q"], check=True)
                result[f"rectify_threads{threads}_s"] = round(time.perf_counter() - start, 2)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
