"""Large-area maps on Dask (docs/distributed.md).

A map (map.h) is split into its render tiles (``MapOptions.tile_size`` pixels on a side); each
tile is one task on a ``dask.distributed`` cluster. A task reads only the frames whose footprint
may meet its tile (``MapWindowViews`` in map.h: a conservative projection test on poses and
cameras), decoded from their files into a per-worker cache with a byte budget (least recently
used frames are dropped first), renders its window (``RenderMapWindow``) and returns it; the
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
import copy
import math
import os
import threading
import time
import uuid
from dataclasses import dataclass, field
from typing import Any, Callable, Optional, Sequence

import numpy as np

from .. import _core

__all__ = ["DistributedMapResult", "render_map", "prepare_map", "run_cases", "local_client", "DEFAULT_CACHE_BYTES"]

# Per-worker frame cache budget: decoded frames held between tasks, bytes. A task's own frames
# are always held, so a worker's frames peak at max(budget, one tile's frames).
DEFAULT_CACHE_BYTES = 1 << 30

_LOAD_KEYS = ("grey", "mask", "mask_dir")


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
    frames_read: int = 0  # frame decodes summed over the tasks (cache misses)
    seconds_decode: float = 0.0  # the tasks' time reading frames (cache misses), summed
    seconds_render: float = 0.0  # the tasks' time rendering their windows, summed
    seconds: float = 0.0  # the whole call
    seconds_write: float = 0.0  # of which the COG copy and rename at the end (serial)
    _image: Optional[np.ndarray] = field(default=None, repr=False)
    _count: Optional[np.ndarray] = field(default=None, repr=False)

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


class _FrameCache:
    """The frames one worker process holds for one run: a poses-only light field into which
    frames are decoded, least recently used dropped first beyond the byte budget."""

    def __init__(self, light_field: Any, load: dict, budget: int):
        self.light_field = copy.copy(light_field)
        self.load = load
        self.budget = budget
        self.order: "collections.OrderedDict[int, None]" = collections.OrderedDict()
        self.frame_bytes = 0  # bytes of one decoded frame, learnt from the first decode
        self.decoded = 0

    def hold(self, indices: Sequence[int]) -> None:
        needed = set(indices)
        missing = [i for i in indices if i not in self.order]
        for i in indices:
            if i in self.order:
                self.order.move_to_end(i)
        # Make room first, so that the cache never holds more than the budget plus this tile.
        if missing and self.frame_bytes:
            room = self.budget - len(missing) * self.frame_bytes
            held = len(self.order) * self.frame_bytes
            drop = []
            for i in self.order:
                if held <= room:
                    break
                if i in needed:
                    continue
                drop.append(i)
                held -= self.frame_bytes
            if drop:
                _core._drop_view_images(self.light_field, drop)
                for i in drop:
                    del self.order[i]
        if missing:
            before = self.light_field.image_bytes()
            _core._load_view_images(self.light_field, missing, num_threads=1, **self.load)
            self.decoded += len(missing)
            if not self.frame_bytes:
                self.frame_bytes = max(1, (self.light_field.image_bytes() - before) // len(missing))
            for i in missing:
                self.order[i] = None


def _narrow_count(count: np.ndarray) -> np.ndarray:
    """``count`` (uint32) in the smallest unsigned type that holds its values, exactly: uint8
    where no pixel has more than 255 samples, as in most survey tiles. A tile's count then
    travels in a quarter (or half) of its bytes: tiles are what the client takes in over the
    network, which bounds it on a cluster (docs/distributed.md)."""
    return count.astype(np.min_scalar_type(int(count.max()) if count.size else 0))


_CACHE_LOCK = threading.Lock()
_CACHES: "dict[str, _FrameCache]" = {}


def _render_tile(token: str, light_field: Any, options: Any, load: dict, budget: int,
                 x0: int, y0: int, w: int, h: int, first_view: int) -> dict:
    """One task: the window's frames (cached), then its pixels."""
    with _CACHE_LOCK:  # one tile at a time per process; the render releases the GIL
        cache = _CACHES.get(token)
        if cache is None:
            _CACHES.clear()  # one run's frames at a time
            cache = _FrameCache(light_field, load, budget)
            _CACHES[token] = cache
        views = _core._map_window_views(cache.light_field, options, x0, y0, w, h)
        if not views:
            # No view meets the window: any selected view renders it empty (count 0), the one
            # held already if there is one.
            views = [next(iter(cache.order), first_view)]
        decoded_before = cache.decoded
        started = time.perf_counter()
        cache.hold(views)
        decoded = time.perf_counter()
        out = _core._render_map_window(cache.light_field, options, x0, y0, w, h, views)
        out["seconds_decode"] = decoded - started
        out["seconds_render"] = time.perf_counter() - decoded
        out["count"] = _narrow_count(out["count"])
        out["x0"], out["y0"] = x0, y0
        out["frames_read"] = cache.decoded - decoded_before
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
    can look at it while the run lasts. Close the client and its cluster
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
    config: dict = {"distributed.nanny.pre-spawn-environ.MALLOC_MMAP_THRESHOLD_": 262144}
    if not dashboard:
        config["distributed.scheduler.http.routes"] = ["distributed.http.health"]
        config["distributed.worker.http.routes"] = ["distributed.http.health"]
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


def render_map(light_field: Any, options: Any, *, path: Optional[str], client: Any = None,
               scheduler: Optional[str] = None, workers: Optional[int] = None,
               load: Optional[dict] = None, force: bool = False, arrays: bool = False,
               cache_bytes: int = DEFAULT_CACHE_BYTES,
               progress: Optional[Callable[[str, int, int], object]] = None
               ) -> DistributedMapResult:
    """Renders the map of ``light_field`` (a LightField, with or without its images: the
    workers read the frames from their files) and ``options`` (a MapOptions) on Dask; see the
    module's docstring. ``path``: the Cloud-Optimised GeoTIFF to write (None with arrays=True
    keeps the map in memory only). ``load``: how the frames are decoded (grey, mask, mask_dir
    as load_lightfield). ``progress(stage, done, total)`` is called on the client as tiles
    arrive ("render map", tiles) and while the COG is written. Raises ValueError naming the
    field or the file; nothing is written at ``path`` on any error."""
    started = time.perf_counter()
    load = dict(load or {})
    if cache_bytes < 0:
        raise ValueError(f"render_map(): cache_bytes: must be >= 0 (got {cache_bytes})")
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
    try:
        if client is None:
            from dask.distributed import Client

            if scheduler:
                client = owned = Client(scheduler)
            else:
                client = owned = local_client(workers or 1)
        image: Optional[np.ndarray] = None
        count: Optional[np.ndarray] = None
        if arrays:
            shape = (grid["height"], grid["width"]) + ((channels,) if channels > 1 else ())
            image = np.zeros(shape, np.float32)
            count = np.zeros((grid["height"], grid["width"]), np.uint32)
        token = uuid.uuid4().hex
        [poses_future] = client.scatter([poses], broadcast=True, hash=False)
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
        # A bounded number of tiles in flight, two per worker (one rendering, one queued):
        # finished tiles wait on their worker until the client has written them, so an
        # unbounded queue would hold the whole map there.
        group_of: dict = {}

        def submit_next(group: int) -> Any:
            queue = queues[group]
            if queue:
                window = queue.popleft()
            else:
                donor = max(range(len(queues)), key=lambda i: len(queues[i]))
                if not queues[donor]:
                    return None
                window = queues[donor].pop()
            x0, y0, w, h = window
            future = client.submit(_render_tile, token, poses_future, options, load, cache_bytes,
                                   x0, y0, w, h, selection[0], pure=False,
                                   key=f"aos-map-tile-{x0}-{y0}-{token}",
                                   workers=[addresses[group]], allow_other_workers=True)
            futures.append(future)
            group_of[future.key] = group
            return future

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
            out = future.result()  # re-raises the task's error (a frame's ValueError)
            future.release()
            following = submit_next(group_of.pop(future.key))
            if following is not None:
                completed.add(following)
            x0, y0 = out["x0"], out["y0"]
            h, w = out["count"].shape
            if writer is not None:
                writer.write(x0, y0, out["image"], out["count"].astype(np.uint32, copy=False))
            if image is not None and count is not None:
                image[y0:y0 + h, x0:x0 + w] = out["image"]
                count[y0:y0 + h, x0:x0 + w] = out["count"]
            used.update(out["used_view_indices"])
            result.samples += int(out["samples"])
            result.uncovered_pixels += int(out["uncovered_pixels"])
            result.frames_read += int(out["frames_read"])
            result.seconds_decode += float(out["seconds_decode"])
            result.seconds_render += float(out["seconds_render"])
            result.tiles += 1
            done += 1
            if progress is not None:
                progress("render map", done, len(windows))
        result.views_used = len(used)
        if writer is not None:
            write_started = time.perf_counter()
            writer.commit(progress)
            result.seconds_write = time.perf_counter() - write_started
        result._image, result._count = image, count
        result.seconds = time.perf_counter() - started
        return result
    except BaseException:
        for future in futures:
            future.cancel()
        writer = None  # the writer's destructor removes its temporary files
        raise
    finally:
        writer = None
        if owned is not None:
            cluster = getattr(owned, "cluster", None)
            owned.close()
            if cluster is not None and scheduler is None:
                cluster.close()


# ---- studies ----------------------------------------------------------------------------------


def run_cases(function: Callable[[Any], Any], cases: Sequence[Any], *, client: Any = None,
              scheduler: Optional[str] = None, workers: Optional[int] = None,
              progress: Optional[Callable[[int, Any], object]] = None) -> list:
    """``[function(case) for case in cases]``, each call a Dask task (a study's cases:
    tools/appendix_b.py --workers N). The cluster is chosen as in render_map: ``client``, else
    ``scheduler``, else a local cluster of ``workers`` processes (closed at the end).
    ``function`` and the cases must pickle (cloudpickle takes a script's own functions by
    value). ``progress(index, result)`` is called on the client as each case finishes, in
    completion order; the list is in the cases' order. The first failing case's exception is
    raised and the other tasks are cancelled."""
    from dask.distributed import Client, as_completed

    owned = None
    if client is None:
        client = owned = Client(scheduler) if scheduler else local_client(workers or 1)
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
            if cluster is not None and scheduler is None:
                cluster.close()
