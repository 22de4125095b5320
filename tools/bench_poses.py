#!/usr/bin/env python3
"""Poses from frames: COLMAP's time per stage and the accuracy of the recovered poses.

Simulates a drone flight with known poses (aos.simulate): a lawnmower path of ROWS x COLS frames
(default 10 x 10 = 100) of 1152 x 864 (1.0 MP) pinhole frames, 60-degree FOV, 20 m above textured
ground with trees, 4 m between frames and rows. Runs the whole pipeline (`aos-render poses`,
each preset of --presets in turn, self-calibrated PINHOLE camera started from the true FOV, positions CSV at
UTM-sized coordinates), then compares with the truth:
  * time per stage (features, matching, mapping, import) and in all, on this machine;
  * camera-centre error (cm) and rotation error (degrees) after geo-referencing;
  * the integral image rendered from the recovered poses against the one from the true poses
    (PSNR, SSIM; virtual 40-degree camera over the flight's centre, focal plane on the ground).

Usage: python3 tools/bench_poses.py [--rows 10] [--cols 10] [--width 1152] [--height 864]
                                    [--overlap 5] [--presets default,quick]
                                    [--write-docs]   (docs/poses.md)
"""

from __future__ import annotations

import argparse
import math
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import aos

UTM = np.array([512000.0, 5300000.0, 300.0])
ALTITUDE = 20.0
FOV = 60.0
SPACING = 4.0


def flight_positions(rows: int, cols: int) -> list[list[float]]:
    """A lawnmower path: rows along x, alternating direction, SPACING apart."""
    positions = []
    for r in range(rows):
        xs = range(cols) if r % 2 == 0 else reversed(range(cols))
        for c in xs:
            positions.append([SPACING * (c - (cols - 1) / 2), SPACING * (r - (rows - 1) / 2), ALTITUDE])
    return positions


def scene(rows: int, cols: int, width: int, height: int) -> dict:
    return {"seed": 11,
            "ground": {"texture": {"type": "noise", "square": 0.25, "colors": [0.1, 0.9]}},
            "occluders": {"trees": {"per_hectare": 60, "leaves_per_tree": 400}},
            "camera": {"width": width, "height": height, "fov_deg": FOV},
            "sampling": {"positions": flight_positions(rows, cols)},
            "truth": {"width": 256, "height": 256, "fov_deg": 40.0, "blocked_fraction": False}}


def rotation_error_deg(a: np.ndarray, b: np.ndarray) -> float:
    cos = (np.trace(a @ b.T) - 1.0) / 2.0
    return math.degrees(math.acos(max(-1.0, min(1.0, cos))))


def simulate(args: argparse.Namespace, work: Path) -> tuple:
    start = time.perf_counter()
    simulation = aos.simulate(scene(args.rows, args.cols, args.width, args.height), work / "sim")
    simulate_s = time.perf_counter() - start
    lines = ["name,x,y,z"]
    for k, pose in enumerate(simulation.true_cam_from_world):
        c = pose.center + UTM
        lines.append(f"{k:04d}.png,{c[0]:.4f},{c[1]:.4f},{c[2]:.4f}")
    (work / "gps.csv").write_text("\n".join(lines) + "\n")
    return simulation, simulate_s


def run(args: argparse.Namespace, work: Path, simulation, preset: str) -> dict:
    frames = work / "sim" / "views"
    output = work / f"poses-{preset}.json"
    command = ["aos-render", "poses", str(frames), "-o", str(output),
               "--positions-file", str(work / "gps.csv"), "--camera-model", "PINHOLE",
               "--frames-fov-deg", str(FOV), "--preset", preset]
    if preset == "default":
        command += ["--sequential-overlap", str(args.overlap)]
    else:
        command += args.extra_flags.split()
    print("$ " + " ".join(command), flush=True)
    # Wall time, and the CPU time of aos-render and COLMAP (user + system, all threads): on a
    # machine shared with other work the wall time swings with the load, the CPU time far less.
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(command, stdout=subprocess.PIPE, text=True)
    total_s = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_s = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    print(done.stdout, flush=True)
    if done.returncode != 0:
        raise SystemExit(f"aos-render poses failed ({done.returncode})")
    stages = {}
    for line in done.stdout.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[2] == "s" and parts[0] in ("features", "matching", "mapping", "import"):
            stages[parts[0]] = float(parts[1])
    recovered = aos.load_lightfield(str(output)).light_field
    origin = np.asarray(recovered.origin)
    truth = simulation.true_cam_from_world
    centre, rotation = [], []
    for view in recovered.views:
        k = int(Path(view.name).stem)
        centre.append(np.linalg.norm(view.cam_from_world.center + origin - (truth[k].center + UTM)))
        rotation.append(rotation_error_deg(np.asarray(view.cam_from_world.rotation),
                                           np.asarray(truth[k].rotation)))
    # The integral over every view, from a 40-degree camera over the flight's centre.
    shift = UTM - origin
    pose = simulation.truth.cam_from_world
    r = np.asarray(pose.rotation)
    moved = aos.Rigid3d(r, np.asarray(pose.translation) - r @ shift)
    common = dict(fov_deg=40.0, width=256, height=256, aperture_radius=math.inf)
    true_image = aos.render_integral(simulation.light_field, cam_from_world=pose,
                                     focal_surface=aos.Plane.at_height(0.0), **common).image
    recovered_image = aos.render_integral(recovered, cam_from_world=moved,
                                          focal_surface=aos.Plane.at_height(shift[2]), **common).image
    quality = aos.compare_images(recovered_image, true_image, np.ones(true_image.shape, np.uint8),
                                 data_range=255.0)
    source = recovered.pose_source
    return {"preset": preset, "frames": args.rows * args.cols, "registered": len(recovered),
            "total_s": total_s, "cpu_s": cpu_s, "stages": stages, "centre_cm": 100 * np.array(centre),
            "rotation_deg": np.array(rotation), "psnr": quality.psnr_db, "ssim": quality.ssim,
            "reprojection_px": source.mean_reprojection_error_px, "pose_error_m": source.pose_error,
            "georef_rms_m": source.georeference_rms_m, "median_depth": source.median_depth}


def table(args: argparse.Namespace, r: dict) -> str:
    stages = r["stages"]
    stage_rows = "\n".join(f"| {name} | {seconds:.1f} s |" for name, seconds in stages.items())
    c, q = r["centre_cm"], r["rotation_deg"]
    return f"""### Preset {r['preset']}

| frames | registered | whole pipeline (wall) | CPU time (all threads) |
|---|---|---|---|
| {r['frames']} x {args.width} x {args.height} ({args.width * args.height / 1e6:.1f} MP) | {r['registered']} | {r['total_s']:.0f} s ({r['total_s'] / 60:.1f} min) | {r['cpu_s']:.0f} s |

| stage | time |
|---|---|
{stage_rows}

| accuracy (after geo-referencing) | value |
|---|---|
| camera-centre error, median / max | {np.median(c):.2f} / {c.max():.2f} cm |
| rotation error, median / max | {np.median(q):.3f} / {q.max():.3f} degrees |
| COLMAP mean reprojection error | {r['reprojection_px']:.3f} px |
| pose error e at the median depth ({r['median_depth']:.1f} m) | {100 * r['pose_error_m']:.2f} cm |
| geo-referencing RMS (centres vs positions) | {100 * r['georef_rms_m']:.2f} cm |
| integral from recovered vs true poses | {r['psnr']:.1f} dB PSNR, SSIM {r['ssim']:.4f} |
"""


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rows", type=int, default=10)
    parser.add_argument("--cols", type=int, default=10)
    parser.add_argument("--width", type=int, default=1152)
    parser.add_argument("--height", type=int, default=864)
    parser.add_argument("--overlap", type=int, default=5)
    parser.add_argument("--presets", default="default,quick",
                        help="comma-separated presets, run in turn on the same frames; the first is the baseline")
    parser.add_argument("--extra-flags", default="",
                        help="more `aos-render poses` flags for the presets other than default, e.g. "
                             "'--max-num-features 512' (exploring; not written into the docs)")
    parser.add_argument("--write-docs", action="store_true")
    args = parser.parse_args()
    if shutil.which("colmap") is None:
        print("COLMAP is not installed (apt-get install colmap)", file=sys.stderr)
        return 1
    presets = args.presets.split(",")
    with tempfile.TemporaryDirectory(prefix="aos-bench-poses-") as work:
        simulation, simulate_s = simulate(args, Path(work))
        results = [run(args, Path(work), simulation, preset) for preset in presets]
    summary = "\n".join(table(args, r) for r in results)
    if len(results) > 1:
        base = results[0]
        summary += ("\n| preset | wall | speed-up (wall) | CPU time | speed-up (CPU) | centre error, "
                    "median | integral PSNR |\n|---|---|---|---|---|---|---|\n")
        for r in results:
            summary += (f"| {r['preset']} | {r['total_s']:.0f} s | {base['total_s'] / r['total_s']:.2f}x "
                        f"| {r['cpu_s']:.0f} s | {base['cpu_s'] / r['cpu_s']:.2f}x "
                        f"| {np.median(r['centre_cm']):.2f} cm | {r['psnr']:.1f} dB |\n")
    print(summary)
    if args.write_docs and args.extra_flags:
        print("--write-docs: not with --extra-flags (the docs describe the presets as they are)", file=sys.stderr)
    elif args.write_docs:
        path = Path(__file__).resolve().parent.parent / "docs" / "poses.md"
        text = path.read_text()
        marker = "\nHow the pieces fit:"
        tail = text[text.index(marker):] if marker in text else "\n"
        path.write_text(f"""# Poses from frames (COLMAP)

Figures from `python3 tools/bench_poses.py --rows {args.rows} --cols {args.cols} --width {args.width} --height {args.height} --overlap {args.overlap} --presets {args.presets} --write-docs`
on the 2-core machine, shared with other work (rerun it to reproduce; simulating the flight took {simulate_s:.0f} s and is not
counted). The presets ran one after the other on the same simulated frames.

A simulated flight with known poses: a lawnmower path of {args.rows} rows x {args.cols} frames,
{SPACING:.0f} m apart, {ALTITUDE:.0f} m above textured ground with trees, 60-degree pinhole frames.
`aos-render poses` ran COLMAP 3.8 (CPU) with a self-calibrated PINHOLE camera started from the
true FOV, and the true centres (shifted to UTM-sized coordinates) as the positions CSV that
geo-references the model. `--preset default` matched sequentially (overlap {args.overlap}) with
up to 2048 features a frame on the full 1152-pixel frames; `--preset quick` (`preset="quick"` in
Python) extracts up to 512 features on frames downscaled to 480 pixels, without SIFT's 2x
upsampled first octave, and, having positions,
matches each frame with its 8 nearest by position (spatial matching) instead of sequentially.

{summary}
The quick preset (`PosesOptions::preset`, applied by `WithPreset`): each of these fields still at
its default takes the quick value; a field given another value keeps it (`--preset quick
--max-num-features 2048` keeps 2048 features).

| field (flag) | default | quick |
|---|---|---|
| `max_image_size` (`--max-image-size`) | 1600 | 480 |
| `max_num_features` (`--max-num-features`) | 2048 | 512 |
| `sift_first_octave` (`--sift-first-octave`) | -1 | 0 |
| `sequential_overlap` (`--sequential-overlap`) | 5 | 3 |
| `spatial_neighbors` (`--spatial-neighbors`) | 50 | 8 |
| `matcher` (`--matcher`), with positions | sequential | spatial |
{tail}""")
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
