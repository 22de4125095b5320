"""Signals in CLI tests: whether a process has installed its handler yet.

A test that signals `aos-render` must wait until the program catches the signal (its handler
is installed before the command runs; on a loaded machine loading the program takes seconds),
else the default action ends it and the test measures nothing. Linux only (/proc).
"""
from __future__ import annotations

import re
import signal
import time
from pathlib import Path


def catches(pid: int, sig: signal.Signals = signal.SIGTERM) -> bool:
    """Whether the process has a handler for `sig` (SigCgt of /proc/PID/status)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    mask = int(re.search(r"^SigCgt:\s*([0-9a-f]+)", status, flags=re.M).group(1), 16)
    return bool(mask >> (sig - 1) & 1)


def wait_until_it_catches(pid: int, sig: signal.Signals = signal.SIGTERM,
                          timeout: float = 60.0) -> None:
    """Until the process catches `sig`, it has ended, or `timeout` seconds have passed."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and Path(f"/proc/{pid}").exists():
        if catches(pid, sig):
            return
        time.sleep(0.02)
