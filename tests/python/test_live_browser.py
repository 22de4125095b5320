"""The live page in a real browser (Debian's headless Chromium driven by selenium): a simulated
flight is added frame by frame to an aos.LiveIntegrator shown by aos.view(live=...); the page
shows every update it is given (the newest at the end), the hidden person's marker and track,
and the flight path. The latency from an add's return to the page showing that update is
printed (what docs/live.md reports), not asserted. Skips without selenium or chromium-driver."""

from __future__ import annotations

import math
import threading
import time
from pathlib import Path
from typing import Any, Iterator

import numpy as np
import pytest

import aos

pytest.importorskip("aiohttp", reason="the viewer needs aiohttp (pip install aiohttp)")
webdriver = pytest.importorskip("selenium.webdriver",
                                reason="selenium is not installed (pip install 'aos[test]')")

from browser_util import CHROMEDRIVER, CHROMIUM, make_driver  # noqa: E402
pytestmark = pytest.mark.skipif(
    CHROMEDRIVER is None or CHROMIUM is None,
    reason="Chromium and its driver are missing (apt-get install chromium chromium-driver)")


@pytest.fixture(scope="module")
def driver() -> Iterator[Any]:
    browser = make_driver("1280,900")
    browser.set_script_timeout(30)
    yield browser
    browser.quit()


def test_the_live_page_follows_the_flight_and_marks_the_person(
        forest: aos.LightField, driver: Any, tmp_path: Path) -> None:
    flight = forest  # conftest.py: the default scene, 9 x 9 views
    live = aos.LiveIntegrator(flight, aos.IntegralOptions(focal_surface=0.0), aos.DetectOptions(),
                              aos.LiveOptions(window_frames=20))
    viewer = aos.view(live=live, open_browser=False)
    added: dict[int, float] = {}
    try:
        driver.get(viewer.url)
        time.sleep(0.5)

        def feed() -> None:
            for view in flight.views:
                live.add_view(view)
                added[live.updates] = time.time()
                time.sleep(0.15)

        feeder = threading.Thread(target=feed)
        feeder.start()
        latencies = []
        seen = set()
        deadline = time.monotonic() + 90
        while feeder.is_alive() or len(seen) == 0 or max(seen) < len(flight):
            assert time.monotonic() < deadline, "the page did not keep up"
            state = driver.execute_script(
                "const l = window.aosLive; return [l.update, l.shownAt, l.errors];")
            update, shown_at, errors = state
            assert errors == 0
            if update and update not in seen:
                seen.add(update)
                if update in added:
                    latencies.append(shown_at / 1000.0 - added[update])
            time.sleep(0.01)
        feeder.join()
        driver.save_screenshot(str(tmp_path / "live.png"))
        final = driver.execute_script("return window.aosLive.state;")
        assert final["update"] == len(flight)
        # Every update is shown unless a newer one came first; most are shown here.
        assert len(seen) >= len(flight) // 2, sorted(seen)
        width = driver.execute_script("return document.getElementById('live-image').naturalWidth;")
        assert width == 128
        # The person: a track at the target, the list names it, the path is drawn.
        person = [t for t in final["tracks"] if math.hypot(t["local"][0], t["local"][1]) < 0.5]
        assert person and person[0]["sightings"] >= 3, final["tracks"]
        items = driver.execute_script(
            "return Array.from(document.querySelectorAll('#tracks li')).map(e => e.textContent);")
        assert items and "47." in items[0]  # latitude of the UTM 33N scene
        assert driver.execute_script("return document.querySelector('#live-path') !== null;")
        lat = np.array(latencies) * 1000
        print(f"\nlive page: {len(seen)} of {len(flight)} updates shown; add -> shown "
              f"p50 {np.percentile(lat, 50):.0f} ms, p95 {np.percentile(lat, 95):.0f} ms")
    finally:
        viewer.stop()
