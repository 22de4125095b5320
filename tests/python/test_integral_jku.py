"""The renderer on real data: the JKU-ICG F0 thermal light field (382 views), compared with an
independent float64 numpy reference. Skips when ../shared/data/jku-f0 is absent."""
import json
import os
from pathlib import Path

import numpy as np
import pytest

import aos

FOV_DEG = 50.815436217896945  # from the data set's README: full FOV, horizontal = vertical
DATA = Path(os.environ.get("AOS_JKU_F0", Path(__file__).resolve().parents[3] / "shared" / "data" / "jku-f0"))
POSES = DATA / "poses" / "poses.json"

# Skips where the data is absent, unless AOS_REQUIRE_F0=1 demands it.
if os.environ.get("AOS_REQUIRE_F0") == "1" and not POSES.exists():
    raise RuntimeError(f"AOS_REQUIRE_F0=1 but the JKU F0 data is not at {DATA}")
pytestmark = pytest.mark.skipif(not POSES.exists(), reason=f"JKU F0 data not found at {DATA}")


def _load_reference_poses():
    """Poses straight from the JSON (numbers or numeric strings), independent of aos."""
    entries = json.loads(POSES.read_text())["images"]
    poses = []
    for entry in entries:
        m = np.array([[float(v) for v in row] for row in entry["M3x4"]], dtype=np.float64)
        poses.append((entry["imagefile"], m[:, :3], m[:, 3]))
    return poses


def _reference_integral(images, poses, virtual_index, width, height, fov_deg, min_angle_deg=1.0):
    """Eq. 1 in float64, per the documented conventions: pixel centres at +0.5, principal point
    at the image centre, bilinear sampling with edges replicated inside [0, w] x [0, h], views
    must see the focal point in front, inside the image, at >= min_angle to the plane z = 0."""
    f = 0.5 * width / np.tan(np.radians(fov_deg) / 2)
    _, R_v, t_v = poses[virtual_index]
    c = -R_v.T @ t_v
    xs, ys = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    rays_cam = np.stack([(xs - width / 2) / f, (ys - height / 2) / f, np.ones_like(xs)], -1)
    rays = rays_cam @ R_v  # R_v^T applied to each ray
    t = -c[2] / rays[..., 2]
    X = c + t[..., None] * rays  # focal points on z = 0
    total = np.zeros((height, width))
    count = np.zeros((height, width), dtype=np.int64)
    sin_min = np.sin(np.radians(min_angle_deg))
    for image, (_, R, tr) in zip(images, poses):
        h_img, w_img = image.shape
        fi = 0.5 * w_img / np.tan(np.radians(fov_deg) / 2)
        P = X @ R.T + tr
        z = P[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = fi * P[..., 0] / z + w_img / 2
            v = fi * P[..., 1] / z + h_img / 2
        C = -R.T @ tr
        to_view = C - X
        sin_angle = np.abs(to_view[..., 2]) / np.linalg.norm(to_view, axis=-1)
        ok = (z > 0) & (u >= 0) & (u <= w_img) & (v >= 0) & (v <= h_img) & (sin_angle >= sin_min)
        sx = np.where(ok, u - 0.5, 0.0)
        sy = np.where(ok, v - 0.5, 0.0)
        x0 = np.floor(sx).astype(np.int64)
        y0 = np.floor(sy).astype(np.int64)
        ax, ay = sx - x0, sy - y0
        img = image.astype(np.float64)

        def tap(yy, xx):
            return img[np.clip(yy, 0, h_img - 1), np.clip(xx, 0, w_img - 1)]

        top = tap(y0, x0) * (1 - ax) + tap(y0, x0 + 1) * ax
        bottom = tap(y0 + 1, x0) * (1 - ax) + tap(y0 + 1, x0 + 1) * ax
        value = top * (1 - ay) + bottom * ay
        total += np.where(ok, value, 0.0)
        count += ok
    return np.where(count > 0, total / np.maximum(count, 1), 0.0), count


@pytest.fixture(scope="module")
def f0():
    return aos.load_lightfield(str(POSES), fov_deg=FOV_DEG)


def test_loads_all_382_views_and_says_which_frames_it_used(f0):
    light_field = f0.light_field
    assert len(light_field) == 382
    assert f0.format == "jku"
    assert any(".png" in note for note in f0.notes), f0.notes
    image = light_field.views[0].image
    assert image.shape == (512, 512) and image.dtype == np.uint8


def test_view_191_on_z0_matches_an_independent_float64_reference(f0, tmp_path_factory):
    light_field = f0.light_field
    result = aos.render_integral(light_field, pose_view=191, fov_deg=FOV_DEG, width=512, height=512,
                                 focal_surface=aos.Plane.at_height(0.0))
    assert result.image.shape == (512, 512) and result.image.dtype == np.float32
    assert np.all(np.isfinite(result.image))
    assert result.count.min() > 0, "every pixel must be covered (view 191 itself sees all)"

    images = [view.image for view in light_field.views]
    reference, reference_count = _reference_integral(images, _load_reference_poses(), 191, 512, 512, FOV_DEG)
    mae = float(np.mean(np.abs(result.image - reference)))
    # Pixels whose set of views differs (a focal point exactly on a view's image border) are rare.
    count_mismatch = float(np.mean(result.count != reference_count))
    print(f"F0 MAE vs float64 reference: {mae:.5f} grey levels; count mismatch {count_mismatch:.2e}")
    if not (mae < 0.05 and count_mismatch < 1e-3):
        # Leave the render, the reference and their difference for inspection.
        folder = Path(tmp_path_factory.mktemp("f0_failure"))
        aos.write_image(str(folder / "render.exr"), result.image)
        aos.write_image(str(folder / "reference.exr"), reference.astype(np.float32))
        aos.write_image(str(folder / "difference.exr"), (result.image - reference).astype(np.float32))
        print(f"F0 comparison images written to {folder}")
    assert mae < 0.05
    assert count_mismatch < 1e-3
