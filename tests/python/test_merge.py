"""Focal stacks and all-in-focus merging: the proof that improved beats the paper's sobel merge,
the robust mean against clean ground, the Python API and the CLI.

The proof runs tools/merge_study.py's code on 64 x 64 scenes (the tool writes the full table to
docs/merge-study.md).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import aos

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))
import merge_study  # noqa: E402

SIZE = 64
SEEDS = (1, 2, 3, 4, 5)
SLICES = [6, 12, 24]


@pytest.mark.parametrize("occluders", ["voxels", "trees"])
def test_improved_beats_sobel_on_every_seed_and_slice_count(occluders: str) -> None:
    for seed in SEEDS:
        rows = merge_study.evaluate(seed, occluders, SIZE, SLICES)
        for slices in SLICES:
            by = {r["method"]: r for r in rows if r["slices"] == slices}
            sobel, improved = by["sobel"], by["improved"]
            case = f"{occluders}, seed {seed}, N={slices}: sobel {sobel}, improved {improved}"
            for key in ("psnr", "ssim", "psnr_oracle", "ssim_oracle"):
                assert improved[key] > sobel[key], f"{key}: {case}"
            # Depth on smooth ground: lower error, and far less banding (state both).
            assert improved["depth_rmse"] < sobel["depth_rmse"], case
            assert improved["banding"] < 0.5 * sobel["banding"], (
                f"banding improved {improved['banding']:.3f} vs sobel {sobel['banding']:.3f}: {case}")


@pytest.mark.parametrize("density", [0.5, 0.7])
def test_robust_lowers_the_error_where_fewer_than_60_percent_are_blocked(density: float) -> None:
    bins = merge_study.robust_bins(1, SIZE, density)
    assert bins["below_pixels"] > 0.3 and bins["above_pixels"] > 0.02, bins
    assert bins["below_robust"] < 0.97 * bins["below_plain"], bins
    # No worse above: the robust mean falls back to the plain mean where too few rays agree
    # (a 1 % margin for the pixels where a cluster of occluders happens to agree).
    assert bins["above_robust"] <= 1.01 * bins["above_plain"], bins
    # The whole method (its own depth, then the robust re-integration) against improved's merge.
    assert bins["below_robust_merge"] < 0.97 * bins["below_improved_merge"], bins
    assert bins["above_robust_merge"] <= 1.01 * bins["above_improved_merge"], bins


@pytest.fixture(scope="module")
def simulation() -> aos.SimulationResult:
    return aos.simulate(merge_study.study_scene(3, 48, "voxels"))


def camera(simulation: aos.SimulationResult) -> dict:
    return merge_study.camera_options(simulation.truth, 48)


def test_stack_planes_interpolate_between_the_boundaries(simulation: aos.SimulationResult) -> None:
    stack = aos.render_focal_stack(simulation.light_field, first_plane=aos.Plane.at_height(-1.0),
                                   last_plane=aos.Plane.at_height(2.0), slices=4, **camera(simulation))
    heights = [plane.point[2] for plane in stack.planes]
    np.testing.assert_allclose(heights, [-1.0, 0.0, 1.0, 2.0], atol=1e-9)
    assert len(stack) == 4 and stack.images.shape == (4, 48, 48) and stack.variances is None
    single = aos.render_integral(simulation.light_field, focal_surface=stack.planes[2], **camera(simulation))
    np.testing.assert_array_equal(stack.images[2], single.image)


def test_pipeline_matches_merging_the_stored_stack(simulation: aos.SimulationResult, tmp_path: Path) -> None:
    options = dict(first_plane=aos.Plane.at_height(-1.5), last_plane=aos.Plane.at_height(2.5),
                   slices=10, **camera(simulation))
    stack = aos.render_focal_stack(simulation.light_field, **options)
    aos.write_focal_stack(str(tmp_path / "stack"), stack)
    stored = aos.read_focal_stack(str(tmp_path / "stack"))
    for method in ("sobel", "improved"):
        merged = aos.merge_focal_stack(stored, method=method)
        streamed = aos.all_in_focus(simulation.light_field, method=method, **options)
        # The same focus state, refinement and smoothing: identical depth maps.
        np.testing.assert_array_equal(merged.depth, streamed.depth)
        np.testing.assert_array_equal(merged.confidence, streamed.confidence)
        assert np.isfinite(merged.image).all() and np.isfinite(streamed.image).all()
    np.testing.assert_array_equal(aos.merge_focal_stack(stored, method="sobel").image,
                                  aos.all_in_focus(simulation.light_field, method="sobel", **options).image)


def test_keyword_arguments_are_routed_and_checked(simulation: aos.SimulationResult) -> None:
    result = aos.all_in_focus(simulation.light_field, method="robust", window_radius=1, slices=3,
                              first_plane=aos.Plane.at_height(0.0), last_plane=aos.Plane.at_height(1.0),
                              agreement=0.05, **camera(simulation))
    assert result.image.shape == (48, 48) and result.depth.dtype == np.float32
    with pytest.raises(TypeError, match="unexpected keyword argument 'slice_count'"):
        aos.all_in_focus(simulation.light_field, slice_count=3)
    with pytest.raises(ValueError, match="unknown merge method 'best'"):
        aos.all_in_focus(simulation.light_field, method="best", **camera(simulation))
    with pytest.raises(ValueError, match="window_radius"):
        aos.all_in_focus(simulation.light_field, window_radius=100, **camera(simulation))
    stack = aos.render_focal_stack(simulation.light_field, slices=2, **camera(simulation))
    with pytest.raises(ValueError, match="no variance images"):
        aos.merge_focal_stack(stack, method="robust", light_field=simulation.light_field)


def test_coarse_to_fine_keyword_and_flag(simulation: aos.SimulationResult) -> None:
    # The knob is one field (AllInFocusOptions.coarse_to_fine), reached by the keyword and by
    # aos-render allinfocus --coarse-to-fine; the full stack renders every pixel of every slice,
    # coarse-to-fine at most 2 x 4 + 1 = 9 of the 24 slices a pixel.
    planes = dict(first_plane=aos.Plane.at_height(-1.5), last_plane=aos.Plane.at_height(2.5),
                  slices=24, **camera(simulation))
    full = aos.all_in_focus(simulation.light_field, **planes)
    fine = aos.all_in_focus(simulation.light_field, coarse_to_fine=4, **planes)
    assert full.rendered_fraction == 1.0
    assert 0.0 < fine.rendered_fraction <= 9 / 24
    assert fine.image.shape == full.image.shape and np.isfinite(fine.depth).all()
    assert aos.AllInFocusOptions().coarse_to_fine == 0
    with pytest.raises(ValueError, match="coarse_to_fine"):
        aos.all_in_focus(simulation.light_field, coarse_to_fine=1, **planes)
    help_text = aos_render("allinfocus", "--help").stdout
    assert "--coarse-to-fine" in help_text


MEMORY_PROBE = r"""
import json, os, sys, threading, time
import numpy as np
import aos
sys.path.insert(0, sys.argv[1])
import merge_study
slices = int(sys.argv[2])
simulation = aos.simulate(merge_study.study_scene(1, 32, "none"))
options = dict(first_plane=aos.Plane.at_height(-1.5), last_plane=aos.Plane.at_height(2.5),
               slices=slices, cam_from_world=simulation.truth.cam_from_world, fov_deg=40.0,
               width=128, height=128, num_threads=1)
page = os.sysconf("SC_PAGE_SIZE")
def rss():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * page
peak, done = [0], [False]
def sample():
    while not done[0]:
        peak[0] = max(peak[0], rss())
        time.sleep(0.002)
before = rss()
thread = threading.Thread(target=sample)
thread.start()
result = aos.all_in_focus(simulation.light_field, method="improved", **options)
done[0] = True
thread.join()
print(json.dumps({"growth": peak[0] - before, "finite": bool(np.isfinite(result.depth).all())}))
"""


def test_a_thousand_slices_stream_without_memory_growth() -> None:
    def growth(slices: int) -> dict:
        output = subprocess.run([sys.executable, "-c", MEMORY_PROBE, str(ROOT / "tools"), str(slices)],
                                check=True, capture_output=True, text=True).stdout
        return json.loads(output)

    few, many = growth(10), growth(1000)
    assert few["finite"] and many["finite"]
    # Holding 1000 slices of 128 x 128 would take 1000 x (64 KiB image + 64 KiB counts) = 125 MiB;
    # streaming keeps a few slices' worth whatever N is (16 MiB of slack for the allocator).
    assert many["growth"] < few["growth"] + 16 * 2**20, (few, many)


def aos_render(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["aos-render", *args], capture_output=True, text=True)


def test_cli_stack_merge_and_allinfocus(tmp_path: Path) -> None:
    sim = tmp_path / "sim"
    aos.simulate(merge_study.study_scene(2, 48, "voxels"), str(sim))
    truth = json.loads((sim / "truth" / "truth.json").read_text())
    centre = truth["truth_position"]
    look = ",".join(str(v) for v in [*centre, centre[0], centre[1], 0.0, 0, 1, 0])
    common = ["--look-at", look, "--fov-deg", "40", "--width", "48", "--height", "48",
              "--first-plane", "-1.5", "--last-plane", "2.5", "--slices", "8", "-q"]
    lightfield = str(sim / "lightfield.json")
    done = aos_render("stack", lightfield, *common, "--variance", "-o", str(tmp_path / "stack"))
    assert done.returncode == 0, done.stderr
    meta = json.loads((tmp_path / "stack" / "stack.json").read_text())
    assert len(meta["slices"]) == 8 and "variance" in meta["slices"][0]
    # Contact sheets that open in any viewer: 8 tiles of 48 x 48 in one row, 2-pixel gaps; the
    # slices share one stretch (so they compare), the counts run from black to white.
    sheet = aos.read_image(str(tmp_path / "stack" / "stack_preview.png"))
    counts = aos.read_image(str(tmp_path / "stack" / "count_preview.png"))
    assert sheet.dtype == np.uint8 and sheet.shape[:2] == (48, 8 * 48 + 7 * 2)
    assert counts.dtype == np.uint8 and counts.shape == (48, 8 * 48 + 7 * 2)
    assert sheet.max() - sheet.min() > 128 and counts.max() == 255
    assert (sheet[:, 48:50] == 0).all() and (counts[:, 48:50] == 0).all()   # the gaps
    for method in ("sobel", "improved"):
        done = aos_render("merge", str(tmp_path / "stack"), "--method", method, "-q",
                          "-o", str(tmp_path / method))
        assert done.returncode == 0, done.stderr
        depth = aos.read_image(str(tmp_path / method / "depth.tif"))
        assert depth.shape == (48, 48) and np.isfinite(depth).all()
    refused = aos_render("merge", str(tmp_path / "stack"), "--method", "robust", "-o",
                         str(tmp_path / "robust"))
    assert refused.returncode == 2 and "--lightfield" in refused.stderr
    assert not (tmp_path / "robust").exists()
    done = aos_render("merge", str(tmp_path / "stack"), "--method", "robust", "--lightfield",
                      lightfield, "-q", "-o", str(tmp_path / "robust"))
    assert done.returncode == 0, done.stderr
    done = aos_render("allinfocus", lightfield, *common, "-o", str(tmp_path / "aif"))
    assert done.returncode == 0, done.stderr
    assert sorted(os.listdir(tmp_path / "aif")) == [
        "all_in_focus.tif", "all_in_focus_preview.png", "confidence.tif",
        "confidence_preview.png", "depth.tif", "depth_preview.png", "slice.tif"]
    # Previews a user can open: 8-bit, the image stretched (not all one grey), the depth in
    # colour (turbo), the confidence likewise; each the size of the render.
    image_preview = aos.read_image(str(tmp_path / "aif" / "all_in_focus_preview.png"))
    depth_preview = aos.read_image(str(tmp_path / "aif" / "depth_preview.png"))
    confidence_preview = aos.read_image(str(tmp_path / "aif" / "confidence_preview.png"))
    assert image_preview.dtype == np.uint8 and image_preview.shape[:2] == (48, 48)
    assert image_preview.max() - image_preview.min() > 128
    assert depth_preview.dtype == np.uint8 and depth_preview.shape == (48, 48, 3)
    assert len(np.unique(depth_preview.reshape(-1, 3), axis=0)) > 4
    assert confidence_preview.dtype == np.uint8 and confidence_preview.shape == (48, 48, 3)
    # The depth preview orders depths by colour: the nearest and the farthest covered pixels
    # get the two ends of the turbo map (blue and red dominated).
    depth = aos.read_image(str(tmp_path / "aif" / "depth.tif"))
    shown = np.where(depth_preview.sum(axis=2) > 0, depth, np.nan)   # uncovered pixels: black
    near = np.unravel_index(np.nanargmin(shown), depth.shape)
    far = np.unravel_index(np.nanargmax(shown), depth.shape)
    assert depth_preview[near][2] > depth_preview[near][0]   # more blue than red
    assert depth_preview[far][0] > depth_preview[far][2]     # more red than blue
    # Never overwrite: a used output folder is refused and left as it was.
    again = aos_render("allinfocus", lightfield, *common, "-o", str(tmp_path / "aif"))
    assert again.returncode == 1 and "not empty" in again.stderr
    bad = aos_render("allinfocus", lightfield, *common[:-3], "--slices", "0", "-o",
                     str(tmp_path / "bad"))
    assert bad.returncode == 2 and "--slices" in bad.stderr
    assert not (tmp_path / "bad").exists()
