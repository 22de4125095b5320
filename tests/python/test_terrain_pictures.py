"""tools/terrain_pictures.py (the pictures of docs/terrain-and-maps.md) runs on F0 and writes
what its docstring says. Skips when ../shared/data/jku-f0 or gdaldem is absent."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import aos

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(os.environ.get("AOS_JKU_F0", ROOT.parent / "shared" / "data" / "jku-f0"))

pytestmark = [
    pytest.mark.skipif(not (DATA / "poses" / "poses.json").exists(),
                       reason=f"JKU F0 data not found at {DATA}"),
    pytest.mark.skipif(shutil.which("gdaldem") is None, reason="gdaldem not installed"),
]


def test_the_pictures_are_made_as_documented(tmp_path: Path) -> None:
    pytest.importorskip("rasterio")
    result = subprocess.run([sys.executable, str(ROOT / "tools" / "terrain_pictures.py"),
                             "--data", str(DATA), "--out", str(tmp_path), "--keep"],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    views = aos.read_image(tmp_path / "terrain-f0-view191.png")
    # Three 512 x 512 panels with 8 px gaps over three crops of 192 x 144 enlarged 8/3 x.
    assert views.dtype == np.uint8 and views.shape == (512 + 8 + 384, 3 * 512 + 2 * 8)
    assert (views[:512, 512:520] == 255).all()  # the white gap
    picture = aos.read_image(tmp_path / "terrain-f0-map.png")
    dem = aos.Heightfield.read(str(tmp_path / "dem.tif"))
    assert picture.shape == (dem.height, dem.width, 3)
    # The map's pixels are grey (r = g = b) exactly where its count band says a view sees them,
    # placed by the geotransforms; beyond the mesh (NaN heights) the picture is white.
    rasterio = pytest.importorskip("rasterio")
    with rasterio.open(tmp_path / "map.tif") as src:
        count = src.read(2)
        col0 = round((src.transform.c - dem.geotransform[0]) / dem.geotransform[1])
        row0 = round((dem.geotransform[3] - src.transform.f) / -dem.geotransform[5])
    window = picture[row0:row0 + count.shape[0], col0:col0 + count.shape[1]].astype(int)
    grey = (window[..., 0] == window[..., 1]) & (window[..., 1] == window[..., 2])
    assert grey[count > 0].all()
    beyond = np.isnan(dem.heights)
    assert beyond.any() and (picture[beyond] == 255).all()
    tinted = ~beyond.copy()
    tinted[row0:row0 + count.shape[0], col0:col0 + count.shape[1]] &= count == 0
    assert (picture[tinted][:, 0] > picture[tinted][:, 2]).all()  # brown, not grey
