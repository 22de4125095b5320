#!/usr/bin/env python3
"""The vocabulary of aos: every field of every Options struct, its Python name, its CLI flag on
each command, its default and its unit, generated from the package and `aos-render --help`.

    python3 tools/vocabulary.py              # writes docs/vocabulary.md
    python3 tools/vocabulary.py --check      # exit 1 if the page is stale or the surfaces drift

The options are defined once, in the C++ Options structs; Python exposes their fields under the
same names with the C++ defaults (aos.XxxOptions), and the CLI binds each flag to the field it
sets (cpp/exe/cli.h: Flags). `aos-render flags` lists those bindings (command, flag, field path,
default as --help prints it). This tool walks every field of the struct each command fills
(nested structs included) and finds its binding, or a reason in NOT_ON_THE_CLI. `rows()` lists
as problems every field with neither, every binding whose default differs from the struct's (as
Python sees it) or from what --help prints, and bindings of fields the struct does not have;
tests/python/test_vocabulary.py asserts there are none and that docs/vocabulary.md is what this
tool writes. Standard library only (and the aos under test).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any, Optional

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "vocabulary.md"

# Command -> the Options struct its flags fill (by Python class name).
COMMANDS = [
    ("integral", "IntegralOptions"),
    ("detect", "IntegralOptions"),
    ("live", "IntegralOptions"),
    ("stack", "FocalStackOptions"),
    ("merge", "MergeOptions"),
    ("allinfocus", "AllInFocusOptions"),
    ("map", "MapOptions"),
    ("view", "IntegralOptions"),
    ("simulate", "SimulateOptions"),
    ("demo", "DemoOptions"),
    ("rectify", "RectifyOptions"),
    ("calibrate", "CalibrateOptions"),
    ("poses", "PosesOptions"),
    ("import-colmap", "PosesOptions"),
    ("ground", "GroundOptions"),
    ("import-telemetry", "TelemetryOptions"),
    ("import-video", "VideoFramesOptions"),
    ("resolution", "ResolutionOptions"),
    ("metrics", "QualityOptions"),
    ("camera", "LensCamera"),
    ("plan", "FlightPlanOptions"),
]

# Structs outside a command's Options whose fields the command binds too, under a prefix of the
# bindings' field paths: (command, Python class name, prefix).
OUTSIDE = [
    ("map", "DistributedOptions", "distributed."),
    ("map", "DetectOptions", "detect."),
    ("detect", "DetectOptions", "detect."),
    ("live", "LiveOptions", "live."),
    ("live", "DetectOptions", "detect."),
    ("live", "TelemetryOptions", "telemetry."),
    ("live", "ViewerOptions", "viewer."),
    ("live", "MapOptions", "map."),
    ("view", "ViewerOptions", "viewer."),
    ("import-video", "TelemetryOptions", "telemetry."),
]


def structs() -> list[tuple[str, str, str]]:
    """Every (command, struct, field-path prefix) the vocabulary covers, in page order."""
    entries = [(command, class_name, "") for command, class_name in COMMANDS]
    for command, class_name, prefix in OUTSIDE:
        at = max(i for i, entry in enumerate(entries) if entry[0] == command)
        entries.insert(at + 1, (command, class_name, prefix))
    return entries


class LensCameraFields:
    """The fields of a default aos.LensCamera that `aos-render camera` sets (the flags are bound
    to LensCamera's own fields; max_radius and theta_max are derived by Finalize, not set)."""

    _fields = ("model", "width", "height", "fx", "fy", "cx", "cy", "distortion", "xi", "skew")

    def __init__(self) -> None:
        import aos

        # A Python LensCamera is validated when made (no empty one): these are the C++ member
        # initialisers of LensCamera (lens.h), which the CLI prints as defaults.
        self.model = aos.LensModel.pinhole
        self.width = self.height = 0
        self.fx = self.fy = self.cx = self.cy = 0.0
        self.distortion: list[float] = []
        self.xi = self.skew = 0.0


def options_of(class_name: str) -> Any:
    """A default instance of the struct a command fills."""
    import aos

    return LensCameraFields() if class_name == "LensCamera" else getattr(aos, class_name)()

# Fields set on the command line in another way, or Python only: (command or "*", field) -> why.
NOT_ON_THE_CLI = {
    ("stack", "render.surface_offset"): "a stack's slices lie at --first-offset..--last-offset",
    ("allinfocus", "stack.render.surface_offset"): "a stack's slices lie at --first-offset..--last-offset",
    ("integral", "variance"): "Python only (render_integral(variance=True))",
    ("detect", "variance"): "the scores come from the image; variance is render_integral's",
    ("view", "variance"): "the viewer shows images, not variances",
    ("allinfocus", "stack.render.variance"): "set by --method robust",
    ("merge", "robust.robust"): "set by --method robust",
    ("allinfocus", "merge.robust.robust"): "set by --method robust",
    ("import-colmap", "colmap"): "import-colmap runs no COLMAP",
    ("import-colmap", "workspace"): "import-colmap runs no COLMAP",
    ("import-colmap", "matcher"): "import-colmap runs no COLMAP",
    ("import-colmap", "sequential_overlap"): "import-colmap runs no COLMAP",
    ("import-colmap", "spatial_neighbors"): "import-colmap runs no COLMAP",
    ("import-colmap", "preset"): "import-colmap runs no COLMAP",
    ("import-colmap", "camera_file"): "the model holds the cameras",
    ("import-colmap", "camera_model"): "the model holds the cameras",
    ("import-colmap", "fov_deg"): "the model holds the cameras",
    ("import-colmap", "max_image_size"): "import-colmap runs no COLMAP",
    ("import-colmap", "max_num_features"): "import-colmap runs no COLMAP",
    ("import-colmap", "sift_first_octave"): "import-colmap runs no COLMAP",
    ("import-colmap", "max_focal_deviation"): "the model's intrinsics are kept as they are",
    ("import-colmap", "num_threads"): "import-colmap decodes frames on all cores",
    ("live", "variance"): "live shows images, not variances",
    ("live", "map.aperture_radius"): "--follow map takes it from the render flags",
    ("live", "map.view_indices"): "--follow map takes it from the render flags",
    ("live", "map.min_view_angle_deg"): "--follow map takes it from the render flags",
    ("live", "map.lens_tolerance_px"): "--follow map takes it from the render flags",
    ("live", "map.num_threads"): "--follow map takes it from the render flags",
    ("live", "map.width"): "--follow map takes it from the render flags",
    ("live", "map.focal_surface"): "--follow map takes it from the render flags",
    ("live", "map.surface_offset"): "--follow map takes it from the render flags",
    ("live", "map.tile_size"): "a live map is one window's: the default tiles",
    ("live", "map.max_pixels"): "a live map is bounded by its extent and pixel size",
    ("live", "map.min_view_count"): "a window of 30 frames: every view counts",
    ("live", "viewer.render_workers"): "the live page renders nothing (the run does)",
    ("live", "pose_view"): "--follow latest sets it to the newest view",
    ("live", "view_indices"): "the window is the selection (--window-frames)",
    ("live", "min_view_count"): "a window of 30 frames: every view counts",
    ("live", "telemetry.fov_deg"): "--frames-fov-deg gives it",
    ("live", "telemetry.grey"): "--grey gives it",
    ("live", "telemetry.altitude_window"): "one frame at a time: no running median",
    ("live", "telemetry.max_altitude_deviation_m"): "one frame at a time: no running median",
    ("live", "telemetry.radiometric"): "not yet live (issue 35's note)",
    ("live", "telemetry.kelvin_per_count"): "not yet live (issue 35's note)",
    ("live", "telemetry.kelvin_offset"): "not yet live (issue 35's note)",
    ("live", "telemetry.temperature_frames_dir"): "not yet live (issue 35's note)",
    ("import-video", "telemetry.telemetry_file"): "the import's own telemetry.csv",
    ("import-video", "telemetry.frame_interval_s"): "the CSV gives each frame's time",
    ("import-video", "telemetry.time_offset_s"): "the CSV gives each frame's time",
    ("import-video", "telemetry.altitude"): "EXIF/XMP only; --srt-altitude picks the SRT's",
    ("import-video", "telemetry.radiometric"): "decoded video frames are not radiometric",
    ("import-video", "telemetry.kelvin_per_count"): "decoded video frames are not radiometric",
    ("import-video", "telemetry.kelvin_offset"): "decoded video frames are not radiometric",
    ("import-video", "telemetry.temperature_frames_dir"): "decoded video frames are not radiometric",
}

# Fields whose flag prints no default in --help, because "not given" is the default and means
# something the help text states (no pose, all views, no file); every other flag must print the
# struct's default, so that a drifted default is seen.
NO_PRINTED_DEFAULT = {"cam_from_world", "pose_view", "view_indices", "camera_file", "focal_surface",
                      "ground_plane",  # --ground FILE: none = first_plane/last_plane
                      "positions_file", "positions_crs", "workspace", "telemetry_file", "srt_file",
                      "temperature_frames_dir",  # none: only with radiometric flir
                      "pose_error_px", "pose_error_m",  # exclusive flags; none = no pose error
                      "fy", "cx", "cy",  # camera: fy = fx, cx/cy = the centre
                      "extent",  # the map's extent: none = the views' footprints
                      "vertices",  # plan: none = a circle, sector or rectangle
                      "crs", "dem",  # plan: none = a local frame, flat ground
                      "scheduler",  # map: none = no Dask scheduler (--workers or this process)
                      "open_browser"}  # view: none = where a desktop session exists

# Flags on two commands with the same spelling and different meanings (listed on the page).
UNITS = [("_mps", "m/s"), ("_mb", "MiB"), ("_min", "minutes"), ("_s", "seconds"), ("_deg", "degrees"), ("_m", "metres"), ("_px", "pixels"), ("radius", "metres"),
         ("width", "pixels"), ("height", "pixels"), ("sigma", "pixels"), ("fraction", "0..1")]


def unit_of(command: str, field: str) -> str:
    name = field.rsplit(".", 1)[-1]
    if name == "window_radius":
        return "pixels"
    if name == "surface_offset":
        return "metres"
    if name == "edge_sigma":
        return "fraction of the image's range"
    if name == "agreement":
        return "fraction of the image's range"
    if name in ("pixel_size", "extent"):
        return "metres"
    if name == "tile_size":
        return "pixels"
    for suffix, unit in UNITS:
        if name.endswith(suffix):
            return unit
    return ""


def leaves(options: Any, prefix: str = "") -> list[tuple[str, Any]]:
    """(dotted field path, default value) of every field, nested Options expanded."""
    result = []
    for name in type(options)._fields:
        value = getattr(options, name)
        path = prefix + name
        if hasattr(type(value), "_fields"):
            result += leaves(value, path + ".")
        else:
            result.append((path, value))
    return result


HELP_LINE = re.compile(r"^\s{2}(-\w,)?(--[\w-]+)(?:,--[\w-]+)*(?:\s+([A-Z]+(?::[A-Z]+>=-?\d+)?))?(?:=(\S+))?")


def cli_flags(aos_render: str, command: str) -> dict[str, Optional[str]]:
    """Flag -> its default as `--help` prints it (None when it prints none)."""
    text = subprocess.run([aos_render, command, "--help"], capture_output=True, text=True,
                          check=True, timeout=30).stdout
    flags: dict[str, Optional[str]] = {}
    for line in text.splitlines():
        match = HELP_LINE.match(line)
        if match:
            flags[match.group(2)] = match.group(4)
    return flags


def python_default(value: Any) -> str:
    if hasattr(value, "name") and hasattr(type(value), "__members__"):
        return value.name
    if isinstance(value, float):
        return "inf" if math.isinf(value) else repr(value)
    if isinstance(value, (list, tuple)):
        return "[]" if not value else repr(list(value))
    if isinstance(value, str):
        return value if value else "''"
    if type(value).__name__ == "FocalSurface" and value.plane is not None:
        return "plane " + python_default(value.plane)
    if type(value).__name__ == "Plane":
        point = list(value.point)
        if list(value.normal) == [0.0, 0.0, 1.0] and point[:2] == [0.0, 0.0]:
            return f"z = {point[2]:g}"
        return repr(value)
    if type(value).__name__ == "Rigid3d":
        return "identity" if value == type(value)() else repr(value)
    return repr(value)


def same_default(python_value: Any, cli: Optional[str], path: str = "") -> bool:
    """Whether the CLI's printed default means the struct's default."""
    if cli is None:
        return True  # the flag prints none: the struct's applies
    if hasattr(python_value, "name") and hasattr(type(python_value), "__members__"):
        return cli == python_value.name
    if type(python_value).__name__ == "FocalSurface" and python_value.plane is not None:
        python_value = python_value.plane
    if type(python_value).__name__ == "Plane":
        try:
            return float(cli) == python_value.point[2] and list(python_value.normal) == [0, 0, 1]
        except ValueError:
            return False
    if isinstance(python_value, bool):
        return cli.lower() in (("true", "1") if python_value else ("false", "0"))
    if isinstance(python_value, (int, float)):
        try:
            return float(cli) == float(python_value)
        except ValueError:
            return False
    if isinstance(python_value, str):
        return cli == python_value
    return True


def cli_bindings(aos_render: str) -> list[dict[str, str]]:
    """Every flag bound to an Options field, from `aos-render flags`."""
    text = subprocess.run([aos_render, "flags"], capture_output=True, text=True, check=True,
                          timeout=30).stdout
    return json.loads(text)


def binding_for(bindings: list[dict[str, str]], command: str, path: str) -> Optional[dict]:
    """The binding of one field: its own flag (source "table", or "hand" for a struct without a
    table); shorthands (--focal-height for focal_surface) only where it has none."""
    found = [b for b in bindings if b["command"] == command and b["field"] == path]
    for candidates in ([b for b in found if b.get("source") != "shorthand"], found):
        if candidates:
            return candidates[0]
    return None


def shorthands_for(bindings: list[dict[str, str]], command: str, path: str) -> list[str]:
    """The other spellings of one field (Flags::Shorthand), in declaration order."""
    return [b["flag"] for b in bindings if b["command"] == command and b["field"] == path
            and b.get("source") == "shorthand"]


def has_table(class_name: str) -> bool:
    """Whether the struct lists its fields in a C++ field table (util/option_fields.h)."""
    import aos

    return hasattr(getattr(aos, class_name, None), "_field_table")


def rows(aos_render: str) -> tuple[list[dict[str, str]], list[str]]:
    """One row per (command, field), and the problems found."""
    import aos

    table: list[dict[str, str]] = []
    problems: list[str] = []
    bindings = cli_bindings(aos_render)
    for command, class_name, prefix in structs():
        flags = cli_flags(aos_render, command)
        fields = [(prefix + path, value) for path, value in leaves(options_of(class_name))]
        known = {path for path, _ in fields}
        # Bindings under the prefix of another struct of this command are that struct's.
        others = ["load."] + [p for c, _, p in structs() if c == command and p and p != prefix]
        for binding in bindings:
            field = binding["field"]
            if (binding["command"] == command and field not in known and "/" not in field
                    and field.startswith(prefix)
                    and not any(field.startswith(other) for other in others)):
                problems.append(f"{command} {binding['flag']}: bound to {class_name}."
                                f"{field[len(prefix):]}, which the struct does not have")
        for path, value in fields:
            name = path.rsplit(".", 1)[-1]
            binding = binding_for(bindings, command, path)
            flag = binding["flag"] if binding else None
            why = (NOT_ON_THE_CLI.get((command, path)) or NOT_ON_THE_CLI.get(("*", name)))
            shown = f"{class_name}.{path[len(prefix):]}"
            row = {"command": command, "python": shown,
                   "flag": flag or "",
                   "how": binding.get("source", "") if binding else "",
                   "also": ", ".join(f"`{f}`" for f in shorthands_for(bindings, command, path)),
                   "default": python_default(value), "unit": unit_of(command, path),
                   "note": ""}
            if binding is None:
                if why is None:
                    problems.append(f"{command}: {shown} has no flag "
                                    f"(--{name.replace('_', '-')}) and no reason in NOT_ON_THE_CLI")
                row["note"] = why or "MISSING"
            else:
                if has_table(class_name) and binding.get("source") != "table":
                    problems.append(f"{command} {flag}: {shown}'s flag is not its table row's "
                                    "(bind it with Flags::Field(options, name); another "
                                    "spelling is a Flags::Shorthand beside it)")
                if why is not None:
                    problems.append(f"{command}: NOT_ON_THE_CLI gives a reason for "
                                    f"{shown}, but {flag} sets it: a stale entry")
                bound = binding["default"] or None
                if bound is None and not (value is False or value is None or name in NO_PRINTED_DEFAULT):
                    problems.append(f"{command} {flag}: --help prints no default for "
                                    f"{shown} ({python_default(value)}): bind it "
                                    "with Flags::Field or list it in NO_PRINTED_DEFAULT")
                if not same_default(value, bound, path):
                    problems.append(f"{command} {flag}: the CLI default {bound!r} is not "
                                    f"{shown}'s {python_default(value)}")
                if "/" not in flag and flags.get(flag) != bound and not (
                        bound is None and value is False):
                    problems.append(f"{command} {flag}: --help prints {flags.get(flag)!r} but "
                                    f"the flag is bound with the default {bound!r}")
                if flag != "--" + name.replace("_", "-") and name != "num_threads":
                    row["note"] = "the row names its flag (OptionFieldSpec::flag)"
            table.append(row)
    return table, problems


def page(table: list[dict[str, str]]) -> str:
    how = [row["how"] for row in table if row["how"]]
    counts = (f"Of the {len(how)} fields on the command line, {how.count('table')} take their "
              f"flag from their table row and {how.count('hand')} are declared by hand; "
              f"{sum(1 for row in table if row['also'])} also have shorthands.")
    lines = """\
# Vocabulary: every option, its Python name, CLI flag, default and unit

Generated by `python3 tools/vocabulary.py` from the installed `aos` (the C++ Options structs as
Python exposes them) and `aos-render <command> --help`. `tests/python/test_vocabulary.py` fails
when this page is stale, when a field has neither a flag nor a stated reason, or when a flag's
default differs from the struct's. In Python every field is also a keyword argument of the
command's function, routed by its name (`aos.all_in_focus(lf, agreement=0.1)` sets
`merge.robust.agreement`).

Every flag is bound to the Options field it sets (cpp/exe/cli.h: Flags), and `aos-render flags`
lists the bindings with how each was declared. A field of a struct with a field table
(cpp/aos/util/option_fields.h) gets its flag from its row: the flag is the field's name
(`view_indices` is `--view-indices`), its help and range are the row's, its default the
member's; `tests/python/test_vocabulary.py` fails for a field whose flag is declared any other
way. {counts}

The rule and the exceptions, each stated in one place:
- `num_threads` is `--threads` on every command (every stage of the command, and a cap on the
  process's workers; `allinfocus` sets the stack's and the merge's from one flag).
- A row names its own flag (OptionFieldSpec::flag, the Note column says so) where one command
  would otherwise have two fields of one name or the name alone would mislead: `--frames-fov-deg`
  is the input frames' field of view (LoadOptions on the rendering commands, `poses`,
  `import-telemetry`) beside the virtual camera's `--fov-deg` (`integral`, `stack`,
  `allinfocus`, `view`); `--rectified-fov-deg` the rectified frames' (`rectify`);
  `--ssim-window-radius` the SSIM window (`metrics`) beside the merge's focus `--window-radius`.
- Shorthands (the Also column): other spellings of a field that has its own flag, such as
  `--focal-height H` (the horizontal plane) for `--focal-surface`, `--look-at` for
  `--cam-from-world`, `--pattern COLUMNSxROWS` for `--pattern-columns`/`--pattern-rows`,
  `--ground FILE` (a plane fitted to points) for `--ground-plane`, `--browser`/`--no-browser` for
  `--open-browser`.
- `aos-render camera` binds LensCamera's table (lens.h). `resolution`'s description of a lens
  (`--width`, `--height`, `--lens-fov-deg`, `--focal`, `--principal`, `--model`,
  `--distortion`, `--xi`, `--skew`) sets no Options field and is declared in the command.

Flags outside the Options structs: `-q/--quiet`, `--json` (the command's report as one JSON
object on stdout) and `--threads` on every command, `-o` (the output path) on every command that
writes, `--force` on commands that write files (output folders are never replaced),
`--sample-type`/`--range` where a rendered image is written in a chosen type (`integral`; the
other commands write float32 data products, 8-bit previews, or frames in their input's type).

Old spellings work for one release with a warning naming the new one (CHANGELOG.md): `--fov-deg`
on `poses`, `rectify` and `resolution`; `--window-radius` on `metrics`; `--images` on
`import-colmap`; `--square-size` (`calibrate`), `--distance` (`resolution`), `--camera`,
`--overlap`, `--max-features` (`poses`), `--min-registered`, `--positions`,
`--positions-from-exif` (`poses`, `import-colmap`); `--views` (`--view-indices`, on every command
that renders).
""".format(counts=counts).split("\n")
    for command, class_name, prefix in structs():
        lines += [f"## `aos-render {command}` ({class_name})", "",
                  "| Python field | CLI flag | Also | Default | Unit | Note |",
                  "|---|---|---|---|---|---|"]
        for row in table:
            if row["command"] == command and row["python"].startswith(class_name + "."):
                flag = f"`{row['flag']}`" if row["flag"] else ""
                lines.append(f"| `{row['python']}` | {flag} | {row['also']} | `{row['default']}` "
                             f"| {row['unit']} | {row['note']} |")
        lines.append("")
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true",
                        help="exit 1 if docs/vocabulary.md is stale or a field has no flag")
    parser.add_argument("--aos-render", default=shutil.which("aos-render") or "aos-render")
    args = parser.parse_args()
    table, problems = rows(args.aos_render)
    text = page(table)
    for problem in problems:
        print(f"vocabulary: {problem}", file=sys.stderr)
    if args.check:
        stale = not PAGE.exists() or PAGE.read_text() != text
        if stale:
            print(f"vocabulary: {os.path.relpath(PAGE)} is stale: run tools/vocabulary.py",
                  file=sys.stderr)
        return 1 if stale or problems else 0
    PAGE.write_text(text)
    print(f"wrote {os.path.relpath(PAGE)} ({len(table)} fields, {len(problems)} problems)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
