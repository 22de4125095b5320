"""Appendix B trends at a reduced size (128 x 128 views, 50^3 voxels), with the functions of
tools/appendix_b.py: quality falls with occlusion density, rises with the aperture and with the
number of views, and the single (pinhole) view is worst. The full-size figures are in
docs/appendix-b.md.

Measured here (seed 1): density 0/30/50/70/90 % at 9x9, 30 m: SSIM 0.794/0.674/0.561/0.436/0.310;
at 50 %: 30 m 3x3/9x9/27x27 SSIM 0.539/0.561/0.567, 15 m 0.428/0.500/0.514, pinhole 0.284.
PSNR falls with density and with a smaller aperture too, but not with more views: the mean's
bias (occluder colours mixed in by the blocked fraction) does not shrink with N, only its noise
does, which SSIM sees and PSNR barely does. So the views trend is asserted on SSIM.
"""

from __future__ import annotations

import importlib.util
import pathlib
import sys

import pytest

TOOL = pathlib.Path(__file__).resolve().parents[2] / "tools" / "appendix_b.py"
spec = importlib.util.spec_from_file_location("appendix_b", TOOL)
appendix_b = importlib.util.module_from_spec(spec)
sys.modules["appendix_b"] = appendix_b  # dataclasses look their module up
spec.loader.exec_module(appendix_b)  # type: ignore[union-attr]

SIZE, VOXELS = 128, 50


def evaluate(density: float, grid: int, aperture: float):
    return appendix_b.evaluate(appendix_b.Case("test", density, grid, aperture), SIZE, VOXELS)


@pytest.fixture(scope="module")
def density_sweep():
    return [evaluate(d, 9, 30.0) for d in (0.0, 0.3, 0.5, 0.7, 0.9)]


def test_quality_falls_with_density(density_sweep) -> None:
    for denser, sparser in zip(density_sweep[1:], density_sweep[:-1]):
        assert denser.ssim < sparser.ssim - 0.05, (denser.label, denser.ssim, sparser.ssim)
        assert denser.psnr_db < sparser.psnr_db - 0.5, (denser.label, denser.psnr_db)


@pytest.fixture(scope="module")
def aperture_views():
    return {(a, g): evaluate(0.5, g, a) for a in (30.0, 15.0, 0.0) for g in (3, 9)}


def test_quality_rises_with_aperture_and_pinhole_is_worst(aperture_views) -> None:
    for grid in (3, 9):
        wide, narrow, pinhole = (aperture_views[(a, grid)] for a in (30.0, 15.0, 0.0))
        assert wide.ssim > narrow.ssim + 0.03 and wide.psnr_db > narrow.psnr_db + 0.3
        assert narrow.ssim > pinhole.ssim + 0.03 and narrow.psnr_db > pinhole.psnr_db + 0.3


def test_quality_rises_with_views(aperture_views) -> None:
    for aperture in (30.0, 15.0):
        few, many = aperture_views[(aperture, 3)], aperture_views[(aperture, 9)]
        assert many.ssim > few.ssim + 0.01, (aperture, few.ssim, many.ssim)
