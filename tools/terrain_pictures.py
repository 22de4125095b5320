#!/usr/bin/env python3
"""The pictures of docs/terrain-and-maps.md: the JKU F0 light field on its terrain.

(a) docs/terrain-f0-view191.png: F0 integrated for the virtual camera of view 191 (its pose,
    50.815 degrees, 512 x 512, all 382 views, aperture infinite), side by side on
    1. the horizontal plane z = +21 (F0's frame has z DOWN: 21 m below z = 0),
    2. the terrain mesh dem/dem_lr.obj,
    3. the same mesh 1 m above the terrain (surface_offset 1.0, towards the drone).
    The three share one grey mapping: the 1st..99th percentile of their covered pixels together
    to 0..255; pixels no view sees (count 0) are black. 8 px white gaps between panels. Below
    them, the same three cropped to pixels x 64..256, y 256..400 (three warm spots) and enlarged
    8/3 times (pixel repetition).

(b) docs/terrain-f0-map.png: the F0 map rendered on the mesh (aos.render_map, pixel size
    0.25 m, focal_surface dem_lr.obj; the same as `aos-render map poses.json --frames-fov-deg
    50.815436217896945 --pixel-size 0.25 --focal-surface dem_lr.obj -o map.tif`), drawn over a
    hillshade of the terrain: the mesh is rasterised onto the map's grid widened to the mesh's
    extent (aos.FocalSurface.heights_at: the vertical line through each pixel centre), written as
    a float32 GeoTIFF (aos.Heightfield.write) with elevation = -z (the frame's z points down),
    shaded by `gdaldem hillshade` (azimuth 315, altitude 45), and composed with numpy: the map
    (1st..99th percentile to 0..255, grey) where its count is > 0, the hillshade tinted brown
    elsewhere, white beyond the mesh. The map is streamed into a Cloud-Optimised GeoTIFF and read
    back with rasterio, placed by the file's own geotransform. Both rasters are in the frame's own x/y axes, north-up (row 0 = largest y); F0 has
    no CRS, so "north" is the frame's +y and the map, seen along the frame's -up = +z, is the
    ground as seen from below (mirrored against a photograph from above: docs/terrain-and-maps.md,
    "Up").

Images are written with aos.write_image (PNG); no plotting library is needed. The F0 data
(../shared/data/jku-f0, or --data) is (c) 2021 Johannes Kepler University Linz, Institute of
Computer Graphics, licensed for evaluation, education and research with its notice kept
(LICENSE.txt there); the pictures are derived from it and carry that notice in the docs.

    python tools/terrain_pictures.py                 # writes the two PNGs into docs/
    python tools/terrain_pictures.py --out /tmp/pics --keep   # also keeps map.tif, dem.tif, ...
"""

from __future__ import annotations

import argparse
import json
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

import aos

ROOT = pathlib.Path(__file__).resolve().parent.parent
FOV_DEG = 50.815436217896945  # F0's frames (README.md of the data)
VIEW = 191
PLANE_Z = 21.0
MAP_PIXEL_M = 0.25
CROP = (64, 256, 256, 400)  # x0, y0, x1, y1 of the enlarged crop of (a), pixels of the 512 x 512


def stretch(images: list[np.ndarray], masks: list[np.ndarray]) -> list[np.ndarray]:
    """One grey mapping for all: the 1st..99th percentile of the covered pixels to 0..255."""
    values = np.concatenate([image[mask] for image, mask in zip(images, masks)])
    lo, hi = np.percentile(values, [1.0, 99.0])
    out = []
    for image, mask in zip(images, masks):
        grey = np.clip((image - lo) / max(hi - lo, 1e-6) * 255.0 + 0.5, 0, 255).astype(np.uint8)
        out.append(np.where(mask, grey, 0).astype(np.uint8))
    return out


def side_by_side(panels: list[np.ndarray], gap: int = 8) -> np.ndarray:
    height = max(p.shape[0] for p in panels)
    parts = []
    for i, panel in enumerate(panels):
        if i:
            parts.append(np.full((height, gap), 255, dtype=np.uint8))
        parts.append(panel)
    return np.concatenate(parts, axis=1)


def view_panels(light_field: aos.LightField, mesh: aos.Mesh, report: dict) -> np.ndarray:
    common = dict(pose_view=VIEW, fov_deg=FOV_DEG, width=512, height=512)
    renders = {}
    for name, extra in (("plane z=+21", dict(focal_surface=aos.Plane.at_height(PLANE_Z))),
                        ("dem_lr.obj", dict(focal_surface=mesh)),
                        ("dem_lr.obj +1 m", dict(focal_surface=mesh, surface_offset=1.0))):
        start = time.perf_counter()
        result = aos.render_integral(light_field, **common, **extra)
        renders[name] = result
        report[name] = dict(seconds=round(time.perf_counter() - start, 3),
                            views_used=result.views_used, samples=result.samples,
                            uncovered_pixels=result.uncovered_pixels)
    images = [r.image for r in renders.values()]
    masks = [r.count > 0 for r in renders.values()]
    panels = stretch(images, masks)
    # Below: the crop around the three warm spots, CROP (x0, y0, x1, y1), enlarged 8/3 x by
    # pixel repetition, with the same mapping.
    x0, y0, x1, y1 = CROP
    crops = [np.repeat(np.repeat(p[y0:y1, x0:x1], 8, axis=0), 8, axis=1)[::3, ::3] for p in panels]
    top = side_by_side(panels)
    bottom = side_by_side(crops)
    bottom = np.pad(bottom, ((0, 0), (0, top.shape[1] - bottom.shape[1])), constant_values=255)
    return np.concatenate([top, np.full((8, top.shape[1]), 255, np.uint8), bottom], axis=0)


def map_over_hillshade(light_field: aos.LightField, mesh: aos.Mesh, work: pathlib.Path,
                       report: dict) -> np.ndarray:
    start = time.perf_counter()
    surface = aos.FocalSurface(mesh)
    m = aos.render_map(light_field, pixel_size=MAP_PIXEL_M, focal_surface=surface,
                       path=work / "map.tif")  # streamed into the file; read back below
    report["map"] = dict(seconds=round(time.perf_counter() - start, 3), width=m.width,
                         height=m.height, geotransform=list(m.geotransform), crs=m.crs,
                         views_used=m.views_used, views_selected=m.views_selected,
                         uncovered_pixels=m.uncovered_pixels, up_z=m.up_z)
    # The map as GIS tools open it: its bands and geotransform from the file (rasterio).
    import rasterio

    with rasterio.open(work / "map.tif") as src:
        value, count = src.read(1), src.read(2)
        x0, p, y0 = src.transform.c, src.transform.a, src.transform.f
        assert src.transform.b == src.transform.d == 0.0 and src.transform.e == -p
        assert src.crs is None  # F0's frame has no CRS
    # The DEM's grid: the map's, widened by whole pixels to the mesh's extent.
    v = mesh.vertices
    left = int(np.ceil((x0 - v[:, 0].min()) / p))
    top = int(np.ceil((v[:, 1].max() - y0) / p))
    right = int(np.ceil((v[:, 0].max() - (x0 + m.width * p)) / p))
    bottom = int(np.ceil(((y0 - m.height * p) - v[:, 1].min()) / p))
    left, top, right, bottom = (max(0, k) for k in (left, top, right, bottom))
    width, height = m.width + left + right, m.height + top + bottom
    dem_x0, dem_y0 = x0 - left * p, y0 + top * p
    cols, rows = np.meshgrid(np.arange(width), np.arange(height))
    xy = np.stack([dem_x0 + (cols.ravel() + 0.5) * p, dem_y0 - (rows.ravel() + 0.5) * p], axis=1)
    z = surface.heights_at(light_field, xy).reshape(height, width)
    elevation = (-z).astype(np.float32)  # z points down in F0's frame
    aos.Heightfield(elevation, (dem_x0, p, 0.0, dem_y0, 0.0, -p)).write(str(work / "dem.tif"))
    subprocess.run(["gdaldem", "hillshade", "-q", "-az", "315", "-alt", "45", "-compute_edges",
                    str(work / "dem.tif"), str(work / "hillshade.tif")], check=True)
    shade = aos.read_image(work / "hillshade.tif").astype(np.float64)
    if shade.ndim == 3:
        shade = shade[..., 0]
    report["dem"] = dict(width=width, height=height, elevation_min=float(np.nanmin(elevation)),
                         elevation_max=float(np.nanmax(elevation)))
    # The hillshade, tinted brown; the map (grey) where a view sees it.
    tint = np.array([1.0, 0.85, 0.65])
    rgb = np.clip(shade[..., None] * tint, 0, 255)
    rgb[~np.isfinite(elevation)] = 255.0  # beyond the mesh: white
    covered = count > 0
    (grey,) = stretch([np.nan_to_num(value)], [covered])
    window = rgb[top:top + m.height, left:left + m.width]
    window[covered] = grey[covered][:, None]
    return (rgb + 0.5).astype(np.uint8)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", default=str(ROOT.parent / "shared" / "data" / "jku-f0"))
    parser.add_argument("--out", default=str(ROOT / "docs"))
    parser.add_argument("--keep", action="store_true", help="keep map.tif, dem.tif, hillshade.tif")
    args = parser.parse_args()
    data = pathlib.Path(args.data)
    if not (data / "poses" / "poses.json").exists():
        print(f"terrain_pictures: no F0 data in {data}", file=sys.stderr)
        return 1
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    loaded = aos.load_lightfield(data / "poses" / "poses.json", fov_deg=FOV_DEG)
    light_field = loaded.light_field
    mesh = aos.Mesh.read(str(data / "dem" / "dem_lr.obj"))
    report: dict = {}
    work = pathlib.Path(tempfile.mkdtemp(prefix="terrain_pictures_"))
    try:
        aos.write_image(out / "terrain-f0-view191.png", view_panels(light_field, mesh, report))
        aos.write_image(out / "terrain-f0-map.png",
                        map_over_hillshade(light_field, mesh, work, report))
        if args.keep:
            for name in ("map.tif", "dem.tif", "hillshade.tif"):
                shutil.copy(work / name, out / name)
    finally:
        shutil.rmtree(work)
    print(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
