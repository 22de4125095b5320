"""Flight planning (aos.plan_flight, aos-render plan): the paper's two apertures, the exports read
back to the same coordinates, CLI and Python agreeing, and bad input writing nothing."""
from __future__ import annotations

import json
import math
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import numpy as np
import pytest

import aos
from signal_util import wait_until_it_catches

EXE = shutil.which("aos-render")
needs_cli = pytest.mark.skipif(EXE is None, reason="aos-render is not on PATH")
F0_DEM = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "jku-f0" / "dem" / "dem_lr.obj"

EXPERIMENT_1 = dict(shape="circle", radius_m=15.0, spacing_m=3.0, along_spacing_m=1.0, altitude_m=20.0)
EXPERIMENT_2 = dict(shape="sector", radius_m=50.0, sector_angle_deg=90.0, spacing_m=1.0,
                    along_spacing_m=2.0, outer_scale=2.0, heading_deg=45.0, altitude_m=35.0,
                    battery_min=40.0)


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([EXE, *args], capture_output=True, text=True, timeout=120)


def test_paper_experiment_1():
    plan = aos.plan_flight(**EXPERIMENT_1)
    assert plan.images == 231
    # 1 m at 1 m/s + 1 s a shot: 30 frames a minute along the lines, a little less with the turns.
    assert 28.0 < plan.frames_per_minute <= 30.0
    assert plan.flight_time_s == pytest.approx(plan.length_m / 1.0 + 231 * 1.0)


def test_paper_experiment_2():
    plan = aos.plan_flight(**EXPERIMENT_2)
    assert abs(plan.images - 505) <= 0.02 * 505
    assert 12.0 < plan.frames_per_minute < 20.0
    assert plan.eq2_samples_per_m2 == pytest.approx(1014.7, abs=0.1)  # Appendix A's camera at 35 m
    # Without the larger budget, the 34-minute flight is refused naming the field.
    with pytest.raises(ValueError, match="battery_min: the plan takes"):
        aos.plan_flight(**{**EXPERIMENT_2, "battery_min": 25.0})


def test_exports_read_back(tmp_path: Path):
    plan = aos.plan_flight(**EXPERIMENT_1, coordinates="latlon", center=(48.3356, 14.3262),
                           csv=tmp_path / "p.csv", geojson=tmp_path / "p.geojson",
                           kml=tmp_path / "p.kml", png=tmp_path / "p.png")
    lonlat = np.array([(w.longitude_deg, w.latitude_deg) for w in plan.waypoints])
    geojson = json.loads((tmp_path / "p.geojson").read_text())
    points = np.array([f["geometry"]["coordinates"][:2] for f in geojson["features"][1:]])
    np.testing.assert_array_equal(points, lonlat)
    path = np.array(geojson["features"][0]["geometry"]["coordinates"])[:, :2]
    np.testing.assert_array_equal(path, lonlat)
    kml = ElementTree.parse(tmp_path / "p.kml")
    ns = {"k": "http://www.opengis.net/kml/2.2"}
    coords = [c.text.split(",") for c in kml.findall(".//k:Point/k:coordinates", ns)]
    np.testing.assert_allclose(np.array(coords, dtype=float)[:, :2], lonlat, atol=1e-10, rtol=0)
    rows = (tmp_path / "p.csv").read_text().splitlines()
    assert len(rows) == 232
    np.testing.assert_allclose([float(v) for v in rows[1].split(",")[1:3]],
                               [lonlat[0, 1], lonlat[0, 0]], atol=1e-10, rtol=0)
    image = aos.read_image(str(tmp_path / "p.png"))
    assert image.shape == (800, 800, 3)
    # The shots lie within the 15 m circle around the centre (in metres, through UTM 33N).
    for w in plan.waypoints:
        assert math.hypot(w.x - plan.growth_center[0], w.y - plan.growth_center[1]) <= 15.0 + 1e-6


def test_bad_input_writes_nothing(tmp_path: Path):
    outputs = dict(csv=tmp_path / "a.csv", png=tmp_path / "a.png")
    cases = [
        (dict(shape="polygon", vertices=[(0, 0), (10, 10), (10, 0), (0, 10)]), "vertices: the polygon intersects itself"),
        (dict(shape="polygon", vertices=[(0, 0), (10, 10)]), "vertices: a polygon needs at least 3"),
        (dict(spacing_m=0.0), "spacing_m"),
        (dict(spacing_m=-2.0), "spacing_m"),
        (dict(shape="sector", sector_angle_deg=361.0), "sector_angle_deg"),
        (dict(radius_m=200.0, spacing_m=1.0), "battery_min: the plan takes"),
        (dict(crs="EPSG:32633", center=(48.3, 14.3)), "look like degrees"),
    ]
    for options, message in cases:
        with pytest.raises(ValueError, match=re.escape(message)):
            aos.plan_flight(**options, **outputs)
        assert list(tmp_path.iterdir()) == []
    with pytest.raises(TypeError):
        aos.plan_flight(spacing=3.0)  # not a field


@needs_cli
def test_cli_twin(tmp_path: Path):
    out = run("plan", "--radius-m", "15", "--spacing-m", "3", "--along-spacing-m", "1",
              "--json", "--csv", str(tmp_path / "p.csv"))
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout)
    plan = aos.plan_flight(**EXPERIMENT_1)
    assert report["images"] == 231
    assert report["length_m"] == pytest.approx(plan.length_m, rel=1e-12)
    assert (tmp_path / "p.csv").read_text() == aos.flight_plan_csv(plan)
    # Bad input: one line naming the flag, exit code 2, nothing written.
    bad = run("plan", "--spacing-m", "0", "--csv", str(tmp_path / "q.csv"))
    assert bad.returncode == 2
    assert "spacing_m" in bad.stderr and "--spacing-m" in bad.stderr
    over = run("plan", "--radius-m", "200", "--spacing-m", "1", "--csv", str(tmp_path / "q.csv"))
    assert over.returncode != 0 and "battery_min" in over.stderr
    # GeoJSON of a local frame: refused before anything is written.
    local = run("plan", "--geojson", str(tmp_path / "q.geojson"), "--csv", str(tmp_path / "q.csv"))
    assert local.returncode != 0 and "geojson" in local.stderr
    assert not (tmp_path / "q.csv").exists() and not (tmp_path / "q.geojson").exists()
    # An existing output is refused without --force.
    again = run("plan", "--csv", str(tmp_path / "p.csv"))
    assert again.returncode != 0 and "--force" in again.stderr


@pytest.mark.skipif(not F0_DEM.exists(), reason="F0's DEM is not in ../shared/data")
def test_follows_f0_dem():
    # F0's frame has z down: terrain-following keeps every shot 20 m above (at smaller z than)
    # the terrain under it.
    plan = aos.plan_flight(**EXPERIMENT_1, dem=str(F0_DEM), terrain_up="-z")
    assert plan.images == 231
    for w in plan.waypoints:
        assert w.z == pytest.approx(w.ground_z - 20.0)
    assert max(w.ground_z for w in plan.waypoints) - min(w.ground_z for w in plan.waypoints) > 1.0


# A small forest (64 x 64 views, a 48 x 48 truth) for the preview.
SMALL_FOREST = {
    "seed": 3,
    "ground": {"texture": {"type": "noise", "square": 0.5}},
    "targets": [{"center": [0.0, 0.0], "size": [1.8, 0.6]}],
    "occluders": {"trees": {"area": [-25, -25, 25, 25], "per_hectare": 300, "height": [8, 12],
                            "crown_radius": [1.5, 2.5], "leaves_per_tree": 300}},
    "camera": {"width": 64, "height": 64, "fov_deg": 50},
    "truth": {"width": 48, "height": 48, "fov_deg": 20},
}


def test_preview_on_a_small_forest():
    plan = aos.plan_flight(radius_m=6.0, spacing_m=2.0, along_spacing_m=2.0)
    preview = aos.preview_flight_plan(plan, SMALL_FOREST)
    assert preview.views == plan.images
    assert 0.0 < preview.visible_fraction < 1.0
    assert preview.integral.shape[:2] == (48, 48)
    # The integral sees through the canopy better than one photo does.
    assert preview.psnr_db > preview.single_view_psnr_db
    # A wider aperture (the same spacing) reveals more of the ground: the occluders blur over
    # more views (the visible fraction is a property of the forest, not of the plan's size).
    wide = aos.preview_flight_plan(aos.plan_flight(radius_m=12.0, spacing_m=3.0, along_spacing_m=3.0),
                                   SMALL_FOREST)
    assert wide.psnr_db > preview.psnr_db


@needs_cli
def test_cli_preview(tmp_path: Path):
    scene = tmp_path / "forest.json"
    scene.write_text(json.dumps(SMALL_FOREST))
    out = run("plan", "--radius-m", "6", "--spacing-m", "2", "--along-spacing-m", "2", "--json",
              "--simulate", str(scene), "--preview-png", str(tmp_path / "preview.png"))
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout)
    python = aos.preview_flight_plan(aos.plan_flight(radius_m=6.0, spacing_m=2.0, along_spacing_m=2.0),
                                     SMALL_FOREST)
    assert report["preview"]["psnr_db"] == pytest.approx(python.psnr_db, rel=1e-9)
    assert (tmp_path / "preview.png").exists()


def test_study_tool_picks_the_cheapest_plan_reaching_the_target(tmp_path: Path):
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "plan_study", Path(__file__).resolve().parents[2] / "tools" / "plan_study.py")
    study = importlib.util.module_from_spec(spec)
    sys.modules["plan_study"] = study  # dataclasses look their module up
    spec.loader.exec_module(study)
    rows = study.run([8.0, 16.0], [4.0], [20.0], per_hectare=300)
    assert [r.images for r in rows] == [aos.plan_flight(radius_m=d / 2, spacing_m=4.0, along_spacing_m=4.0,
                                                        min_shots_per_line=1).images for d in (8.0, 16.0)]
    best = study.cheapest(rows, min(r.psnr_db for r in rows))
    assert best is min(rows, key=lambda r: r.flight_min)
    assert study.cheapest(rows, 1000.0) is None
    ElementTree.fromstring(study.svg(rows, best, 18.0, "test"))  # well-formed SVG


# The cases (issue 31): each was minutes of work, 16 GB and a 6.6 GB CSV, or
# std::bad_alloc / MemoryError; now each is refused from the count, before a waypoint is stored.
LARGE_PLANS = [
    (dict(radius_m=3000.0, spacing_m=0.5, along_spacing_m=0.5, battery_min=math.inf),
     "max_waypoints: the plan has more than 1,000,000 waypoints (about 113,097,336"),
    (dict(radius_m=1e7), "max_waypoints:"),
    (dict(radius_m=5000.0), "max_waypoints:"),
    (dict(radius_m=1e5), "max_waypoints:"),
    (dict(spacing_m=1e-9), "(spacing_m 1e-09 m x along_spacing_m 1 m); radius_m 15; 30,000,00"),
    (dict(along_spacing_m=1e-9), "max_waypoints:"),
    (dict(radius_m=math.inf), "radius_m: must be a finite number > 0"),
    (dict(radius_m=math.nan), "radius_m: must be a finite number > 0"),
]


def test_large_plans_are_refused_quickly(tmp_path: Path):
    for options, message in LARGE_PLANS:
        start = time.process_time()  # CPU time: the machine running the tests may be loaded
        with pytest.raises(ValueError, match=re.escape(message)):
            aos.plan_flight(**options, csv=tmp_path / "big.csv")
        # Milliseconds each (the count stops at 10^6 shots, or knows the lines are too many).
        assert time.process_time() - start < 1.0, options
        assert list(tmp_path.iterdir()) == []
    assert aos.FlightPlanOptions().max_waypoints == 1_000_000
    assert aos.plan_flight(**EXPERIMENT_1, max_waypoints=231).images == 231
    with pytest.raises(ValueError, match="max_waypoints: the plan has more than 230 waypoints"):
        aos.plan_flight(**EXPERIMENT_1, max_waypoints=230)


@needs_cli
def test_cli_refuses_large_plans_quickly(tmp_path: Path):
    # (Python's test above has the rest of the cases; each run here loads the program.)
    flags = [
        ["--radius-m", "3000", "--spacing-m", "0.5", "--along-spacing-m", "0.5", "--battery-min", "inf"],
        ["--radius-m", "1e7", "--battery-min", "inf"],
        ["--spacing-m", "1e-9"],
        ["--radius-m", "nan"],
    ]
    def cpu_of_children() -> float:
        usage = resource.getrusage(resource.RUSAGE_CHILDREN)
        return usage.ru_utime + usage.ru_stime

    start = cpu_of_children()
    run("--version")
    startup = cpu_of_children() - start  # loading the program: about 0.5 s of CPU
    errors = []
    for args in flags:
        start = cpu_of_children()
        out = run("plan", *args, "--csv", str(tmp_path / "big.csv"))
        cpu = cpu_of_children() - start  # CPU time: wall time on a loaded machine says little
        assert out.returncode in (1, 2), (args, out.stderr)
        assert len(out.stderr.strip().splitlines()) == 1, out.stderr  # one line
        assert "bad_alloc" not in out.stderr
        assert cpu < startup + 1.0, (args, cpu, startup)
        assert not (tmp_path / "big.csv").exists()
        errors.append(out.stderr)
    assert "113,097,336" in errors[0] and "[option --max-waypoints]" in errors[0]
    assert "radius_m" in errors[3] and "--radius-m" in errors[3]
    # The bound is a flag bound to the field.
    assert run("plan", *"--radius-m 15 --spacing-m 3 --along-spacing-m 1 --max-waypoints 231".split()).returncode == 0
    assert run("plan", *"--radius-m 15 --spacing-m 3 --along-spacing-m 1 --max-waypoints 230".split()).returncode != 0


def slow_polygon(vertices: int = 2000, radius: float = 300.0) -> list[tuple[float, float]]:
    """A circle as a polygon of many corners: every inside test visits each edge, so a plan of
    ~280,000 shots takes many seconds while its memory stays small (~50 MB)."""
    return [(radius * math.cos(2 * math.pi * k / vertices), radius * math.sin(2 * math.pi * k / vertices))
            for k in range(vertices)]


@needs_cli
@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads /proc/PID/status")
def test_cli_stops_on_sigterm_and_writes_nothing(tmp_path: Path):
    vertices = ";".join(f"{x:.6f},{y:.6f}" for x, y in slow_polygon())
    csv = tmp_path / "big.csv"
    process = subprocess.Popen(
        [EXE, "plan", "--shape", "polygon", "--vertices", vertices, "--spacing-m", "1",
         "--along-spacing-m", "1", "--battery-min", "inf", "--max-waypoints", "2000000",
         "--csv", str(csv)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # Once the program catches SIGTERM (its handler is installed before the command runs; on a
    # loaded machine loading it takes seconds), let it plan for 0.5 s.
    wait_until_it_catches(process.pid)
    time.sleep(0.5)
    assert process.poll() is None, "the plan finished before the signal: make it larger"
    process.send_signal(signal.SIGTERM)
    signalled = time.monotonic()
    try:
        _, stderr = process.communicate(timeout=10)
    finally:
        process.kill()
    assert time.monotonic() - signalled < 2.0
    assert process.returncode == 143  # 128 + SIGTERM
    assert "interrupted" in stderr
    assert list(tmp_path.iterdir()) == []


def test_python_stops_on_ctrl_c_and_writes_nothing(tmp_path: Path):
    script = (
        "import sys, aos, json\n"
        "vertices = json.loads(sys.argv[1])\n"
        "print('ready', flush=True)\n"
        "try:\n"
        "    aos.plan_flight(shape='polygon', vertices=vertices, spacing_m=1.0, along_spacing_m=1.0,\n"
        "                    battery_min=float('inf'), csv=sys.argv[2])\n"
        "except KeyboardInterrupt:\n"
        "    print('interrupted', flush=True)\n"
        "    sys.exit(3)\n"
    )
    env = dict(os.environ)
    # A test run started in the background (nohup ... &) passes SIGINT on as ignored, and Python
    # then installs no KeyboardInterrupt handler: restore the default in the child.
    process = subprocess.Popen([sys.executable, "-c", script, json.dumps(slow_polygon()),
                                str(tmp_path / "big.csv")],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        assert process.stdout.readline().strip() == "ready"
        time.sleep(0.5)
        assert process.poll() is None
        process.send_signal(signal.SIGINT)
        signalled = time.monotonic()
        stdout, stderr = process.communicate(timeout=10)
    finally:
        process.kill()
    assert time.monotonic() - signalled < 2.0
    assert process.returncode == 3, stderr
    assert "interrupted" in stdout
    assert list(tmp_path.iterdir()) == []
