"""Debian's headless Chromium driven by selenium, for the browser tests (the viewer's page and
the live page): one place for the driver's options."""

from __future__ import annotations

import shutil
from typing import Any

CHROMEDRIVER = shutil.which("chromedriver")
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


def make_driver(window_size: str = "1280,1000") -> Any:
    """A headless Chromium (selenium must be importable: the tests importorskip it first)."""
    from selenium import webdriver

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for argument in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--disable-gpu",
                     f"--window-size={window_size}", "--disable-background-networking",
                     "--no-first-run", "--no-default-browser-check"):
        options.add_argument(argument)
    service = webdriver.ChromeService(executable_path=CHROMEDRIVER)
    return webdriver.Chrome(options=options, service=service)
