"""Every command of aos-render, from its own command table: an input is never an output (every
output flag against every input flag, by real path, --force or not), --threads is bounded, every
command stops within 2 s of SIGTERM or SIGINT leaving no output, and an oversized input under a
memory limit gives one clear error. The commands and their file flags are read from the
executable (`aos-render --help`, `aos-render flags --files`), so a command or flag added later is
in these tests by construction: a command with no row in the tables below fails the test that
lists them, naming what to add."""
from __future__ import annotations

import concurrent.futures
import functools
import json
import os
import re
import resource
import shutil
import signal
import struct
import subprocess
import time
import zlib
from pathlib import Path

import numpy as np
import pytest

import aos
from avi_util import write_mjpeg_avi
from signal_util import catches

EXE = shutil.which("aos-render")
pytestmark = pytest.mark.skipif(EXE is None, reason="aos-render is not on PATH (pip install .)")


def run(*args: str, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run([EXE, *args], capture_output=True, text=True, timeout=60, **kwargs)


def commands() -> list[str]:
    """The command table, as `aos-render --help` lists it."""
    text = run("--help").stdout
    section = re.split(r"^subcommands:", text, flags=re.M | re.I)[1]
    return re.findall(r"^\s{2}([a-z][a-z-]*)\s", section, flags=re.M)


def file_flags() -> list[dict[str, str]]:
    result = run("flags", "--files")
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


# ---- an input is never an output ----

# The smallest command line each command parses, by flag (positionals by their name, in order);
# the values are placeholders: the file check runs before the command reads anything.
BASE: dict[str, dict[str, str]] = {
    "integral": {"lightfield": "lf.json", "--output": "out.tif"},
    "detect": {"lightfield": "lf.json", "--geojson": "found.geojson"},
    "live": {"--replay": "lf.json", "--geojson": "found.geojson"},
    "stack": {"lightfield": "lf.json", "--output-dir": "out_dir"},
    "merge": {"stack": "stack_dir", "--output-dir": "out_dir"},
    "allinfocus": {"lightfield": "lf.json", "--output-dir": "out_dir"},
    "map": {"lightfield": "lf.json", "--output": "out.tif"},
    "view": {"lightfield": "lf.json"},
    "calibrate": {"frames": "frame.png", "--output": "camera.json"},
    "camera": {"--width": "64", "--height": "48", "--fx": "50", "--output": "camera.json"},
    "rectify": {"frames": "frame.png", "--camera": "camera.json", "--output-dir": "out_dir"},
    "poses": {"frames": "frames_dir", "--output": "lf.json"},
    "import-colmap": {"model": "model_dir", "--images-dir": "frames_dir", "--output": "lf.json"},
    "ground": {"lightfield": "lf.json", "--output": "dem.tif"},
    "import-telemetry": {"frames": "frames_dir", "--output": "lf.json"},
    "import-video": {"video": "video.avi", "--srt-file": "flight.srt", "--output": "out_dir"},
    "export-odm": {"lightfield": "lf.json", "--output": "geo.txt"},
    "check-gcp": {"lightfield": "lf.json", "gcp_file": "gcp_list.txt"},
    "simulate": {"--output-dir": "out_dir"},
    "demo": {"--output-dir": "out_dir"},
    "metrics": {"test": "a.png", "reference": "b.png"},
    "plan": {"--csv": "plan.csv"},
}
# Flags of the base that a flag under test excludes (CLI11 refuses both together).
EXCLUDES: dict[tuple[str, str], list[str]] = {
    ("rectify", "--lightfield"): ["frames", "--camera"],
}


def command_line(command: str, values: dict[str, str]) -> list[str]:
    positional = [v for k, v in values.items() if not k.startswith("-")]
    options = [x for k, v in values.items() if k.startswith("-") for x in (k, v)]
    return [command, *positional, *options]


@functools.lru_cache(maxsize=None)
def has_force(command: str) -> bool:
    return "--force" in run(command, "--help").stdout


def pairs() -> list[tuple[str, str, str, str, str]]:
    """(command, output flag, its role, input flag, its role) for every pair of every command."""
    flags = file_flags()
    out = []
    for o in flags:
        if not o["role"].startswith("output"):
            continue
        for i in flags:
            if i["command"] == o["command"] and i["role"].startswith("input"):
                out.append((o["command"], o["flag"], o["role"], i["flag"], i["role"]))
    return out


def test_every_command_with_files_has_a_base_command_line() -> None:
    listed = {f["command"] for f in file_flags()}
    assert listed, "aos-render flags --files lists nothing"
    missing = sorted(listed - set(BASE))
    assert not missing, f"add a BASE command line for {missing} to {__file__}"
    assert listed <= set(commands())
    # The roles of known flags, so that a declaration lost in a refactoring fails here.
    roles = {(f["command"], f["flag"]): f["role"] for f in file_flags()}
    for key, role in {("integral", "--mask"): "input", ("integral", "--mask-dir"): "input-folder",
                      ("integral", "--count"): "output", ("map", "--output"): "output",
                      ("stack", "--output-dir"): "output-folder",
                      ("merge", "stack"): "input-folder", ("metrics", "reference"): "input",
                      ("plan", "--dem"): "input", ("plan", "--preview-png"): "output"}.items():
        assert roles.get(key) == role, (key, roles.get(key))


def test_every_output_flag_refuses_every_input_flag(tmp_path: Path) -> None:
    """For every (command, output, input): the output set to the input's file (or to a file in,
    or the folder of, an input folder) with --force exits 1 with one line naming the input
    flag, and the input's bytes are unchanged."""
    cases = pairs()
    assert len(cases) >= 40, len(cases)

    def check(n: int, case: tuple[str, str, str, str, str]) -> str:
        command, output, output_role, input_flag, input_role = case
        work = tmp_path / str(n)
        work.mkdir()
        values = dict(BASE[command])
        for excluded in EXCLUDES.get((command, input_flag), []):
            values.pop(excluded, None)
        if input_role == "input-folder":
            folder = work / "input_dir"
            folder.mkdir()
            victim = folder / "0001.png"
            victim.write_bytes(b"input bytes")
            values[input_flag] = str(folder)
            values[output] = str(folder if output_role == "output-folder" else victim)
        else:
            victim = work / "input.png"
            victim.write_bytes(b"input bytes")
            values[input_flag] = str(victim)
            values[output] = str(victim)
        force = ["--force"] if has_force(command) else []  # folder commands never replace
        result = run(*command_line(command, values), *force, cwd=work)
        lines = result.stderr.strip().splitlines()
        if (result.returncode == 1 and len(lines) == 1 and "refusing" in lines[0]
                and input_flag in lines[0] and victim.read_bytes() == b"input bytes"):
            return ""
        return (f"{command} {output}={input_flag}: rc {result.returncode}, "
                f"{result.stderr.strip()!r}")

    for command in {case[0] for case in cases}:
        has_force(command)  # cached before the threads start
    # Processes in parallel: each is mostly start-up (the check runs before any work).
    with concurrent.futures.ThreadPoolExecutor(max_workers=8) as pool:
        failures = [f for f in pool.map(check, range(len(cases)), cases) if f]
    assert not failures, "\n".join(failures)


def test_two_outputs_naming_one_file_are_refused(tmp_path: Path) -> None:
    result = run("plan", "--csv", "plan.out", "--kml", "./plan.out", cwd=tmp_path)
    assert result.returncode == 1 and len(result.stderr.strip().splitlines()) == 1
    assert "--kml and --csv name the same file" in result.stderr
    assert not (tmp_path / "plan.out").exists()


# ---- --threads is bounded ----

@pytest.mark.parametrize("command", ["integral", "map", "simulate", "metrics"])
def test_threads_above_the_bound_is_a_usage_error(command: str, tmp_path: Path) -> None:
    """--threads 100000 crashed inside libgomp (SIGSEGV); 5000 gave "Thread creation failed".
    The bound is aos's kMaxThreads (1024, parallel.h), the same in Python."""
    values = dict(BASE[command])
    for threads in ("100000", "1025"):
        result = run(*command_line(command, values), "--threads", threads, cwd=tmp_path)
        assert result.returncode == 2, result.stderr
        assert "num_threads: must be in [1, 1024] or -1, got " in result.stderr
        assert "--threads" in result.stderr and len(result.stderr.strip().splitlines()) == 1


def test_python_num_threads_above_the_bound_raises(make_lightfield) -> None:
    light_field = make_lightfield()
    with pytest.raises(ValueError, match=r"num_threads: must be in \[1, 1024\] or -1, got 100000"):
        aos.render_integral(light_field, pose_view=4, num_threads=100000)


# ---- every command stops when asked ----

# Commands that cannot run long, with the reason.
NOT_LONG = {
    "flags": "prints a table compiled into the executable",
    "camera": "writes one small JSON file from its flags; no loop over user-sized work",
    "resolution": "closed-form formulas over the flags; reads no file",
    "export-odm": "reads a light field's poses (no frames) and writes one line per view",
    "check-gcp": "reads a light field's poses (no frames) and a text file (ReadTextFile's size "
                 "bound), one projection per line",
}
# Known failures, xfail until fixed (the reason names the fix).
FIXED_ELSEWHERE: dict[str, str] = {}
CANCEL_XFAIL: dict[str, str] = {}
# Commands not yet covered by a long-running input here, with the reason (a known gap).
NOT_YET: dict[str, str] = {}
# Commands whose long step is one library call that cannot poll, ended by the CLI's backstop
# 1.5 s after the signal (with no output), with the reason.
BETWEEN_POLLS = {
    "calibrate": "OpenCV's chessboard search of one frame is one call (about 1.5 s on a 3 MP "
                 "frame without a board); the poll is between frames",
}


def needs(command: str) -> list:
    """`poses` runs COLMAP: skipped where it is not installed (as test_poses.py is)."""
    if command == "poses":
        return [pytest.mark.skipif(shutil.which("colmap") is None, reason="COLMAP is not installed")]
    return []


def has_child(pid: int, name: str) -> bool:
    """Whether process `pid` has a child whose command is `name` (COLMAP under poses)."""
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)
        except OSError:
            continue
        if fields[0].endswith("(" + name) and int(fields[1].split()[1]) == pid:
            return True
    return False


def random_lightfield(folder: Path, views_per_side: int, size: int) -> Path:
    """Nadir views of random 8-bit noise, 1 m apart at 20 m, written as folder/lf.json."""
    rng = np.random.default_rng(7)
    light_field = aos.LightField()
    camera = aos.PinholeCamera.from_fov(size, size, 60.0)
    offset = 0.5 * (views_per_side - 1)
    for j in range(views_per_side):
        for i in range(views_per_side):
            image = rng.integers(0, 256, (size, size), dtype=np.uint8)
            pose = aos.look_at((i - offset, j - offset, 20.0), (i - offset, j - offset, 0.0),
                               up=(0.0, 1.0, 0.0))
            light_field.add_view(image, camera, pose, name=f"{j * views_per_side + i:04d}")
    folder.mkdir(parents=True, exist_ok=True)
    aos.write_lightfield(str(folder / "lf.json"), light_field)
    return folder / "lf.json"


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("long")
    found = {"lf": random_lightfield(root / "lf", 4, 256)}
    rng = np.random.default_rng(3)
    frames = root / "frames"
    frames.mkdir()
    for k in range(4):
        aos.write_image(str(frames / f"{k:04d}.png"),
                        rng.integers(0, 256, (1500, 2000), dtype=np.uint8))
    found["frames"] = frames
    camera = root / "camera.json"
    assert run("camera", "--width", "2000", "--height", "1500", "--fx", "1500",
               "-o", str(camera)).returncode == 0
    found["camera"] = camera
    stack = root / "stack"
    result = run("stack", str(found["lf"]), "--pose-view", "5", "--width", "1024", "--height",
                 "1024", "--slices", "6", "--first-plane", "0", "--last-plane", "4",
                 "--variance", "-o", str(stack))
    assert result.returncode == 0, result.stderr
    found["stack"] = stack
    # 1.5 million points of a noisy plane (binary PLY), for `ground`.
    points = np.column_stack([rng.uniform(-200, 200, 1_500_000), rng.uniform(-200, 200, 1_500_000),
                              rng.normal(0, 0.2, 1_500_000)]).astype("<f4")
    ply = root / "points.ply"
    ply.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 1500000\n"
                    b"property float x\nproperty float y\nproperty float z\nend_header\n"
                    + points.tobytes())
    found["points"] = ply
    # A COLMAP text model with 2 million points (about 2 s to read), for `import-colmap`.
    model = root / "model"
    model.mkdir()
    (model / "cameras.txt").write_text("1 PINHOLE 2000 1500 1500 1500 1000 750\n")
    (model / "images.txt").write_text("".join(
        f"{k + 1} 1 0 0 0 {k} 0 0 1 {k:04d}.png\n\n" for k in range(4)))
    with open(model / "points3D.txt", "w") as stream:
        for start in range(0, 2_000_000, 100_000):
            stream.write("".join(f"{k + 1} {k % 97} {k % 89} {k % 83} 128 128 128 0.5\n"
                                 for k in range(start, start + 100_000)))
    found["model"] = model
    # 20000 small frames and a CSV log naming each (about 3 s of header reads), for
    # `import-telemetry`.
    flight = root / "flight"
    flight.mkdir()
    aos.write_image(str(flight / "00000.png"), np.zeros((8, 8), np.uint8))
    rows = ["frame,lat,lon,alt,yaw,pitch,roll"]
    for k in range(20_000):
        if k:
            shutil.copyfile(flight / "00000.png", flight / f"{k:05d}.png")
        rows.append(f"{k:05d}.png,{48.3 + 1e-6 * k:.7f},14.3,300,0,-90,0")
    log = root / "log.csv"
    log.write_text("\n".join(rows) + "\n")
    found["flight"] = flight
    found["log"] = log
    # A 3000-frame Motion-JPEG video (5 minutes at 10 fps) and its SRT, every frame taken (about
    # 3 s of decoding and writing frames), for `import-video`.
    aos.write_image(str(root / "f.jpg"), rng.integers(0, 256, (96, 128), dtype=np.uint8))
    write_mjpeg_avi(root / "video.avi", [(root / "f.jpg").read_bytes()] * 3000, 128, 96, 10)
    (root / "flight.srt").write_text("\n".join(
        f"{k + 1}\n00:{k // 600:02d}:{k // 10 % 60:02d},{k % 10 * 100:03d} --> "
        f"00:{(k + 1) // 600:02d}:{(k + 1) // 10 % 60:02d},{(k + 1) % 10 * 100:03d}\n"
        f"[latitude: {48.3 + 1e-5 * k:.7f}] [longitude: 14.3] [rel_alt: 30.0 abs_alt: 400.0] "
        "[gb_yaw: 0.0 gb_pitch: -90.0 gb_roll: 0.0]\n" for k in range(3000)))
    found["video"] = root / "video.avi"
    found["srt"] = root / "flight.srt"
    scene = root / "scene.json"
    scene.write_text(json.dumps({
        "camera": {"width": 1024, "height": 1024, "fov_deg": 50},
        "sampling": {"altitude": 35, "grid": 8, "aperture": {"diameter": 14}},
    }))
    found["scene"] = scene
    return found


def long_command(command: str, found: dict[str, Path], out: Path) -> tuple[list[str], Path | None]:
    """A command line that runs for seconds, and the output it would write."""
    lf = str(found["lf"])
    camera = ["--pose-view", "5"]
    table: dict[str, tuple[list[str], Path | None]] = {
        "integral": ([lf, *camera, "--width", "2048", "--height", "2048", "--aperture-radius",
                      "inf", "--focal-height", "0", "-o", str(out / "out.tif")], out / "out.tif"),
        "detect": ([lf, *camera, "--width", "2048", "--height", "2048", "--aperture-radius",
                    "inf", "--focal-height", "0", "--geojson", str(out / "found.geojson")],
                   out / "found.geojson"),
        # live rewrites its outputs after every update (complete at any signal): they are
        # written beside `out`, which must stay as it was.
        "live": (["--replay", lf, "--width", "2048", "--height", "2048", "--focal-height", "0",
                  "--geojson", str(out.parent / "live.geojson")], None),
        "stack": ([lf, *camera, "--width", "512", "--height", "512", "--slices", "400",
                   "--first-plane", "0", "--last-plane", "5", "-o", str(out / "d")], out / "d"),
        "allinfocus": ([lf, *camera, "--width", "512", "--height", "512", "--slices", "400",
                        "--first-plane", "0", "--last-plane", "5", "-o", str(out / "d")],
                       out / "d"),
        "merge": ([str(found["stack"]), "--method", "robust", "--lightfield", lf,
                   "--smoothing-iterations", "20", "-o", str(out / "d")], out / "d"),
        "map": ([lf, "--width", "6000", "--focal-height", "0", "-o", str(out / "map.tif")],
                out / "map.tif"),
        "view": ([lf, *camera, "--no-browser", "-q"], None),
        "calibrate": ([*sorted(str(p) for p in found["frames"].iterdir()), "-o",
                       str(out / "cam.json")], out / "cam.json"),
        "rectify": ([*sorted(str(p) for p in found["frames"].iterdir()), "--camera",
                     str(found["camera"]), "--width", "8000", "--height", "6000", "--fill", "-o",
                     str(out / "d")], out / "d"),
        "poses": ([str(found["frames"]), "-o", str(out / "lf.json")], out / "lf.json"),
        "import-colmap": ([str(found["model"]), "--images-dir", str(found["frames"]), "-o",
                           str(out / "lf.json")], out / "lf.json"),
        "import-telemetry": ([str(found["flight"]), "--telemetry-file", str(found["log"]),
                              "--frames-fov-deg", "50", "-o", str(out / "lf.json")],
                             out / "lf.json"),
        "import-video": ([str(found["video"]), "--srt", str(found["srt"]), "--frame-every-s",
                          "0.1", "--frames-fov-deg", "50", "-o", str(out / "d")], out / "d"),
        "ground": ([lf, "--points", str(found["points"]), "--cell-size-m", "0.25", "-o",
                    str(out / "dem.tif")], out / "dem.tif"),
        "simulate": ([str(found["scene"]), "-o", str(out / "d")], out / "d"),
        "demo": (["-o", str(out / "d")], out / "d"),
        "metrics": ([lf, lf], None),  # replaced below: two large images
        # About 7 M waypoints (a few seconds): the default --max-waypoints (10^6) is raised.
        "plan": (["--radius-m", "3000", "--spacing-m", "2", "--along-spacing-m", "2",
                  "--battery-min", "inf", "--max-waypoints", "100000000",
                  "--csv", str(out / "p.csv")],
                 out / "p.csv"),
    }
    if command == "metrics":
        big = np.random.default_rng(1).random((3000, 3000), dtype=np.float32)
        for name in ("a.tif", "b.tif"):
            aos.write_image(str(out / name), big)
        return [str(out / "a.tif"), str(out / "b.tif")], None
    return table[command]


def running_python(pid: int) -> bool:
    try:
        return b"aos.viewer" in Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return False


def cpu_seconds(pid: int) -> float:
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def test_every_command_is_in_the_cancellation_table() -> None:
    known = set(NOT_LONG) | set(NOT_YET) | {
        "integral", "detect", "live", "stack", "allinfocus", "merge", "map", "view", "calibrate",
        "rectify",
        "import-colmap", "import-telemetry", "import-video", "poses", "ground", "simulate", "demo",
        "metrics", "plan"}
    missing = sorted(set(commands()) - known)
    assert not missing, f"add a long-running command line for {missing} to long_command()"


def cancellable() -> list:
    cases = []
    for command in commands():
        if command in NOT_LONG or command in NOT_YET:
            continue
        for sig in (signal.SIGTERM, signal.SIGINT):
            marks = ([pytest.mark.xfail(reason=CANCEL_XFAIL[command], strict=False)]
                     if command in CANCEL_XFAIL else []) + needs(command)
            cases.append(pytest.param(command, sig, id=f"{command}-{sig.name}", marks=marks))
    return cases


@pytest.mark.parametrize("command,sig", cancellable())
def test_command_stops_within_2_s_of_a_signal(command: str, sig: signal.Signals,
                                              inputs: dict[str, Path], tmp_path: Path) -> None:
    """Started on an input that runs for seconds, signalled once it is working (its handler
    installed and 0.3 s of CPU used since): it exits within 2 s with 128 + the signal (143 SIGTERM,
    130 SIGINT), and leaves no output (nor a temporary file) behind."""
    out = tmp_path / "out"
    out.mkdir()
    args, output = long_command(command, inputs, out)
    before = set(out.iterdir())
    env = dict(os.environ, AOS_PYTHON=os.environ.get("AOS_PYTHON", shutil.which("python3") or ""))
    process = subprocess.Popen([EXE, command, *args], stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE, text=True, env=env,
                               # A process started in the background inherits SIGINT ignored.
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        # Working: its handler installed (or, for view, the Python viewer running), then 0.3 s
        # of CPU more (1.5 s of waiting for poses, whose work is COLMAP's).
        deadline = time.monotonic() + 60
        ready = (lambda: running_python(process.pid)) if command == "view" else (
            lambda: catches(process.pid, sig))
        while process.poll() is None and not ready():
            assert time.monotonic() < deadline, "the command did not start in 60 s"
            time.sleep(0.02)
        start_cpu = cpu_seconds(process.pid)
        if command == "poses":  # the work is COLMAP's (a child process): wait until it runs
            while process.poll() is None and not has_child(process.pid, "colmap"):
                assert time.monotonic() < deadline, "COLMAP did not start in 60 s"
                time.sleep(0.02)
            time.sleep(0.3)
            start_cpu = -1.0
        while process.poll() is None and cpu_seconds(process.pid) < start_cpu + 0.3:
            assert time.monotonic() < deadline, "the command did not start working in 60 s"
            time.sleep(0.02)
        assert process.poll() is None, (
            f"{command} ended (rc {process.returncode}) before the signal: make its input "
            f"larger; {process.stderr.read()[-500:]}")
        process.send_signal(sig)
        sent = time.monotonic()
        try:
            process.wait(timeout=2.0)
        except subprocess.TimeoutExpired:
            pytest.fail(f"{command} still running 2 s after {sig.name}")
        elapsed = time.monotonic() - sent
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    stderr = process.stderr.read()
    # view: the Python viewer stops cleanly once serving (exit 0, docs/viewer.md), 128 + the
    # signal while it loads.
    # Before it serves, the signal's default action ends it (-sig: the shell shows 128 + sig).
    expected = {0, 128 + sig, 130, -sig} if command == "view" else {128 + sig}
    assert process.returncode in expected, (process.returncode, elapsed, stderr[-500:])
    # Stopped at one of its own polls, not by the CLI's 1.5 s backstop (progress_bar.cpp).
    if command not in BETWEEN_POLLS:
        assert "between polls" not in stderr, (command, elapsed, stderr[-500:])
    if output is not None:
        assert not output.exists(), f"{output} left behind"
    assert set(out.iterdir()) == before, f"left behind: {set(out.iterdir()) - before}"


# ---- memory: one clear error, never a kill or std::bad_alloc ----

ADDRESS_SPACE = 4 << 30  # RLIMIT_AS for the memory tests: 4 GiB


def zero_png(path: Path, width: int, height: int) -> None:
    """A valid 8-bit grey PNG of zeros, written in about a second whatever its size: each row is
    one deflate block after a full flush (so every block's bytes are equal), and the zlib
    checksum of n zero bytes is (n mod 65521) << 16 | 1."""
    raw = zlib.compressobj(9, zlib.DEFLATED, -15)
    block = raw.compress(b"\0" * (width + 1)) + raw.flush(zlib.Z_FULL_FLUSH)
    samples = height * (width + 1)
    data = (b"\x78\xda" + block * height + raw.flush(zlib.Z_FINISH)
            + struct.pack(">I", ((samples % 65521) << 16) | 1))

    def chunk(kind: bytes, body: bytes) -> bytes:
        return (struct.pack(">I", len(body)) + kind + body
                + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF))

    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", data)
                     + chunk(b"IEND", b""))


@pytest.fixture(scope="module")
def big(tmp_path_factory, inputs: dict[str, Path]) -> dict[str, Path]:
    """Valid inputs whose decoded size is beyond ADDRESS_SPACE: three 46000 x 46000 frames (2.1 GB
    decoded each, 2 MB on disk), a light field of them, a stack.json of 4000 slices."""
    root = tmp_path_factory.mktemp("big")
    frames = root / "frames"
    frames.mkdir()
    zero_png(frames / "0000.png", 46000, 46000)
    for k in (1, 2):
        os.link(frames / "0000.png", frames / f"{k:04d}.png")
    log = root / "log.csv"
    log.write_text("frame,lat,lon,alt,yaw,pitch,roll\n" + "".join(
        f"{k:04d}.png,48.3,{14.3 + 1e-5 * k:.5f},300,0,-90,0\n" for k in range(3)))
    assert run("import-telemetry", str(frames), "--telemetry-file", str(log), "--frames-fov-deg",
               "50", "-o", str(root / "lf.json"), "-q").returncode == 0
    # The test stack's slice 0 named 4000 times (absolute paths).
    stack = json.loads((inputs["stack"] / "stack.json").read_text())
    first = {key: (str(inputs["stack"] / value) if key in ("image", "count", "variance")
                   else value) for key, value in stack["slices"][0].items()}
    stack["slices"] = [first] * 4000
    (root / "stack").mkdir()
    (root / "stack" / "stack.json").write_text(json.dumps(stack))
    return {"frames": frames, "lf": root / "lf.json", "stack": root / "stack",
            "frame": frames / "0000.png"}


def sparse_file(path: Path, header: bytes, size: int) -> Path:
    """`header`, then zeros up to `size` bytes (a sparse file: no disk used)."""
    path.write_bytes(header)
    os.truncate(path, size)
    return path


def oversized(command: str, found: dict[str, Path], large: dict[str, Path],
              out: Path) -> list[str] | None:
    """A command line whose input-sized allocation is far beyond ADDRESS_SPACE."""
    lf = str(found["lf"])
    frames = sorted(str(p) for p in large["frames"].iterdir())
    table = {
        "integral": [lf, "--pose-view", "5", "--width", "40000", "--height", "40000", "-o",
                     str(out / "out.tif")],
        "detect": [lf, "--pose-view", "5", "--width", "40000", "--height", "40000", "--geojson",
                   str(out / "found.geojson")],
        "live": ["--replay", lf, "--width", "40000", "--height", "40000", "--geojson",
                 str(out / "found.geojson")],
        "stack": [lf, "--pose-view", "5", "--width", "8192", "--height", "8192", "--slices",
                  "400", "-o", str(out / "d")],
        "allinfocus": [lf, "--pose-view", "5", "--width", "20000", "--height", "20000",
                       "--slices", "8", "-o", str(out / "d")],
        "map": [lf, "--width", "200000", "--focal-height", "0", "-o", str(out / "map.tif")],
        "rectify": [*sorted(str(p) for p in found["frames"].iterdir()), "--camera",
                    str(found["camera"]), "--width", "60000", "--height", "60000", "-o",
                    str(out / "d")],
        # 4000 slices of 1024^2 in memory (slice 0 read, the rest refused from stack.json).
        "merge": [str(large["stack"]), "-o", str(out / "d")],
        "metrics": [str(large["frame"]), str(large["frame"])],
        "calibrate": [*frames, "-o", str(out / "cam.json")],
        # COLMAP would decode a 46000^2 frame per extraction thread (aos checks first).
        "poses": [str(large["frames"]), "-o", str(out / "lf.json")],
        # The viewer loads the light field's three 2.1 GB frames.
        "view": [str(large["lf"]), "--no-browser"],
        # 113 million waypoints (the waypoint bound raised): 9 GiB.
        "plan": ["--radius-m", "3000", "--spacing-m", "0.5", "--along-spacing-m", "0.5",
                 "--battery-min", "inf", "--max-waypoints", "1000000000", "--csv",
                 str(out / "p.csv")],
        # Sizes from headers against the file's size, before anything is allocated:
        # 10^12 points in a 20 GB (sparse) points3D.bin; a 20 GB telemetry log; a 30 GB PLY.
        "import-colmap": [str(found["model"]), "--images-dir", str(found["frames"]), "-o",
                          str(out / "lf.json")],
        "import-telemetry": [str(found["frames"]), "--telemetry-file",
                             str(sparse_file(out / "log.csv", b"frame,lat,lon,alt,yaw,pitch,"
                                             b"roll\n", 20 << 30)),
                             "--frames-fov-deg", "50", "-o", str(out / "lf.json")],
        # A 20 GB (sparse) SRT: refused by its size before it is read.
        "import-video": [str(found["video"]), "--srt",
                         str(sparse_file(out / "flight.srt", b"1\n", 20 << 30)),
                         "--frames-fov-deg", "50", "-o", str(out / "d")],
        "ground": [lf, "--points", str(sparse_file(
            out / "points.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex "
            b"2000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
            30 << 30)), "-o", str(out / "dem.tif")],
    }
    if command == "import-colmap":
        model = out / "model"
        model.mkdir()
        (model / "cameras.bin").write_bytes(struct.pack("<QIiQQ4d", 1, 1, 1, 2000, 1500, 1500.0,
                                                        1500.0, 1000.0, 750.0))
        (model / "images.bin").write_bytes(struct.pack("<Q", 0))
        sparse_file(model / "points3D.bin", struct.pack("<Q", 10**12), 20 << 30)
        table[command][0] = str(model)
    if command in ("simulate", "demo"):
        scene = out / "huge.json"
        scene.write_text(json.dumps({"camera": {"width": 60000, "height": 60000, "fov_deg": 50},
                                     "sampling": {"altitude": 35, "grid": 2}}))
        return ([str(scene), "-o", str(out / "d")] if command == "simulate"
                else ["--scene", str(scene), "-o", str(out / "d")])
    return table.get(command)


# Commands without an oversized case here yet, with the reason.
MEMORY_NOT_YET: dict[str, str] = {}
# Inputs the test itself writes (the rest of tmp_path must stay empty).
WRITTEN_HERE = {"huge.json", "log.csv", "points.ply", "model", "flight.srt"}


def memory_cases() -> list:
    cases = []
    for command in commands():
        if command in NOT_LONG:
            continue
        if command in MEMORY_NOT_YET:
            continue
        marks = ([pytest.mark.xfail(reason=FIXED_ELSEWHERE[command], strict=False)]
                 if command in FIXED_ELSEWHERE else []) + needs(command)
        cases.append(pytest.param(command, id=command, marks=marks))
    return cases


@pytest.mark.parametrize("command", memory_cases())
def test_oversized_input_under_an_address_space_limit_is_one_clear_error(
        command: str, inputs: dict[str, Path], big: dict[str, Path], tmp_path: Path) -> None:
    """Under RLIMIT_AS (the budget honours it, memory.h) an input-sized allocation beyond it is
    refused up front with one line naming the flag or file and the memory needed (or the stated
    bound that refuses the size first), exit 1 or 2; never a kill or std::bad_alloc."""
    args = oversized(command, inputs, big, tmp_path)
    assert args is not None, f"add an oversized command line for {command} to oversized()"

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))

    result = subprocess.run([EXE, command, *args, "-q"], capture_output=True, text=True, timeout=120,
                            preexec_fn=limit)
    lines = [line for line in result.stderr.strip().splitlines()
             if not line.startswith("aos-render: warning")]
    assert result.returncode in (1, 2), (result.returncode, result.stderr[-800:])
    assert len(lines) == 1 and "bad_alloc" not in result.stderr, result.stderr[-800:]
    # The memory budget's refusal, or a stated bound refusing the size first (both name it).
    assert re.search(r"memory|at most|must be|outside|more than|larger than|cannot fit",
                     lines[0]), lines[0]
    # It names what it refuses: one of the command line's files or folders, or a flag (the
    # CLI's "[option --width]"); field names such as "width/height:" alone do not count.
    message = re.sub(r"^aos-render( view)?: error: ", "", lines[0])
    named = [arg for arg in args if "/" in arg and Path(arg).name in message]
    assert named or re.search(r"--[a-z]", message), lines[0]
    assert not any(p.name not in WRITTEN_HERE for p in tmp_path.iterdir()), list(tmp_path.iterdir())


def test_every_command_is_in_the_memory_table() -> None:
    listed = set(NOT_LONG) | set(MEMORY_NOT_YET) | {c.values[0] for c in memory_cases()}
    assert set(commands()) <= listed
