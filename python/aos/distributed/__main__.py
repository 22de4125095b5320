"""``python -m aos.distributed --spec JSON``: what ``aos-render map --workers N`` (or
``--scheduler ADDRESS``) runs once it has checked its command line and the output path. The
flags' values come as one JSON object (the flags are declared once, in C++): light_field;
load, options and distributed: aos::LoadOptions, aos::MapOptions and aos::DistributedOptions in
their JSON form (cpp/aos/lightfield/options_json.h; options and distributed are read here by
from_json, load is a dict whose keys are load_lightfield's: no field is listed twice; a focal
surface travels in options as its plane or its file); views ("" = all), resolved once the light
field is loaded; output, force, quiet, json. Draws a progress bar on stderr (plain lines when
stderr is not a terminal), prints
the report (a JSON object with --json), exits 0; errors: one line on stderr, exit 1 (bad input)
or 2 (bad spec)."""

from __future__ import annotations

import json
import sys
import time
from typing import Any


def _fail(message: str, code: int = 1) -> int:
    sys.stderr.write(f"aos-render map: error: {message}\n")
    return code


class _Bar:
    """A progress bar on stderr: redrawn in place on a terminal, else a line per 10 %."""

    def __init__(self, quiet: bool):
        self.quiet = quiet
        self.tty = sys.stderr.isatty()
        self.stage = ""
        self.last = -1
        self.started = time.monotonic()

    def __call__(self, stage: str, done: int, total: int) -> None:
        if self.quiet or total <= 0:
            return
        if stage != self.stage:
            self.finish()
            self.stage, self.last, self.started = stage, -1, time.monotonic()
        percent = int(100 * done / total)
        if self.tty:
            if percent == self.last:
                return
            filled = percent * 30 // 100
            sys.stderr.write(f"\r{stage:14s} [{'#' * filled}{'.' * (30 - filled)}] "
                             f"{percent:3d}% {done}/{total} {time.monotonic() - self.started:.0f} s")
        elif percent // 10 != self.last // 10 or done == total:
            sys.stderr.write(f"{stage}: {percent}% ({done}/{total})\n")
        self.last = percent
        sys.stderr.flush()

    def finish(self) -> None:
        if self.tty and self.stage and not self.quiet:
            sys.stderr.write("\n")
        self.stage = ""


def _dashboard_link(client: Any, local: bool) -> str:
    """The dashboard's address: a local cluster serves it only with bokeh installed here (without
    it Dask serves a page asking for bokeh); a remote scheduler's is its own."""
    if local:
        try:
            import bokeh  # noqa: F401
        except ImportError:
            return ""
    try:
        return str(client.dashboard_link or "")
    except Exception:  # a scheduler without an HTTP server
        return ""


def main(argv: list[str]) -> int:
    if len(argv) != 2 or argv[0] != "--spec":
        return _fail("usage: python -m aos.distributed --spec JSON (run `aos-render map "
                     "--workers N`)", 2)
    try:
        spec: dict[str, Any] = json.loads(argv[1])
    except ValueError as error:
        return _fail(f"--spec: not JSON ({error})", 2)
    try:
        import dask.distributed  # noqa: F401
    except ImportError:
        return _fail("--workers/--scheduler need Dask: pip install dask distributed")
    import aos
    from aos import distributed
    from aos.viewer.session import BadParameter, parse_view_list

    quiet = bool(spec.get("quiet")) or bool(spec.get("json"))
    bar = _Bar(quiet)
    try:
        load = spec["load"]
        options = aos.MapOptions.from_json(json.dumps(spec["options"]))
        run = aos.DistributedOptions.from_json(json.dumps(spec["distributed"]))
        loaded = aos.load_lightfield(spec["light_field"], fov_deg=load["fov_deg"],
                                     images_dir=load["images_dir"], load_images=False)
        for note in loaded.notes:
            sys.stderr.write(f"note: {note}\n")
        light_field = loaded.light_field
        if spec.get("views"):
            options.view_indices = parse_view_list(spec["views"], len(light_field))
        if light_field.crs:  # a surface read from its file (its JSON form), in the map's CRS
            options.focal_surface = options.focal_surface.in_crs(light_field.crs)
        if not light_field.crs:
            sys.stderr.write(f"warning: {spec['light_field']}: the light field has no CRS, so the "
                             "map has none: GIS tools will place it in the frame's own "
                             "coordinates (origin + local), not on the Earth\n")
        frame_load = {key: load[key] for key in ("grey", "mask", "mask_dir") if load.get(key)}
        # --detect: the map is kept in memory here too and scored once rendered.
        detect_path = spec.get("detect") or ""
        detect = None
        if detect_path:
            detect = aos.DetectOptions.from_json(json.dumps(spec["detect_options"]))
        workers = run.workers
        scheduler = run.scheduler
        if not scheduler:
            try:
                import cryptography  # noqa: F401  (the local cluster's TLS credentials)
            except ImportError:
                return _fail("--workers needs the cryptography package for the local cluster's "
                             "session credentials: pip install 'aos[dask]'")

        def started(client: Any) -> None:
            # render_map checked the inputs (the poses, the grid, one frame decoded) and the
            # output (folder, existing file, free space) before it started the cluster.
            if quiet:
                return
            where = f"the cluster at {scheduler}" if scheduler else \
                f"a local cluster of {workers} worker processes"
            sys.stderr.write(f"map: {len(light_field)} frames, tiles of {options.tile_size} "
                             f"pixels as Dask tasks on {where}\n")
            if scheduler or run.dashboard:
                link = _dashboard_link(client, local=not scheduler)
                sys.stderr.write(f"map: Dask dashboard at {link}\n" if link else
                                 "map: no Dask dashboard (pip install bokeh)\n")

        common = dict(scheduler=scheduler or None, workers=workers, dashboard=run.dashboard,
                      on_start=started, load=frame_load, force=bool(spec.get("force", False)),
                      cache_mb=run.cache_mb, share_mb=run.share_mb, progress=bar)
        found = None
        if detect_path:
            result, found = distributed.detect_map(light_field, options, detect,
                                                   path=spec["output"],
                                                   detections_path=detect_path, **common)
        else:
            result = distributed.render_map(light_field, options, path=spec["output"], **common)
        bar.finish()
    except BadParameter as error:
        bar.finish()
        return _fail(str(error))
    except (ValueError, OSError) as error:
        bar.finish()
        return _fail(str(error).splitlines()[0] if str(error) else type(error).__name__)
    except KeyError as error:
        bar.finish()
        return _fail(f"--spec: missing {error}", 2)
    except KeyboardInterrupt:
        bar.finish()
        return _fail("interrupted; nothing written", 130)

    x0, p, _, y0, _, _ = result.geotransform
    pixels = result.width * result.height
    report = {"command": "map", "output": spec["output"], "width": result.width,
              "height": result.height, "pixel_size": result.pixel_size,
              "geotransform": list(result.geotransform), "crs": result.crs,
              "up": "+z" if result.up_z > 0 else "-z", "views_used": result.views_used,
              "views_selected": result.views_selected, "samples": result.samples,
              "uncovered_pixels": result.uncovered_pixels, "tiles": result.tiles,
              "workers": workers, "scheduler": scheduler, "frames_read": result.frames_read,
              "frames_shared": result.frames_shared, "seconds": round(result.seconds, 3)}
    if found is not None:
        report.update({"detect": detect_path, "detections": len(found.detections),
                       "threshold_rule": found.threshold_rule})
    if spec.get("json"):
        print(json.dumps(report), flush=True)
    else:
        crs = f", {result.crs}" if result.crs else ""
        print(f"wrote {spec['output']}: {result.width} x {result.height} pixels of {p:g} m, "
              f"x {x0:g} .. {x0 + result.width * p:g}, y {y0 - result.height * p:g} .. {y0:g}{crs}")
        print(f"integrated {result.views_used} of {result.views_selected} selected views: "
              f"{result.samples} samples, {result.uncovered_pixels} of {pixels} pixels seen by "
              f"no view (nodata, count 0); {result.tiles} tiles, {result.frames_read} frame "
              f"reads, {result.frames_shared} frames handed between workers, "
              f"{result.seconds:.1f} s")
        if found is not None:
            print(f"wrote {detect_path}: {len(found.detections)} detections on the map "
                  f"({found.threshold_rule}: threshold {found.threshold:g})")
            for number, d in enumerate(found.detections, 1):
                print(f"{number}: map pixel ({d.pixel[0]:.1f}, {d.pixel[1]:.1f}), {d.area_px} px, "
                      f"peak {d.peak_score:g}, world {d.world[0]:g} {d.world[1]:g} "
                      f"{d.world[2]:g}, seen by {len(d.views)} views")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
