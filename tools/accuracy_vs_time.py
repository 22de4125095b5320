#!/usr/bin/env python3
"""What accuracy costs in time: sweeps every knob of aos that trades quality for time.

On seeded simulated scenes with ground truth (aos.simulate), for each setting of each knob, the
tool measures the time the knob costs (median of --repeats runs, all in this run) and the
quality of the result (PSNR and SSIM against the simulator's ground truth, aos.compare_images),
then prints a line per setting as it completes. Knobs (what aos offers; see KNOBS_NOT_OFFERED
for what it does not):

  views       number of views (N x N grid) and aperture: the simulated aperture's diameter and
              render_integral's aperture_radius
  resolution  output resolution of the integral image
  bit-depth   storage type of the views (8-bit, 16-bit, float32: camera.bit_depth)
  merge       all-in-focus: number of focal slices x merge method (sobel, improved, robust)
  lens        fisheye and omnidirectional views: direct sampling through the lens model against
              rectify-first (make_rectifier, then a pinhole render)
  simulator   the simulator's own knobs: samples_per_pixel and view resolution (simulate time
              and the quality of the integral made from its views)

With --write-docs it writes docs/accuracy-vs-time.md (tables, reading guide) and one PNG per
knob (quality against time, the Pareto front highlighted) into --docs-dir (default: docs/).

    python3 tools/accuracy_vs_time.py --write-docs      # full run, about 6 min on 2 cores
    python3 tools/accuracy_vs_time.py --quick           # smoke test: tiny sizes, 1 repeat
    python3 tools/accuracy_vs_time.py --knobs views,lens  # a subset (development)

Needs matplotlib for --write-docs (pip install '.[bench]').
"""

from __future__ import annotations

import argparse
import copy
import datetime
import functools
import json
import math
import os
import pathlib
import platform
import statistics
import sys
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Optional

import numpy as np

import aos

ROOT = pathlib.Path(__file__).resolve().parent.parent
KNOBS = ("views", "resolution", "bit-depth", "merge", "lens", "simulator")
PAGE = "accuracy-vs-time.md"
MEMORY = "views' memory (MiB)"

# The occlusion scene (Appendix B of the AOS paper, as tools/appendix_b.py): views at 20 m, an
# 80-degree field of view, a square 30 m aperture, a 2.4 x 0.8 m target on a chart-textured
# ground, a 10 x 10 x 10 m random voxel volume (z from 1 to 11 m) over the target.
ALTITUDE = 20.0
VIEW_FOV_DEG = 80.0
BOX = 10.0
# The output camera is the truth camera: at the aperture centre, nadir, seeing the volume's
# footprint plus 1 m on each side.
OUT_FOV_DEG = 2.0 * math.degrees(math.atan((BOX / 2 + 1.0) / ALTITUDE))
# Reference truths are simulated with 8 x 8 rays a pixel (the simulator's most), in float32
# (see reference_truth): against 6 x 6 rays their RMSE is about 0.009 (on a [0, 1] scale), far
# below the errors measured here, whereas 2 x 2 rays would be about 0.025 off.
TRUTH_SPP = 8
# The merge scene (tools/merge_study.py): the stack spans the ground's heights.
MERGE_FIRST, MERGE_LAST, MERGE_FOV_DEG = -1.5, 2.5, 40.0

KNOBS_NOT_OFFERED = [
    ("sampling of the views (nearest, bicubic, ...)",
     "render_integral samples bilinearly only (IntegralOptions has no sampling option); there "
     "is nothing cheaper or higher-order to trade against it, so no table. Every figure below "
     "is bilinear."),
    ("accumulation precision",
     "the renderer always accumulates in double precision (IntegralOptions has no precision "
     "option). The storage precision of the views is the knob offered instead: see the "
     "bit-depth table."),
    ("rectified frames' field of view and size",
     "offered by RectifyOptions; swept only as the rectified width (full and half) at a "
     "100-degree field of view, in the lens table."),
]


@dataclass
class Config:
    """Sizes of one run; --quick shrinks everything."""

    size: int = 512            # views of the occlusion scene, pixels
    out: int = 512             # output (truth camera) of the occlusion scene, pixels
    voxel_grid: int = 100      # voxel cells per axis
    spp: int = 2               # rays per pixel side of the views
    grids: tuple[int, ...] = (3, 5, 9, 15, 27)
    base_grid: int = 9
    big_grid: int = 27
    diameters: tuple[float, ...] = (10.0, 20.0, 30.0, 40.0)
    radii: tuple[float, ...] = (0.0, 2.5, 5.0, 10.0, 15.0, math.inf)
    resolutions: tuple[int, ...] = (128, 256, 512, 1024)
    merge_size: int = 256
    merge_grid: int = 7
    slices: tuple[int, ...] = (4, 8, 16, 32, 64)
    lens_size: int = 1024
    lens_out: int = 512
    sim_grid: int = 5
    sim_settings: tuple[tuple[int, int], ...] = ((256, 1), (256, 2), (512, 1), (512, 2),
                                                 (512, 4), (1024, 1))


QUICK = Config(size=64, out=64, voxel_grid=25, grids=(3, 9, 15), big_grid=15,
               resolutions=(32, 64, 128),
               radii=(0.0, 5.0, math.inf), diameters=(15.0, 30.0), merge_size=64,
               slices=(4, 8), lens_size=128, lens_out=64,
               sim_settings=((32, 1), (64, 1), (64, 2)))


@dataclass
class Row:
    """One setting of one knob: its time and its quality."""

    knob: str
    group: str                 # a series: one colour in the plot, one Pareto front by default
    label: str                 # short name of the setting
    seconds: float             # the time the knob costs (median of the repeats)
    columns: dict[str, str]    # the setting and extra measurements, as printed in the table
    psnr: float = math.nan
    ssim: float = math.nan
    pareto_psnr: bool = False
    pareto_ssim: bool = False
    reference: bool = False    # not a setting one can choose (e.g. needs the truth): off the front
    extra: dict[str, float] = field(default_factory=dict)
    front: str = ""            # rows with the same front share a Pareto front ("" = the group)

    @property
    def front_key(self) -> str:
        return self.front or self.group


@dataclass
class Knob:
    name: str
    title: str
    setup: str                 # markdown: scene, truth, mask, what is timed
    time_label: str            # what the time column measures
    rows: list[Row]
    notes: list[str] = field(default_factory=list)


class Run:
    """Shared state of a run: configuration, repeats, threads, the clock and the log."""

    def __init__(self, config: Config, repeats: int, threads: int, seed: int) -> None:
        self.config, self.repeats, self.threads, self.seed = config, repeats, threads, seed
        self.start = time.perf_counter()
        self._cache: dict[str, aos.SimulationResult] = {}

    def log(self, text: str) -> None:
        print(f"[{time.perf_counter() - self.start:7.1f} s] {text}", flush=True)

    def timed(self, call: Callable[[], Any], repeats: Optional[int] = None) -> tuple[float, Any]:
        """Median wall time of `repeats` calls (default: the run's) and the last result."""
        times, result = [], None
        for _ in range(repeats or self.repeats):
            start = time.perf_counter()
            result = call()
            times.append(time.perf_counter() - start)
        return statistics.median(times), result

    def simulate(self, scene: dict[str, Any], keep: bool = False) -> aos.SimulationResult:
        """Simulates `scene`; with keep, the result is kept and reused for the same scene (the
        small base scenes that several knobs share)."""
        key = json.dumps(scene, sort_keys=True)
        if key in self._cache:
            return self._cache[key]
        result = aos.simulate(scene, num_threads=self.threads)
        if keep:
            self._cache[key] = result
        return result


# ---------------------------------------------------------------------------------------------
# Scenes, truths, masks, scores


def occlusion_scene(config: Config, seed: int, grid: int, diameter: float = 30.0,
                    density: float = 0.5, size: Optional[int] = None, spp: Optional[int] = None,
                    bit_depth: int = 8) -> dict[str, Any]:
    """The Appendix B scene (docs/scenes.md schema). The chart is scaled with the run's view size
    (config.size), not with `size`, so the view-resolution sweep sees the same ground."""
    scale = 512.0 / config.size
    scene: dict[str, Any] = {
        "seed": seed,
        "ground": {"texture": {"type": "chart", "patch": 4.0 * scale,
                               "squares": [1.0 * scale, 0.5 * scale, 0.25 * scale]}},
        "targets": [{"center": [0.0, 0.0], "size": [2.4, 0.8]}],
        "camera": {"width": size or config.size, "height": size or config.size,
                   "fov_deg": VIEW_FOV_DEG, "samples_per_pixel": spp or config.spp,
                   "bit_depth": bit_depth},
        "sampling": {"altitude": ALTITUDE, "aperture": {"shape": "square", "diameter": diameter},
                     "grid": grid},
        "truth": {"fov_deg": OUT_FOV_DEG, "width": config.out, "height": config.out,
                  "blocked_fraction": False},
    }
    if density > 0.0:
        scene["occluders"] = {"voxels": {"center": [0.0, 0.0, 1.0 + BOX / 2], "size": [BOX] * 3,
                                         "grid": config.voxel_grid, "density": density}}
    return scene


def merge_scene(config: Config, seed: int) -> dict[str, Any]:
    """The merge study's voxel scene (tools/merge_study.py): sloped ground with a 1 m step, chart
    texture, a target, a 50 % voxel volume 12 x 12 x 6 m, 7 x 7 views at 25 m over 30 m."""
    size = config.merge_size
    return {
        "seed": seed,
        "ground": {"slope": [0.05, 0.0],
                   "steps": [{"point": [4.0, 0.0], "direction": [1.0, 0.0], "height": 1.0}],
                   "cell_size": 0.1, "extent": [-40.0, -40.0, 40.0, 40.0],
                   "texture": {"type": "chart", "patch": 4.0, "squares": [2.0, 1.0, 0.5]}},
        "targets": [{"center": [-2.0, 0.0], "size": [2.4, 0.8]}],
        "camera": {"width": size, "height": size, "fov_deg": 60.0,
                   "samples_per_pixel": config.spp},
        "sampling": {"altitude": 25.0, "aperture": {"shape": "square", "diameter": 30.0},
                     "grid": config.merge_grid},
        "truth": {"fov_deg": MERGE_FOV_DEG, "width": size, "height": size,
                  "blocked_fraction": False},
        "occluders": {"voxels": {"center": [0.0, 0.0, 8.0], "size": [12.0, 12.0, 6.0],
                                 "grid": [120, 120, 60], "density": 0.5}},
    }


LENSES = {
    "fisheye": {"lens": "fisheye", "fov_deg": 180.0, "distortion": [0.01, -0.002]},
    "omnidir": {"lens": "omnidir", "fov_deg": 200.0, "xi": 1.2, "distortion": [-0.05, 0.01]},
}


def lens_scene(config: Config, seed: int, lens: dict[str, Any]) -> dict[str, Any]:
    """tools/bench_lens.py's scene: 5 x 5 nadir views from 20 m, 4 m apart, of a ground of
    smooth value noise (0.4 m lattice, no occluders), float32, through `lens`."""
    return {"seed": seed, "ground": {"texture": {"type": "noise", "square": 0.4}},
            "camera": {"width": config.lens_size, "height": config.lens_size, "bit_depth": 32,
                       "samples_per_pixel": config.spp, **lens},
            "sampling": {"altitude": ALTITUDE, "grid": 5,
                         "aperture": {"shape": "square", "diameter": 16.0}},
            "truth": {"fov_deg": 60.0, "width": config.lens_out, "height": config.lens_out,
                      "blocked_fraction": False}}


@dataclass
class Truth:
    ground: np.ndarray         # float32 in [0, 1]
    depth: np.ndarray          # float32, metres along the optical axis
    truth: aos.GroundTruth


def reference_truth(run: Run, scene: dict[str, Any], width: int, height: int) -> Truth:
    """The occluder-free ground seen by the scene's truth camera at width x height, simulated
    with TRUTH_SPP x TRUTH_SPP rays a pixel in float32: the same truth whatever the views' own
    samples_per_pixel, bit depth or lens (the simulator writes its truth in the views' type and
    sampling). Only the truth matters here, so one tiny pinhole view is simulated."""
    ref = copy.deepcopy(scene)
    ref.pop("occluders", None)
    ref["camera"] = {"width": 16, "height": 16, "fov_deg": VIEW_FOV_DEG, "bit_depth": 32,
                     "samples_per_pixel": TRUTH_SPP}
    ref["sampling"]["grid"] = 1  # the truth camera sits at (sampling.center, altitude) all the same
    ref["truth"] = dict(scene["truth"], width=width, height=height, blocked_fraction=False)
    truth = run.simulate(ref).truth
    return Truth(np.asarray(truth.ground, np.float32), np.asarray(truth.depth, np.float32), truth)


def unit_range(image: np.ndarray, bit_depth: int) -> np.ndarray:
    """An integral image of views of `bit_depth` scaled to [0, 1] like the truth."""
    scale = {8: 255.0, 16: 65535.0, 32: 1.0}[bit_depth]
    return np.asarray(image, np.float32) / np.float32(scale)


def footprint_mask(truth: aos.GroundTruth) -> np.ndarray:
    """Pixels of the nadir truth camera whose ground point lies under the voxel volume
    (|x|, |y| <= BOX / 2), as in tools/appendix_b.py."""
    camera = truth.camera
    x0, y0, z0 = truth.cam_from_world.center
    depth = z0 - truth.ground_height_at_center
    half = BOX / 2
    u0 = camera.cx + camera.fx * (-half - x0) / depth
    u1 = camera.cx + camera.fx * (half - x0) / depth
    v0 = camera.cy - camera.fy * (half - y0) / depth
    v1 = camera.cy - camera.fy * (-half - y0) / depth
    mask = np.zeros((camera.height, camera.width), bool)
    mask[max(int(math.floor(v0)), 0):max(int(math.ceil(v1)), 0),
         max(int(math.floor(u0)), 0):max(int(math.ceil(u1)), 0)] = True
    return mask


def score(row: Row, image: np.ndarray, truth: np.ndarray, mask: np.ndarray) -> None:
    quality = aos.compare_images(image, truth, mask.astype(np.uint8), data_range=1.0)
    row.psnr, row.ssim = quality.psnr_db, quality.ssim


def smooth_ground(true_depth: np.ndarray) -> np.ndarray:
    """Pixels whose true depth differs from each 4-neighbour's by less than 2 cm (the slope, not
    the step, nor the image border), as in tools/merge_study.py."""
    smooth = np.zeros(true_depth.shape, dtype=bool)
    smooth[1:-1, 1:-1] = True
    vertical = np.abs(np.diff(true_depth, axis=0)) >= 0.02
    horizontal = np.abs(np.diff(true_depth, axis=1)) >= 0.02
    smooth[1:, :] &= ~vertical
    smooth[:-1, :] &= ~vertical
    smooth[:, 1:] &= ~horizontal
    smooth[:, :-1] &= ~horizontal
    return smooth


def out_options(truth: aos.GroundTruth, width: int, **kwargs: Any) -> aos.IntegralOptions:
    """The output camera = the truth camera (pose, field of view), width x width pixels,
    focused on the ground under it."""
    return aos.IntegralOptions(cam_from_world=truth.cam_from_world,
                               fov_deg=truth.camera.fov_x_deg(), width=width, height=width,
                               focal_surface=aos.Plane.at_height(truth.ground_height_at_center),
                               **kwargs)


def ms(seconds: float) -> str:
    return f"{1e3 * seconds:.1f}" if seconds < 0.1 else f"{1e3 * seconds:.0f}"


def mib(n: int) -> str:
    return f"{n / 2**20:.1f}"


def radius_text(radius: float) -> str:
    return "inf" if math.isinf(radius) else ("0 (pinhole)" if radius == 0 else f"{radius:g} m")


# ---------------------------------------------------------------------------------------------
# Knobs


def knob_views(run: Run) -> Knob:
    """Number of views, simulated aperture diameter, render aperture_radius."""
    c = run.config
    rows: list[Row] = []
    renders: list[tuple[Row, np.ndarray, np.ndarray]] = []
    base = occlusion_scene(c, run.seed, c.base_grid)
    ref = reference_truth(run, base, c.out, c.out)

    def measure(group: str, label: str, light_field: aos.LightField,
                options: aos.IntegralOptions, columns: dict[str, str]) -> None:
        seconds, result = run.timed(lambda: aos.render_integral(light_field, options))
        row = Row("views", group, label, seconds, dict(columns), front="one scene")
        row.columns["views used"] = str(result.views_used)
        row.columns["samples (M)"] = f"{result.samples / 1e6:.1f}"
        rows.append(row)
        renders.append((row, unit_range(result.image, 8), np.asarray(result.count) > 0))

    for grid in c.grids:
        sim = run.simulate(occlusion_scene(c, run.seed, grid), keep=grid == c.base_grid)
        run.log(f"views: simulated {grid}x{grid} views "
                f"({sim.stats['seconds_views']:.1f} s)")
        lf, truth = sim.light_field, sim.truth
        measure("grid, 30 m aperture", f"{grid}x{grid}", lf, out_options(truth, c.out),
                {"views": f"{grid}x{grid}", "aperture (simulated)": "30 m",
                 "aperture_radius": "inf"})
        run.log(f"views: {grid}x{grid}, 30 m: render {ms(rows[-1].seconds)} ms")
        if grid in (c.base_grid, c.big_grid):
            for radius in c.radii:
                if math.isinf(radius):
                    continue  # the row above
                measure(f"aperture_radius, {grid}x{grid}",
                        f"{grid}x{grid} r={radius_text(radius)}", lf,
                        out_options(truth, c.out, aperture_radius=radius),
                        {"views": f"{grid}x{grid}", "aperture (simulated)": "30 m",
                         "aperture_radius": radius_text(radius)})
                run.log(f"views: {grid}x{grid}, aperture_radius {radius_text(radius)}: "
                        f"render {ms(rows[-1].seconds)} ms")
        del sim, lf
    for diameter in c.diameters:
        if diameter == 30.0:
            continue  # the grid row
        sim = run.simulate(occlusion_scene(c, run.seed, c.base_grid, diameter))
        measure(f"simulated aperture, {c.base_grid}x{c.base_grid}",
                f"{c.base_grid}x{c.base_grid} {diameter:g} m", sim.light_field,
                out_options(sim.truth, c.out),
                {"views": f"{c.base_grid}x{c.base_grid}",
                 "aperture (simulated)": f"{diameter:g} m", "aperture_radius": "inf"})
        run.log(f"views: {c.base_grid}x{c.base_grid}, {diameter:g} m aperture: "
                f"render {ms(rows[-1].seconds)} ms")
        del sim
    mask = footprint_mask(ref.truth)
    for _, _, covered in renders:
        mask &= covered
    for row, image, _ in renders:
        score(row, image, ref.ground, mask)
    setup = (
        f"Scene: Appendix B of the paper (`occlusion_scene` in the tool; seed {run.seed}): "
        f"{c.size} x {c.size} grey 8-bit views ({c.spp} x {c.spp} rays a pixel, "
        f"{VIEW_FOV_DEG:.0f}-degree field of view) from {ALTITUDE:.0f} m over a square aperture "
        f"(30 m unless stated), a chart-textured ground with a 2.4 x 0.8 m target, under a "
        f"10 x 10 x 10 m voxel volume ({c.voxel_grid}^3 cells) at 50 % density (half the nadir "
        f"rays through it are blocked). Output: the truth camera (nadir at the aperture centre, "
        f"{OUT_FOV_DEG:.1f} degrees: the volume's footprint plus 1 m), {c.out} x {c.out}, "
        f"focused on the ground.\n\n"
        f"Truth: the occluder-free ground seen by that camera ({TRUTH_SPP} x {TRUTH_SPP} rays a "
        f"pixel, float). Mask: the pixels under the voxel volume (|x|, |y| <= 5 m) that every "
        f"setting of this table covers ({int(mask.sum())} pixels). PSNR with L = 1 (values "
        f"scaled to [0, 1]). Time: `render_integral` alone, median of {run.repeats}; the "
        f"simulation is not timed here (see the simulator table).")
    notes = [
        "`aperture_radius` is measured on the virtual camera's lens plane, here the views' "
        "plane: a view contributes when it lies within that distance of the aperture centre "
        "(0: each pixel takes the one nearest view). The simulated aperture is the square "
        "the views are spread over."]
    return Knob("views", "Number of views and aperture", setup, "render (ms)", rows, notes)


def knob_resolution(run: Run) -> Knob:
    c = run.config
    rows: list[Row] = []
    finest = max(c.resolutions)
    for density, group in ((0.5, "50 % voxels"), (0.0, "no occluders")):
        scene = occlusion_scene(c, run.seed, c.base_grid, density=density)
        lf = run.simulate(scene, keep=True).light_field
        fine = reference_truth(run, scene, finest, finest)
        mask = footprint_mask(fine.truth)
        renders = []
        for width in c.resolutions:
            own = reference_truth(run, scene, width, width)
            options = out_options(own.truth, width)
            seconds, result = run.timed(lambda: aos.render_integral(lf, options))
            row = Row("resolution", group, f"{width}", seconds,
                      {"scene": group, "output": f"{width} x {width}",
                       "samples (M)": f"{result.samples / 1e6:.1f}"})
            image, covered = unit_range(result.image, 8), np.asarray(result.count) > 0
            # Against a truth of its own size, over its own footprint and coverage.
            quality = aos.compare_images(image, own.ground,
                                         (footprint_mask(own.truth) & covered).astype(np.uint8),
                                         data_range=1.0)
            row.columns["PSNR / SSIM vs a truth of its own size"] = \
                f"{quality.psnr_db:.2f} / {quality.ssim:.4f}"
            # Enlarged to the finest size by pixel replication (output pixels are aligned
            # blocks of the finest grid: same camera, integer size ratios).
            factor = finest // width
            image = np.kron(image, np.ones((factor, factor), np.float32))
            mask &= np.kron(covered, np.ones((factor, factor), bool))
            rows.append(row)
            renders.append((row, image))
            run.log(f"resolution: {group}, {width} x {width}: render {ms(seconds)} ms")
        for row, image in renders:
            score(row, image, fine.ground, mask)
        del lf
    setup = (
        f"Scene: the views table's, {c.base_grid} x {c.base_grid} views over 30 m, with the "
        f"voxel volume (50 %) and without occluders. Output: the truth camera (same pose and "
        f"field of view) at each size.\n\n"
        f"Truth: the occluder-free ground at the finest size, {finest} x {finest} "
        f"({TRUTH_SPP} x {TRUTH_SPP} rays a pixel, float); each output is enlarged to that size "
        f"by pixel replication (its pixels are aligned blocks of the finest grid), so PSNR and "
        f"SSIM count the detail a coarse output loses. Mask: pixels under the voxel volume that "
        f"every size covers. The column \"vs a truth of its own size\" compares each output "
        f"instead with the truth simulated at its size (how faithful it is at that size). Time: "
        f"`render_integral`, median of {run.repeats}.")
    # Output width whose ground pixel equals the views' at nadir (same altitude, nadir).
    matched = (c.size * math.tan(math.radians(OUT_FOV_DEG / 2))
               / math.tan(math.radians(VIEW_FOV_DEG / 2)))
    notes = [f"The views are {c.size} x {c.size}: at the output's "
             f"{OUT_FOV_DEG:.1f}-degree field of view an output of about {matched:.0f} pixels "
             f"samples the ground as finely as the views do at nadir; larger outputs "
             f"interpolate between view pixels."]
    return Knob("resolution", "Output resolution", setup, "render (ms)", rows, notes)


def knob_bit_depth(run: Run) -> Knob:
    c = run.config
    rows: list[Row] = []
    for density, group in ((0.5, "50 % voxels"), (0.0, "no occluders")):
        renders = []
        ref = None
        for bits in (8, 16, 32):
            scene = occlusion_scene(c, run.seed, c.base_grid, density=density, bit_depth=bits)
            if ref is None:
                ref = reference_truth(run, scene, c.out, c.out)
            lf = run.simulate(scene, keep=bits == 8).light_field
            options = out_options(ref.truth, c.out)
            seconds, result = run.timed(lambda: aos.render_integral(lf, options))
            kind = {8: "8-bit", 16: "16-bit", 32: "float32"}[bits]
            row = Row("bit-depth", group, kind, seconds,
                      {"scene": group, "views' type": kind,
                       MEMORY: mib(lf.image_bytes())})
            rows.append(row)
            renders.append((row, unit_range(result.image, bits), np.asarray(result.count) > 0))
            run.log(f"bit depth: {group}, {kind}: render {ms(seconds)} ms")
            del lf
        mask = footprint_mask(ref.truth)
        for _, _, covered in renders:
            mask &= covered
        for row, image, _ in renders:
            score(row, image, ref.ground, mask)
    setup = (
        f"Scene: the views table's, {c.base_grid} x {c.base_grid} views over 30 m, with the "
        f"voxel volume (50 %) and without occluders; the views stored as 8-bit or 16-bit "
        f"integers or float32 (`camera.bit_depth`; the simulator rounds to the integer types). "
        f"The renderer keeps views in their native type and always accumulates in double.\n\n"
        f"Truth and mask: as in the views table (float truth; pixels under the voxel volume "
        f"that every row covers). Time: `render_integral`, median of {run.repeats}.")
    return Knob("bit-depth", "Storage precision of the views (bit depth)", setup, "render (ms)",
                rows)


COARSE_TO_FINE = 4  # the factor the merge table tries (AllInFocusOptions.coarse_to_fine)


def knob_merge(run: Run) -> Knob:
    c = run.config
    scene = merge_scene(c, run.seed)
    sim = run.simulate(scene)
    lf, sim_truth = sim.light_field, sim.truth
    ref = reference_truth(run, scene, c.merge_size, c.merge_size)
    true_depth = np.asarray(sim_truth.depth, np.float32)
    smooth = smooth_ground(true_depth)
    camera = dict(cam_from_world=sim_truth.cam_from_world, fov_deg=MERGE_FOV_DEG,
                  width=c.merge_size, height=c.merge_size)
    rows: list[Row] = []
    renders: list[tuple[Row, np.ndarray, np.ndarray, Optional[np.ndarray]]] = []
    first, last = aos.Plane.at_height(MERGE_FIRST), aos.Plane.at_height(MERGE_LAST)
    # Coarse-to-fine (AllInFocusOptions.coarse_to_fine, factor 4) where it has slices to skip.
    settings = [(slices, method, 0) for slices in c.slices
                for method in ("sobel", "improved", "robust")]
    settings += [(slices, method, COARSE_TO_FINE) for slices in c.slices if slices >= 32
                 for method in ("improved", "robust")]
    for slices, method, coarse_to_fine in settings:
        splits: list[tuple[float, float]] = []

        def call() -> aos.MergeResult:
            result = aos.all_in_focus(lf, method=method, first_plane=first,
                                      last_plane=last, slices=slices,
                                      coarse_to_fine=coarse_to_fine, **camera)
            splits.append((result.seconds_render, result.seconds_merge))
            return result

        seconds, merged = run.timed(call)
        name = method if not coarse_to_fine else f"{method}, coarse_to_fine {coarse_to_fine}"
        label = f"{method} {slices}" + (f" c2f{coarse_to_fine}" if coarse_to_fine else "")
        row = Row("merge", name, label, seconds,
                  {"method": name, "slices": str(slices),
                   "render (ms)": ms(statistics.median(r for r, _ in splits)),
                   "merge (ms)": ms(statistics.median(m for _, m in splits))},
                  front="all-in-focus")
        depth = np.asarray(merged.depth, np.float32)
        rows.append(row)
        renders.append((row, np.asarray(merged.image, np.float32) / 255.0,
                        np.asarray(merged.slice) >= 0, depth))
        run.log(f"merge: {name}, {slices} slices: {ms(seconds)} ms")
    mid = 0.5 * (MERGE_FIRST + MERGE_LAST)
    plane = aos.IntegralOptions(focal_surface=aos.Plane.at_height(mid), **camera)
    seconds, single = run.timed(lambda: aos.render_integral(lf, plane))
    row = Row("merge", "one plane", f"one plane z={mid:g}", seconds,
              {"method": f"one plane (z = {mid:g} m)", "slices": "1",
               "render (ms)": ms(seconds), "merge (ms)": "-"}, front="all-in-focus")
    rows.append(row)
    renders.append((row, np.asarray(single.image, np.float32) / 255.0,
                    np.asarray(single.count) > 0,
                    np.asarray(aos.plane_depth(sim_truth.camera, sim_truth.cam_from_world,
                                               aos.Plane.at_height(mid)), np.float32)))
    run.log(f"merge: one plane: {ms(seconds)} ms")
    seconds, oracle = run.timed(lambda: aos.render_integral_on_depth(lf, true_depth, **camera))
    row = Row("merge", "oracle (reference)", "oracle (true depth)", seconds,
              {"method": "oracle: plain mean on the true depth", "slices": "-",
               "render (ms)": ms(seconds), "merge (ms)": "-"}, reference=True,
              front="all-in-focus")
    rows.append(row)
    renders.append((row, np.asarray(oracle.integral.image, np.float32) / 255.0,
                    np.asarray(oracle.integral.count) > 0, None))
    run.log(f"merge: oracle: {ms(seconds)} ms")
    mask = true_depth > 0
    for _, _, covered, _ in renders:
        mask &= covered
    for row, image, _, depth in renders:
        score(row, image, ref.ground, mask)
        if depth is not None:
            ok = smooth & mask
            rmse = float(np.sqrt(np.mean((depth[ok] - true_depth[ok]) ** 2)))
            row.columns["depth RMSE (m)"] = f"{rmse:.3f}"
            row.extra["depth_rmse"] = rmse
        else:
            row.columns["depth RMSE (m)"] = "0 (given)"
    setup = (
        f"Scene: the merge study's (`merge_scene` in the tool, as `tools/merge_study.py`; seed "
        f"{run.seed}): a ground sloping 5 % with a 1 m step, chart-textured, a target, under a "
        f"12 x 12 x 6 m voxel volume at 50 % density; {c.merge_grid} x {c.merge_grid} views of "
        f"{c.merge_size} x {c.merge_size} ({c.spp} x {c.spp} rays a pixel) from 25 m over 30 m. "
        f"All-in-focus by `aos.all_in_focus` (slices rendered one at a time and merged) from "
        f"the truth camera ({MERGE_FOV_DEG:.0f} degrees, {c.merge_size} x {c.merge_size}), "
        f"slices evenly between z = {MERGE_FIRST} m and z = {MERGE_LAST} m.\n\n"
        f"Truth: the occluder-free ground ({TRUTH_SPP} x {TRUTH_SPP} rays a pixel, float). "
        f"Mask: the pixels every row covers ({int(mask.sum())}). Depth RMSE against the true "
        f"depth on smooth ground (pixels whose true depth is within 2 cm of their 4 "
        f"neighbours: the slope, not the step). Time: the whole `all_in_focus` call (render of "
        f"every slice + merge), median of {run.repeats}, and the medians of its own render and "
        f"merge timers (`seconds_render`, `seconds_merge`). The one-plane row is a single "
        f"`render_integral` at the middle of the range; the oracle row (the plain mean on the "
        f"true depth, `render_integral_on_depth`) needs the truth, so it is a reference, not on "
        f"the Pareto front. The coarse_to_fine {COARSE_TO_FINE} rows (the knob "
        f"`AllInFocusOptions.coarse_to_fine`, merge.h) render a coarse stack at 1/{COARSE_TO_FINE} "
        f"the width and height on every {COARSE_TO_FINE}th slice, then each "
        f"{COARSE_TO_FINE} x {COARSE_TO_FINE} block's full-resolution slices near its coarse "
        f"focus peak only (4-5 a pixel; all of them in one render call, packed block by block); "
        f"the saving grows with the number of slices and the output size "
        f"(`tools/bench_coarse_to_fine.py`, 100 slices: docs/benchmarks.md).")
    return Knob("merge", "Focal slices and merge method (all-in-focus)", setup,
                "all_in_focus (ms)", rows)


def knob_lens(run: Run) -> Knob:
    c = run.config
    rows: list[Row] = []
    for name, lens in LENSES.items():
        scene = lens_scene(c, run.seed, lens)
        sim = run.simulate(scene)
        ref = reference_truth(run, scene, c.lens_out, c.lens_out)
        lf = sim.light_field
        options = out_options(ref.truth, c.lens_out)
        renders = []
        seconds, direct = run.timed(lambda: aos.render_integral(lf, options))
        row = Row("lens", name, "direct", seconds,
                  {"lens": name, "method": "direct (through the lens model)",
                   "rectify frames (ms)": "-", "render (ms)": ms(seconds), "maps (ms)": "-"})
        rows.append(row)
        renders.append((row, np.asarray(direct.image, np.float32), np.asarray(direct.count) > 0))
        run.log(f"lens: {name}, direct: {ms(seconds)} ms")
        views = lf.views
        frames = [view.image for view in views]
        for width in (c.lens_size, c.lens_size // 2):
            start = time.perf_counter()
            rectifier = aos.make_rectifier(views[0].camera, aos.RectifyOptions(
                fov_deg=100.0, width=width, height=width))
            maps = time.perf_counter() - start
            rectify_s, rectified = run.timed(lambda: [rectifier.rectify(f) for f in frames])
            rectified_field = aos.LightField()
            for frame, view in zip(rectified, views):
                rectified_field.add_view(frame, rectifier.camera, view.cam_from_world)
            render_s, result = run.timed(lambda: aos.render_integral(rectified_field, options))
            row = Row("lens", name, f"rectify {width}", rectify_s + render_s,
                      {"lens": name, "method": f"rectify-first to {width} x {width}, 100 deg",
                       "rectify frames (ms)": ms(rectify_s), "render (ms)": ms(render_s),
                       "maps (ms)": ms(maps)})
            rows.append(row)
            renders.append((row, np.asarray(result.image, np.float32),
                            np.asarray(result.count) > 0))
            run.log(f"lens: {name}, rectify-first {width}: {ms(rectify_s)} + {ms(render_s)} ms")
            del rectified_field, rectified
        mask = np.ones(ref.ground.shape, bool)
        for _, _, covered in renders:
            mask &= covered
        for row, image, _ in renders:
            score(row, image, ref.ground, mask)
        del sim, lf, frames
    setup = (
        f"Scene: `tools/bench_lens.py`'s (seed {run.seed}): 5 x 5 nadir views from "
        f"{ALTITUDE:.0f} m, 4 m apart, of a ground of smooth value noise (0.4 m lattice, no "
        f"occluders), {c.lens_size} x {c.lens_size} float32 views ({c.spp} x {c.spp} rays a "
        f"pixel) through a fisheye `{LENSES['fisheye']}` or an omnidirectional lens "
        f"`{LENSES['omnidir']}`. Output: a 60-degree {c.lens_out} x {c.lens_out} pinhole at the "
        f"aperture centre focused on the ground. Direct: `render_integral` on the raw frames "
        f"(each sample projected through the lens: one resampling). Rectify-first: every frame "
        f"rectified to a 100-degree pinhole frame (`make_rectifier`, full or half width), then a "
        f"pinhole render (two resamplings).\n\n"
        f"Truth: the simulator's ground seen by the output camera ({TRUTH_SPP} x {TRUTH_SPP} "
        f"rays a pixel, float). Mask: pixels every row of that lens covers. Time: direct = the "
        f"render; rectify-first = rectifying the 25 frames + the render (medians of "
        f"{run.repeats}); building the rectification maps is listed apart and not counted "
        f"(built once per lens).")
    notes = ["Rectifying pays when the same rectified frames are rendered many times: the "
             "render column alone is then the cost per image."]
    return Knob("lens", "Direct lens sampling against rectify-first", setup, "total (ms)", rows,
                notes)


def knob_simulator(run: Run) -> Knob:
    c = run.config
    rows: list[Row] = []
    renders = []
    ref = reference_truth(run, occlusion_scene(c, run.seed, c.sim_grid), c.out, c.out)
    options = out_options(ref.truth, c.out)
    for size, spp in c.sim_settings:
        scene = occlusion_scene(c, run.seed, c.sim_grid, size=size, spp=spp)
        seconds, sim = run.timed(lambda: run.simulate(scene))
        result = aos.render_integral(sim.light_field, options)
        rays = sim.stats["primary_rays"]
        row = Row("simulator", "simulate", f"{size}px spp{spp}", seconds,
                  {"views": f"{c.sim_grid}x{c.sim_grid} of {size} x {size}",
                   "samples_per_pixel": f"{spp} ({spp * spp} ray{'s' if spp > 1 else ''})",
                   "primary rays (M)": f"{rays / 1e6:.1f}",
                   "M rays/s": f"{rays / max(sim.stats['seconds_views'], 1e-9) / 1e6:.1f}"})
        rows.append(row)
        renders.append((row, unit_range(result.image, 8), np.asarray(result.count) > 0))
        run.log(f"simulator: {size} x {size}, spp {spp}: simulate {seconds:.2f} s")
        del sim
    mask = footprint_mask(ref.truth)
    for _, _, covered in renders:
        mask &= covered
    for row, image, _ in renders:
        score(row, image, ref.ground, mask)
    setup = (
        f"Scene: the views table's with {c.sim_grid} x {c.sim_grid} views over 30 m (fewer "
        f"views, to keep the repeats affordable) and the 50 % voxel volume; the views' size "
        f"(`camera.width`/`height`, same 80-degree field of view, so the ground sampling "
        f"changes) and `camera.samples_per_pixel` (n: an n x n stratified grid of rays a "
        f"pixel) vary. Quality: the integral of those views rendered as in the views table "
        f"({c.out} x {c.out} output).\n\n"
        f"Truth and mask: as in the views table. Time: the whole `aos.simulate` call (voxels, "
        f"BVH, views, truth), median of {run.repeats}.")
    return Knob("simulator", "The simulator's own knobs", setup, "simulate (s)", rows)


KNOB_FUNCTIONS = {"views": knob_views, "resolution": knob_resolution,
                  "bit-depth": knob_bit_depth, "merge": knob_merge, "lens": knob_lens,
                  "simulator": knob_simulator}


# ---------------------------------------------------------------------------------------------
# Pareto fronts, tables, plots, the page


def mark_pareto(rows: list[Row]) -> None:
    """Marks, per front (by default per group), the rows no other row beats on both time and
    quality (PSNR and SSIM separately): sorted by time, a row is on the front when its quality
    exceeds every faster row's."""
    for front in {r.front_key for r in rows}:
        candidates = [r for r in rows if r.front_key == front and not r.reference]
        for attribute in ("psnr", "ssim"):
            best = -math.inf
            for r in sorted(candidates, key=lambda r: (r.seconds, -getattr(r, attribute))):
                value = getattr(r, attribute)
                if value > best:
                    setattr(r, f"pareto_{attribute}", True)
                    best = value


def time_text(knob: Knob, seconds: float) -> str:
    return f"{seconds:.2f}" if knob.time_label.endswith("(s)") else ms(seconds)


def table(knob: Knob) -> str:
    extra = []
    for row in knob.rows:
        for key in row.columns:
            if key not in extra:
                extra.append(key)
    header = extra + [knob.time_label, "PSNR (dB)", "SSIM", "Pareto"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for row in knob.rows:
        front = ", ".join(name for name, on in (("PSNR", row.pareto_psnr),
                                                ("SSIM", row.pareto_ssim)) if on)
        if row.reference:
            front = "(reference)"
        cells = [row.columns.get(key, "") for key in extra]
        cells += [time_text(knob, row.seconds), f"{row.psnr:.2f}", f"{row.ssim:.4f}", front]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def plot(knob: Knob, path: pathlib.Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter

    scale = 1.0 if knob.time_label.endswith("(s)") else 1e3
    unit = "s" if scale == 1.0 else "ms"
    groups = list(dict.fromkeys(r.group for r in knob.rows))
    fronts = list(dict.fromkeys(r.front_key for r in knob.rows))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    colour_of = {g: colours[i % len(colours)] for i, g in enumerate(groups)}
    figure, axes = plt.subplots(1, 2, figsize=(12, 4.8))
    for axis, attribute, name in ((axes[0], "psnr", "PSNR (dB)"), (axes[1], "ssim", "SSIM")):
        for group in groups:
            rows = [r for r in knob.rows if r.group == group]
            axis.scatter([r.seconds * scale for r in rows], [getattr(r, attribute) for r in rows],
                         color=colour_of[group], s=24, zorder=3, label=group,
                         marker="x" if all(r.reference for r in rows) else "o")
            for r in rows:
                axis.annotate(r.label, (r.seconds * scale, getattr(r, attribute)), fontsize=6.5,
                              xytext=(3, 3), textcoords="offset points")
        for front_name in fronts:
            front = sorted((r for r in knob.rows if r.front_key == front_name
                            and getattr(r, f"pareto_{attribute}")), key=lambda r: r.seconds)
            if not front:
                continue
            # One series: its colour; a front across series: black.
            colour = colour_of[front_name] if front_name in colour_of else "black"
            axis.step([r.seconds * scale for r in front], [getattr(r, attribute) for r in front],
                      where="post", color=colour, linewidth=2.4, alpha=0.5, zorder=2)
            axis.scatter([r.seconds * scale for r in front],
                         [getattr(r, attribute) for r in front], s=100, facecolors="none",
                         edgecolors="black", linewidths=1.2, zorder=4)
        axis.set_xscale("log")
        # From the 1-2-5 value at or below the fastest point (with a margin): a labelled tick
        # left of every point, so the fastest times can be read off the axis.
        times = [r.seconds * scale for r in knob.rows if r.seconds > 0]
        if times:
            low = min(times) / 1.3
            decade = 10.0 ** math.floor(math.log10(low))
            axis.set_xlim(max(m * decade for m in (1, 2, 5) if m * decade <= low),
                          max(times) * 1.3)
        axis.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        # Minor ticks labelled at 2 and 5 x 10^k, so a range within one decade has labels.
        axis.xaxis.set_minor_formatter(FuncFormatter(
            lambda v, _: f"{v:g}" if f"{v:.0e}"[0] in "25" else ""))
        axis.tick_params(axis="x", which="minor", labelsize=7)
        axis.set_xlabel(f"{knob.time_label.split(' (')[0]} time ({unit}, log scale)")
        axis.set_ylabel(name)
        axis.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=8, loc="best")
    figure.suptitle(f"{knob.title}: quality against time (circled and joined: the Pareto "
                    f"front)", fontsize=10)
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)


def find(knob: Optional[Knob], label: str) -> Optional[Row]:
    if knob is None:
        return None
    return next((r for r in knob.rows if r.label == label), None)


def change(delta: float, unit: str, digits: int = 2) -> str:
    return f"adds {delta:.{digits}f}{unit}" if delta >= 0 else f"loses {-delta:.{digits}f}{unit}"


def reading_guide(knobs: dict[str, Knob], config: Config) -> list[str]:
    """The reading guide, every figure taken from the rows."""
    guide: list[str] = []
    views = knobs.get("views")
    base, big = find(views, f"{config.base_grid}x{config.base_grid}"), \
        find(views, f"{config.big_grid}x{config.big_grid}")
    if views and base and big:
        text = (f"For a {config.out}x{config.out} preview (50 % voxel occlusion, focused on the "
                f"ground), bilinear with {config.base_grid}x{config.base_grid} views gives "
                f"{base.psnr:.2f} dB (SSIM {base.ssim:.3f}) in {ms(base.seconds)} ms; "
                f"{config.big_grid}x{config.big_grid} {change(big.psnr - base.psnr, ' dB')} "
                f"(SSIM {big.ssim - base.ssim:+.3f}) for {big.seconds / base.seconds:.1f} times "
                f"the cost.")
        if big.psnr < base.psnr and big.ssim > base.ssim:
            text += (" PSNR and SSIM disagree here: more views lower the noise, which SSIM's "
                     "structure term sees, but not the bias of the plain mean (occluder colours "
                     "mixed in by each pixel's blocked fraction), which dominates the PSNR.")
        guide.append(text)
        n = f"{config.base_grid}x{config.base_grid}"
        pin = find(views, f"{n} r=0 (pinhole)")
        apertures = sorted([r for r in views.rows if r.label.startswith(f"{n} ")
                            and r.label.endswith(" m") and "r=" not in r.label] + [base],
                           key=lambda r: float(r.columns["aperture (simulated)"].split()[0]))
        if pin:
            guide.append(
                f"Aperture ({n} views): the pinhole (aperture_radius 0: each pixel from the one "
                f"nearest view, here the centre view) gives {pin.psnr:.2f} dB (SSIM "
                f"{pin.ssim:.3f}), {base.psnr - pin.psnr:.2f} dB below the whole 30 m "
                f"aperture; the same views flown over " + ", ".join(
                    f"{r.columns['aperture (simulated)']} give {r.psnr:.2f} dB (SSIM "
                    f"{r.ssim:.3f})" for r in apertures) + ".")
        # A radius that admits the centre view alone renders the pinhole's image: compare times.
        one = next((r for r in views.rows if r.label.startswith(f"{n} r=")
                    and r.columns["views used"] == "1" and r is not pin), None)
        if pin and one and abs(one.psnr - pin.psnr) < 1e-6 and pin.seconds > 10 * one.seconds:
            guide.append(
                f"aperture_radius 0 is a slow path: {ms(pin.seconds)} ms with {n} views, while "
                f"aperture_radius {one.columns['aperture_radius']}, which admits the centre view "
                f"alone and renders the same image, takes {ms(one.seconds)} ms. For a one-view "
                f"preview, a small radius (or view_indices) is the cheaper choice.")
        for attribute, name in (("psnr", "PSNR"), ("ssim", "SSIM")):
            front = sorted((r for r in views.rows if getattr(r, f"pareto_{attribute}")),
                           key=lambda r: r.seconds)
            value = ("{:.2f} dB" if attribute == "psnr" else "{:.3f}").format
            guide.append(f"Views and aperture settings on the {name} front, fastest first: " +
                         "; ".join(f"{r.label} ({value(getattr(r, attribute))}, "
                                   f"{ms(r.seconds)} ms)" for r in front) + ".")
    resolution = knobs.get("resolution")
    if resolution:
        finest = max(config.resolutions)
        for group in ("50 % voxels", "no occluders"):
            rows = [r for r in resolution.rows if r.group == group]
            guide.append(
                f"Output resolution ({group}, scored against the {finest}x{finest} truth): " +
                ", ".join(f"{r.label}x{r.label} {r.psnr:.2f} dB / SSIM {r.ssim:.3f} in "
                          f"{ms(r.seconds)} ms" for r in rows) + ".")
    bits = knobs.get("bit-depth")
    if bits:
        for group in ("no occluders", "50 % voxels"):
            b8, b16, b32 = (find_in(bits, group, k) for k in ("8-bit", "16-bit", "float32"))
            if b8 and b16 and b32:
                guide.append(
                    f"Bit depth ({group}): 16-bit views instead of 8-bit change PSNR by "
                    f"{b16.psnr - b8.psnr:+.3f} dB and float32 by {b32.psnr - b8.psnr:+.3f} dB, "
                    f"for {b16.seconds / b8.seconds:.2f} and {b32.seconds / b8.seconds:.2f} "
                    f"times the render time and {b16.columns[MEMORY]} / "
                    f"{b32.columns[MEMORY]} MiB of views instead of {b8.columns[MEMORY]}.")
    merge = knobs.get("merge")
    if merge:
        n = max(config.slices)
        sobel, improved, robust = (find(merge, f"{m} {n}") for m in ("sobel", "improved",
                                                                        "robust"))
        if sobel and improved and robust:
            guide.append(
                f"All-in-focus with {n} slices: sobel {sobel.psnr:.2f} dB in "
                f"{ms(sobel.seconds)} ms, improved {improved.psnr:.2f} dB in "
                f"{ms(improved.seconds)} ms, robust {robust.psnr:.2f} dB in "
                f"{ms(robust.seconds)} ms (depth RMSE {sobel.columns['depth RMSE (m)']} / "
                f"{improved.columns['depth RMSE (m)']} / {robust.columns['depth RMSE (m)']} m).")
        front = sorted((r for r in merge.rows if r.pareto_psnr), key=lambda r: r.seconds)
        if front:
            guide.append("Merge settings on the PSNR front, fastest first: " + "; ".join(
                f"{r.label} ({r.psnr:.2f} dB, {ms(r.seconds)} ms)" for r in front) + ".")
    lens = knobs.get("lens")
    if lens:
        for name in LENSES:
            direct = find_in(lens, name, "direct")
            rect = find_in(lens, name, f"rectify {config.lens_size}")
            if direct and rect:
                guide.append(
                    f"{name}: direct sampling gives {direct.psnr:.2f} dB in "
                    f"{ms(direct.seconds)} ms; rectify-first at full width "
                    f"{change(rect.psnr - direct.psnr, ' dB')} and takes "
                    f"{rect.seconds / direct.seconds:.2f} times as long "
                    f"({rect.columns['render (ms)']} ms of it the render, the part paid per "
                    f"image when rectified frames are reused).")
    simulator = knobs.get("simulator")
    if simulator:
        first = simulator.rows[0]
        parts = []
        for r in simulator.rows[1:]:
            parts.append(f"{r.label}: {r.seconds / first.seconds:.1f} times the simulate time, "
                         f"{change(r.psnr - first.psnr, ' dB')} (SSIM {r.ssim - first.ssim:+.3f})")
        guide.append(
            f"Simulator ({config.sim_grid}x{config.sim_grid} views; 'px' the views' size, "
            f"'spp' samples_per_pixel): {first.label} simulates in {first.seconds:.2f} s and its "
            f"integral gives {first.psnr:.2f} dB (SSIM {first.ssim:.3f}); against it, " +
            "; ".join(parts) + ".")
    return guide


def find_in(knob: Knob, group: str, label: str) -> Optional[Row]:
    return next((r for r in knob.rows if r.group == group and r.label == label), None)


def machine() -> str:
    model = platform.processor() or platform.machine()
    try:
        for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{os.cpu_count()} cores ({model}), {platform.system()} {platform.release()}"


def write_page(knobs: dict[str, Knob], args: argparse.Namespace, config: Config,
               seconds: float, docs: pathlib.Path) -> list[pathlib.Path]:
    docs.mkdir(parents=True, exist_ok=True)
    written = []
    command = "python3 tools/accuracy_vs_time.py --write-docs"
    if args.quick:
        command += " --quick"
    if args.repeats_given:
        command += f" --repeats {args.repeats}"
    if args.knobs != ",".join(KNOBS):
        command += f" --knobs {args.knobs}"
    guide = reading_guide(knobs, config)
    lines = [
        "# Accuracy versus time",
        "",
        f"Written by `{command}` (rerun it to regenerate this page and its plots; every figure "
        f"below comes from that one run). Run on {datetime.date.today().isoformat()}: "
        f"{machine()}, aos {aos.__version__}, `num_threads` {args.threads} (all cores), "
        f"{args.repeats} timed run{'s' if args.repeats > 1 else ''} a setting (the median is "
        f"reported), seed {args.seed}; the whole run took {seconds / 60:.1f} min. The machine "
        f"is shared: the load average was {args.load[0]:.1f} at the start and {args.load[1]:.1f}"
        f" at the end (on {os.cpu_count()} cores), so times can drift by tens of percent "
        f"between runs, and fast settings (a few ms) are the noisiest; qualities do not depend "
        f"on the load. `--quick` runs the same sweep at tiny sizes as a smoke test.",
        "",
        "Each table sweeps one knob on a seeded simulated scene (`aos.simulate`) whose ground "
        "truth is known, and gives for every setting the time it costs and the quality of the "
        "result: PSNR and SSIM (`aos.compare_images`, docs/metrics.md; values scaled to [0, 1], "
        "L = 1) against the occluder-free ground, over the mask stated with the table. The "
        "Pareto column marks the settings that no other setting of the same series beats on "
        "both time and quality (PSNR and SSIM fronts separately; in the views table all rows "
        "form one front); the plots show quality against time with that front circled and "
        "joined.",
        "",
        "## Reading guide",
        "",
    ]
    lines += [f"- {text}" for text in guide] or ["- (no knob run)"]
    lines += ["", "## Not offered", "",
              "Knobs the issue names that aos does not offer, and what stands in for them:", ""]
    lines += [f"- **{name}**: {text}" for name, text in KNOBS_NOT_OFFERED]
    for name, knob in knobs.items():
        png = f"accuracy-vs-time-{name}.png"
        plot(knob, docs / png)
        written.append(docs / png)
        lines += ["", f"## {knob.title}", "", knob.setup, "", table(knob), ""]
        lines += [f"{note}\n" for note in knob.notes]
        lines += [f"![{knob.title}: quality against time]({png})"]
    lines += [""]
    page = docs / PAGE
    page.write_text("\n".join(lines), encoding="utf-8")
    written.insert(0, page)
    return written


def run_knob(run: Run, name: str) -> Knob:
    """One knob's study: a Dask task with --workers/--scheduler."""
    return KNOB_FUNCTIONS[name](run)


def main(argv: Optional[list[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true",
                        help="tiny sizes and 1 repeat: a smoke test (under a minute)")
    parser.add_argument("--repeats", type=int, default=None,
                        help="timed runs per setting, median reported (3; 1 with --quick)")
    parser.add_argument("--knobs", default=",".join(KNOBS),
                        help=f"comma-separated subset of {','.join(KNOBS)}")
    parser.add_argument("--seed", type=int, default=1, help="scene seed (1)")
    parser.add_argument("--threads", type=int, default=-1, help="worker threads (-1: all cores)")
    parser.add_argument("--workers", type=int, default=0,
                        help="run the knobs as Dask tasks on a local cluster of N processes "
                             "(aos.distributed.run_cases): the same quality columns, but each "
                             "knob's times then include the other tasks' load")
    parser.add_argument("--scheduler", default="",
                        help="run the knobs as Dask tasks on the cluster of this scheduler")
    parser.add_argument("--write-docs", action="store_true",
                        help="write the page and the plots into --docs-dir")
    parser.add_argument("--docs-dir", default=str(ROOT / "docs"),
                        help="where --write-docs writes (default: the repository's docs/)")
    args = parser.parse_args(argv)
    args.repeats_given = args.repeats is not None
    if args.repeats is None:
        args.repeats = 1 if args.quick else 3
    if args.repeats < 1:
        parser.error("--repeats must be at least 1")
    if args.workers < 0 or (args.workers and args.scheduler):
        parser.error("--workers N (>= 1) and --scheduler ADDRESS exclude each other")
    names = [n.strip() for n in args.knobs.split(",") if n.strip()]
    unknown = [n for n in names if n not in KNOBS]
    if unknown:
        parser.error(f"--knobs: unknown {', '.join(unknown)} (known: {', '.join(KNOBS)})")
    if args.write_docs:
        import matplotlib  # noqa: F401  (fail now, not after the sweep)
    config = QUICK if args.quick else Config()
    run = Run(config, args.repeats, args.threads, args.seed)
    load_start = os.getloadavg()[0]
    run.log(f"aos {aos.__version__}, {machine()}; {args.repeats} repeats; knobs: "
            f"{', '.join(names)}")
    knobs: dict[str, Knob] = {}
    computed: dict[str, Knob] = {}
    if args.workers or args.scheduler:
        from aos.distributed import run_cases

        results = run_cases(functools.partial(run_knob, run), names,
                            workers=args.workers or None, scheduler=args.scheduler or None,
                            progress=lambda i, _: run.log(f"{names[i]}: computed on Dask"))
        computed = dict(zip(names, results))
    for name in names:
        knob = computed[name] if name in computed else KNOB_FUNCTIONS[name](run)
        mark_pareto(knob.rows)
        knobs[name] = knob
        for row in knob.rows:
            front = "*" if row.pareto_psnr else " "
            print(f"    {front} {name:10s} {row.group:34s} {row.label:24s} "
                  f"{time_text(knob, row.seconds):>9s} {knob.time_label.split(' ')[-1]:5s}"
                  f" {row.psnr:7.2f} dB  SSIM {row.ssim:.4f}", flush=True)
        run.log(f"{name}: done")
    seconds = time.perf_counter() - run.start
    args.load = (load_start, os.getloadavg()[0])
    for text in reading_guide(knobs, config):
        print(f"- {text}")
    if args.write_docs:
        written = write_page(knobs, args, config, seconds, pathlib.Path(args.docs_dir))
        print("wrote " + ", ".join(str(p) for p in written))
    run.log("finished")
    return 0


if __name__ == "__main__":
    sys.exit(main())
