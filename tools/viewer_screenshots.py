#!/usr/bin/env python3
"""Screenshots of the browser viewer for the README and docs/viewer.md, taken in headless
Chromium (selenium + Debian's chromium-driver):

    python3 tools/viewer_screenshots.py            # writes docs/viewer-f0.png, docs/viewer-demo.png

* F0 (../shared/data/jku-f0, read in place; skipped when absent): view 191's pose, focused on
  the ground at z = 21 with every view, thermal data in the "iron" colour map, auto range.
* The demo scene (the built-in default: a red target under forest canopy, 11 x 11 views),
  seen by its truth camera and focused on the ground.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
F0 = ROOT.parent / "shared" / "data" / "jku-f0" / "poses" / "poses.json"


def shoot(viewer, path: Path, setup_script: str = "") -> None:
    from selenium import webdriver

    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which("chromium") or "chromium"
    for argument in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage",
                     "--disable-gpu", "--window-size=1100,1000", "--hide-scrollbars"):
        options.add_argument(argument)
    driver = webdriver.Chrome(options=options, service=webdriver.ChromeService(
        executable_path=shutil.which("chromedriver")))
    try:
        driver.get(viewer.url)
        ready = ("const s = window.aosStats; return s && s.lastFrame && !s.lastFrame.preview && "
                 "s.lastFrame.id >= s.lastFullId;")
        deadline = time.monotonic() + 120
        while not driver.execute_script(ready) and time.monotonic() < deadline:
            time.sleep(0.2)
        if setup_script:
            driver.execute_script(setup_script)
            time.sleep(0.5)
            while not driver.execute_script(ready) and time.monotonic() < deadline:
                time.sleep(0.2)
        time.sleep(0.5)
        driver.save_screenshot(str(path))
        print(f"wrote {path}")
    finally:
        driver.quit()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs")
    args = parser.parse_args()
    import aos

    if F0.exists():
        light_field = aos.load_lightfield(str(F0), fov_deg=50.815436217896945).light_field
        viewer = aos.view(light_field, pose_view=191, focal_surface=21.0, open_browser=False,
                          source="jku-f0/poses/poses.json")
        try:
            shoot(viewer, args.out / "viewer-f0.png", """
                const set = (id, value) => { const e = document.getElementById(id);
                  e.value = value; e.dispatchEvent(new Event('change')); };
                set('colormap', 'iron'); set('range', 'auto');
                window.aosPickAt(300, 200);""")
        finally:
            viewer.stop()
    else:
        print(f"{F0} not found: no F0 screenshot")
    simulation = aos.simulate(aos.default_scene())
    truth = simulation.truth
    viewer = aos.view(simulation.light_field, cam_from_world=truth.cam_from_world,
                      fov_deg=truth.camera.fov_x_deg(), width=truth.camera.width,
                      height=truth.camera.height, focal_surface=0.0, open_browser=False,
                      source="aos-render demo (scenes/forest_person.json)")
    try:
        shoot(viewer, args.out / "viewer-demo.png", "window.aosPickAt(128, 128);")
    finally:
        viewer.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
