"""The demo from Python (aos.run_demo / aos.write_demo) and its folder: the figures say the target
is hidden in one view and visible in the integral, index.html links only to files in the folder,
and the commands it prints reproduce its images."""
from __future__ import annotations

import json
import re
import shlex
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import aos

ROOT = Path(__file__).resolve().parents[2]
EXE = shutil.which("aos-render")


def small_default_scene() -> dict:
    """The default scene (the trees, the target, the aperture) with 7 x 7 views of 160 x 160 and a
    128 x 128 truth image: a few seconds."""
    scene = json.loads(aos.default_scene().to_json())
    scene["sampling"]["grid"] = 7
    scene["camera"]["width"] = scene["camera"]["height"] = 160
    scene["truth"]["width"] = scene["truth"]["height"] = 128
    return scene


@pytest.fixture(scope="module")
def demo() -> aos.DemoResult:
    return aos.run_demo(small_default_scene(), all_in_focus_slices=4)


def test_the_target_is_hidden_in_one_view_and_visible_in_the_integral(demo: aos.DemoResult) -> None:
    assert [r.name for r in demo.renders] == ["single_view", "integral_ground", "integral_occluders",
                                              "all_in_focus"]
    single = demo.render("single_view").visibility
    integral = demo.render("integral_ground").visibility
    assert demo.truth_visibility.has_target and demo.truth_visibility.standout_fraction > 0.95
    # The trees block 50-70 % of the rays to the target (tests/cpp/demo_test.cpp explains the
    # bounds): one view shows less than a third of it, the integral nearly all of it.
    assert 0.5 < demo.target_blocked_fraction < 0.8
    assert single.standout_fraction < 0.33 and integral.standout_fraction > 0.8
    assert integral.contrast_to_noise > 4 * max(single.contrast_to_noise, 0.25)
    # The mask: target pixels (1) inside surroundings (2).
    mask = demo.target_mask
    assert mask.shape == (128, 128) and set(np.unique(mask)) == {0, 1, 2}
    assert int((mask == 1).sum()) == single.target_pixels
    image = demo.render("integral_ground").image
    assert image.dtype == np.float32 and image.shape == (128, 128, 3)
    assert demo.render("all_in_focus").count is None
    with pytest.raises(ValueError, match="no render named"):
        demo.render("nothing")


def test_options_by_keyword_and_checked() -> None:
    with pytest.raises(TypeError, match="all_in_focus_slices"):
        aos.run_demo(small_default_scene(), all_in_focus_slice=3)
    with pytest.raises(ValueError, match="target_margin_m"):
        aos.run_demo(small_default_scene(), target_margin_m=0.0)
    assert aos.DemoOptions().all_in_focus_slices == 16


def links_of(html: str) -> list[str]:
    return re.findall(r'(?:href|src)="([^"]*)"', html)


def test_write_demo_folder_and_page(demo: aos.DemoResult, tmp_path: Path) -> None:
    folder = tmp_path / "demo"
    files = aos.write_demo(demo, str(folder))
    on_disk = sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())
    assert files == on_disk
    html = (folder / "index.html").read_text()
    assert html == demo.index_html()
    links = links_of(html)
    assert len(links) > 10
    for link in links:
        assert ":" not in link and not link.startswith(("/", "..")), link
        assert (folder / link).is_file(), link
    assert "<script" not in html
    for render in demo.renders:
        assert f"{render.quality.psnr_db:.2f}" in html
        assert f"{100 * render.visibility.standout_fraction:.0f} %" in html
    summary = json.loads((folder / "demo.json").read_text())
    assert [r["name"] for r in summary["renders"]] == [r.name for r in demo.renders]
    png = aos.read_image(str(folder / "integral_ground.png"))
    expected = np.clip(np.round(demo.render("integral_ground").image), 0, 255)
    assert png.dtype == np.uint8 and np.max(np.abs(png - expected)) <= 1
    # Nothing is overwritten.
    with pytest.raises(ValueError, match="not an empty folder"):
        aos.write_demo(demo, str(folder))
    with pytest.raises(ValueError, match="not an empty folder"):
        aos.run_demo(small_default_scene(), folder)  # refused before any work
    assert sorted(p.name for p in tmp_path.iterdir()) == ["demo"]


@pytest.mark.skipif(EXE is None, reason="aos-render is not on PATH (pip install .)")
def test_the_page_commands_reproduce_its_images(demo: aos.DemoResult, tmp_path: Path) -> None:
    folder = tmp_path / "demo"
    aos.write_demo(demo, str(folder))
    html = (folder / "index.html").read_text()
    commands = re.search(r"<pre>(.*?)</pre>", html, re.S).group(1).replace("\\\n", " ")
    for line in commands.splitlines():
        words = shlex.split(line)
        if words[:2] != ["aos-render", "integral"]:
            continue
        out = words[words.index("-o") + 1]
        result = subprocess.run([EXE, *words[1:], "-q"], capture_output=True, text=True,
                                cwd=folder, timeout=120)
        assert result.returncode == 0, result.stderr
        name = Path(out).name
        # Same bytes as the demo's own PNG of that name.
        assert (tmp_path / name).read_bytes() != b""
        np.testing.assert_array_equal(aos.read_image(str(tmp_path / name)),
                                      aos.read_image(str(folder / name)), err_msg=name)


def test_default_scene_is_the_forest_person_file() -> None:
    assert aos.load_scene(str(ROOT / "scenes" / "forest_person.json")).to_json() == \
        aos.default_scene().to_json()


def test_run_demo_writes_the_folder_and_float_views_get_a_png_truth(tmp_path: Path) -> None:
    # Float views: truth/ground is a TIFF, which browsers do not show, so the page shows
    # truth_ground.png (16-bit). No all-in-focus image with 0 slices.
    scene = small_default_scene()
    scene["sampling"]["grid"] = 3
    scene["camera"].update(width=64, height=64, bit_depth=32)
    scene["truth"].update(width=48, height=48)
    folder = tmp_path / "float"
    result = aos.run_demo(scene, folder, all_in_focus_slices=0)
    assert [r.name for r in result.renders] == ["single_view", "integral_ground",
                                                "integral_occluders"]
    html = (folder / "index.html").read_text()
    assert 'src="truth_ground.png"' in html and "all_in_focus" not in html
    for link in links_of(html):
        assert (folder / link).is_file(), link
    truth_png = aos.read_image(str(folder / "truth_ground.png"))
    assert truth_png.dtype == np.uint16 and truth_png.shape == (48, 48, 3)
    assert (folder / "truth" / "ground.tif").is_file()
    assert "--all-in-focus-slices 0" in html
