"""The viewer's page in a real browser: Debian's headless Chromium driven by selenium, on a small
simulated scene with ground truth (the default scene: a red target under forest canopy, 7 x 7
views of 160 x 160, a 128 x 128 truth image from 30 m above the target).

* Focus: the page opens focused in the crowns (10 m); the focus slider is dragged to the ground
  (input events every step, then the change event a release sends). The hidden target appears:
  the displayed image's PSNR against the occluder-free truth rises by at least 1.5 dB (measured
  on this scene: about 20.5 dB in the crowns, 23.0 dB on the ground).
* Picking: a click on the image shows the world coordinate where the pixel's ray meets the
  focal plane, checked against the truth camera's geometry.

Screenshots (and the displayed images) are written to pytest's tmp_path for every test and
their folder is printed when a test fails (pytest keeps the last three runs' folders).
Skips with the reason when selenium or chromium-driver is missing (tools/setup_debian.sh
installs both)."""

from __future__ import annotations

import base64
import json
import math
import re
import time
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np
import pytest

import aos

pytest.importorskip("aiohttp", reason="the viewer needs aiohttp (pip install aiohttp)")
webdriver = pytest.importorskip("selenium.webdriver",
                                reason="selenium is not installed (pip install 'aos[test]')")
from selenium.webdriver.common.action_chains import ActionChains  # noqa: E402
from selenium.webdriver.common.by import By  # noqa: E402

from browser_util import CHROMEDRIVER, CHROMIUM, make_driver  # noqa: E402
pytestmark = pytest.mark.skipif(
    CHROMEDRIVER is None or CHROMIUM is None,
    reason="Chromium and its driver are missing (apt-get install chromium chromium-driver)")

CANOPY_HEIGHT = 10.0  # inside the crowns (trees 8-13 m, crowns their top 60 %)
PSNR_GAIN_DB = 1.5


def small_scene() -> dict:
    scene = json.loads(aos.default_scene().to_json())
    scene["sampling"]["grid"] = 7
    scene["camera"]["width"] = scene["camera"]["height"] = 160
    scene["truth"]["width"] = scene["truth"]["height"] = 128
    return scene


@pytest.fixture(scope="module")
def simulation() -> aos.SimulationResult:
    return aos.simulate(small_scene())


@pytest.fixture(scope="module")
def viewer(simulation: aos.SimulationResult) -> Iterator[Any]:
    truth = simulation.truth
    handle = aos.view(simulation.light_field, cam_from_world=truth.cam_from_world,
                      fov_deg=truth.camera.fov_x_deg(), width=truth.camera.width,
                      height=truth.camera.height, focal_surface=CANOPY_HEIGHT,
                      open_browser=False)
    yield handle
    handle.stop()


@pytest.fixture(scope="module")
def driver() -> Iterator[Any]:
    browser = make_driver()
    browser.set_script_timeout(30)
    yield browser
    browser.quit()


@pytest.fixture
def evidence(driver: Any, tmp_path: Path, request: pytest.FixtureRequest) -> Iterator[Callable]:
    """shoot(name): a screenshot into tmp_path (also one at the end of the test)."""

    def shoot(name: str) -> Path:
        path = tmp_path / f"{name}.png"
        driver.save_screenshot(str(path))
        return path

    # Printed output shows only for a failed test: then it names the kept screenshots.
    print(f"\nviewer screenshots in {tmp_path}")
    yield shoot
    shoot("at_end")


def wait_for(driver: Any, script: str, timeout: float = 60.0) -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = driver.execute_script(script)
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for: {script}")


def wait_full_frame(driver: Any) -> dict[str, Any]:
    """The newest full-size frame, once the page has displayed the last full request."""
    return wait_for(driver, "const s = window.aosStats; return s && s.lastFrame && "
                    "!s.lastFrame.preview && s.lastFullId > 0 && s.lastFrame.id >= s.lastFullId "
                    "? s.lastFrame : null;")


def displayed_image(driver: Any, path: Path) -> np.ndarray:
    """The image canvas's pixels (RGB), via a PNG the page encodes."""
    url = driver.execute_script("return document.getElementById('image').toDataURL('image/png');")
    path.write_bytes(base64.b64decode(url.split(",", 1)[1]))
    return np.ascontiguousarray(aos.read_image(str(path))[:, :, :3])


def focus_at(driver: Any, height: float) -> dict[str, Any]:
    """Sets the focus slider to `height` (a release: the change event) and waits for the
    full frame."""
    driver.execute_script("""
        const slider = document.getElementById('focal_height');
        slider.value = arguments[0];
        slider.dispatchEvent(new Event('change', {bubbles: true}));""", height)
    return wait_full_frame(driver)


def open_page(driver: Any, viewer: Any) -> None:
    driver.get(viewer.url)
    wait_for(driver, "return window.aosStats && window.aosStats.connected;")
    wait_full_frame(driver)


def test_dragging_focus_from_canopy_to_ground_reveals_the_target(
        driver: Any, viewer: Any, simulation: aos.SimulationResult, tmp_path: Path,
        evidence: Callable, monkeypatch: pytest.MonkeyPatch) -> None:
    """A drag: every frame shown has the full size (the previews take a subset of the views,
    here the fewest: a frame budget nothing meets), and the image at rest is the exact render of
    every view, pixel for pixel."""
    from aos.viewer import session as session_module

    truth = simulation.truth.image
    open_page(driver, viewer)
    assert driver.execute_script("return Number(document.getElementById('focal_height').value)") \
        == pytest.approx(CANOPY_HEIGHT)
    canopy = displayed_image(driver, tmp_path / "canopy_canvas.png")
    evidence("canopy")
    assert canopy.shape == truth.shape
    ground_height = simulation.truth.ground_height_at_center
    monkeypatch.setattr(session_module, "FRAME_BUDGET_MS", -1.0)
    viewer.session.preview_view_count = 1
    before = driver.execute_script("return window.aosStats.lastFrame.id;")
    # Drag: 20 input events down to the ground (what a pointer drag fires), a preview shown
    # (a release at once could replace it before it renders), then the release.
    driver.execute_script("""
        const slider = document.getElementById('focal_height');
        const from = Number(slider.value), to = arguments[0], steps = 20;
        for (let k = 1; k <= steps; k++) {
          slider.value = from + (to - from) * k / steps;
          slider.dispatchEvent(new Event('input', {bubbles: true}));
        }""", ground_height)
    wait_for(driver, f"return window.aosStats.frames.some((f) => f.preview && f.id > {before});")
    driver.execute_script("""document.getElementById('focal_height').dispatchEvent(
        new Event('change', {bubbles: true}));""")
    frame = wait_full_frame(driver)
    assert frame["width"] == truth.shape[1]
    ground = displayed_image(driver, tmp_path / "ground_canvas.png")
    evidence("ground")
    psnr_canopy = aos.compare_images(canopy, truth).psnr_db
    psnr_ground = aos.compare_images(ground, truth).psnr_db
    print(f"PSNR against the truth: canopy {psnr_canopy:.2f} dB, ground {psnr_ground:.2f} dB")
    assert psnr_ground >= psnr_canopy + PSNR_GAIN_DB, (psnr_canopy, psnr_ground, tmp_path)
    # The page shows what the server renders for that state, pixel for pixel.
    expected = aos.render_integral(simulation.light_field,
                                   cam_from_world=simulation.truth.cam_from_world,
                                   fov_deg=simulation.truth.camera.fov_x_deg(),
                                   width=128, height=128, focal_surface=ground_height).image
    np.testing.assert_array_equal(ground, np.clip(expected + 0.5, 0, 255).astype(np.uint8))
    stats = driver.execute_script("return window.aosStats;")
    assert not stats["errors"], stats["errors"]
    previews = [f for f in stats["frames"] if f["preview"] and f["id"] > before]
    fewest = min(session_module.MIN_PREVIEW_VIEWS, len(simulation.light_field))
    assert previews and all(f["view_stride"] > 1 and f["views_used"] <= fewest
                            for f in previews), (previews, len(simulation.light_field))
    assert all((f["width"], f["height"]) == (128, 128) for f in stats["frames"]), stats["frames"]
    assert frame["views_used"] > 1


def test_clicking_a_pixel_shows_its_world_coordinate(
        driver: Any, viewer: Any, simulation: aos.SimulationResult, evidence: Callable) -> None:
    open_page(driver, viewer)
    ground_height = simulation.truth.ground_height_at_center
    focus_at(driver, ground_height)
    canvas = driver.find_element(By.ID, "image")
    rect = driver.execute_script("const r = arguments[0].getBoundingClientRect(); "
                                 "return [r.width, r.height];", canvas)
    driver.execute_script("window.aosLastPick = null;")
    # Selenium offsets are from the element's centre: click 30 % right and 20 % up of it.
    dx, dy = int(0.3 * rect[0]), int(-0.2 * rect[1])
    ActionChains(driver).move_to_element_with_offset(canvas, dx, dy).click().perform()
    pick = wait_for(driver, "return window.aosLastPick;")
    evidence("picked")
    text = driver.find_element(By.ID, "pick").text
    u, v = pick["u"], pick["v"]
    # The clicked pixel is where the click landed (to a CSS pixel's rounding).
    scale = 128 / rect[0]
    assert u == pytest.approx(64 + dx * scale, abs=2 * scale)
    assert v == pytest.approx(64 + dy * scale, abs=2 * scale)
    # Geometry: the truth camera's ray through (u, v) meets the ground plane z = ground_height.
    camera = simulation.truth.camera
    pose = simulation.truth.cam_from_world
    direction = pose.rotation.T @ np.asarray(camera.unproject((u, v)))
    centre = np.asarray(pose.center)
    depth_along = (ground_height - centre[2]) / direction[2]
    expected = centre + depth_along * direction
    np.testing.assert_allclose(pick["world"], expected, atol=1e-6)
    assert pick["world"][2] == pytest.approx(ground_height, abs=1e-9)
    assert pick["depth"] == pytest.approx(depth_along, abs=1e-6)  # unproject gives z = 1
    assert 0 < pick["count"] <= len(simulation.light_field)
    shown = re.search(r"world \(([-\d.]+), ([-\d.]+), ([-\d.]+)\)", text)
    assert shown, text
    np.testing.assert_allclose([float(g) for g in shown.groups()], expected, atol=1e-3)
    assert f"seen by {pick['count']} views" in text


def test_the_page_drives_every_control_without_errors(
        driver: Any, viewer: Any, evidence: Callable) -> None:
    """Every slider and select sends a valid request (no error reaches the page). Each request
    of the sweep has one slider at three quarters of its range; some of those states (the
    camera panned or tilted off the flight) see no part of the focal plane, and the server
    answers that honestly ("no pixel is covered") when such a request is rendered before the
    next one supersedes it, which depends on timing (1 run in 4 here). Those answers are
    allowed; any other error fails."""
    open_page(driver, viewer)
    driver.execute_script("""
        for (const el of document.querySelectorAll('#controls input[type=range]')) {
          el.value = (Number(el.min) + 3 * Number(el.max)) / 4;
          el.dispatchEvent(new Event('input', {bubbles: true}));
          el.dispatchEvent(new Event('change', {bubbles: true}));
          el.value = el.defaultValue;
        }
        const c = document.getElementById('colormap'); c.value = 'iron';
        c.dispatchEvent(new Event('change'));
        const m = document.getElementById('mode'); m.value = 'map';
        m.dispatchEvent(new Event('change'));""")
    frame = wait_full_frame(driver)
    evidence("map_iron")
    stats = driver.execute_script("return window.aosStats;")
    errors = [e for e in stats["errors"] if "no pixel is covered" not in e]
    assert not errors, stats["errors"]
    assert frame["width"] > 0


def test_buttons_copy_the_command_and_compute_all_in_focus_and_a_stack(
        driver: Any, viewer: Any, evidence: Callable) -> None:
    open_page(driver, viewer)
    driver.find_element(By.ID, "copy_cli").click()
    wait_for(driver, "return document.getElementById('command').value.length > 0;")
    command = driver.find_element(By.ID, "command").get_attribute("value")
    assert command.startswith("aos-render integral ") and "--cam-from-world" in command
    driver.find_element(By.ID, "copy_python").click()
    wait_for(driver, "return document.getElementById('command').value.startsWith('result');")
    driver.execute_script("document.getElementById('slices').value = 4;")
    driver.find_element(By.ID, "allinfocus").click()
    wait_for(driver, "return document.getElementById('status').textContent === "
             "'all-in-focus done';")
    evidence("all_in_focus")
    assert driver.execute_script("return document.getElementById('progress').value") > 0
    driver.find_element(By.ID, "stack").click()
    wait_for(driver, "return document.getElementById('status').textContent.startsWith("
             "'focal stack ready');")
    assert driver.execute_script("return window.aosLastDownload.url").startswith("/api/download/")
    assert not driver.execute_script("return window.aosStats.errors;")


def test_the_browser_opens_the_page_through_its_redirect_file(
        driver: Any, simulation: aos.SimulationResult, evidence: Callable,
        monkeypatch: pytest.MonkeyPatch) -> None:
    """aos.view gives the browser a local file that redirects to the tokenised URL (so the token
    is never on the browser's command line): Chromium follows it to a working page."""
    import webbrowser

    opened: list[str] = []
    monkeypatch.setattr(webbrowser, "open", lambda url, *a, **k: opened.append(url) or True)
    handle = aos.view(simulation.light_field, open_browser=True, width=64, height=64)
    try:
        assert len(opened) == 1 and handle.token not in opened[0]
        driver.get(opened[0])
        wait_for(driver, "return window.aosStats && window.aosStats.connected;")
        wait_full_frame(driver)
        evidence("opened_through_redirect")
        assert driver.current_url == handle.url
    finally:
        handle.stop()


def test_a_page_beyond_max_pages_says_why(driver: Any, simulation: aos.SimulationResult,
                                          evidence: Callable) -> None:
    """With max_pages=1, a second tab is refused and shows the reason, not a bare
    'disconnected'."""
    handle = aos.view(simulation.light_field, open_browser=False, width=64, height=64,
                      max_pages=1)
    first_tab = driver.current_window_handle
    try:
        open_page(driver, handle)
        driver.switch_to.new_window("tab")
        driver.get(handle.url)
        text = wait_for(driver, "const s = document.getElementById('status').textContent; "
                        "return s.includes('max_pages') && s.startsWith('disconnected') ? s : "
                        "null;")
        evidence("refused_tab")
        assert "at most 1 open pages" in text, text
    finally:
        if driver.current_window_handle != first_tab:
            driver.close()
            driver.switch_to.window(first_tab)
        handle.stop()


def test_detect_marks_the_hidden_target_and_a_click_centres_on_it(
        driver: Any, viewer: Any, simulation: aos.SimulationResult, evidence: Callable) -> None:
    """Focused on the ground, the Detect button lists the hidden target (the scene's target is
    centred on the world origin) and every later frame marks it; clicking the list entry pans
    the view so that it sits at the image centre. (Last in the module: with detections held by
    the shared viewer, the control sweep above failed now and then on an intermediate state's
    render, "no pixel is covered"; not explained yet.)"""
    open_page(driver, viewer)
    ground_height = simulation.truth.ground_height_at_center
    focus_at(driver, ground_height)
    driver.execute_script("window.aosLastDetect = null;")
    driver.find_element(By.ID, "detect").click()
    answer = wait_for(driver, "return window.aosLastDetect;")
    assert answer["detections"], answer
    best = answer["detections"][0]
    assert math.hypot(best["world"][0], best["world"][1]) < 0.3, best
    wait_for(driver, "return document.querySelectorAll('#detections li').length > 0;")
    frame = wait_full_frame(driver)
    markers = wait_for(driver, "const m = window.aosStats.lastMarkers; "
                       "return m && m.length ? m : null;")
    number, u, v = markers[0]
    assert number == 1
    # The marker sits on the detection's pixel (the same camera: the page's full frame).
    assert (u, v) == pytest.approx(best["pixel"], abs=0.5)
    evidence("detected")
    before = driver.execute_script("return window.aosStats.lastFrame.id;")
    driver.find_element(By.CSS_SELECTOR, "#detections li").click()
    wait_for(driver, f"return window.aosStats.lastFullId > {before} && "
             "window.aosStats.lastFrame.id >= window.aosStats.lastFullId;")
    markers = driver.execute_script("return window.aosStats.lastMarkers;")
    centre = (frame["width"] / 2, frame["height"] / 2)
    # Pan sliders step 0.1 m: at 30 m with this camera that is under 1 pixel.
    assert markers and markers[0][1:] == pytest.approx(centre, abs=1.5), markers
    evidence("centred")
    assert not driver.execute_script("return window.aosStats.errors;")
