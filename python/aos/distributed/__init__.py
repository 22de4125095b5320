"""Large-area maps on Dask (docs/distributed.md).

A map (map.h) is split into its render tiles (``MapOptions.tile_size`` pixels on a side); each
tile is one task on a ``dask.distributed`` cluster. A task reads only the frames whose footprint
may meet its tile (``MapWindowViews`` in map.h: a conservative projection test on poses and
cameras), decoded from their files into a per-worker cache with a byte budget (least recently
used frames are dropped first; a frame that tiles of two workers need is handed from one worker
to the others on its machine through shared memory rather than decoded twice, see
``_FrameStore``), renders its window (``RenderMapWindow``) and returns it; the
client writes the windows into the GeoTIFF as they arrive (``MapGeoTiffWriter``: a temporary
file beside the output, the Cloud-Optimised copy renamed into place at the end, nothing left at
the output path on an error). Every pixel is bit for bit the single-process render: the frames
left out of a window admit no sample there, and each pixel sums its samples in view order.

Cluster: ``client`` (a ``dask.distributed.Client``), else ``scheduler`` (an address such as
``tcp://10.0.0.5:8786``), else a ``LocalCluster`` of ``workers`` processes with one thread
each, bound to 127.0.0.1 and closed at the end. Every worker must import the same aos version
and read the frame files under the same paths (a shared file system on a cluster).

Threads: each task renders with ``num_threads`` threads; -1 (all cores) means 1 here, since
the workers are the parallelism.

Faults: a worker that dies is replaced by Dask and its tasks run again elsewhere (the map is
unchanged); a frame that cannot be read stops the run with the ValueError naming it, and no
output is written.
"""

from __future__ import annotations

import collections
import contextlib
import copy
import math
import os
import pickle
import shutil
import tempfile
import threading
import time
import uuid
import warnings
from concurrent.futures import CancelledError
from dataclasses import dataclass, field
from typing import Any, Callable, Optional, Sequence

import numpy as np

from .. import _core

__all__ = ["DistributedMapResult", "render_map", "detect_map", "prepare_map", "run_cases",
           "local_client"]

_MIB = 1 << 20


def __getattr__(name: str) -> Any:
    """The old default constants, for one release (DeprecationWarning): the defaults are
    aos.DistributedOptions' now, in MiB."""
    fields = {"DEFAULT_CACHE_BYTES": "cache_mb", "DEFAULT_SHARE_BYTES": "share_mb"}
    if name in fields:
        warnings.warn(f"aos.distributed.{name} is deprecated; use "
                      f"aos.DistributedOptions().{fields[name]} (MiB)", DeprecationWarning,
                      stacklevel=2)
        return int(getattr(_core.DistributedOptions(), fields[name]) * _MIB)
    raise AttributeError(f"module 'aos.distributed' has no attribute {name!r}")

_LOAD_KEYS = ("grey", "mask", "mask_dir")

# Times a tile is submitted when Dask cancels it without being asked (a worker lost with it).
_TILE_ATTEMPTS = 3


@dataclass
class DistributedMapResult:
    """What a distributed render_map returns: the grid and the summary of MapResult (same
    names), and the arrays when asked for (``arrays=True``)."""

    width: int
    height: int
    pixel_size: float
    up_z: float
    geotransform: tuple
    crs: str
    views_selected: int = 0
    views_used: int = 0
    samples: int = 0
    uncovered_pixels: int = 0
    tiles: int = 0
    frames_read: int = 0  # frame decodes summed over the tasks
    frames_shared: int = 0  # cache misses served by another worker's decode (same machine)
    seconds_decode: float = 0.0  # the tasks' time reading frames (cache misses), summed
    seconds_render: float = 0.0  # the tasks' time rendering their windows, summed
    seconds: float = 0.0  # the whole call
    seconds_write: float = 0.0  # of which the COG copy and rename at the end (serial)
    _image: Optional[np.ndarray] = field(default=None, repr=False)
    _count: Optional[np.ndarray] = field(default=None, repr=False)
    _scores: Optional[np.ndarray] = field(default=None, repr=False)  # detect_map: anomaly imaging

    @property
    def has_arrays(self) -> bool:
        return self._image is not None

    @property
    def image(self) -> np.ndarray:
        if self._image is None:
            raise ValueError("DistributedMapResult.image: the map was streamed to its file and "
                             "not kept in memory; pass arrays=True to keep it")
        return self._image

    @property
    def count(self) -> np.ndarray:
        if self._count is None:
            raise ValueError("DistributedMapResult.count: the map was streamed to its file and "
                             "not kept in memory; pass arrays=True to keep it")
        return self._count


# ---- worker side ------------------------------------------------------------------------------


class _FrameStore:
    """Decoded frames handed between the worker processes of one machine for one run: one .npy
    file per frame in a folder named after the run's token, in shared memory (/dev/shm) where
    there is one. The client tells each task which of its frames tiles of other workers need
    (``publish``); the worker that decodes such a frame first writes it here, and a worker
    that misses a frame in its cache looks here before it decodes. A file is written whole
    under a temporary name and renamed, so a reader sees a frame complete or not at all; a
    frame that cannot be written (no space, the worker's ``budget`` of bytes spent) or read is
    simply decoded again. The pixels are the decoded ones, so the map is unchanged. Workers on
    other machines see their own folder; the client removes the folders at the end of the run
    (``_remove_frame_store`` on every worker)."""

    # Left free in the store's file system after each frame: a quarter of it, at least 64 MiB
    # (shared memory is RAM, and other programs use it too; Docker gives 64 MiB by default).
    FREE_FRACTION = 0.25
    FREE_BYTES = 64 << 20
    # Folders of runs whose client and workers died without removing them are removed by the
    # next run on the machine once they are this old (a frame missing only means a decode).
    STALE_SECONDS = 6 * 3600

    def __init__(self, token: str, budget: int):
        self.base = "/dev/shm" if os.access("/dev/shm", os.W_OK) else tempfile.gettempdir()
        self.folder = os.path.join(self.base, f"aos-frames-{token}")
        self.budget = budget  # bytes this worker may write
        self.written = 0

    def _path(self, index: int) -> str:
        return os.path.join(self.folder, f"{index}.npy")

    def sweep(self) -> None:
        """Removes other runs' folders older than STALE_SECONDS."""
        with contextlib.suppress(OSError):
            for entry in os.scandir(self.base):
                if (entry.name.startswith("aos-frames-") and entry.path != self.folder and
                        time.time() - entry.stat().st_mtime > self.STALE_SECONDS):
                    shutil.rmtree(entry.path, ignore_errors=True)

    def get(self, index: int) -> Optional[np.ndarray]:
        try:
            return np.load(self._path(index), allow_pickle=False)
        except (OSError, ValueError, EOFError):
            return None

    def _room(self, nbytes: int) -> bool:
        try:
            fs = os.statvfs(self.base)
        except OSError:
            return False
        free, size = fs.f_bavail * fs.f_frsize, fs.f_blocks * fs.f_frsize
        return free - nbytes >= max(self.FREE_BYTES, self.FREE_FRACTION * size)

    def put(self, index: int, image: np.ndarray) -> None:
        if (self.written + image.nbytes > self.budget or os.path.exists(self._path(index)) or
                not self._room(image.nbytes)):
            return
        temporary = f"{self._path(index)}.{os.getpid()}.tmp"
        try:
            os.makedirs(self.folder, mode=0o700, exist_ok=True)  # this user's frames
            with open(temporary, "wb") as file:
                np.save(file, image, allow_pickle=False)
            os.replace(temporary, self._path(index))
            self.written += image.nbytes
        except OSError:
            with contextlib.suppress(OSError):
                os.remove(temporary)


def _drop_run(token: str) -> None:
    """Drops this process's frames of the run ``token`` and the run's shared frames on its
    machine. Called with _CACHE_LOCK held."""
    _CACHES.pop(token, None)
    shutil.rmtree(_FrameStore(token, 0).folder, ignore_errors=True)


def _remove_frame_store(token: str) -> None:
    """The end of the run ``token`` on this worker (the client runs it on every worker, after
    the run or its error): the run is marked finished, so that a task of it that starts later
    (one cancelled but already queued here) renders nothing, and its frames are dropped, now or,
    when a tile is being rendered, by that task before it returns (never waiting for it: this
    runs on the worker's event loop)."""
    _FINISHED.append(token)
    if _CACHE_LOCK.acquire(blocking=False):
        try:
            _drop_run(token)
        finally:
            _CACHE_LOCK.release()


class _FrameCache:
    """The frames one worker process holds for one run: a poses-only light field into which
    frames are decoded, least recently used dropped first beyond the byte budget; with a
    ``store``, frames other workers of this machine decoded are taken from it (_FrameStore)."""

    def __init__(self, light_field: Any, load: dict, budget: int,
                 store: Optional[_FrameStore] = None):
        self.light_field = copy.copy(light_field)
        self.poses = light_field  # as given: no frame decoded into it
        self.load = load
        self.budget = budget
        self.store = store
        self.order: "collections.OrderedDict[int, None]" = collections.OrderedDict()
        self.frame_bytes = 0  # bytes of one decoded frame, learnt from the first decode
        self.decoded = 0
        self.shared = 0  # frames taken from the store
        # Anomaly imaging (detect_map): the held frames' scores, in a poses-only light field of
        # their own (made on the first tile that needs them), dropped with their frames.
        self.score_field: Any = None
        self.scored: set = set()
        self.score_bytes = 0  # bytes of one view's scores, learnt from the first made

    def _from_store(self, missing: list) -> list:
        """Sets the frames of ``missing`` found in the store; returns the others. Only once this
        cache has decoded a frame itself: the decode sets the light field's mask state."""
        if self.store is None or not self.decoded:
            return missing
        rest = []
        for i in missing:
            image = self.store.get(i)
            if image is not None:
                with contextlib.suppress(ValueError):  # not this view's frame: decode it
                    _core._set_view_image(self.light_field, i, image)
                    self.shared += 1
                    continue
            rest.append(i)
        return rest

    def hold(self, indices: Sequence[int], publish: Sequence[int] = ()) -> None:
        needed = set(indices)
        missing = [i for i in indices if i not in self.order]
        for i in indices:
            if i in self.order:
                self.order.move_to_end(i)
        # Make room first, so that the cache never holds more than the budget plus this tile.
        # A held view costs its frame and, for anomaly imaging, its scores (learnt from the
        # first scores made: the budget bounds both).
        per_view = self.frame_bytes + self.score_bytes
        if missing and self.frame_bytes:
            room = self.budget - len(missing) * per_view
            held = len(self.order) * per_view
            drop = []
            for i in self.order:
                if held <= room:
                    break
                if i in needed:
                    continue
                drop.append(i)
                held -= per_view
            if drop:
                _core._drop_view_images(self.light_field, drop)
                for i in drop:
                    del self.order[i]
                dropped_scores = sorted(self.scored.intersection(drop))
                if dropped_scores:
                    _core._drop_view_images(self.score_field, dropped_scores)
                    self.scored.difference_update(dropped_scores)
        if missing:
            before = self.light_field.image_bytes()
            decode = self._from_store(missing)
            if decode:
                _core._load_view_images(self.light_field, decode, num_threads=1, **self.load)
                self.decoded += len(decode)
                if self.store is not None:
                    for i in sorted(set(decode) & set(publish)):
                        image = _core._view_image(self.light_field, i)
                        if image is not None:
                            self.store.put(i, image)
            if not self.frame_bytes:
                self.frame_bytes = max(1, (self.light_field.image_bytes() - before) // len(missing))
            for i in missing:
                self.order[i] = None


    def hold_scores(self, indices: Sequence[int], detect: Any) -> Any:
        """The light field of the scores of frames ``indices`` (held: call hold first), each
        frame scored once while it is held (QuantisedFrameScores: what aos.detect_map renders
        for anomaly imaging)."""
        if self.score_field is None:
            self.score_field = copy.copy(self.poses)
        for i in indices:
            if i not in self.scored:
                frame = _core._view_image(self.light_field, i)
                if frame is None:  # hold() decodes every frame asked for
                    raise ValueError(f"view {i}: its frame is not held, so it cannot be scored")
                scores = _core._quantised_frame_scores(frame, detect)
                _core._set_view_image(self.score_field, i, scores)
                self.scored.add(i)
                self.score_bytes = self.score_bytes or int(scores.nbytes)
        return self.score_field


def _narrow_count(count: np.ndarray) -> np.ndarray:
    """``count`` (uint32) in the smallest unsigned type that holds its values, exactly: uint8
    where no pixel has more than 255 samples, as in most survey tiles. A tile's count then
    travels in a quarter (or half) of its bytes: tiles are what the client takes in over the
    network, which bounds it on a cluster (docs/distributed.md)."""
    return count.astype(np.min_scalar_type(int(count.max()) if count.size else 0))


_CACHE_LOCK = threading.Lock()
_CACHES: "dict[str, _FrameCache]" = {}
_FINISHED: "collections.deque[str]" = collections.deque(maxlen=64)  # runs that ended


def _render_tile(token: str, light_field: Any, options: Any, load: dict, budget: int,
                 x0: int, y0: int, w: int, h: int, first_view: int,
                 publish: Sequence[int] = (), share_bytes: int = 0,
                 views: Optional[Sequence[int]] = None, anomaly: Any = None) -> dict:
    """One task: the window's frames (``views``, else found here; cached; with
    ``share_bytes``, shared with the other workers of this machine, ``publish`` being the
    frames they need), then its pixels. ``light_field``: the poses (a LightField without
    images), or them pickled (bytes: render_map sends them so). With ``anomaly`` (the
    DetectOptions of anomaly imaging), also the window of the frames' integrated scores,
    ``scores`` (float32, score units)."""
    with _CACHE_LOCK:  # one tile at a time per process; the render releases the GIL
        if token in _FINISHED:  # cancelled with its run, but already queued here
            _drop_run(token)
            return {"finished": True}
        cache = _CACHES.get(token)
        if cache is None:
            for old in list(_CACHES):  # one run's frames at a time
                _drop_run(old)
            if isinstance(light_field, bytes):  # the poses as render_map scatters them
                light_field = pickle.loads(light_field)
            store = _FrameStore(token, share_bytes) if share_bytes > 0 else None
            if store is not None:
                store.sweep()
            cache = _FrameCache(light_field, load, budget, store)
            _CACHES[token] = cache
        if views is None:
            views = _core._map_window_views(cache.light_field, options, x0, y0, w, h)
        if not views:
            # No view meets the window: any selected view renders it empty (count 0), the one
            # held already if there is one.
            views = [next(iter(cache.order), first_view)]
        decoded_before, shared_before = cache.decoded, cache.shared
        started = time.perf_counter()
        cache.hold(views, publish)
        decoded = time.perf_counter()
        out = _core._render_map_window(cache.light_field, options, x0, y0, w, h, views)
        if anomaly is not None:
            scores = _core._render_map_window(cache.hold_scores(views, anomaly), options, x0, y0,
                                              w, h, views)
            out["scores"] = (scores["image"] * np.float32(_core._frame_score_step)).astype(
                np.float32, copy=False)
        out["seconds_decode"] = decoded - started
        out["seconds_render"] = time.perf_counter() - decoded
        out["count"] = _narrow_count(out["count"])
        out["x0"], out["y0"] = x0, y0
        out["frames_read"] = cache.decoded - decoded_before
        out["frames_shared"] = cache.shared - shared_before
        if token in _FINISHED:  # the run ended while this tile rendered
            _drop_run(token)
        return out


# ---- client side ------------------------------------------------------------------------------


def _tile_groups(windows: Sequence[tuple], width: int, tile: int, groups: int) -> list:
    """``windows`` (row-major, ``tile`` pixels on a side, over a map ``width`` pixels wide) in
    ``groups`` compact groups of nearly equal size: the tiles in boustrophedon order (left to
    right, then right to left on the next row, so that consecutive tiles are neighbours) cut
    into consecutive runs, bands of whole rows where the rows divide evenly."""
    columns = max(1, -(-width // tile))
    rows = [list(windows[i:i + columns]) for i in range(0, len(windows), columns)]
    order = [w for r, row in enumerate(rows) for w in (row if r % 2 == 0 else row[::-1])]
    groups = max(1, min(groups, len(order)))
    bounds = [round(i * len(order) / groups) for i in range(groups + 1)]
    return [order[bounds[i]:bounds[i + 1]] for i in range(groups)]


def local_client(workers: int, *, dashboard: bool = False, **cluster_kwargs: Any) -> Any:
    """A Client of a new LocalCluster: ``workers`` processes of one thread each, bound to
    127.0.0.1. The cluster talks TLS with credentials made for this session only
    (``security=True``: Dask's temporary self-signed certificates, held in memory), so no other
    program on this machine can submit work to it. ``dashboard``: also serve Dask's dashboard
    (progress, tasks, memory; needs bokeh) on a free port of 127.0.0.1 at
    ``client.dashboard_link`` - read-only pages, but without a token: anyone on this machine
    can look at it while the run lasts (without it, the workers' stack profiler is off). Dask's
    periodic housekeeping runs less often than its defaults (see the settings below). Close
    the client and its cluster
    (``client.close(); client.cluster.close()``) or use it as a context manager."""
    from dask.distributed import Client, LocalCluster

    if workers < 1:
        raise ValueError(f"workers: must be >= 1 (got {workers})")
    # Dask's scheduler and workers always run an HTTP server (on 127.0.0.1 here, a free port);
    # without the dashboard it answers only its health check.
    settings = dict(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                    dashboard_address="127.0.0.1:0", security=True,
                    scheduler_kwargs={"dashboard": dashboard})
    settings.update(cluster_kwargs)
    config: dict = {"distributed.nanny.pre-spawn-environ.MALLOC_MMAP_THRESHOLD_": 262144,
                    # Dask's housekeeping, every process waking 50 times a second (the event
                    # loop's tick), twice (system monitor) and ten times (each nanny's memory
                    # check): 2 workers idle for 10 s cost 0.5-0.6 s of the client's CPU and
                    # 0.4-0.5 s of each worker's, 0.13 and 0.05 s with these (docs/distributed.md):
                    # CPU the tiles need on a small machine. The placement of tiles is
                    # render_map's own (two in flight per worker), so no work stealing.
                    "distributed.admin.tick.interval": "500ms",
                    "distributed.admin.system-monitor.interval": "2s",
                    "distributed.worker.memory.monitor-interval": "1s",
                    "distributed.scheduler.work-stealing": False}
    if not dashboard:
        config["distributed.scheduler.http.routes"] = ["distributed.http.health"]
        config["distributed.worker.http.routes"] = ["distributed.http.health"]
        # Each worker samples its task thread's stack every 10 ms for the dashboard's profile.
        config["distributed.worker.profile.enabled"] = False
    # Frames (about a megabyte each) come and go: with glibc's default, its mmap threshold rises
    # after the first free and later frames stay in the heap, whose high-water mark then grows
    # with the frames read. A fixed threshold gives each frame its own mapping, returned on free.
    import dask

    with dask.config.set(config):
        cluster = LocalCluster(**settings)
    return Client(cluster, security=cluster.security)


def _poses_only(light_field: Any, load: dict) -> Any:
    if isinstance(light_field, (str, os.PathLike)):
        raise TypeError("render_map(): light_field: load it first (aos.load_lightfield(path, "
                        "load_images=False) reads poses only)")
    poses = copy.copy(light_field)
    _core._drop_view_images(poses, list(range(len(poses))))
    for index, view in enumerate(poses.views):
        if not view.image_path:
            raise ValueError(f"render_map(): view {index}: image_path: the view has no frame "
                             "file; a distributed map reads every frame from its file")
    if light_field.masked and not (load.get("mask") or load.get("mask_dir")):
        raise ValueError("render_map(): the light field is masked; give load=dict(mask=...) or "
                         "mask_dir=... so that the workers apply the same masks")
    return poses


def prepare_map(light_field: Any, options: Any, load: Optional[dict] = None) -> tuple:
    """What render_map checks before it starts or uses a cluster: the load keys, the poses (every
    view with a frame file), the grid, the selection and the output's channels (one frame
    decoded here, which also checks the load options and that frame). Returns (options with
    num_threads resolved, poses, grid, selection, channels); raises ValueError naming the field
    or the file. The CLI calls it before it starts a local cluster."""
    load = dict(load or {})
    unknown = set(load) - set(_LOAD_KEYS)
    if unknown:
        raise TypeError(f"render_map(): load: unknown keys {sorted(unknown)} (known: "
                        f"{', '.join(_LOAD_KEYS)})")
    options = copy.copy(options)
    if options.num_threads == -1:
        options.num_threads = 1
    poses = _poses_only(light_field, load)
    grid = _core._map_grid(poses, options)
    selection = sorted(options.view_indices) or list(range(len(poses)))
    probe = copy.copy(poses)
    _core._load_view_images(probe, [selection[0]], num_threads=1, **load)
    first = probe.views[selection[0]].image
    channels = 1 if first.ndim == 2 else first.shape[2]
    if probe.masked:
        channels -= 1
    return options, poses, grid, selection, channels


def _worker_addresses(client: Any, timeout_s: float = 120.0) -> list:
    """The addresses of the cluster's workers, once at least one has joined (all of them:
    client.nthreads(), not scheduler_info(), which some Dask versions cut at 5)."""
    try:
        client.wait_for_workers(1, timeout=timeout_s)
    except Exception as error:  # TimeoutError (dask's or asyncio's)
        raise ValueError(f"render_map(): no Dask worker joined the cluster within {timeout_s:g} s "
                         f"({error})") from error
    return sorted(client.nthreads())


def _run_options(client: Any, scheduler: Optional[str], workers: Optional[int],
                 cache_mb: Optional[float], share_mb: Optional[float], dashboard: bool,
                 cache_bytes: Optional[int], share_bytes: Optional[int],
                 caller: str = "render_map") -> Any:
    """render_map's (or ``caller``'s) cluster options as a checked DistributedOptions (its defaults where None).
    Python always renders on Dask: without a client or a scheduler, workers None or 0 means a
    local cluster of one worker. A client brings its own cluster, so workers, scheduler and
    dashboard are refused with it. The old byte spellings cache_bytes/share_bytes work for one
    release, with a DeprecationWarning. Raises ValueError (TypeError for a wrong type) naming
    the field."""
    run = _core.DistributedOptions()
    if client is not None and (workers or scheduler or dashboard):
        given = "/".join(name for name, value in (("workers", workers), ("scheduler", scheduler),
                                                  ("dashboard", dashboard)) if value)
        raise ValueError(f"{caller}(): {given}: not with client (the client's cluster has its "
                         "own workers and dashboard)")
    for old, new, value in (("cache_bytes", "cache_mb", cache_bytes),
                            ("share_bytes", "share_mb", share_bytes)):
        if value is None:
            continue
        if (cache_mb if new == "cache_mb" else share_mb) is not None:
            raise ValueError(f"{caller}(): {old}: not with {new} (the same budget in MiB)")
        warnings.warn(f"{caller}(): {old} is deprecated; use {new} (MiB)", DeprecationWarning,
                      stacklevel=3)
        if not isinstance(value, int) or value < 0:
            raise ValueError(f"{caller}(): {old}: must be a whole number of bytes >= 0 "
                             f"(got {value!r})")
        if new == "cache_mb":
            cache_mb = value / _MIB
        else:
            share_mb = value / _MIB
    if client is None and not scheduler and not workers:
        workers = 1
    for name, value in (("workers", workers), ("scheduler", scheduler or ""),
                        ("cache_mb", cache_mb), ("share_mb", share_mb),
                        ("dashboard", dashboard)):
        if value is None:
            continue
        try:
            setattr(run, name, value)
        except TypeError:
            expected = type(getattr(run, name)).__name__
            raise TypeError(f"{caller}(): {name}: expected {expected}, got "
                            f"{type(value).__name__} {value!r}") from None
    try:
        run.check()
    except ValueError as error:
        raise ValueError(f"{caller}(): {error}") from None
    return run


def render_map(light_field: Any, options: Any, *, path: Optional[str], client: Any = None,
               scheduler: Optional[str] = None, workers: Optional[int] = None,
               load: Optional[dict] = None, force: bool = False, arrays: bool = False,
               cache_mb: Optional[float] = None,
               share_mb: Optional[float] = None,
               progress: Optional[Callable[[str, int, int], object]] = None,
               dashboard: bool = False,
               on_start: Optional[Callable[[Any], object]] = None,
               cache_bytes: Optional[int] = None,
               share_bytes: Optional[int] = None,
               _anomaly: Any = None,
               ) -> DistributedMapResult:
    """Renders the map of ``light_field`` (a LightField, with or without its images: the
    workers read the frames from their files) and ``options`` (a MapOptions) on Dask; see the
    module's docstring. ``path``: the Cloud-Optimised GeoTIFF to write (None with arrays=True
    keeps the map in memory only). ``load``: how the frames are decoded (grey, mask, mask_dir
    as load_lightfield). ``workers``, ``scheduler``, ``cache_mb``, ``share_mb`` and
    ``dashboard`` are the fields of :class:`aos.DistributedOptions` (its defaults where None;
    without a client or a scheduler, workers None or 0 means one local worker, as this function
    always renders on Dask): each worker's frame cache budget in MiB, and the MiB of decoded
    frames each worker may hand to the other workers of its machine through shared memory (0:
    none; see _FrameStore). With ``client``, workers, scheduler and dashboard are refused (its
    cluster has its own). ``cache_bytes``/``share_bytes`` are the old spellings in bytes
    (deprecated).
    ``progress(stage, done, total)`` is
    called on the client as tiles
    arrive ("render map", tiles) and while the COG is written. ``dashboard``: the local
    cluster render_map starts serves Dask's dashboard (local_client). ``on_start(client)`` is
    called once the inputs and the output are checked and the cluster is there, before the
    first task (the CLI prints where the tiles run). Raises ValueError naming the field or the
    file, before any cluster is started where the inputs or the output are at fault; nothing
    is written at ``path`` on any error. ``_anomaly`` (detect_map's): the DetectOptions of
    anomaly imaging, whose frames' integrated scores the workers render beside each tile and
    the client keeps (``_scores``, with arrays=True)."""
    started = time.perf_counter()
    load = dict(load or {})
    run = _run_options(client, scheduler, workers, cache_mb, share_mb, dashboard, cache_bytes,
                       share_bytes)
    cache_bytes = int(run.cache_mb * _MIB)
    share_bytes = int(run.share_mb * _MIB)
    if path is None and not arrays:
        raise ValueError("render_map(): arrays=False without a path keeps nothing; give a path")
    options, poses, grid, selection, channels = prepare_map(light_field, options, load)

    # The writer first: it checks the output (folder, existing file, CRS, free disk space)
    # before a cluster is started.
    writer = None
    if path is not None:
        writer = _core._MapGeoTiffWriter(poses, options, channels, os.fspath(path), force)
    owned = None
    futures: list = []
    token = uuid.uuid4().hex
    views_of: dict = {}  # tile window -> its frames
    shared: set = set()  # frames that tiles of two groups need, when frames are shared
    submitted: dict = {}  # key of each tile in flight -> (window, group, publish, attempt)
    try:
        if client is None:
            from dask.distributed import Client

            if run.scheduler:
                client = owned = Client(run.scheduler, timeout=30)
            else:
                client = owned = local_client(run.workers, dashboard=run.dashboard)
        if on_start is not None:
            on_start(client)
        image: Optional[np.ndarray] = None
        count: Optional[np.ndarray] = None
        if arrays:
            shape = (grid["height"], grid["width"]) + ((channels,) if channels > 1 else ())
            image = np.zeros(shape, np.float32)
            count = np.zeros((grid["height"], grid["width"]), np.uint32)
        scores: Optional[np.ndarray] = None
        if _anomaly is not None:
            scores = np.zeros((grid["height"], grid["width"]), np.float32)
        # The poses go to every worker once, pickled here: Dask then copies bytes from worker
        # to worker, where a LightField would be unpickled and pickled again on each hop (1.1 s
        # against 0.3-0.6 s for 2,025 views and two workers); each worker unpickles them once,
        # in its run's first task.
        blob = pickle.dumps(poses, protocol=pickle.HIGHEST_PROTOCOL)
        [poses_future] = client.scatter([blob], broadcast=True, hash=False)
        tile = options.tile_size
        windows = [(x0, y0, min(tile, grid["width"] - x0), min(tile, grid["height"] - y0))
                   for y0 in range(0, grid["height"], tile)
                   for x0 in range(0, grid["width"], tile)]
        from dask.distributed import as_completed

        # Tiles go to workers in compact groups (see _tile_groups): neighbouring tiles share
        # most of their frames, so a worker that renders a band of the map decodes each of its
        # frames about once, where tiles dealt out in turn would have every worker decode nearly
        # every frame. The placement is a preference (allow_other_workers): a worker that dies
        # or falls behind leaves its tiles to the others, and a worker whose group is done takes
        # tiles from the far end of the largest group left.
        addresses = _worker_addresses(client)
        queues = [collections.deque(group)
                  for group in _tile_groups(windows, grid["width"], tile, len(addresses))]
        # The frames that tiles of two groups need (the bands' borders): the worker that decodes
        # one first hands it to the others on its machine (_FrameStore), where each would
        # decode it. A tile taken from another group hands on all its frames: the donor's next
        # tiles need them.
        # Each tile's frames, found here for all tiles at once (MapWindowViews, the grid resolved
        # once) and sent with the task.
        views_of.update(zip(windows, _core._map_windows_views(poses, options, windows)))
        groups_of: "dict[int, set]" = collections.defaultdict(set)
        for group, queue in enumerate(queues):
            for window in queue:
                for view in views_of[window]:
                    groups_of[view].add(group)
        if share_bytes > 0 and len(queues) > 1:
            shared = {view for view, groups in groups_of.items() if len(groups) > 1}
        # A bounded number of tiles in flight, two per worker (one rendering, one queued):
        # finished tiles wait on their worker until the client has written them, so an
        # unbounded queue would hold the whole map there.

        def submit(window: tuple, group: int, publish: list, attempt: int) -> Any:
            x0, y0, w, h = window
            future = client.submit(_render_tile, token, poses_future, options, load, cache_bytes,
                                   x0, y0, w, h, selection[0], publish,
                                   share_bytes if shared else 0, views_of[window], _anomaly,
                                   pure=False,
                                   key=f"aos-map-tile-{x0}-{y0}-{token}-{attempt}",
                                   workers=[addresses[group]], allow_other_workers=True)
            futures.append(future)
            submitted[future.key] = (window, group, publish, attempt)
            return future

        def submit_next(group: int) -> Any:
            queue = queues[group]
            if queue:
                window = queue.popleft()
                publish = [v for v in views_of[window] if v in shared]
            else:
                donor = max(range(len(queues)), key=lambda i: len(queues[i]))
                if not queues[donor]:
                    return None
                window = queues[donor].pop()
                publish = list(views_of[window]) if shared else []
            return submit(window, group, publish, 0)

        for _ in range(2):
            for group in range(len(queues)):
                submit_next(group)
        completed = as_completed(list(futures))

        result = DistributedMapResult(width=grid["width"], height=grid["height"],
                                      pixel_size=grid["pixel_size"], up_z=grid["up_z"],
                                      geotransform=tuple(grid["geotransform"]), crs=poses.crs,
                                      views_selected=len(selection))
        used: set = set()
        done = 0
        if progress is not None:
            progress("render map", 0, len(windows))
        for future in completed:
            window, group, publish, attempt = submitted.pop(future.key)
            try:
                out = future.result()  # re-raises the task's error (a frame's ValueError)
            except CancelledError as error:
                # Not cancelled here (that happens only on the way out): Dask dropped the task,
                # which it can do when a worker dies with it (seen as "already forgotten" with
                # a worker killed mid-run). The tile is submitted again, a few times at most.
                future.release()
                if attempt >= _TILE_ATTEMPTS - 1:
                    raise ValueError(f"render_map(): the tile at pixel {window[0]}, {window[1]}: "
                                     f"Dask cancelled it {_TILE_ATTEMPTS} times (workers lost?); "
                                     "nothing written") from error
                completed.add(submit(window, group, publish, attempt + 1))
                continue
            future.release()
            following = submit_next(group)
            if following is not None:
                completed.add(following)
            x0, y0 = out["x0"], out["y0"]
            h, w = out["count"].shape
            if writer is not None:
                writer.write(x0, y0, out["image"], out["count"].astype(np.uint32, copy=False))
            if image is not None and count is not None:
                image[y0:y0 + h, x0:x0 + w] = out["image"]
                count[y0:y0 + h, x0:x0 + w] = out["count"]
            if scores is not None:
                scores[y0:y0 + h, x0:x0 + w] = out["scores"]
            used.update(out["used_view_indices"])
            result.samples += int(out["samples"])
            result.uncovered_pixels += int(out["uncovered_pixels"])
            result.frames_read += int(out["frames_read"])
            result.frames_shared += int(out["frames_shared"])
            result.seconds_decode += float(out["seconds_decode"])
            result.seconds_render += float(out["seconds_render"])
            result.tiles += 1
            done += 1
            if progress is not None:
                progress("render map", done, len(windows))
        result.views_used = len(used)
        # A map on a surface with no pixel covered is refused, as on one machine (no file).
        _core._check_map_covered(poses, options, result.uncovered_pixels)
        if writer is not None:
            write_started = time.perf_counter()
            writer.commit(progress)
            result.seconds_write = time.perf_counter() - write_started
        result._image, result._count, result._scores = image, count, scores
        result.seconds = time.perf_counter() - started
        return result
    except BaseException:
        live = [future for future in futures if future.key in submitted]
        if live:
            with contextlib.suppress(Exception):
                client.cancel(live)  # one message for all
        writer = None  # the writer's destructor removes its temporary files
        raise
    finally:
        writer = None
        if client is not None:
            # The shared frames of this run, on every worker's machine (a dead worker's too:
            # its folder is its machine's, named by the run).
            with contextlib.suppress(Exception):
                client.run(_remove_frame_store, token)
        if owned is not None:
            cluster = getattr(owned, "cluster", None)
            owned.close()
            if cluster is not None and not run.scheduler:
                cluster.close()


# ---- studies ----------------------------------------------------------------------------------


def detect_map(light_field: Any, options: Any, detect: Any, *, path: Optional[str] = None,
               detections_path: Optional[str] = None,
               **render: Any) -> tuple[DistributedMapResult, Any]:
    """Detection on a map rendered on Dask (``aos-render map --detect F --workers N``): the
    tiles render as in :func:`render_map` (``render``: its keywords; ``path``: the GeoTIFF, or
    None), the client keeps the assembled map and scores it (``DetectOnRenderedMap``, detect.h:
    the same detections as :func:`aos.detect_map` on one machine). ``detect`` is a
    DetectOptions. For anomaly imaging the workers also score the frames they hold and render
    the scores beside each tile (the map of a masked load is refused, as on one machine). With
    ``detections_path`` they are
    written there too (GeoJSON, KML, CSV by extension; an existing file is refused unless
    ``force``, as the map), moved into
    place after the map; if scoring or writing them fails, the map written at ``path`` is
    removed: neither output. Returns the map's result (with its arrays) and the DetectResult."""
    detect.check()
    imaging = detect.detector == "anomaly-imaging"
    if imaging and (light_field.masked or (render.get("load") or {}).get("mask")
                    or (render.get("load") or {}).get("mask_dir")):
        raise ValueError("detector: 'anomaly-imaging' does not take a masked light field (its "
                         "frames carry a weight channel); load it without the mask")
    if detections_path is not None:
        if os.path.lexists(detections_path) and not render.get("force", False):
            raise ValueError(f"{detections_path}: exists (force=True replaces it)")
        if detections_path.lower().endswith(".kml") and not light_field.crs:
            raise ValueError(f"{detections_path}: KML needs a CRS and the light field has none")
    render.pop("arrays", None)
    result = render_map(light_field, options, path=path, arrays=True,
                        _anomaly=detect if imaging else None, **render)
    stem, extension = os.path.splitext(detections_path or "")
    partial = f"{stem}.aos-partial{extension}"
    try:
        found = _core._detect_on_rendered_map(light_field, options, detect, result.image,
                                              result.count, result.views_used,
                                              result.views_selected, result._scores)
        if detections_path is not None:
            found.write(partial, True)  # beside its place (the format follows the extension)
            os.replace(partial, detections_path)
    except BaseException:
        for written in ([path] if path else []) + ([partial] if detections_path else []):
            with contextlib.suppress(OSError):
                os.remove(written)
        raise
    return result, found


def run_cases(function: Callable[[Any], Any], cases: Sequence[Any], *, client: Any = None,
              scheduler: Optional[str] = None, workers: Optional[int] = None,
              progress: Optional[Callable[[int, Any], object]] = None) -> list:
    """``[function(case) for case in cases]``, each call a Dask task (a study's cases:
    tools/appendix_b.py --workers N). The cluster is chosen as in render_map (and its options
    checked the same way): ``client``, else ``scheduler``, else a local cluster of ``workers``
    processes (None or 0: one; closed at the end).
    ``function`` and the cases must pickle (cloudpickle takes a script's own functions by
    value). ``progress(index, result)`` is called on the client as each case finishes, in
    completion order; the list is in the cases' order. The first failing case's exception is
    raised and the other tasks are cancelled."""
    from dask.distributed import Client, as_completed

    run = _run_options(client, scheduler, workers, None, None, False, None, None, "run_cases")
    owned = None
    if client is None:
        client = owned = Client(run.scheduler) if run.scheduler else local_client(run.workers)
    futures: list = []
    try:
        token = uuid.uuid4().hex
        futures = [client.submit(function, case, pure=False, key=f"aos-case-{i}-{token}")
                   for i, case in enumerate(cases)]
        index = {future.key: i for i, future in enumerate(futures)}
        results: list = [None] * len(cases)
        for future in as_completed(futures):
            i = index[future.key]
            results[i] = future.result()
            if progress is not None:
                progress(i, results[i])
        return results
    except BaseException:
        for future in futures:
            future.cancel()
        raise
    finally:
        if owned is not None:
            cluster = getattr(owned, "cluster", None)
            owned.close()
            if cluster is not None and not run.scheduler:
                cluster.close()
