"""Shared fixtures of the Python tests: a tiny deterministic light field."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

import aos


def nadir_pose(x: float, y: float, altitude: float) -> aos.Rigid3d:
    """A camera at (x, y, altitude) looking straight down, image top towards +y."""
    return aos.look_at((x, y, altitude), (x, y, 0.0), up=(0.0, 1.0, 0.0))


def build_lightfield(
    views_per_side: int = 3,
    width: int = 16,
    height: int = 12,
    fov_deg: float = 60.0,
    altitude: float = 10.0,
    spacing: float = 1.0,
    dtype: type = np.uint8,
    value: float = 100.0,
    channels: int = 1,
) -> aos.LightField:
    """A grid of nadir views whose images are all `value` (so any average of them is `value`)."""
    light_field = aos.LightField()
    camera = aos.PinholeCamera.from_fov(width, height, fov_deg)
    shape = (height, width) if channels == 1 else (height, width, channels)
    offset = 0.5 * (views_per_side - 1) * spacing
    for j in range(views_per_side):
        for i in range(views_per_side):
            image = np.full(shape, value, dtype=dtype)
            pose = nadir_pose(i * spacing - offset, j * spacing - offset, altitude)
            light_field.add_view(image, camera, pose, name=f"{j * views_per_side + i:04d}")
    return light_field


@pytest.fixture(scope="module")
def forest() -> aos.LightField:
    """The default scene (a red 0.6 x 1.8 m target, a person lying, under 300 trees per
    hectare), small: 9 x 9 views of 128 x 128 pixels in flight order (a serpentine grid),
    geo-referenced in UTM 33N: origin 500000 E, 5300000 N, 300 m (the target at the local
    origin, on the ground z = 0)."""
    scene = json.loads((Path(__file__).resolve().parents[2] / "scenes" /
                        "forest_person.json").read_text())
    scene["camera"].update(width=128, height=128)
    scene["sampling"]["grid"] = 9
    light_field = aos.simulate(scene).light_field
    light_field.origin = (500000.0, 5300000.0, 300.0)
    light_field.crs = "EPSG:32633"
    return light_field


@pytest.fixture
def make_lightfield() -> Callable[..., aos.LightField]:
    """Builder of tiny constant-valued light fields (see build_lightfield)."""
    return build_lightfield


def write_colmap_text_model(light_field: Path, model: Path) -> None:
    """A COLMAP text model of the light field's views (poses are not checked by the import)."""
    lf = json.loads(light_field.read_text())
    camera = next(iter(lf["cameras"].values()))
    model.mkdir()
    (model / "cameras.txt").write_text(
        f"1 PINHOLE {camera['width']} {camera['height']} {camera['fx']} {camera['fy']} "
        f"{camera['cx']} {camera['cy']}\n")
    lines = []
    for i, view in enumerate(lf["views"], start=1):
        t = view["cam_from_world"]["translation"]
        # cam_from_world = diag(1, -1, -1): the quaternion (w, x, y, z) = (0, 1, 0, 0).
        lines += [f"{i} 0 1 0 0 {t[0]} {t[1]} {t[2]} 1 {Path(view['image']).name}", ""]
    (model / "images.txt").write_text("\n".join(lines) + "\n")
    (model / "points3D.txt").write_text("")
