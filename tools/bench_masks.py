#!/usr/bin/env python3
"""Masks (LoadOptions::mask): what a burnt-in letterbox and logo cost, and what the mask costs.

1. Quality (--quality): the forest scene (scenes/forest.json with 30 trees a hectare, grey
   256 x 192 frames like a thermal camera's 4:3, 11 x 11 views) is simulated; a letterbox (the top and bottom 12% of the
   rows) and a logo (a block near a corner) are painted white into every frame. The truth camera's
   render on the ground plane is compared with the truth (the occluder-free ground) for the clean
   frames, the painted frames without a mask, and the painted frames with the mask: Pearson
   correlation and PSNR over the pixels covered in all three.
2. Speed (--speed): JKU F0 (../shared/data/jku-f0, 382 grey 512 x 512 frames), the plane z = 0
   rendered from view 191 at 512 x 512, without and with an artificial letterbox mask (32 rows at
   top and bottom, a 96 x 40 logo): median of --repeats interleaved rounds after a warm-up, and the
   median per-round ratio; the same for the terrain mesh (dem/dem_lr.obj, the per-sample path).

Usage: python3 tools/bench_masks.py [--quality] [--speed] [--data DIR] [--repeats 5]
"""
from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

import aos

ROOT = Path(__file__).resolve().parents[1]
F0_FOV_DEG = 50.815436217896945


def letterbox(width: int, height: int, bar: int, logo: tuple[int, int, int, int]) -> np.ndarray:
    """uint8 mask, 255 = valid: bars of `bar` rows at top and bottom, a logo x0, y0, w, h."""
    valid = np.full((height, width), 255, np.uint8)
    valid[:bar] = 0
    valid[height - bar:] = 0
    x0, y0, w, h = logo
    valid[y0:y0 + h, x0:x0 + w] = 0
    return valid


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    a = a - a.mean()
    b = b - b.mean()
    return float((a * b).sum() / np.sqrt((a * a).sum() * (b * b).sum()))


def quality() -> None:
    scene = json.loads((ROOT / "scenes" / "forest.json").read_text())
    scene["camera"] = {"width": 256, "height": 192, "fov_deg": 60.0, "channels": 1}
    # Sparse trees (30 a hectare instead of 300): the clean render is then close to the truth,
    # so what the paint and the mask change is not lost under the occlusion.
    scene["occluders"]["trees"]["per_hectare"] = 30
    scene["truth"] = {"fov_deg": 30.0, "width": 256, "height": 256}
    sim = aos.simulate(scene)
    truth = sim.truth
    width, height = 256, 192
    valid = letterbox(width, height, bar=height * 12 // 100, logo=(190, 30, 50, 24))
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        painted = aos.LightField()
        for i, view in enumerate(sim.light_field.views):
            image = view.image.copy()
            image[valid == 0] = 255
            painted.add_view(image, view.camera, view.cam_from_world, f"{i:04d}.png")
        aos.write_lightfield(str(folder / "lf.json"), painted)
        aos.write_image(str(folder / "mask.png"), valid)
        render = dict(cam_from_world=truth.cam_from_world, fov_deg=truth.camera.fov_x_deg(),
                      width=truth.camera.width, height=truth.camera.height,
                      focal_surface=truth.ground_height_at_center)
        runs = {
            "clean frames": sim.light_field,
            "painted, no mask": aos.load_lightfield(folder / "lf.json").light_field,
            "painted, mask": aos.load_lightfield(folder / "lf.json",
                                                 mask=folder / "mask.png").light_field,
        }
        results = {name: aos.render_integral(lf, **render) for name, lf in runs.items()}
    covered = np.logical_and.reduce([r.count > 0 for r in results.values()])
    reference = truth.ground.astype(np.float64)
    print(f"quality: forest scene, {len(sim.light_field)} views of {width}x{height}, letterbox "
          f"+ logo = {100 * (valid == 0).mean():.1f}% of each frame; {covered.mean() * 100:.1f}% "
          f"of the {reference.shape[1]}x{reference.shape[0]} truth pixels covered in all three")
    for name, result in results.items():
        image = result.image.astype(np.float64)
        mse = ((image - reference)[covered] ** 2).mean()
        psnr = 10 * np.log10(255.0 ** 2 / mse)
        if name == "painted, mask":
            difference = np.abs(image - results["clean frames"].image)[covered]
            print(f"  masked render against the clean-frame render: mean |difference| "
                  f"{difference.mean():.2f} grey, 99th percentile {np.percentile(difference, 99):.2f}")
        print(f"  {name:18s} correlation {correlation(image[covered], reference[covered]):.4f}  "
              f"PSNR {psnr:.2f} dB  mean count {result.count[covered].mean():.1f}")


def speed(data: Path, repeats: int) -> None:
    poses = data / "poses" / "poses.json"
    valid = letterbox(512, 512, bar=32, logo=(400, 48, 96, 40))
    with tempfile.TemporaryDirectory() as folder:
        mask = Path(folder) / "mask.png"
        aos.write_image(str(mask), valid)
        plain = aos.load_lightfield(poses, fov_deg=F0_FOV_DEG).light_field
        masked = aos.load_lightfield(poses, fov_deg=F0_FOV_DEG, mask=mask).light_field
    render = dict(pose_view=191, width=512, height=512, focal_surface=0.0)
    mesh = aos.Mesh.read(str(data / "dem" / "dem_lr.obj"))
    cases = {"plane": render,
             "mesh": {**{k: v for k, v in render.items() if k != "focal_surface"},
                      "focal_surface": mesh}}
    print(f"speed: F0, {len(plain)} views, mask {100 * (valid == 0).mean():.1f}% masked, "
          f"{repeats} interleaved rounds")
    for case, options in cases.items():
        for lf in (plain, masked):
            aos.render_integral(lf, **options)  # warm-up
        times = {"plain": [], "masked": []}
        for _ in range(repeats):
            for name, lf in (("plain", plain), ("masked", masked)):
                start = time.perf_counter()
                result = aos.render_integral(lf, **options)
                times[name].append(time.perf_counter() - start)
                if name == "masked":
                    samples = result.samples
        ratios = [m / p for m, p in zip(times["masked"], times["plain"])]
        print(f"  {case:5s} plain {statistics.median(times['plain']) * 1e3:7.1f} ms  masked "
              f"{statistics.median(times['masked']) * 1e3:7.1f} ms  ratio "
              f"{statistics.median(ratios):.2f}  (masked samples {samples})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quality", action="store_true")
    parser.add_argument("--speed", action="store_true")
    parser.add_argument("--data", default=str(ROOT.parent / "shared" / "data" / "jku-f0"))
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    if not args.quality and not args.speed:
        args.quality = args.speed = True
    if args.quality:
        quality()
    if args.speed:
        speed(Path(args.data), args.repeats)


if __name__ == "__main__":
    main()
