#!/usr/bin/env python3
"""All-in-focus merge study: sobel (the paper's) against improved and robust, with ground truth.

For each seeded simulated scene (a height-field ground with a slope and a 1 m step, a chart
texture and a target, under a voxel volume or a forest) and each number of slices N, the tool
renders a focal stack from the truth camera between z = -1.5 m and z = 2.5 m (the ground's range)
and merges it with every method. It reports, per method:

- PSNR and SSIM of the all-in-focus image against the ground truth (the occluder-free ground
  seen by the truth camera) and against the "oracle" (the integral rendered at the true
  per-pixel depth, the best any depth-based merge can do with plain averaging);
- banding: the fraction of horizontally neighbouring pixel pairs on smooth ground (true depths
  differ by less than 2 cm) whose merged depths differ by more than 5 cm;
- depth RMSE on smooth ground (pixels whose true depth is within 2 cm of all 4 neighbours);
- merge time.

It also checks robust against the clean ground (the same scene without occluders, integrated on
the true depth), split by the truth's per-pixel fraction of blocked rays (below / at least
60 %): the robust mean alone against the plain mean, both on the true depth, and the whole
robust merge against the improved one.

Usage: python3 tools/merge_study.py [--size 256] [--seeds 5] [--slices 6,12,24]
                                    [--write-docs]   (docs/merge-study.md and .png)
The tests (tests/python/test_merge.py) run the same code on smaller sizes.
"""

from __future__ import annotations

import argparse
import copy
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import aos

METHODS = ("sobel", "improved", "robust")
FIRST_HEIGHT, LAST_HEIGHT = -1.5, 2.5  # the stack spans the ground's heights
TRUTH_FOV_DEG = 40.0


def study_scene(seed: int, size: int, occluders: str, density: float = 0.5) -> dict[str, Any]:
    """A seeded scene: sloped ground with a 1 m step, chart texture, a target, occluders."""
    scene: dict[str, Any] = {
        "seed": seed,
        "ground": {
            "slope": [0.05, 0.0],
            "steps": [{"point": [4.0, 0.0], "direction": [1.0, 0.0], "height": 1.0}],
            "cell_size": 0.1,
            "extent": [-40.0, -40.0, 40.0, 40.0],
            "texture": {"type": "chart", "patch": 4.0, "squares": [2.0, 1.0, 0.5]},
        },
        "targets": [{"center": [-2.0, 0.0], "size": [2.4, 0.8]}],
        "camera": {"width": size, "height": size, "fov_deg": 60.0, "samples_per_pixel": 2},
        "sampling": {"altitude": 25.0, "aperture": {"shape": "square", "diameter": 30.0},
                     "grid": 7},
        "truth": {"fov_deg": TRUTH_FOV_DEG, "width": size, "height": size},
    }
    if occluders == "voxels":
        scene["occluders"] = {"voxels": {"center": [0.0, 0.0, 8.0], "size": [12.0, 12.0, 6.0],
                                         "grid": [120, 120, 60], "density": density}}
    elif occluders == "trees":
        scene["occluders"] = {"trees": {"area": [-15, -15, 15, 15], "per_hectare": 400,
                                        "height": [6, 12], "leaves_per_tree": 800}}
        scene["sampling"]["altitude"] = 30.0
    elif occluders != "none":
        raise ValueError(f"occluders: {occluders!r}")
    return scene


def camera_options(truth: Any, size: int) -> dict[str, Any]:
    return {"cam_from_world": truth.cam_from_world, "fov_deg": TRUTH_FOV_DEG, "width": size,
            "height": size}


def smooth_ground(true_depth: np.ndarray) -> np.ndarray:
    """Pixels whose true depth differs from each of their 4 neighbours by less than 2 cm: the
    slope, not the step (nor the image border)."""
    smooth = np.zeros(true_depth.shape, dtype=bool)
    smooth[1:-1, 1:-1] = True
    for axis in (0, 1):
        step = np.abs(np.diff(true_depth, axis=axis)) >= 0.02
        if axis == 0:
            smooth[1:, :] &= ~step
            smooth[:-1, :] &= ~step
        else:
            smooth[:, 1:] &= ~step
            smooth[:, :-1] &= ~step
    return smooth


def banding(depth: np.ndarray, true_depth: np.ndarray) -> float:
    """Fraction of horizontal neighbour pairs on smooth ground (true depths within 2 cm: the
    slope, not the step) whose merged depths differ by more than 5 cm."""
    smooth = np.abs(np.diff(true_depth, axis=1)) < 0.02
    steps = np.abs(np.diff(depth, axis=1)) > 0.05
    return float(np.mean(steps[smooth]))


def evaluate(seed: int, occluders: str, size: int, slice_counts: list[int]) -> list[dict[str, Any]]:
    """One scene, every N and method: a row per (N, method)."""
    simulation = aos.simulate(study_scene(seed, size, occluders))
    truth, light_field = simulation.truth, simulation.light_field
    camera = camera_options(truth, size)
    true_depth = np.asarray(truth.depth).astype(np.float32)
    ground = np.asarray(truth.ground).astype(np.float32)
    smooth = smooth_ground(true_depth)
    oracle = np.asarray(aos.render_integral_on_depth(light_field, true_depth, **camera)
                        .integral.image)
    rows = []
    for slices in slice_counts:
        stack = aos.render_focal_stack(light_field, first_plane=aos.Plane.at_height(FIRST_HEIGHT),
                                       last_plane=aos.Plane.at_height(LAST_HEIGHT),
                                       slices=slices, variance=True, **camera)
        for method in METHODS:
            start = time.perf_counter()
            merged = aos.merge_focal_stack(stack, method=method, light_field=light_field)
            seconds = time.perf_counter() - start
            image, depth = np.asarray(merged.image), np.asarray(merged.depth)
            versus_truth = aos.compare_images(image, ground, data_range=255.0)
            versus_oracle = aos.compare_images(image, oracle, data_range=255.0)
            rows.append({
                "occluders": occluders, "seed": seed, "slices": slices, "method": method,
                "psnr": versus_truth.psnr_db, "ssim": versus_truth.ssim,
                "psnr_oracle": versus_oracle.psnr_db, "ssim_oracle": versus_oracle.ssim,
                "banding": banding(depth, true_depth),
                "depth_rmse": float(np.sqrt(np.mean((depth[smooth] - true_depth[smooth]) ** 2))),
                "seconds": seconds, "image": image,
            })
    return rows


def robust_bins(seed: int, size: int, density: float, slices: int = 24) -> dict[str, float]:
    """RMSE against the clean ground (the same scene without occluders, integrated on the true
    depth), split by the truth's fraction of blocked rays (< 0.6, >= 0.6), of: the plain and the
    robust mean on the true depth (the estimator alone), and the improved and robust merges of a
    stack (the whole method)."""
    scene = study_scene(seed, size, "voxels", density)
    simulation = aos.simulate(scene)
    clean_scene = copy.deepcopy(scene)
    del clean_scene["occluders"]
    clean_scene["truth"]["blocked_fraction"] = False
    clean_field = aos.simulate(clean_scene).light_field
    truth = simulation.truth
    camera = camera_options(truth, size)
    true_depth = np.asarray(truth.depth).astype(np.float32)
    blocked = np.asarray(truth.blocked_fraction)
    clean = np.asarray(aos.render_integral_on_depth(clean_field, true_depth, **camera).integral.image)
    plain = np.asarray(aos.render_integral_on_depth(simulation.light_field, true_depth, **camera)
                       .integral.image)
    robust = np.asarray(aos.render_integral_on_depth(simulation.light_field, true_depth,
                                                     robust=True, **camera).integral.image)
    stack = aos.render_focal_stack(simulation.light_field,
                                   first_plane=aos.Plane.at_height(FIRST_HEIGHT),
                                   last_plane=aos.Plane.at_height(LAST_HEIGHT), slices=slices,
                                   variance=True, **camera)
    merged = {method: np.asarray(aos.merge_focal_stack(stack, method=method,
                                                       light_field=simulation.light_field).image)
              for method in ("improved", "robust")}
    out: dict[str, float] = {}
    for name, mask in (("below", blocked < 0.6), ("above", blocked >= 0.6)):
        out[f"{name}_pixels"] = float(np.mean(mask))
        for label, image in (("plain", plain), ("robust", robust),
                             ("improved_merge", merged["improved"]),
                             ("robust_merge", merged["robust"])):
            out[f"{name}_{label}"] = (float(np.sqrt(np.mean((image[mask] - clean[mask]) ** 2)))
                                      if mask.any() else float("nan"))
    return out


def summary_table(rows: list[dict[str, Any]]) -> str:
    lines = ["| occluders | N | method | PSNR dB | SSIM | PSNR vs oracle | SSIM vs oracle | "
             "banding | depth RMSE m (smooth ground) | merge ms |", "|---|---|---|---|---|---|---|---|---|---|"]
    keys = sorted({(r["occluders"], r["slices"]) for r in rows}, key=lambda k: (k[0], k[1]))
    for occluders, slices in keys:
        for method in METHODS:
            sel = [r for r in rows if r["occluders"] == occluders and r["slices"] == slices
                   and r["method"] == method]
            mean = lambda key: statistics.mean(r[key] for r in sel)  # noqa: E731
            lines.append(f"| {occluders} | {slices} | {method} | {mean('psnr'):.2f} | "
                         f"{mean('ssim'):.3f} | {mean('psnr_oracle'):.2f} | "
                         f"{mean('ssim_oracle'):.3f} | {mean('banding'):.3f} | "
                         f"{mean('depth_rmse'):.3f} | {1e3 * statistics.median(r['seconds'] for r in sel):.0f} |")
    return "\n".join(lines)


def per_seed_table(rows: list[dict[str, Any]]) -> str:
    lines = ["| occluders | N | seed | PSNR sobel / improved / robust | "
             "SSIM sobel / improved / robust | banding sobel / improved / robust |",
             "|---|---|---|---|---|---|"]
    keys = sorted({(r["occluders"], r["slices"], r["seed"]) for r in rows})
    for occluders, slices, seed in keys:
        by = {r["method"]: r for r in rows
              if (r["occluders"], r["slices"], r["seed"]) == (occluders, slices, seed)}
        fmt = lambda key, f: " / ".join(format(by[m][key], f) for m in METHODS)  # noqa: E731
        lines.append(f"| {occluders} | {slices} | {seed} | {fmt('psnr', '.2f')} | "
                     f"{fmt('ssim', '.3f')} | {fmt('banding', '.3f')} |")
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--slices", default="6,12,24")
    parser.add_argument("--write-docs", action="store_true")
    args = parser.parse_args()
    slice_counts = [int(n) for n in args.slices.split(",")]
    rows: list[dict[str, Any]] = []
    start = time.perf_counter()
    for occluders in ("voxels", "trees"):
        for seed in range(1, args.seeds + 1):
            print(f"[{time.perf_counter() - start:6.1f} s] {occluders}, seed {seed}", flush=True)
            rows += evaluate(seed, occluders, args.size, slice_counts)
    summary, seeds = summary_table(rows), per_seed_table(rows)
    wins = all(
        by["improved"]["psnr"] > by["sobel"]["psnr"] and by["improved"]["ssim"] > by["sobel"]["ssim"]
        and by["improved"]["psnr_oracle"] > by["sobel"]["psnr_oracle"]
        and by["improved"]["ssim_oracle"] > by["sobel"]["ssim_oracle"]
        for by in ({r["method"]: r for r in rows if (r["occluders"], r["slices"], r["seed"]) == key}
                   for key in {(r["occluders"], r["slices"], r["seed"]) for r in rows}))
    print(summary)
    print(f"improved beats sobel on PSNR and SSIM (truth and oracle) in every case: {wins}")
    bins = []
    for density in (0.3, 0.5, 0.7):
        for seed in range(1, min(args.seeds, 3) + 1):
            b = robust_bins(seed, args.size, density)
            bins.append((density, seed, b))
            print(f"density {density:.1f} seed {seed}: blocked < 60 % ({b['below_pixels']:.0%} of "
                  f"pixels) RMSE plain {b['below_plain']:.1f} robust {b['below_robust']:.1f}, "
                  f"merges improved {b['below_improved_merge']:.1f} robust "
                  f"{b['below_robust_merge']:.1f}; >= 60 % plain {b['above_plain']:.1f} robust "
                  f"{b['above_robust']:.1f}, merges improved {b['above_improved_merge']:.1f} robust "
                  f"{b['above_robust_merge']:.1f}")
    if args.write_docs:
        write_docs(args, rows, summary, seeds, wins, bins)
    return 0


def write_docs(args: argparse.Namespace, rows: list[dict[str, Any]], summary: str, seeds: str,
               wins: bool, bins: list[tuple[float, int, dict[str, float]]]) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    root = Path(__file__).resolve().parent.parent / "docs"
    # Figure: one scene (voxels, seed 1, the largest N).
    n = max(int(s) for s in args.slices.split(","))
    simulation = aos.simulate(study_scene(1, args.size, "voxels"))
    single = np.asarray(aos.render_integral(simulation.light_field, pose_view=len(
        simulation.light_field.views) // 2, width=args.size, height=args.size,
        fov_deg=TRUTH_FOV_DEG, aperture_radius=0.0, focal_surface=aos.Plane.at_height(0.0)).image)
    panels = [("single view", single)]
    for method in METHODS:
        row = next(r for r in rows if r["occluders"] == "voxels" and r["seed"] == 1
                   and r["slices"] == n and r["method"] == method)
        panels.append((f"{method}\nPSNR {row['psnr']:.1f} dB, SSIM {row['ssim']:.2f}", row["image"]))
    panels.append(("ground truth", np.asarray(simulation.truth.ground)))
    figure, axes = plt.subplots(1, len(panels), figsize=(3 * len(panels), 3.4))
    for axis, (title, image) in zip(axes, panels):
        axis.imshow(image, cmap="gray", vmin=0, vmax=255)
        axis.set_title(title, fontsize=9)
        axis.axis("off")
    figure.tight_layout()
    figure.savefig(root / "merge-study.png", dpi=110)
    bin_lines = ["| density | seed | pixels < 60 % blocked | mean on the true depth, plain / "
                 "robust (< 60 %) | (>= 60 %) | merge, improved / robust (< 60 %) | (>= 60 %) |",
                 "|---|---|---|---|---|---|---|"]
    for density, seed, b in bins:
        bin_lines.append(f"| {density:.1f} | {seed} | {b['below_pixels']:.0%} | "
                         f"{b['below_plain']:.1f} / {b['below_robust']:.1f} | "
                         f"{b['above_plain']:.1f} / {b['above_robust']:.1f} | "
                         f"{b['below_improved_merge']:.1f} / {b['below_robust_merge']:.1f} | "
                         f"{b['above_improved_merge']:.1f} / {b['above_robust_merge']:.1f} |")
    text = f"""# All-in-focus merging: sobel (the paper's) against improved and robust

Written by `python3 tools/merge_study.py --size {args.size} --seeds {args.seeds} --slices {args.slices} --write-docs`
(the figures below come from that run; rerun it to reproduce). Methods: `cpp/aos/render/merge.h`.

Scenes: seeded simulations (`study_scene` in the tool) with a sloped ground (5 %) and a 1 m step,
a chart texture and a 2.4 x 0.8 m target, 7 x 7 views of {args.size}^2 over a 30 m aperture,
under a 50 %-density voxel volume (12 x 12 x 6 m) or a forest (400 trees/ha). The stack is
rendered from the truth camera ({TRUTH_FOV_DEG:.0f} degrees, {args.size}^2) between z = {FIRST_HEIGHT} m and
z = {LAST_HEIGHT} m. Truth = the occluder-free ground; oracle = the integral rendered at the true
per-pixel depth. Banding = fraction of neighbouring pixel pairs on smooth ground whose merged
depths differ by more than 5 cm.

![single view, sobel, improved, robust, ground truth](merge-study.png)

## Means over {args.seeds} seeds

{summary}

Improved beats sobel on PSNR and SSIM against the truth and against the oracle in every
(occluders, N, seed) case: **{wins}**.

## Robust against the clean ground, by fraction of blocked rays

RMSE in grey levels against the integral of the same scene without occluders (on the true
depth): the robust mean alone (on the true depth, against the plain mean), and the whole robust
method against the improved one (merges of a 24-slice stack).

{chr(10).join(bin_lines)}

## Every seed

{seeds}
"""
    (root / "merge-study.md").write_text(text)
    print(f"wrote {root / 'merge-study.md'} and merge-study.png")


if __name__ == "__main__":
    sys.exit(main())
