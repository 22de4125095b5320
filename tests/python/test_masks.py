"""Masks (issue 15, "Real flights in"): one mask image for all frames or one per frame
(LoadOptions::mask, mask_dir). A letterbox and a logo painted into every frame in a wrong colour
must not reach the render: the masked integral equals the integral of the unpainted frames over
the valid samples alone, computed here independently by a per-pixel loop in numpy."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import aos

EXE = shutil.which("aos-render")
needs_cli = pytest.mark.skipif(EXE is None, reason="aos-render is not on PATH")

W, H = 48, 40


def scene_json(channels: int) -> dict:
    # 3 x 3 views of 48 x 40 pixels, 3 m apart at 35 m, over a voxel volume: textured frames.
    return {
        "occluders": {"voxels": {"center": [0, 0, 11], "size": [20, 20, 6], "grid": [40, 40, 12],
                                 "density": 0.6}},
        "camera": {"width": W, "height": H, "fov_deg": 50, "channels": channels},
        "sampling": {"altitude": 35, "grid": 3, "aperture": {"diameter": 6}},
        "truth": {"width": 8, "height": 8, "blocked_fraction": False},
    }


RENDER = dict(pose_view=4, fov_deg=50.0, width=40, height=32, focal_surface=0.0)
WRONG = 255  # the letterbox and logo colour (every channel)


def letterbox_mask(view: int = 0, logo: bool = True) -> np.ndarray:
    """1 = valid: a letterbox of 5 rows at the top and 4 at the bottom, and a logo block whose
    place depends on `view` (for per-view masks)."""
    valid = np.ones((H, W), np.uint8)
    valid[:5] = 0
    valid[-4:] = 0
    if logo:
        x0 = 4 + 3 * (view % 4)
        valid[8:16, x0:x0 + 10] = 0
    return valid


def painted(image: np.ndarray, valid: np.ndarray) -> np.ndarray:
    out = image.copy()
    out[valid == 0] = WRONG
    return out


def write_scene(tmp_path: Path, channels: int, per_view: bool) -> tuple[Path, aos.LightField]:
    """The painted frames on disk (lf/lightfield.json + views/*.png), and the unpainted light
    field. Masks: lf/mask.png (shared) or masks/<stem>.tif (per view, upper-case names)."""
    clean = aos.simulate(scene_json(channels)).light_field
    light_field = aos.LightField()
    masks = tmp_path / "masks"
    masks.mkdir()
    for i, view in enumerate(clean.views):
        valid = letterbox_mask(i if per_view else 0)
        light_field.add_view(painted(view.image, valid), view.camera, view.cam_from_world,
                             f"{i:04d}.png")
        if per_view:
            aos.write_image(str(masks / f"{i:04d}.tif"), valid * 255)
    folder = tmp_path / "lf"
    folder.mkdir()
    aos.write_lightfield(str(folder / "lightfield.json"), light_field)
    aos.write_image(str(folder / "mask.png"), letterbox_mask() * 255)
    return folder / "lightfield.json", clean


def reference(clean: aos.LightField, valid_of, options: dict) -> dict:
    """The masked integral by a direct per-pixel loop (numpy, float64): every view's bilinear
    sample of the UNPAINTED frame at the focal point, kept when all four taps are valid, left
    out when all four are masked; pixels where some sample straddles a mask edge are marked
    unclean (the renderer weights such a sample by its bilinear mask weight)."""
    integral_options = aos.IntegralOptions()
    for key, value in options.items():
        setattr(integral_options, key, value)
    camera = aos.virtual_camera(clean, integral_options)
    pose = clean.views[options["pose_view"]].cam_from_world
    R, centre = pose.rotation, pose.center
    ys, xs = np.mgrid[0:camera.height, 0:camera.width].astype(np.float64) + 0.5
    pixels = np.stack([xs, ys, np.ones_like(xs)], axis=-1)
    rays = pixels @ np.linalg.inv(camera.K).T @ R  # R^T K^-1 p, row vectors
    s = -centre[2] / rays[..., 2]
    focal = centre + s[..., None] * rays  # on z = 0
    sums = sq = None
    count = np.zeros(xs.shape, np.int64)
    unclean = np.zeros(xs.shape, bool)
    sin_min = np.sin(np.radians(1.0))
    for i, view in enumerate(clean.views):
        image = view.image.astype(np.float64)
        if image.ndim == 2:
            image = image[..., None]
        cam = view.camera.pinhole()
        in_cam = focal @ view.cam_from_world.rotation.T + view.cam_from_world.translation
        z = in_cam[..., 2]
        u = cam.fx * in_cam[..., 0] / z + cam.cx
        v = cam.fy * in_cam[..., 1] / z + cam.cy
        to_view = view.cam_from_world.center - focal
        admitted = (z > 0) & (u >= 0) & (u <= cam.width) & (v >= 0) & (v <= cam.height)
        admitted &= np.abs(to_view[..., 2]) >= sin_min * np.linalg.norm(to_view, axis=-1)
        sx = np.clip(u - 0.5, -1, cam.width - 0.5)
        sy = np.clip(v - 0.5, -1, cam.height - 0.5)
        ix, iy = np.floor(sx).astype(int), np.floor(sy).astype(int)
        ax, ay = (sx - ix)[..., None], (sy - iy)[..., None]
        x0, x1 = np.clip(ix, 0, cam.width - 1), np.clip(ix + 1, 0, cam.width - 1)
        y0, y1 = np.clip(iy, 0, cam.height - 1), np.clip(iy + 1, 0, cam.height - 1)
        top = image[y0, x0] + ax * (image[y0, x1] - image[y0, x0])
        bottom = image[y1, x0] + ax * (image[y1, x1] - image[y1, x0])
        sample = top + ay * (bottom - top)
        valid = valid_of(i)
        taps = valid[y0, x0].astype(int) + valid[y0, x1] + valid[y1, x0] + valid[y1, x1]
        keep = admitted & (taps == 4)
        unclean |= admitted & (taps > 0) & (taps < 4)
        if sums is None:
            sums = np.zeros(sample.shape)
            sq = np.zeros(sample.shape)
        sums += np.where(keep[..., None], sample, 0.0)
        sq += np.where(keep[..., None], sample * sample, 0.0)
        count += keep
    n = np.maximum(count, 1)[..., None]
    mean = sums / n
    variance = np.where(count >= 2, (sq / n - mean * mean).mean(axis=-1), 0.0)
    return dict(image=mean.squeeze(-1) if mean.shape[-1] == 1 else mean, count=count,
                variance=variance, clean=~unclean)


@pytest.mark.parametrize("channels", [1, 3])
def test_masked_integral_equals_the_valid_samples_of_the_unpainted_frames(
        tmp_path: Path, channels: int) -> None:
    path, clean = write_scene(tmp_path, channels, per_view=False)
    mask = path.parent / "mask.png"
    loaded = aos.load_lightfield(path, mask=mask)
    lf = loaded.light_field
    assert lf.masked
    assert lf.views[0].image.shape == (H, W, channels + 1)  # values and the weight channel
    assert any("mask" in note and "valid" in note for note in loaded.notes), loaded.notes
    result = aos.render_integral(lf, variance=True, **RENDER)
    truth = reference(clean, lambda i: letterbox_mask(), RENDER)
    clean_pixels = truth["clean"]
    assert clean_pixels.mean() > 0.5  # most pixels have no sample on a mask edge
    # Outputs have the frames' channels, never the weight.
    assert result.image.shape == truth["image"].shape
    # Float32 sample positions and values against float64: well under 0.01 of 255.
    np.testing.assert_allclose(result.image[clean_pixels], truth["image"][clean_pixels], atol=0.01)
    np.testing.assert_array_equal(result.count[clean_pixels], truth["count"][clean_pixels])
    # Variance of the valid samples, recovered from the premultiplied sums (masked_mean.h):
    # float32 means of values up to 255 squared, ~1e-7 * 255^2 * channels / mbar, mbar >= 1/9.
    np.testing.assert_allclose(result.variance[clean_pixels], truth["variance"][clean_pixels],
                               atol=0.1, rtol=1e-4)
    assert result.uncovered_pixels == int((result.count == 0).sum())
    assert result.samples == int(result.count.sum())
    # The painted colour does reach an unmasked render (what the mask is for).
    plain = aos.render_integral(aos.load_lightfield(path).light_field, **RENDER)
    assert np.abs(plain.image[clean_pixels] - truth["image"][clean_pixels]).max() > 20


def test_mask_dir_one_mask_per_view(tmp_path: Path) -> None:
    path, clean = write_scene(tmp_path, 1, per_view=True)
    loaded = aos.load_lightfield(path, mask_dir=tmp_path / "masks")  # 0000.png -> 0000.tif
    assert loaded.light_field.masked
    result = aos.render_integral(loaded.light_field, **RENDER)
    truth = reference(clean, lambda i: letterbox_mask(i), RENDER)
    ok = truth["clean"]
    assert ok.mean() > 0.5
    np.testing.assert_allclose(result.image[ok], truth["image"][ok], atol=0.01)
    np.testing.assert_array_equal(result.count[ok], truth["count"][ok])
    # The shared mask (logo at one place) is not the per-view truth: the test can tell.
    shared = aos.render_integral(aos.load_lightfield(path, mask=path.parent / "mask.png")
                                 .light_field, **RENDER)
    assert np.abs(shared.image[ok] - truth["image"][ok]).max() > 1


def test_every_render_route_gives_the_masked_mean(tmp_path: Path) -> None:
    """The per-sample path (depth map), the focal stack and nearest mode divide too."""
    path, clean = write_scene(tmp_path, 1, per_view=False)
    lf = aos.load_lightfield(path, mask=path.parent / "mask.png").light_field
    plane = aos.render_integral(lf, **RENDER)
    depth = _depth_of_plane(lf)  # camera z of the plane z = 0
    on_depth = aos.render_integral_on_depth(lf, depth, **RENDER).integral
    assert on_depth.image.shape == plane.image.shape
    np.testing.assert_allclose(on_depth.image, plane.image, atol=2e-3)
    assert np.abs(on_depth.count.astype(int) - plane.count.astype(int)).max() <= 1
    assert (on_depth.count != plane.count).mean() < 0.02  # rounding at mask edges only
    stack = aos.render_focal_stack(lf, first_plane=0.0, last_plane=1.0, slices=2,
                                   **{k: v for k, v in RENDER.items() if k != "focal_surface"})
    np.testing.assert_allclose(stack.images[0], plane.image, atol=1e-5)
    # Nearest mode: the nearest view's sample where it is valid, else uncovered.
    nearest = aos.render_integral(lf, **{**RENDER, "aperture_radius": 0.0})
    truth = reference(clean, lambda i: letterbox_mask(), RENDER)
    assert set(np.unique(nearest.count)) <= {0, 1}
    plain_nearest = aos.render_integral(aos.load_lightfield(path).light_field,
                                        **{**RENDER, "aperture_radius": 0.0})
    covered = nearest.count == 1
    assert 0 < covered.mean() < 1
    np.testing.assert_allclose(nearest.image[covered & truth["clean"]],
                               plain_nearest.image[covered & truth["clean"]], atol=1e-3)
    assert np.all(nearest.image[~covered] == 0)


def test_map(tmp_path: Path) -> None:
    path, _ = write_scene(tmp_path, 1, per_view=False)
    lf = aos.load_lightfield(path, mask=path.parent / "mask.png").light_field
    plain_lf = aos.load_lightfield(path).light_field
    masked_map = aos.render_map(lf, pixel_size=0.5, focal_surface=0.0)
    plain_map = aos.render_map(plain_lf, pixel_size=0.5, focal_surface=0.0)
    assert masked_map.image.shape == plain_map.image.shape  # no weight channel
    covered = masked_map.count > 0
    # The painted letterbox (255) pulls the unmasked map up; the masked one never sees it.
    assert plain_map.image[covered].max() > masked_map.image[covered].max() - 1
    assert np.abs(plain_map.image - masked_map.image)[covered].max() > 20


def test_robust_mean_divides_per_sample(tmp_path: Path) -> None:
    """The robust mean (merge --method robust) leaves out samples of weight 0 and divides the
    others by their weight: with a band wide enough for every sample it is the masked mean."""
    path, clean = write_scene(tmp_path, 1, per_view=False)
    lf = aos.load_lightfield(path, mask=path.parent / "mask.png").light_field
    camera = aos.virtual_camera(lf, aos.IntegralOptions(pose_view=4, fov_deg=50.0, width=40,
                                                       height=32))
    centre = lf.views[4].cam_from_world.center
    R = lf.views[4].cam_from_world.rotation
    ys, xs = np.mgrid[0:camera.height, 0:camera.width] + 0.5
    rays = np.stack([xs, ys, np.ones_like(xs)], -1) @ np.linalg.inv(camera.K).T @ R
    depth = (-centre[2] / rays[..., 2]).astype(np.float32)
    robust = aos.render_integral_on_depth(lf, depth, robust=True, agreement=1.0,
                                          variance=True, **RENDER)
    truth = reference(clean, lambda i: letterbox_mask(), RENDER)
    ok = truth["clean"]
    assert robust.integral.image.shape == (32, 40)
    np.testing.assert_allclose(robust.integral.image[ok], truth["image"][ok], atol=0.01)
    np.testing.assert_array_equal(robust.integral.count[ok], truth["count"][ok])
    np.testing.assert_allclose(robust.integral.variance[ok], truth["variance"][ok], atol=0.01)
    # The whole pipeline runs on a masked light field and returns the frames' channels.
    merged = aos.all_in_focus(lf, method="robust", first_plane=0.0, last_plane=1.0, slices=2,
                              **{k: v for k, v in RENDER.items() if k != "focal_surface"})
    assert merged.image.shape == (32, 40)


# --- Bad input --------------------------------------------------------------------------------

def test_bad_masks_are_refused_naming_the_file(tmp_path: Path) -> None:
    path, _ = write_scene(tmp_path, 1, per_view=True)
    small = tmp_path / "small.png"
    aos.write_image(str(small), np.full((20, 30), 255, np.uint8))
    with pytest.raises(ValueError, match=r"view 0 \(views/0000.png\): mask .*small.png is 30x20 but "
                                         r"the frame is 48x40"):
        aos.load_lightfield(path, mask=small)
    broken = tmp_path / "broken.png"
    broken.write_bytes(b"not a png")
    with pytest.raises(ValueError, match="broken.png"):
        aos.load_lightfield(path, mask=broken)
    with pytest.raises(ValueError, match="missing.png"):
        aos.load_lightfield(path, mask=tmp_path / "missing.png")
    with pytest.raises(ValueError, match="mask/mask_dir"):
        aos.load_lightfield(path, mask=small, mask_dir=tmp_path / "masks")
    # A folder missing one view's mask: that view is named.
    (tmp_path / "masks" / "0003.tif").unlink()
    with pytest.raises(ValueError, match=r"view 3 \(views/0003.png\): mask_dir: no mask for this frame"):
        aos.load_lightfield(path, mask_dir=tmp_path / "masks")
    with pytest.raises(ValueError, match="mask_dir: folder .* does not exist"):
        aos.load_lightfield(path, mask_dir=tmp_path / "nowhere")
    # Two masks for one frame are ambiguous.
    (tmp_path / "masks" / "0003.tif").write_bytes(b"")
    aos.write_image(str(tmp_path / "masks" / "0004.png"), letterbox_mask() * 255)
    with pytest.raises(ValueError, match=r"view 4 \(views/0004.png\): mask_dir: 2 masks match"):
        aos.load_lightfield(path, mask_dir=tmp_path / "masks")
    # An unreadable per-view mask: the view and the file are named.
    (tmp_path / "masks" / "0004.png").unlink()
    with pytest.raises(ValueError, match=r"view 3 \(views/0003.png\): mask .*0003.tif"):
        aos.load_lightfield(path, mask_dir=tmp_path / "masks")


def test_rgba_frames_with_a_mask_are_refused(tmp_path: Path) -> None:
    clean = aos.simulate(scene_json(3)).light_field
    light_field = aos.LightField()
    for i, view in enumerate(clean.views[:2]):
        rgba = np.concatenate([view.image, np.full((H, W, 1), 255, np.uint8)], axis=-1)
        light_field.add_view(rgba, view.camera, view.cam_from_world, f"{i:04d}.png")
    aos.write_lightfield(str(tmp_path / "lf.json"), light_field)
    aos.write_image(str(tmp_path / "mask.png"), letterbox_mask() * 255)
    with pytest.raises(ValueError, match="4 channels.*grey"):
        aos.load_lightfield(tmp_path / "lf.json", mask=tmp_path / "mask.png")
    # Grey first, then the mask: accepted.
    grey = aos.load_lightfield(tmp_path / "lf.json", mask=tmp_path / "mask.png", grey=True)
    assert grey.light_field.views[0].image.shape == (H, W, 2)


def test_all_zero_mask_leaves_every_pixel_uncovered_with_a_note(tmp_path: Path) -> None:
    """An all-zero mask is a note when loading; the render then covers no pixel, which
    aos.render_integral refuses (as the CLI does) naming the masks among the causes."""
    path, _ = write_scene(tmp_path, 1, per_view=False)
    zero = tmp_path / "zero.png"
    aos.write_image(str(zero), np.zeros((H, W), np.uint8))
    loaded = aos.load_lightfield(path, mask=zero)
    assert any("all zero" in note for note in loaded.notes), loaded.notes
    with pytest.raises(ValueError, match=r"no pixel is covered: no view sees the plane .*masks"):
        aos.render_integral(loaded.light_field, variance=True, **RENDER)


def test_masked_light_field_pickles_and_compares(tmp_path: Path) -> None:
    import pickle

    path, _ = write_scene(tmp_path, 1, per_view=False)
    masked = aos.load_lightfield(path, mask=path.parent / "mask.png").light_field
    copy = pickle.loads(pickle.dumps(masked))
    assert copy.masked and copy == masked
    assert "masked=True" in repr(masked)
    assert aos.load_lightfield(path).light_field != masked


# --- CLI --------------------------------------------------------------------------------------

def run(*args: object) -> subprocess.CompletedProcess:
    return subprocess.run([EXE, *map(str, args)], capture_output=True, text=True, timeout=120)


@needs_cli
def test_cli_mask_and_mask_dir(tmp_path: Path) -> None:
    path, _ = write_scene(tmp_path, 1, per_view=True)
    flags = ["--pose-view", "4", "--fov-deg", "50", "--width", "40", "--height", "32",
             "--focal-height", "0"]
    out = tmp_path / "masked.tif"
    result = run("integral", path, *flags, "--mask-dir", tmp_path / "masks", "--sample-type",
                 "float32", "-o", out)
    assert result.returncode == 0, result.stderr
    python = aos.render_integral(
        aos.load_lightfield(path, mask_dir=tmp_path / "masks").light_field, **RENDER)
    np.testing.assert_allclose(aos.read_image(str(out)), python.image, atol=1e-4)
    # --mask and --mask-dir exclude each other; both exist on stack, allinfocus and map.
    result = run("integral", path, *flags, "--mask", path.parent / "mask.png", "--mask-dir",
                 tmp_path / "masks", "-o", tmp_path / "both.tif")
    assert result.returncode != 0 and "excludes" in result.stderr
    for command in ("stack", "allinfocus", "map"):
        help_text = run(command, "--help").stdout
        assert "--mask " in help_text and "--mask-dir" in help_text, command
    result = run("map", path, "--pixel-size", "0.5", "--mask", path.parent / "mask.png", "-o",
                 tmp_path / "map.tif")
    assert result.returncode == 0, result.stderr
    # The map has the render's channels (the weight channel divided out) and the count.
    rasterio = pytest.importorskip("rasterio")
    with rasterio.open(tmp_path / "map.tif") as dataset:
        assert dataset.descriptions[-1] == "count"
        loaded = aos.load_lightfield(path, mask=path.parent / "mask.png").light_field
        expected = aos.render_map(loaded, pixel_size=0.5)
        assert dataset.count == (1 if expected.image.ndim == 2 else expected.image.shape[2]) + 1


def test_rectified_light_field_stays_masked(tmp_path: Path) -> None:
    """rectify resamples the premultiplied frames and their weights alike: still masked."""
    path, _ = write_scene(tmp_path, 1, per_view=False)
    lf = aos.load_lightfield(path, mask=path.parent / "mask.png").light_field
    rectified = aos.rectify_light_field(lf).light_field
    assert rectified.masked
    np.testing.assert_array_equal(aos.render_integral(rectified, **RENDER).image,
                                  aos.render_integral(lf, **RENDER).image)


def test_a_masked_light_field_is_not_written(tmp_path: Path) -> None:
    """Its frames carry premultiplied values and a weight channel: writing them (or the unmasked
    files its views name) would lose the mask silently. Refused, naming the file; nothing
    written (a rectified masked light field included)."""
    path, _ = write_scene(tmp_path, 1, per_view=False)
    lf = aos.load_lightfield(path, mask=path.parent / "mask.png").light_field
    rectified = aos.rectify_light_field(lf).light_field
    for light_field in (lf, rectified):
        target = tmp_path / "out" / "lightfield.json"
        with pytest.raises(ValueError, match="the light field is masked"):
            aos.write_lightfield(str(target), light_field)
        assert not target.exists()


def _depth_of_plane(lf: aos.LightField) -> np.ndarray:
    """Camera z of the plane z = 0 for RENDER's virtual camera (the depth-map routes)."""
    camera = aos.virtual_camera(lf, aos.IntegralOptions(pose_view=4, fov_deg=50.0, width=40,
                                                       height=32))
    centre = lf.views[4].cam_from_world.center
    R = lf.views[4].cam_from_world.rotation
    ys, xs = np.mgrid[0:camera.height, 0:camera.width] + 0.5
    rays = np.stack([xs, ys, np.ones_like(xs)], -1) @ np.linalg.inv(camera.K).T @ R
    return (-centre[2] / rays[..., 2]).astype(np.float32)


@pytest.mark.parametrize("kind", ["constant", "plus_minus_one"])
def test_masked_variance_of_16_bit_frames_is_exact(tmp_path: Path, kind: str) -> None:
    """16-bit frames near the top of their range: every view constant 60000, or 60000 + 1 and
    60000 - 1 in turn. Each sample is then exact (bilinear weights of equal taps), so the
    variance of the valid samples is exactly 0, or the analytic population variance up to double
    rounding (~1e-6), on every render route; where some views are masked out (mean mask weight
    below 1) it was recovered from float32 means of the premultiplied values, tens of units off."""
    geometry = aos.simulate(scene_json(1)).light_field
    valid = letterbox_mask()
    clean, on_disk = aos.LightField(), aos.LightField()
    for i, view in enumerate(geometry.views):
        value = 60000 if kind == "constant" else 60000 + (1 if i % 2 else -1)
        image = np.full((H, W), value, np.uint16)
        clean.add_view(image, view.camera, view.cam_from_world, f"{i:04d}.png")
        on_disk.add_view(np.where(valid == 1, image, 65535).astype(np.uint16), view.camera,
                         view.cam_from_world, f"{i:04d}.png")
    folder = tmp_path / "lf"
    folder.mkdir()
    aos.write_lightfield(str(folder / "lightfield.json"), on_disk)
    aos.write_image(str(folder / "mask.png"), valid * 255)
    lf = aos.load_lightfield(folder / "lightfield.json", mask=folder / "mask.png").light_field
    assert lf.masked and lf.views[0].image.dtype == np.uint16
    truth = reference(clean, lambda i: valid, RENDER)
    ok = truth["clean"] & (truth["count"] >= 2)
    partial = ok & (truth["count"] < 9)  # some views masked out: mean mask weight below 1
    assert partial.sum() > 50
    depth = _depth_of_plane(lf)
    routes = {
        "plane": aos.render_integral(lf, variance=True, **RENDER),
        "depth": aos.render_integral_on_depth(lf, depth, variance=True, **RENDER).integral,
        "robust": aos.render_integral_on_depth(lf, depth, robust=True, agreement=1.0,
                                               variance=True, **RENDER).integral,
    }
    for route, result in routes.items():
        same = ok & (result.count == truth["count"])
        assert same[partial].mean() > 0.9, route
        if kind == "constant":
            assert np.all(result.variance[same] == 0.0), (route, result.variance[same].max())
        else:
            assert truth["variance"][same & partial].max() > 0.5
            np.testing.assert_allclose(result.variance[same], truth["variance"][same], atol=1e-5,
                                       err_msg=route)
