"""Maps on Dask (aos.distributed, aos-render map --workers): a small simulated survey whose
frames are read from disk by the workers. The map must be bit for bit the single-process map
(image, count and the GeoTIFF's bands), whatever the tiling and the frame cache; a worker killed
mid-run changes nothing; an unreadable frame stops the run naming the file, with nothing at the
output path. Clusters are LocalClusters of worker processes bound to 127.0.0.1."""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import subprocess
import sys
import uuid
from pathlib import Path

import numpy as np
import pytest

import aos

distributed = pytest.importorskip("distributed")
rasterio = pytest.importorskip("rasterio")

from aos.distributed import local_client  # noqa: E402

EXE = shutil.which("aos-render")

# 4 x 4 views 5 m up over a 15 m square, each seeing about 5.8 m: most frames meet only a part
# of the map, so the per-tile frame selection matters. Noise texture: every bit of every pixel
# carries information.
SCENE = {
    "ground": {"texture": {"type": "noise", "square": 0.5, "seed": 3}},
    "camera": {"width": 48, "height": 40, "fov_deg": 60},
    "sampling": {"altitude": 5.0, "grid": 4, "aperture": {"diameter": 15}},
    "truth": {"width": 8, "height": 8, "blocked_fraction": False},
}
PIXEL = 0.1
TILE = 32  # the map is about 210 x 210 pixels: 49 tiles


@pytest.fixture(scope="module")
def survey(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("survey") / "flight"
    aos.simulate(SCENE, folder)
    return folder / "lightfield.json"


@pytest.fixture(scope="module")
def client():
    with local_client(2) as c:
        yield c
        c.cluster.close()


def read_bands(path: Path) -> np.ndarray:
    with rasterio.open(path) as dataset:
        return dataset.read()


def test_a_window_from_its_own_frames_is_the_window_from_all(survey: Path) -> None:
    lf = aos.load_lightfield(survey).light_field
    options = aos.MapOptions(pixel_size=PIXEL, tile_size=TILE, num_threads=1)
    grid = aos._core._map_grid(lf, options)
    full = aos.render_map(lf, options)
    assert grid["width"] == full.width and grid["height"] == full.height
    fewer = 0
    for x0, y0 in [(0, 0), (grid["width"] - 20, 0), (60, 70), (0, grid["height"] - 17)]:
        w, h = min(37, grid["width"] - x0), min(29, grid["height"] - y0)
        views = aos._core._map_window_views(lf, options, x0, y0, w, h)
        fewer += len(views) < len(lf)
        # Every view outside the selection admits no sample in the window.
        everything = aos._core._render_map_window(lf, options, x0, y0, w, h, list(range(len(lf))))
        mine = aos._core._render_map_window(lf, options, x0, y0, w, h, views or [0])
        for out in (everything, mine):
            assert np.array_equal(out["image"], full.image[y0:y0 + h, x0:x0 + w])
            assert np.array_equal(out["count"], full.count[y0:y0 + h, x0:x0 + w])
        assert set(everything["used_view_indices"]) <= set(views)
    assert fewer >= 3  # the selection does leave frames out


def test_a_tile_s_count_travels_narrowed_but_exact(survey: Path) -> None:
    for values, dtype in [([0, 0], np.uint8), ([3, 255], np.uint8), ([0, 256], np.uint16),
                          ([65535, 1], np.uint16), ([65536, 0], np.uint32)]:
        count = np.array(values, np.uint32)
        narrow = aos.distributed._narrow_count(count)
        assert narrow.dtype == dtype and np.array_equal(narrow.astype(np.uint32), count)
    # A task's result: the survey's 16 views fit in uint8, the counts unchanged.
    poses = aos.load_lightfield(survey, load_images=False).light_field
    options = aos.MapOptions(pixel_size=PIXEL, tile_size=TILE, num_threads=1)
    out = aos.distributed._render_tile("test-narrow", poses, options, {}, 2**26, 32, 32, 32, 32, 0)
    loaded = aos.load_lightfield(survey).light_field
    views = aos._core._map_window_views(loaded, options, 32, 32, 32, 32)
    reference = aos._core._render_map_window(loaded, options, 32, 32, 32, 32, views)
    assert out["count"].dtype == np.uint8 and out["count"].max() > 0
    assert np.array_equal(out["count"], reference["count"])
    assert np.array_equal(out["image"], reference["image"])
    aos.distributed._CACHES.clear()  # the task's frame cache, held in this process


def test_the_dask_map_is_bit_for_bit_the_single_process_map(survey: Path, tmp_path: Path,
                                                            client) -> None:
    loaded = aos.load_lightfield(survey).light_field
    single = tmp_path / "single.tif"
    reference = aos.render_map(loaded, pixel_size=PIXEL, path=single, arrays=True)
    poses = aos.load_lightfield(survey, load_images=False).light_field
    out = tmp_path / "dask.tif"
    # A cache of two frames: frames are dropped and read again, which must change nothing.
    frame_bytes = loaded.image_bytes() // len(loaded)
    result = aos.distributed.render_map(poses, aos.MapOptions(pixel_size=PIXEL, tile_size=TILE),
                                        path=out, client=client, arrays=True,
                                        cache_mb=2 * frame_bytes / 2**20)
    assert np.array_equal(result.image, reference.image)
    assert np.array_equal(result.count, reference.count)
    assert np.array_equal(read_bands(out), read_bands(single), equal_nan=True)
    assert result.geotransform == reference.geotransform
    assert (result.samples, result.uncovered_pixels, result.views_used, result.views_selected) == (
        reference.samples, reference.uncovered_pixels, reference.views_used,
        reference.views_selected)
    assert result.tiles == 49
    # Each tile read only the frames meeting it: far fewer than every frame for every tile.
    assert result.frames_read < result.tiles * len(poses) / 2
    # aos.render_map(client=...) is the same route.
    again = aos.render_map(loaded, pixel_size=PIXEL, tile_size=64, client=client)
    assert np.array_equal(again.image, reference.image)
    assert not list(tmp_path.glob(".*"))  # no temporary files left


def test_detection_on_a_dask_map_is_the_single_process_detection(survey: Path, tmp_path: Path,
                                                                  client) -> None:
    """aos.distributed.detect_map: the map's tiles on Dask, scored where they are assembled:
    the detections of aos.detect_map on one machine, anomaly imaging's too. A failure after the
    map was written (here: detections in a format nobody writes) leaves neither output."""
    loaded = aos.load_lightfield(survey).light_field
    poses = aos.load_lightfield(survey, load_images=False).light_field
    options = aos.MapOptions(pixel_size=PIXEL, tile_size=TILE, focal_surface=0.0)
    detect = aos.DetectOptions(detector="rx", quantile=0.99, min_area_px=1)
    single = aos._core._detect_map(loaded, options, detect, None)
    out = tmp_path / "dask.tif"
    result, found = aos.distributed.detect_map(poses, options, detect, path=str(out),
                                               detections_path=str(tmp_path / "found.csv"),
                                               client=client)
    assert len(single.detections) >= 1 and len(found.detections) == len(single.detections)
    for ours, theirs in zip(found.detections, single.detections):
        assert ours.pixel == theirs.pixel and ours.world == pytest.approx(theirs.world, abs=1e-9)
    assert np.array_equal(found.scores, single.scores)
    assert out.exists() and (tmp_path / "found.csv").exists()
    with pytest.raises(ValueError, match="unknown detections format"):
        aos.distributed.detect_map(poses, options, detect, path=str(tmp_path / "b.tif"),
                                   detections_path=str(tmp_path / "found.txt"), client=client)
    assert not (tmp_path / "b.tif").exists() and not list(tmp_path.glob("found.aos-partial*"))
    # Anomaly imaging: the workers score the frames they hold and render the scores beside each
    # tile; the client's scores and detections are the single machine's.
    imaging = aos.DetectOptions(detector="anomaly-imaging", quantile=0.99, min_area_px=1)
    single = aos._core._detect_map(loaded, options, imaging, None)
    result, found = aos.distributed.detect_map(poses, options, imaging, path=None, client=client)
    assert np.array_equal(found.scores, single.scores)
    # With a cache of two views (frame and scores), frames and their scores are dropped and
    # made again: nothing changes.
    frame_bytes = loaded.image_bytes() // len(loaded)
    tight, small = aos.distributed.detect_map(poses, options, imaging, path=None, client=client,
                                              cache_mb=2 * 3 * frame_bytes / 2**20)
    assert np.array_equal(small.scores, single.scores)
    assert tight.frames_read > result.frames_read  # frames were dropped and read again
    assert float(found.scores.max()) > 0.0 and result.tiles > 1
    assert len(found.detections) == len(single.detections) >= 1
    for ours, theirs in zip(found.detections, single.detections):
        assert ours.pixel == theirs.pixel and ours.world == pytest.approx(theirs.world, abs=1e-9)
    # A masked load is refused before any work, as on one machine.
    with pytest.raises(ValueError, match="masked"):
        aos.distributed.detect_map(poses, options, imaging, path=str(tmp_path / "c.tif"),
                                   load={"mask": str(tmp_path / "mask.png")}, client=client)
    assert not (tmp_path / "c.tif").exists()


def test_frames_two_workers_need_are_decoded_once_on_their_machine(survey: Path,
                                                                   tmp_path: Path,
                                                                   client) -> None:
    """The shared frame store: frames that tiles of both workers need (the bands' border) are
    handed from one worker to the other rather than decoded twice; the map is unchanged, and
    the run leaves nothing in shared memory."""
    loaded = aos.load_lightfield(survey).light_field
    options = aos.MapOptions(pixel_size=PIXEL, tile_size=TILE)
    reference = aos.render_map(loaded, options)
    poses = aos.load_lightfield(survey, load_images=False).light_field
    base = aos.distributed._FrameStore("x", 0).base

    def stores() -> set:
        return {f for f in os.listdir(base) if f.startswith("aos-frames-")}

    before = stores()
    runs = {}
    default = aos.DistributedOptions().share_mb
    for share in (0.0, default):
        runs[share] = aos.distributed.render_map(poses, options, path=None, client=client,
                                                 arrays=True, share_mb=share)
        assert np.array_equal(runs[share].image, reference.image)
        assert np.array_equal(runs[share].count, reference.count)
    alone, together = runs[0.0], runs[default]
    assert alone.frames_shared == 0
    assert together.frames_shared > 0
    # Each frame is decoded at least once on this machine; a frame taken from the store was
    # decoded by the other worker.
    assert together.frames_read >= together.views_used
    assert stores() <= before  # this run's folder is gone
    with pytest.raises(ValueError, match="share_mb"):
        aos.distributed.render_map(poses, options, path=None, client=client, arrays=True,
                                   share_mb=-1)


def test_render_map_takes_the_cluster_options_of_distributed_options() -> None:
    """render_map's cluster knobs are aos.DistributedOptions' fields (defined once, in C++, as
    the CLI's flags): its defaults where not given, bad values refused naming the field before
    anything starts; the old byte spellings still work for one release, with a warning."""
    defaults = aos.DistributedOptions()
    run = aos.distributed._run_options(None, None, None, None, None, False, None, None)
    assert (run.cache_mb, run.share_mb, run.workers, run.scheduler) == (
        defaults.cache_mb, defaults.share_mb, 1, "")  # no client or scheduler: one local worker
    run = aos.distributed._run_options(None, "tcp://127.0.0.1:1", None, 8.0, 0.0, False, None,
                                       None)
    assert (run.workers, run.cache_mb, run.share_mb) == (0, 8.0, 0.0)
    with pytest.warns(DeprecationWarning, match="cache_bytes is deprecated; use cache_mb"):
        run = aos.distributed._run_options(None, None, 2, None, None, False, 3 << 20, None)
    assert (run.cache_mb, run.workers) == (3.0, 2)
    with pytest.warns(DeprecationWarning, match="share_bytes is deprecated; use share_mb"):
        run = aos.distributed._run_options(None, None, None, None, None, False, None, 1 << 19)
    assert run.share_mb == 0.5
    with pytest.warns(DeprecationWarning, match="DistributedOptions\\(\\).cache_mb"):
        assert aos.distributed.DEFAULT_CACHE_BYTES == int(defaults.cache_mb * 2**20)
    with pytest.warns(DeprecationWarning, match="DistributedOptions\\(\\).share_mb"):
        assert aos.distributed.DEFAULT_SHARE_BYTES == int(defaults.share_mb * 2**20)
    # Always on Dask: workers 0 (the struct's default, "no cluster" on the CLI) is one worker.
    assert aos.distributed._run_options(None, None, 0, None, None, False, None, None).workers == 1
    light_field, options = aos.LightField(), aos.MapOptions()  # never reached
    for kwargs, field in (({"cache_mb": -1.0}, "cache_mb"), ({"share_mb": math.nan}, "share_mb"),
                          ({"cache_mb": float(1 << 30)}, "cache_mb: .* MiB, not bytes"),
                          ({"workers": 2, "scheduler": "tcp://127.0.0.1:1"}, "workers/scheduler"),
                          ({"workers": -1}, "workers"),
                          ({"cache_mb": 1.0, "cache_bytes": 1}, "cache_bytes: not with cache_mb"),
                          ({"dashboard": True, "scheduler": "tcp://127.0.0.1:1"}, "dashboard"),
                          ({"client": object(), "workers": 2}, "workers: not with client"),
                          ({"client": object(), "dashboard": True}, "dashboard: not with client")):
        with pytest.raises(ValueError, match=f"render_map\\(\\): {field}"):
            aos.distributed.render_map(light_field, options, path=None, arrays=True, **kwargs)
    with pytest.warns(DeprecationWarning), pytest.raises(ValueError, match="cache_bytes: must be"):
        aos.distributed.render_map(light_field, options, path=None, arrays=True, cache_bytes=-1)
    with pytest.raises(TypeError, match="render_map\\(\\): workers: expected int, got str"):
        aos.distributed.render_map(light_field, options, path=None, arrays=True, workers="2")
    with pytest.raises(ValueError, match="run_cases\\(\\): workers/scheduler"):
        aos.distributed.run_cases(print, [], workers=2, scheduler="tcp://127.0.0.1:1")


def test_a_frame_from_the_store_is_the_decoded_frame_or_is_decoded_again(survey: Path) -> None:
    """_FrameCache with a _FrameStore, in this process: frames published by one cache are taken
    by another (not decoded), with the decoded pixels; a damaged or foreign file in the store,
    or a budget spent, only means decoding."""
    poses = aos.load_lightfield(survey, load_images=False).light_field
    loaded = aos.load_lightfield(survey).light_field
    token = "test-store-" + uuid.uuid4().hex
    try:
        one = aos.distributed._FrameCache(poses, {}, 2**26,
                                          aos.distributed._FrameStore(token, 2**26))
        one.hold([0, 1, 2, 3], publish=[1, 2, 3])
        assert (one.decoded, one.shared) == (4, 0)
        folder = Path(one.store.folder)
        assert sorted(p.name for p in folder.iterdir()) == ["1.npy", "2.npy", "3.npy"]
        other = aos.distributed._FrameCache(poses, {}, 2**26,
                                            aos.distributed._FrameStore(token, 2**26))
        other.hold([1])  # before its own first decode, the store is not used
        assert (other.decoded, other.shared) == (1, 0)
        # View 3's file damaged, view 2's replaced by another frame size: both decoded.
        (folder / "3.npy").write_bytes(b"\x93NUMPY damaged")
        np.save(folder / "2.npy", np.zeros((5, 7), np.uint8))
        np.save(folder / "5.npy", aos._core._view_image(loaded, 5))
        other.hold([2, 3, 5])
        assert (other.decoded, other.shared) == (3, 1)
        for i in (1, 2, 3, 5):
            assert np.array_equal(aos._core._view_image(other.light_field, i),
                                  loaded.views[i].image)
        # A worker writes no more than its budget.
        frame = loaded.views[0].image.nbytes
        small = aos.distributed._FrameStore(token + "-small", frame + frame // 2)
        full = aos.distributed._FrameCache(poses, {}, 2**26, small)
        full.hold([6, 7, 8], publish=[6, 7, 8])
        assert len(list(Path(small.folder).iterdir())) == 1
        # An empty file (a writer that died between open and write) is decoded again.
        (folder / "9.npy").write_bytes(b"")
        other.hold([9])
        assert other.shared == 1 and other.decoded == 4
    finally:
        aos.distributed._remove_frame_store(token)
        aos.distributed._remove_frame_store(token + "-small")
    assert not Path(one.store.folder).exists() and not Path(small.folder).exists()
    # A task of a run that has ended (cancelled, but already queued on its worker) renders
    # nothing and writes nothing.
    options = aos.MapOptions(pixel_size=PIXEL, tile_size=TILE, num_threads=1)
    late = aos.distributed._render_tile(token, poses, options, {}, 2**26, 0, 0, 32, 32, 0,
                                        [0, 1], 2**26)
    assert late == {"finished": True}
    assert token not in aos.distributed._CACHES and not Path(one.store.folder).exists()


def test_a_worker_killed_mid_run_changes_nothing(survey: Path, tmp_path: Path) -> None:
    poses = aos.load_lightfield(survey, load_images=False).light_field
    options = aos.MapOptions(pixel_size=PIXEL, tile_size=16)  # 169 tiles
    reference = aos.render_map(aos.load_lightfield(survey).light_field, options)
    killed: list[int] = []
    with local_client(2) as c:
        pids = list(c.run(os.getpid).values())

        def progress(stage: str, done: int, total: int) -> None:
            if stage == "render map" and done == 10 and not killed:
                os.kill(pids[0], signal.SIGKILL)
                killed.append(pids[0])

        result = aos.distributed.render_map(poses, options, path=tmp_path / "m.tif", client=c,
                                            arrays=True, progress=progress)
        c.cluster.close()
    assert killed
    assert result.tiles == math.ceil(result.width / 16) * math.ceil(result.height / 16)
    assert np.array_equal(result.image, reference.image)
    assert np.array_equal(result.count, reference.count)


def test_a_tile_dask_drops_is_submitted_again(survey: Path, client) -> None:
    """A tile's future cancelled under render_map (as Dask does when a worker dies with it,
    "already forgotten"): the tile is submitted again and the map is complete and unchanged."""
    from distributed import Future

    poses = aos.load_lightfield(survey, load_images=False).light_field
    options = aos.MapOptions(pixel_size=PIXEL, tile_size=TILE)
    reference = aos.render_map(aos.load_lightfield(survey).light_field, options)
    dropped: list[str] = []

    def progress(stage: str, done: int, total: int) -> None:
        if stage == "render map" and done == 3 and not dropped:
            pending = [key for key, state in client.futures.items()
                       if str(key).startswith("aos-map-tile") and state.status == "pending"]
            assert pending
            Future(pending[0], client).cancel()
            dropped.append(pending[0])

    result = aos.distributed.render_map(poses, options, path=None, client=client, arrays=True,
                                        progress=progress)
    assert dropped and dropped[0].endswith("-0")
    assert result.tiles == 49
    assert np.array_equal(result.image, reference.image)
    assert np.array_equal(result.count, reference.count)


def test_an_unreadable_frame_names_the_file_and_writes_nothing(survey: Path, tmp_path: Path,
                                                               client) -> None:
    folder = tmp_path / "flight"
    shutil.copytree(survey.parent, folder)
    poses = aos.load_lightfield(folder / "lightfield.json", load_images=False).light_field
    broken = poses.views[9].image_path
    # The run starts, then a frame becomes unreadable (view 0 is read first, on the client).
    Path(broken).write_bytes(b"not an image")
    out = tmp_path / "out" / "map.tif"
    out.parent.mkdir()
    with pytest.raises(ValueError, match=Path(broken).name):
        aos.distributed.render_map(poses, aos.MapOptions(pixel_size=PIXEL, tile_size=TILE),
                                   path=out, client=client)
    assert list(out.parent.iterdir()) == []


@pytest.mark.skipif(EXE is None, reason="aos-render not on PATH")
def test_cli_workers_write_the_same_map(survey: Path, tmp_path: Path) -> None:
    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([EXE, "map", str(survey), "--pixel-size", str(PIXEL), "--tile-size",
                               str(TILE), *args], capture_output=True, text=True, timeout=300)

    single = run("-o", str(tmp_path / "single.tif"), "-q", "--cache-mb", "64")
    assert single.returncode == 0, single.stderr
    # A cluster's budget without a cluster: checked, and said to be ignored.
    assert "--cache-mb is ignored without --workers or --scheduler" in single.stderr
    spread = run("-o", str(tmp_path / "dask.tif"), "--workers", "2", "--json")
    assert spread.returncode == 0, spread.stderr
    report = json.loads(spread.stdout)
    assert report["tiles"] == 49 and report["workers"] == 2 and report["frames_shared"] > 0
    assert np.array_equal(read_bands(tmp_path / "dask.tif"), read_bands(tmp_path / "single.tif"),
                          equal_nan=True)
    # Checked before any cluster starts: an existing output, a bad worker count.
    again = run("-o", str(tmp_path / "dask.tif"), "--workers", "2")
    assert again.returncode != 0 and "exists" in again.stderr
    # The writer's checks come before render_map starts a cluster (on_start never called).
    started: list = []
    poses = aos.load_lightfield(survey, load_images=False).light_field
    with pytest.raises(ValueError, match="exists"):
        aos.distributed.render_map(poses, aos.MapOptions(pixel_size=PIXEL, tile_size=TILE),
                                   path=tmp_path / "dask.tif", workers=2,
                                   on_start=started.append)
    assert started == []
    for flags in (["--workers", "-1"], ["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"],
                  ["--workers", "2", "--cache-mb", "-1"], ["--workers", "2", "--share-mb", "-1"],
                  ["--dashboard"], ["--share-mb", "inf"]):
        bad = run("-o", str(tmp_path / "x.tif"), *flags)
        assert bad.returncode == 2, bad.stderr
        assert (flags[-2] if len(flags) > 1 else flags[0]) in bad.stderr
        assert not (tmp_path / "x.tif").exists()


def test_a_study_on_dask_prints_the_same_table(tmp_path: Path) -> None:
    """tools/appendix_b.py --workers 2 runs its cases as Dask tasks (the script's own functions
    travel by value) and finds the same PSNR and SSIM as in one process."""
    tool = Path(__file__).resolve().parents[2] / "tools" / "appendix_b.py"
    env = dict(os.environ)

    def table(*flags: str) -> list[str]:
        result = subprocess.run([sys.executable, str(tool), "--size", "48", "--voxel-grid", "12",
                                 "--max-grid", "3", "--no-write", *flags], capture_output=True,
                                text=True, timeout=600, env=env, cwd=tmp_path)
        assert result.returncode == 0, result.stderr[-2000:]
        rows = [line.split("] ", 1)[1].split(" (simulate")[0]
                for line in result.stdout.splitlines() if line.startswith("[")]
        assert len(rows) == 9
        return sorted(rows)

    assert table("--workers", "2") == table()


def test_a_map_on_a_sloped_dem_is_bit_for_bit_too(survey: Path, tmp_path: Path, client) -> None:
    """A terrain (a DEM sloping 1 m over 10 m, with a nodata hole): the window's focal points
    span heights, and the frame selection must still keep every frame that sees them."""
    lf = aos.load_lightfield(survey).light_field
    ys, xs = np.mgrid[0:30, 0:30].astype(np.float32)
    heights = (0.1 * xs - 1.5).astype(np.float32)
    heights[12:15, 3:6] = np.nan
    dem = aos.Heightfield(heights, (-15.0, 1.0, 0.0, 15.0, 0.0, -1.0))
    options = dict(pixel_size=PIXEL, focal_surface=dem, surface_offset=0.2, tile_size=TILE)
    reference = aos.render_map(lf, **options)
    assert reference.uncovered_pixels > 0
    result = aos.render_map(lf, client=client, path=tmp_path / "dem.tif", arrays=True, **options)
    assert np.array_equal(result.image, reference.image)
    assert np.array_equal(result.count, reference.count)


def test_a_map_on_a_dem_that_covers_no_pixel_is_refused_too(survey: Path, tmp_path: Path,
                                                            client) -> None:
    """A DEM whose valid heights are a ring around the map (nodata inside): its extent spans the
    map, so only the render finds that no pixel is covered. In one process the map is refused;
    on a cluster it was written, every pixel nodata, with exit 0."""
    lf = aos.load_lightfield(survey).light_field
    heights = np.zeros((40, 40), np.float32)
    heights[2:-2, 2:-2] = np.nan
    dem = aos.Heightfield(heights, (-20.0, 1.0, 0.0, 20.0, 0.0, -1.0))
    options = dict(pixel_size=PIXEL, focal_surface=dem, tile_size=TILE)
    with pytest.raises(ValueError, match="no pixel is covered"):
        aos.render_map(lf, **options)
    with pytest.raises(ValueError, match="no pixel is covered"):
        aos.render_map(lf, client=client, path=tmp_path / "dem.tif", **options)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("columns,rows,groups", [(7, 7, 2), (9, 4, 3), (1, 5, 2), (5, 1, 4),
                                                 (3, 3, 9), (2, 2, 5)])
def test_tiles_go_to_workers_in_compact_balanced_groups(columns: int, rows: int,
                                                       groups: int) -> None:
    """The placement of tiles on workers (a preference; the pixels do not depend on it): every
    tile exactly once, group sizes within one of each other, and consecutive tiles of a group
    side by side (boustrophedon), so that a worker's tiles share their frames."""
    tile = 10
    width = columns * tile - 3  # the last column is narrower
    windows = [(x, y, min(tile, width - x), tile) for y in range(0, rows * tile, tile)
               for x in range(0, width, tile)]
    split = aos.distributed._tile_groups(windows, width, tile, groups)
    assert len(split) == min(groups, len(windows))
    assert sorted(w for group in split for w in group) == sorted(windows)
    sizes = [len(group) for group in split]
    assert max(sizes) - min(sizes) <= 1 and min(sizes) >= 1
    for group in split:
        for (xa, ya, *_), (xb, yb, *_) in zip(group, group[1:]):
            assert abs(xa - xb) + abs(ya - yb) == tile  # neighbours


def test_the_plan_study_on_dask_prints_the_same_table(tmp_path: Path) -> None:
    """tools/plan_study.py --workers 2: the plans as Dask tasks, the same table row for row."""
    tool = Path(__file__).resolve().parents[2] / "tools" / "plan_study.py"

    def table(*flags: str) -> list[str]:
        result = subprocess.run([sys.executable, str(tool), "--diameters", "8,12", "--spacings",
                                 "4", "--altitudes", "20", *flags], capture_output=True,
                                text=True, timeout=600, cwd=tmp_path)
        assert result.returncode == 0, result.stderr[-2000:]
        rows = [line for line in result.stdout.splitlines() if line.startswith("| ")]
        assert len(rows) == 3  # the header and two plans
        return rows

    assert table("--workers", "2") == table()


def test_the_local_cluster_admits_only_its_own_client(survey: Path) -> None:
    """local_client's cluster talks TLS with credentials made for the session: a client without
    them is refused (no other program on the machine can run code on the workers); without
    dashboard=True its HTTP server (127.0.0.1) answers only the health check."""
    import urllib.error
    import urllib.request

    from dask.distributed import Client
    from distributed.security import Security

    with local_client(1) as c:
        address = c.scheduler.address
        assert address.startswith("tls://127.0.0.1:")
        # A TLS client with credentials of its own (another certificate authority): refused.
        with pytest.raises(Exception):
            Client(address, security=Security.temporary(), timeout=5)
        assert c.submit(sum, [1, 2]).result(timeout=60) == 3
        # The quieter housekeeping reaches the worker processes (the nannies pass it on).
        import dask

        settings = c.run(lambda: (dask.config.get("distributed.admin.tick.interval"),
                                  dask.config.get("distributed.worker.profile.enabled")))
        assert list(settings.values()) == [("500ms", False)]
        base = c.dashboard_link.rsplit("/", 1)[0]
        assert base.startswith("http://127.0.0.1:")
        with urllib.request.urlopen(base + "/health", timeout=30) as page:
            assert page.status == 200
        for route in ("/status", "/info/main/workers.html", "/json/counts.json"):
            with pytest.raises(urllib.error.HTTPError, match="404"):
                urllib.request.urlopen(base + route, timeout=30)
        c.cluster.close()


def test_the_dashboard_shows_the_map_tasks_on_loopback(survey: Path, tmp_path: Path) -> None:
    """--dashboard: Dask's dashboard on 127.0.0.1 (bokeh), whose task stream lists the tiles."""
    pytest.importorskip("bokeh")
    import urllib.request

    poses = aos.load_lightfield(survey, load_images=False).light_field
    with local_client(1, dashboard=True) as c:
        link = c.dashboard_link
        assert link.startswith("http://127.0.0.1:")
        aos.distributed.render_map(poses, aos.MapOptions(pixel_size=PIXEL, tile_size=64),
                                   path=None, client=c, arrays=True)
        base = link.rsplit("/", 1)[0]
        with urllib.request.urlopen(base + "/status", timeout=30) as page:
            assert page.status == 200 and b"Dask" in page.read()
        # The dashboard's progress bars group the tasks by key prefix: the tiles are one bar.
        prefixes = c.run_on_scheduler(lambda dask_scheduler: list(dask_scheduler.task_prefixes))
        assert "aos-map-tile" in prefixes
        c.cluster.close()


@pytest.mark.parametrize("lens", [
    {"lens": "radtan", "fov_deg": 90.0, "distortion": [-0.05, 0.01, 0.001, -0.001, 0.0]},
    {"lens": "fisheye", "fov_deg": 100.0, "distortion": [0.01, -0.002]},
])
def test_lens_frames_are_selected_without_losing_a_sample(lens: dict, tmp_path: Path,
                                                          client) -> None:
    """Frames through a lens model: the per-tile selection casts the image border back through
    the lens; the map must still be bit for bit the single-process map, and the selection must
    still leave frames out. (A fisheye whose image corners look back past 90 degrees, e.g. 150
    degrees across the width, is never left out: its border has no bounded box.)"""
    scene = dict(SCENE, camera=dict(SCENE["camera"], **lens),
                 sampling=dict(SCENE["sampling"], altitude=3.0))
    folder = tmp_path / "flight"
    aos.simulate(scene, folder)
    lf = aos.load_lightfield(folder / "lightfield.json").light_field
    options = dict(pixel_size=PIXEL, tile_size=TILE, extent=[-9.0, -9.0, 9.0, 9.0])
    reference = aos.render_map(lf, **options)
    poses = aos.load_lightfield(folder / "lightfield.json", load_images=False).light_field
    result = aos.render_map(poses, client=client, path=None, arrays=True, **options)
    assert np.array_equal(result.image, reference.image)
    assert np.array_equal(result.count, reference.count)
    map_options = aos.MapOptions(**options)
    selected = [len(aos._core._map_window_views(poses, map_options, x0, y0,
                                                 min(TILE, result.width - x0),
                                                 min(TILE, result.height - y0)))
                for y0 in range(0, result.height, TILE) for x0 in range(0, result.width, TILE)]
    assert sum(selected) < 0.75 * len(selected) * len(poses), selected


def test_the_dask_map_has_the_single_process_overviews(survey: Path, tmp_path: Path,
                                                       client) -> None:
    """The overviews the writer fills as windows arrive (in any order) equal the single-process
    file's, bit for bit."""
    options = dict(pixel_size=0.035, tile_size=64)  # about 600 pixels: overviews 2 and 4
    lf = aos.load_lightfield(survey).light_field
    aos.render_map(lf, path=tmp_path / "single.tif", **options)
    poses = aos.load_lightfield(survey, load_images=False).light_field
    aos.render_map(poses, client=client, path=tmp_path / "dask.tif", **options)
    with rasterio.open(tmp_path / "single.tif") as a, rasterio.open(tmp_path / "dask.tif") as b:
        assert a.overviews(1) == b.overviews(1) == [2, 4]
        assert np.array_equal(a.read(), b.read(), equal_nan=True)
    for level in range(2):
        with rasterio.open(tmp_path / "single.tif", overview_level=level) as a, \
                rasterio.open(tmp_path / "dask.tif", overview_level=level) as b:
            assert np.array_equal(a.read(), b.read(), equal_nan=True)
