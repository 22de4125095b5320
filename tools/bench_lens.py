#!/usr/bin/env python3
"""Lens models: direct sampling against rectify-then-render, and rectification throughput.

Prints, in one run on this machine:
  1. On simulated light fields with ground truth (aos.simulate) - 5 x 5 nadir views from 20 m,
     4 m apart, of a ground plane textured with smooth value noise (0.4 m lattice; no occluders), recorded at 1024 x 1024
     through a fisheye (equidistant, 180 degrees), an omnidirectional (Mei) and a
     radial-tangential lens - the integral image from the 512 x 512 truth camera (a 60-degree
     pinhole at the aperture centre) on the ground plane, rendered three ways: straight from the
     raw frames through the lens model (direct sampling, one resampling) with the default
     lens_tolerance_px (local maps per quad, "fast") and with lens_tolerance_px = 0
     (every sample projected exactly, "exact"), and after rectifying every frame to a 100-degree
     (radtan: 95-degree) perspective frame of the same width (two resamplings). PSNR and SSIM against the
     simulator's truth image of the ground, and the time of each way, the three renders
     interleaved in each repeat (the machine's load shifts); the rectified frames' pinhole
     render is the reference for render time (the target: direct within 2x of it).
  2. Rectification throughput, frames per second at 1 MP (1024 x 1024) and 14 MP
     (4592 x 3056), 8-bit grey, maps built once (their time reported apart).

Usage: python3 tools/bench_lens.py [--repeats 3] [--write-docs]   (docs/lens-models.md)
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

import aos
from host import cpu_line

ALTITUDE = 20.0
SIZE = 1024
TRUTH = {"fov_deg": 60.0, "width": 512, "height": 512}


def scene(camera: dict, size: int = SIZE, grid: int = 5, truth: dict | None = None) -> dict:
    """A bare textured ground seen through `camera` (lens keys of the scene's camera): smooth
    value noise on a 0.4 m lattice, a few raw pixels (6 cm at nadir) to tens of them, so that
    resampling, not the pixel grid, limits the quality (the default chart has detail below the
    pixel size, which every method aliases alike)."""
    return {"seed": 7, "ground": {"texture": {"type": "noise", "square": 0.4}},
            "camera": {"width": size, "height": size, "bit_depth": 32, "samples_per_pixel": 2,
                       **camera},
            "sampling": {"altitude": ALTITUDE, "grid": grid,
                         "aperture": {"shape": "square", "diameter": 4.0 * (grid - 1)}},
            "truth": truth or TRUTH}


FISHEYE = {"lens": "fisheye", "fov_deg": 180.0, "distortion": [0.01, -0.002]}
OMNI = {"lens": "omnidir", "fov_deg": 200.0, "xi": 1.2, "distortion": [-0.05, 0.01]}
RADTAN = {"lens": "radtan", "fov_deg": 100.0, "distortion": [-0.05, 0.01, 0.001, -0.001, 0.0]}


def median_time(call, repeats: int) -> tuple[float, object]:
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = call()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def compare(camera: dict, name: str, repeats: int, size: int = SIZE, grid: int = 5,
            truth_spec: dict | None = None, rectified_fov_deg: float = 100.0) -> dict:
    simulation = aos.simulate(scene(camera, size, grid, truth_spec))
    truth = simulation.truth
    lens = simulation.light_field.views[0].camera
    options = aos.IntegralOptions(cam_from_world=truth.cam_from_world,
                                  fov_deg=truth.camera.fov_x_deg(), width=truth.camera.width,
                                  height=truth.camera.height)
    exact_options = aos.IntegralOptions(cam_from_world=truth.cam_from_world,
                                        fov_deg=truth.camera.fov_x_deg(),
                                        width=truth.camera.width, height=truth.camera.height,
                                        lens_tolerance_px=0.0)
    direct_field = simulation.light_field
    rectifier_start = time.perf_counter()
    rectifier = aos.make_rectifier(lens, aos.RectifyOptions(fov_deg=rectified_fov_deg))
    maps_time = time.perf_counter() - rectifier_start
    frames = [view.image for view in direct_field.views]
    rectify_time, rectified = median_time(lambda: [rectifier.rectify(f) for f in frames], repeats)
    rectified_field = aos.LightField()
    for frame, view in zip(rectified, direct_field.views):
        rectified_field.add_view(frame, rectifier.camera, view.cam_from_world)
    # The three renders interleaved, repeat by repeat: the load of a shared machine shifts
    # between repeats, less between neighbouring renders.
    calls = {"direct": lambda: aos.render_integral(direct_field, options),
             "exact": lambda: aos.render_integral(direct_field, exact_options),
             "pinhole": lambda: aos.render_integral(rectified_field, options)}
    times: dict[str, list[float]] = {key: [] for key in calls}
    results: dict[str, object] = {}
    for _ in range(repeats):
        for key, call in calls.items():
            start = time.perf_counter()
            results[key] = call()
            times[key].append(time.perf_counter() - start)
    direct, exact, two_step = results["direct"], results["exact"], results["pinhole"]
    ratios = [d / p for d, p in zip(times["direct"], times["pinhole"])]
    mask = ((direct.count > 0) & (two_step.count > 0)).astype(np.uint8)
    q_direct = aos.compare_images(direct.image, truth.ground, mask, data_range=1.0)
    q_exact = aos.compare_images(exact.image, truth.ground, mask, data_range=1.0)
    q_two = aos.compare_images(two_step.image, truth.ground, mask, data_range=1.0)
    return {"name": name, "direct_psnr": q_direct.psnr_db, "direct_ssim": q_direct.ssim,
            "exact_psnr": q_exact.psnr_db, "exact_ssim": q_exact.ssim,
            "two_psnr": q_two.psnr_db, "two_ssim": q_two.ssim,
            "direct_s": statistics.median(times["direct"]),
            "exact_s": statistics.median(times["exact"]),
            "pinhole_render_s": statistics.median(times["pinhole"]),
            "ratio": statistics.median(ratios),
            "fast_minus_exact": float(np.abs(direct.image - exact.image).max()),
            "rectify_s": rectify_time, "maps_s": maps_time}


def relief(camera: dict, name: str, repeats: int, rectified_fov_deg: float) -> dict:
    """The same scene rendered on depth maps (render_integral_on_depth) of the ground plane and
    of a relief on it (+-5 cm, a 128-pixel sine in x times one in y, on the truth camera's
    depth): direct, direct (exact) and the rectified frames' pinhole render, interleaved. The
    relief's focal points leave the plane, so the lens route's maps must hold over the turned
    rays (LensRoute::TurnedError in surface_integral.cpp)."""
    simulation = aos.simulate(scene(camera))
    truth = simulation.truth
    direct = simulation.light_field
    rectifier = aos.make_rectifier(direct.views[0].camera,
                                   aos.RectifyOptions(fov_deg=rectified_fov_deg))
    pinhole = aos.LightField()
    for view in direct.views:
        pinhole.add_view(rectifier.rectify(view.image), rectifier.camera, view.cam_from_world)
    base = dict(cam_from_world=truth.cam_from_world, fov_deg=truth.camera.fov_x_deg(),
                width=truth.camera.width, height=truth.camera.height)
    plane = np.asarray(aos.plane_depth(truth.camera, truth.cam_from_world,
                                       aos.Plane.at_height(0.0)), dtype=np.float32)
    y, x = np.mgrid[0:plane.shape[0], 0:plane.shape[1]]
    bumps = (plane + 0.05 * np.sin(2 * np.pi * x / 128) * np.cos(2 * np.pi * y / 128))
    out = {"name": name}
    for label, depth in (("plane", plane), ("relief", bumps.astype(np.float32))):
        calls = {"direct": aos.IntegralOptions(**base),
                 "exact": aos.IntegralOptions(**base, lens_tolerance_px=0.0)}
        times: dict[str, list[float]] = {"direct": [], "exact": [], "pinhole": []}
        results: dict[str, object] = {}
        for _ in range(repeats):
            for key in times:
                start = time.perf_counter()
                results[key] = aos.render_integral_on_depth(
                    pinhole if key == "pinhole" else direct, depth,
                    calls.get(key, aos.IntegralOptions(**base)))
                times[key].append(time.perf_counter() - start)
        fast, exact = results["direct"].integral, results["exact"].integral
        both = (fast.count > 0) & (fast.count == exact.count)
        out[label] = {
            "direct_s": statistics.median(times["direct"]),
            "exact_s": statistics.median(times["exact"]),
            "pinhole_s": statistics.median(times["pinhole"]),
            "ratio": statistics.median(d / p for d, p in zip(times["direct"], times["pinhole"])),
            "exact_ratio": statistics.median(e / p for e, p in zip(times["exact"],
                                                                    times["pinhole"])),
            "fast_minus_exact": float(np.abs(fast.image - exact.image)[both].max()),
            "count_mismatches": int((fast.count != exact.count).sum())}
    return out


def throughput(width: int, height: int, repeats: int) -> tuple[float, float]:
    f = width / math.pi  # an equidistant lens covering 180 degrees across the width
    lens = aos.LensCamera(aos.LensModel.fisheye, width, height, f, f, width / 2, height / 2)
    start = time.perf_counter()
    rectifier = aos.make_rectifier(lens, aos.RectifyOptions(fov_deg=80.0))
    maps = time.perf_counter() - start
    frame = (np.random.default_rng(1).random((height, width)) * 255).astype(np.uint8)
    seconds, _ = median_time(lambda: rectifier.rectify(frame), repeats)
    return 1.0 / seconds, maps


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--write-docs", action="store_true")
    args = parser.parse_args()
    # The machine is shared: its load average (1 minute) before and after the lens comparison is
    # printed and written with the figures.
    load_before = os.getloadavg()[0]
    rows = []
    # The radial-tangential lens's barrel distortion leaves a 100-degree perspective frame's
    # corners uncovered: its frames are rectified to 95 degrees (the truth camera's footprint
    # needs about 90 from the outer views).
    for camera, name, rectified_fov in ((FISHEYE, "fisheye (equidistant, 180 deg)", 100.0),
                                        (OMNI, "omnidirectional (Mei, xi 1.2, 200 deg)", 100.0),
                                        (RADTAN, "radial-tangential (100 deg)", 95.0)):
        rows.append(compare(camera, name, args.repeats, rectified_fov_deg=rectified_fov))
        print(rows[-1], flush=True)
    lines = ["| lens | direct PSNR / SSIM | direct (exact) PSNR / SSIM | "
             "rectify-then-render PSNR / SSIM | direct render | direct (exact) render | "
             "pinhole render of the rectified frames | direct / pinhole | "
             "rectify 25 frames + render | (maps) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['name']} | {r['direct_psnr']:.2f} dB / {r['direct_ssim']:.4f} | "
                     f"{r['exact_psnr']:.2f} dB / {r['exact_ssim']:.4f} | "
                     f"{r['two_psnr']:.2f} dB / {r['two_ssim']:.4f} | {1e3 * r['direct_s']:.0f} ms | "
                     f"{1e3 * r['exact_s']:.0f} ms | {1e3 * r['pinhole_render_s']:.0f} ms | "
                     f"{r['ratio']:.2f}x | "
                     f"{1e3 * (r['rectify_s'] + r['pinhole_render_s']):.0f} ms | "
                     f"{1e3 * r['maps_s']:.0f} ms |")
    table = "\n".join(lines)
    load_after = os.getloadavg()[0]
    load = (f"load average (1 min) {load_before:.1f} before and {load_after:.1f} after, on "
            f"{os.cpu_count()} cores; {cpu_line()}")
    print(table)
    print(load)
    reliefs = []
    for camera, name, rectified_fov in ((FISHEYE, "fisheye", 100.0), (OMNI, "omnidirectional", 100.0),
                                        (RADTAN, "radial-tangential", 95.0)):
        reliefs.append(relief(camera, name, args.repeats, rectified_fov))
        print(reliefs[-1], flush=True)
    relief_lines = ["| lens | surface | direct render | direct (exact) | pinhole | direct / pinhole | "
                    "direct (exact) / pinhole | max abs(direct - exact) | count mismatches |",
                    "|---|---|---|---|---|---|---|---|---|"]
    for r in reliefs:
        for label in ("plane", "relief"):
            f = r[label]
            relief_lines.append(
                f"| {r['name']} | {'ground plane' if label == 'plane' else '+-5 cm relief'} | "
                f"{1e3 * f['direct_s']:.0f} ms | {1e3 * f['exact_s']:.0f} ms | "
                f"{1e3 * f['pinhole_s']:.0f} ms | {f['ratio']:.2f}x | {f['exact_ratio']:.2f}x | "
                f"{f['fast_minus_exact']:.1e} | {f['count_mismatches']} |")
    relief_table = "\n".join(relief_lines)
    print(relief_table)
    speed = []
    for width, height in ((1024, 1024), (4592, 3056)):
        fps, maps = throughput(width, height, args.repeats)
        speed.append(f"| {width} x {height} ({width * height / 1e6:.1f} MP) | {fps:.1f} | "
                     f"{1e3 * maps:.0f} ms |")
        print(speed[-1], flush=True)
    if args.write_docs:
        path = Path(__file__).resolve().parent.parent / "docs" / "lens-models.md"
        path.write_text(f"""# Lens models: direct sampling, rectification, resolution

Figures from `python3 tools/bench_lens.py --repeats {args.repeats} --write-docs` on the 2-core
machine (rerun it to reproduce). Models and conventions: `cpp/aos/geometry/lens.h`.

## Direct sampling against rectify-then-render

Simulated light fields (`aos.simulate`): 5 x 5 nadir views from {ALTITUDE:.0f} m, 4 m apart,
of a ground plane textured with smooth value noise on a 0.4 m lattice (no occluders), recorded at {SIZE} x {SIZE} (float32, 2 x 2
samples per pixel) through each lens: `{FISHEYE}`, `{OMNI}` and `{RADTAN}`. The integral from the
simulator's 512 x 512 truth camera (a 60-degree pinhole over the aperture centre) on the ground
plane; quality against the simulator's truth image of the ground (PSNR with L = 1, SSIM), over
the pixels both ways cover. Rectify-then-render rectifies to a 100-degree perspective frame of
the same width (radtan: 95 degrees, which its barrel distortion still covers). "direct" is the
default (`lens_tolerance_px` 0.02: local
maps per quad of the output, each checked against the exact projection), "direct
(exact)" projects every sample through the lens (`lens_tolerance_px` 0); the three renders are
interleaved in each of the {args.repeats} repeats, times are medians, "direct / pinhole" the
median of the per-repeat ratios (the machine is shared: single timings move by 2x and more
with its load, the ratios less; this run: {load}):

{table}

Direct sampling resamples each raw frame once, through the lens model; rectifying first
resamples twice (raw -> perspective -> integral) and loses detail at each step. Direct sampling
takes the per-sample render path (`surface_integral.h`): per quad of 64 down to 8 output pixels
and per view, nodes of the quad are projected exactly through the lens and a local map is
fitted to them. Fisheye and omnidirectional lenses first take, on 64- and 32-pixel quads, a
cubic polynomial in the tangent-plane coordinates of the quad's centre ray, by least squares
over a 5 x 5 grid of nodes, its error bounded by the largest error at the nodes plus the
bilinear interpolation error between them (from the nodes' second differences); below that,
and on radial-tangential lenses, the map is affine in the tangent plane through the corners or,
where that misses the tolerance by less than 4x, a full homography by least squares over the
3 x 3 nodes (corners, edge midpoints, centre). The quad is sampled through the map by the point
kernel when that error (plus a bound for the surface's departure from a bilinear sheet) is
within `lens_tolerance_px` view pixels; other quads are split, and the smallest ones projected
sample by sample. At the default 0.02 px the fisheye and omnidirectional tiles pass whole, at
64 output pixels (the cubic's residual there is about 3e-4 px: the PSNR is the exact route's
to 0.01 dB; a homography, which cannot take up these lenses' second-order term, passed only at
16 pixels), the radial-tangential quads at 32 (the homography
takes up most of it). A quad is split without a fit where its parent's error predicts a miss by
more than twice the tolerance (a quarter of it for affine fits, a sixteenth for cubic ones),
except on radial-tangential lenses, whose 32-pixel homographies pass below 64-pixel tiles that
missed by far more than that. The render's time beyond the pinhole path's is then mostly the
point kernel, which costs more per sample than the pinhole path's span kernel (each focal point
is projected in 3-D, and for the wide lenses the cubic evaluated; float frames' two horizontal
taps of a row are read with one 64-bit load per sample, not gathered), then the per-sample
path's own setup (every pixel's focal point, tile by tile) and the fits and node projections
(one fit and 25 nodes per view and tile for the wide lenses, 25 nodes and four homographies for
the radial-tangential one). A sample position off by at most t view pixels moves
a bilinear sample by at most t times the frame's largest step between neighbouring pixels.
Rectifying pays off only when the same frames are rendered many times.

### On a relief

A surface that is not a plane (a terrain, a depth map) puts a quad's focal points off the
bilinear sheet through its corners, so their rays turn away from the sheet's. A local map is a
function of the ray's direction alone, so where the turn, charged at the map's full gradient
(about the lens's focal length), would miss the tolerance, the map is validated over the
nodes' tangent-plane box grown by the turn instead: a 5 x 5 grid of exact projections there,
plus the interpolation estimate from its second differences (`LensRoute::TurnedError`).
Before, a relief of more than about a millimetre at 20 m sent every quad to the exact
projection. The same scenes on depth maps (`render_integral_on_depth`): the truth camera's
ground plane, and the plane with a relief of +-5 cm (a 128-pixel sine in x times one in y),
interleaved as above, {args.repeats} repeats. "max abs(direct - exact)" is over the pixels both
routes cover equally often (images in [0, 1]):

{relief_table}

## Rectification throughput

8-bit grey frames, an equidistant lens covering 180 degrees, rectified to 80 degrees at the
same size (cv::remap, bilinear; maps from the lens model built once):

| frame | frames per second | building the maps |
|---|---|---|
{chr(10).join(speed)}

## Sampling resolution (Eq. 2, Appendix A)

`aos-render resolution --width 1871 --height 1871 --lens-fov-deg 80 --distance-m 35 --pose-error-m 0.0423`
reproduces the paper: 1014.7 samples/m^2 by Eq. 2 (p = 3.14 cm), the same by back-projection
for a pinhole, and p' = p + 2e = 11.60 cm (74.3 samples/m^2) with e = 4.23 cm (the paper,
starting from its measured p = 3.18 cm: 11.64 cm, 74 samples/m^2).
""")
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
