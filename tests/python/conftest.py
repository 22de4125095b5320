"""Shared fixtures of the Python tests: a tiny deterministic light field."""

from __future__ import annotations

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


@pytest.fixture
def make_lightfield() -> Callable[..., aos.LightField]:
    """Builder of tiny constant-valued light fields (see build_lightfield)."""
    return build_lightfield
