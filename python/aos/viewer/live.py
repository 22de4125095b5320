"""What the live page shows (docs/live.md): a feed of updates, each a JSON state and a PNG.

Two feeds:

* ``IntegratorFeed``: an :class:`aos.LiveIntegrator` in this process (``aos.view(live=...)``);
  the caller adds frames from any thread (the integrator locks), the feed notices each update.
* ``FolderFeed``: the folder ``aos-render live --view`` writes after every update: ``live.json``
  (the integrator's ``state_json()`` plus the image's file name and timings) and the image it
  names, each renamed into place, so a reader never sees half a file.

``snapshot()`` gives (update, state bytes, png bytes) of the newest update, or None before the
first (the server's /api/live polls it); ``current()`` the one read last, without reading.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import threading
import time
from pathlib import Path
from typing import Any, Optional

Snapshot = tuple[int, bytes, bytes]


class LiveFeed:
    """The newest update of a live run; subclasses implement ``_read``."""

    poll_s = 0.02

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._snapshot: Optional[Snapshot] = None

    def _read(self, known: int) -> Optional[Snapshot]:
        """The newest update when it is newer than ``known``, else None."""
        raise NotImplementedError

    def snapshot(self) -> Optional[Snapshot]:
        with self._lock:
            known = self._snapshot[0] if self._snapshot else 0
            fresh = self._read(known)
            if fresh is not None and fresh[0] > known:
                self._snapshot = fresh
            return self._snapshot

    def current(self) -> Optional[Snapshot]:
        """The newest update read so far, without reading (never waits)."""
        return self._snapshot

    def close(self) -> None:
        """Releases what the feed holds (the server is stopping)."""


class IntegratorFeed(LiveFeed):
    """An aos.LiveIntegrator's updates: its state_json() and its overlay as PNG."""

    def __init__(self, integrator: Any) -> None:
        super().__init__()
        import aos

        if not isinstance(integrator, aos.LiveIntegrator):
            raise TypeError(f"view(): live must be an aos.LiveIntegrator or a LiveFeed, not "
                            f"{type(integrator).__name__}")
        self.integrator = integrator
        self._folder = tempfile.mkdtemp(prefix="aos-live-view-")  # mode 0700

    def _read(self, known: int) -> Optional[Snapshot]:
        import aos

        if self.integrator.updates <= known:
            return None
        state = json.loads(self.integrator.state_json())
        result = self.integrator.result
        png = b""
        if result.render.image is not None and state["width"] > 0:
            path = os.path.join(self._folder, "live.png")
            aos.write_image(path, result.overlay())
            png = Path(path).read_bytes()
        state["shown_unix"] = time.time()
        return state["update"], json.dumps(state).encode(), png

    def close(self) -> None:
        shutil.rmtree(self._folder, ignore_errors=True)


class FolderFeed(LiveFeed):
    """The folder `aos-render live --view` writes (live.json and the image it names)."""

    def __init__(self, folder: str) -> None:
        super().__init__()
        self.folder = Path(folder)
        self._seen: tuple[int, int, int] = (0, 0, 0)

    def _read(self, known: int) -> Optional[Snapshot]:
        path = self.folder / "live.json"
        try:
            stat = path.stat()
            # Each update renames a new file into place: a new inode, even within one mtime tick.
            seen = (stat.st_ino, stat.st_mtime_ns, stat.st_size)
            if seen == self._seen:
                return None
            text = path.read_bytes()
            state = json.loads(text)
            png = (self.folder / Path(state.get("image", "")).name).read_bytes() \
                if state.get("image") else b""
        except (OSError, ValueError):
            return None  # not written yet, or replaced while read: the next poll has it
        self._seen = seen
        if int(state.get("update", 0)) <= known:
            return None
        return int(state["update"]), text, png
