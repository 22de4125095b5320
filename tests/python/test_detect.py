"""Detection (aos.detect, aos-render detect): RX against an independent implementation (Spectral
Python), and the hidden person of a simulated forest found on the integral image, at its true
position, with CRS-correct WGS84 coordinates in GeoJSON, KML and CSV."""

from __future__ import annotations

import csv
import json
import math
import pickle
import subprocess
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import numpy as np
import pytest

import aos

ROOT = Path(__file__).resolve().parents[2]
UTM_ORIGIN = (500000.0, 5300000.0, 300.0)  # UTM 33N, on its central meridian


def test_rx_equals_spectral_python_on_random_data() -> None:
    """Classical RX (no trimming, no ridge) is spectral.rx: the squared Mahalanobis distance to
    the image's mean and covariance. Spectral's covariance divides by N - 1, aos's by N, so aos's
    scores are spectral's times N / (N - 1); float32 features leave 1e-5 relative."""
    spectral = pytest.importorskip("spectral")
    rng = np.random.default_rng(3)
    mixing = np.array([[1.0, 0.3, 0.0], [0.5, 2.0, 0.1], [-0.4, 0.2, 0.7]])
    image = (rng.normal(size=(48, 64, 3)) @ mixing.T + [50.0, 80.0, 20.0]).astype(np.float32)
    ours = aos.anomaly_scores(image, options=aos.DetectOptions(detector="rx", trim_fraction=0.0,
                                                               regularization=0.0))
    theirs = spectral.rx(image.astype(np.float64))
    n = 48 * 64
    np.testing.assert_allclose(ours, theirs * n / (n - 1), rtol=1e-5, atol=1e-6)


def test_a_constant_image_gives_no_detection_and_no_nan() -> None:
    image = np.full((24, 32, 3), 77.0, np.float32)
    for detector in ("rx", "rx-local"):
        scores = aos.anomaly_scores(image, options=aos.DetectOptions(detector=detector))
        assert np.all(scores == 0.0)
    with pytest.raises(ValueError, match="channels: 'hsv' needs 3 channels"):
        aos.anomaly_scores(np.zeros((8, 8), np.float32), options=aos.DetectOptions(channels="hsv"))
    with pytest.raises(ValueError, match="no pixel with a view"):
        aos.anomaly_scores(np.full((8, 8), np.nan, np.float32))
    with pytest.raises(ValueError, match="quantile"):
        aos.DetectOptions(quantile=1.5).check()


def test_the_hidden_person_is_found_on_the_integral_not_in_the_single_view(
        forest: aos.LightField) -> None:
    """The target's centre is the world origin (local (0, 0, 0)). On the integral image focused
    on the ground, the top detection lies within 0.3 m of it, and every view saw it; in the
    centre view alone the canopy hides it and nothing is found."""
    centre = len(forest) // 2
    for detector in ("rx", "rx-local", "anomaly-imaging"):
        found = aos.detect(forest, pose_view=centre, focal_surface=0.0, detector=detector)
        assert len(found) >= 1
        best = found.detections[0]
        assert math.hypot(best.local[0], best.local[1]) < 0.3, best
        assert best.local[2] == pytest.approx(0.0, abs=1e-6)
        assert len(best.views) == len(forest)
        # 0.6 x 1.8 m at about 0.27 m per pixel: roughly 15 pixels.
        assert 5 <= best.area_px <= 40
    alone = aos.detect(forest, pose_view=centre, focal_surface=0.0, view_indices=[centre])
    assert all(math.hypot(d.local[0], d.local[1]) > 1.0 for d in alone.detections)
    with pytest.raises(ValueError, match="anomaly-imaging's scores are means"):
        aos.detect(forest, pose_view=centre, focal_surface=0.0, detector="anomaly-imaging",
                   false_alarm_rate=1e-4)


def test_detections_carry_crs_correct_wgs84_and_pickle(forest: aos.LightField,
                                                       tmp_path: Path) -> None:
    from rasterio.warp import transform
    found = aos.detect(forest, pose_view=len(forest) // 2, focal_surface=0.0)
    best = found.detections[0]
    (lon,), (lat,) = transform("EPSG:32633", "EPSG:4326", [best.world[0]], [best.world[1]])
    assert best.lon_lat == pytest.approx((lon, lat), abs=1e-9)
    assert 14.99 < lon < 15.01 and 47.8 < lat < 47.9  # 15 E; 5300 km north
    np.testing.assert_allclose(found.world[0], best.world)
    again = pickle.loads(pickle.dumps(found))
    assert again.detections[0].lon_lat == best.lon_lat
    assert np.array_equal(again.scores, found.scores) and again.threshold == found.threshold
    assert "DetectResult(detections=" in repr(found) and "lon_lat=" in repr(best)
    # GeoJSON (RFC 7946: a FeatureCollection of WGS84 points), KML, CSV.
    found.write(str(tmp_path / "found.geojson"))
    document = json.loads((tmp_path / "found.geojson").read_text())
    assert document["type"] == "FeatureCollection"
    feature = document["features"][0]
    assert feature["geometry"]["type"] == "Point"
    assert feature["geometry"]["coordinates"][:2] == pytest.approx([lon, lat], abs=1e-9)
    assert feature["properties"]["views"] == list(range(len(forest)))
    found.write(str(tmp_path / "found.kml"))
    root = ElementTree.parse(tmp_path / "found.kml").getroot()
    coordinates = root.find(".//{http://www.opengis.net/kml/2.2}coordinates").text
    assert [float(v) for v in coordinates.split(",")[:2]] == pytest.approx([lon, lat], abs=1e-8)
    found.write(str(tmp_path / "found.csv"))
    rows = list(csv.DictReader((tmp_path / "found.csv").open()))
    assert float(rows[0]["lon"]) == pytest.approx(lon, abs=1e-9)
    with pytest.raises(ValueError, match="exists"):
        found.write(str(tmp_path / "found.csv"))
    with pytest.raises(ValueError, match="unknown detections format"):
        found.write(str(tmp_path / "found.txt"))
    overlay = found.overlay()
    assert overlay.shape == (128, 128, 3) and overlay.dtype == np.uint8


def test_cli_detect_writes_its_outputs_together(forest: aos.LightField, tmp_path: Path) -> None:
    lf = tmp_path / "lf.json"
    aos.write_lightfield(str(lf), forest)
    out = {k: tmp_path / f"found.{k}" for k in ("geojson", "kml", "csv")}
    overlay, scores = tmp_path / "overlay.png", tmp_path / "scores.tif"
    done = subprocess.run(
        ["aos-render", "detect", str(lf), "--pose-view", str(len(forest) // 2),
         "--focal-height", "0", "--geojson", str(out["geojson"]), "--kml", str(out["kml"]),
         "--csv", str(out["csv"]), "--overlay", str(overlay), "--scores", str(scores), "--json"],
        capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["detections"] >= 1
    assert report["threshold_rule"] == "false_alarm_rate 1e-08 (chi-square, 3 degrees of freedom)"
    assert all(p.exists() for p in [*out.values(), overlay, scores])
    assert json.loads(out["geojson"].read_text())["features"][0]["properties"]["area_px"] >= 5
    assert aos.read_image(str(scores)).dtype == np.float32
    # Without a CRS, KML is refused before anything is written; no output at all is a usage error.
    local = aos.LightField()
    for view in forest.views:
        local.add_view(view.image, view.camera, view.cam_from_world, view.name)
    plain = tmp_path / "plain.json"
    aos.write_lightfield(str(plain), local)
    done = subprocess.run(["aos-render", "detect", str(plain), "--pose-view", "40",
                           "--focal-height", "0", "--kml", str(tmp_path / "x.kml"),
                           "--geojson", str(tmp_path / "x.geojson")],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode != 0 and "no CRS" in done.stderr
    assert not (tmp_path / "x.kml").exists() and not (tmp_path / "x.geojson").exists()
    done = subprocess.run(["aos-render", "detect", str(plain), "--pose-view", "40"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and "give at least one output" in done.stderr
    done = subprocess.run(["aos-render", "detect", str(plain), "--pose-view", "40",
                           "--csv", str(tmp_path / "x.csv"), "--false-alarm-rate", "2"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode != 0 and "false_alarm_rate" in done.stderr
    assert not (tmp_path / "x.csv").exists()


def test_detection_on_the_map_finds_the_person_and_map_writes_them(forest: aos.LightField,
                                                                    tmp_path: Path) -> None:
    """The orthographic map (10 cm pixels over 20 m around the target): the top detection lies
    within 0.3 m of the target; map --detect writes the map and the GeoJSON together, on one
    machine or on a Dask cluster."""
    extent = [UTM_ORIGIN[0] - 10.0, UTM_ORIGIN[1] - 10.0, UTM_ORIGIN[0] + 10.0,
              UTM_ORIGIN[1] + 10.0]
    found = aos.detect_map(forest, pixel_size=0.1, extent=extent, focal_surface=0.0)
    assert found.geotransform == pytest.approx((extent[0], 0.1, 0.0, extent[3], 0.0, -0.1))
    assert found.ground_sampling_m == pytest.approx(0.1)
    best = found.detections[0]
    assert math.hypot(best.local[0], best.local[1]) < 0.3, best
    # The map pixel and the world point agree through the geotransform.
    assert best.world[0] == pytest.approx(extent[0] + 0.1 * best.pixel[0], abs=0.15)
    lf = tmp_path / "lf.json"
    aos.write_lightfield(str(lf), forest)
    done = subprocess.run(
        ["aos-render", "map", str(lf), "--pixel-size", "0.1", "--extent",
         *(str(v) for v in extent), "--focal-height", "0", "-o", str(tmp_path / "map.tif"),
         "--detect", str(tmp_path / "found.geojson"), "--json"],
        capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["detections"] >= 1
    feature = json.loads((tmp_path / "found.geojson").read_text())["features"][0]
    assert feature["geometry"]["coordinates"][:2] == pytest.approx(list(best.lon_lat), abs=1e-7)
    # On a Dask cluster the map is rendered in tiles and scored where it is assembled: the
    # same detections; anomaly imaging too (the workers score the frames they hold).
    pytest.importorskip("distributed")
    done = subprocess.run(
        ["aos-render", "map", str(lf), "--pixel-size", "0.1", "--extent",
         *(str(v) for v in extent), "--focal-height", "0", "-o", str(tmp_path / "map2.tif"),
         "--detect", str(tmp_path / "found2.geojson"), "--workers", "1", "--json"],
        capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-800:]
    report = json.loads(done.stdout)
    assert report["detections"] == len(found.detections) and report["workers"] == 1
    local = json.loads((tmp_path / "found.geojson").read_text())["features"]
    cluster = json.loads((tmp_path / "found2.geojson").read_text())["features"]
    assert len(cluster) == len(local)
    for ours, theirs in zip(cluster, local):
        assert ours["geometry"]["coordinates"] == pytest.approx(theirs["geometry"]["coordinates"],
                                                                abs=1e-9)
    imaging = aos.detect_map(forest, pixel_size=0.1, extent=extent, focal_surface=0.0,
                             detector="anomaly-imaging")
    assert imaging.detections
    done = subprocess.run(
        ["aos-render", "map", str(lf), "--pixel-size", "0.1", "--extent",
         *(str(v) for v in extent), "--focal-height", "0", "-o", str(tmp_path / "map3.tif"),
         "--detect", str(tmp_path / "found3.geojson"), "--workers", "1", "--detector",
         "anomaly-imaging", "--json"], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-800:]
    cluster = json.loads((tmp_path / "found3.geojson").read_text())["features"]
    assert len(cluster) == len(imaging.detections)
    for ours, theirs in zip(cluster, imaging.detections):
        assert ours["geometry"]["coordinates"][:2] == pytest.approx(list(theirs.lon_lat),
                                                                    abs=1e-9)


def test_temperature_threshold_in_degrees_on_a_radiometric_light_field() -> None:
    """A 36.5 C patch on 15 C ground (centikelvin frames, 3 x 3 nadir views): min_temperature_c
    30 finds it, with its temperature; the RX detectors' scores are unitless."""
    light_field = aos.LightField()
    camera = aos.PinholeCamera.from_fov(64, 48, 60.0)
    for j in range(3):
        for i in range(3):
            frame = np.full((48, 64), round((273.15 + 15.0) / 0.01), np.uint16)
            # The patch at world (0, 0): in view (i, j) it sits 1 m * f / 10 m off centre.
            u0 = 32 - int(round((2.0 * i - 2.0) * camera.fx / 10.0))
            v0 = 24 + int(round((2.0 * j - 2.0) * camera.fx / 10.0))
            frame[v0 - 2:v0 + 2, u0 - 2:u0 + 2] = round((273.15 + 36.5) / 0.01)
            pose = aos.look_at((2.0 * i - 2.0, 2.0 * j - 2.0, 10.0), (2.0 * i - 2.0, 2.0 * j - 2.0, 0.0),
                               up=(0.0, 1.0, 0.0))
            light_field.add_view(frame, camera, pose, name=f"v{j * 3 + i}")
    light_field.radiometry = aos.Radiometry(0.01, 0.0)
    found = aos.detect(light_field, pose_view=4, focal_surface=0.0, detector="temperature",
                       min_temperature_c=30.0, min_area_px=1)
    assert len(found) == 1 and found.threshold_rule == "min_temperature_c 30"
    assert found.detections[0].peak_celsius == pytest.approx(36.5, abs=0.01)
    assert math.hypot(*found.detections[0].local[:2]) < 0.2
    with pytest.raises(ValueError, match="min_temperature_c: detector 'temperature' needs"):
        aos.detect(light_field, pose_view=4, focal_surface=0.0, detector="temperature")
    light_field.radiometry = None
    with pytest.raises(ValueError, match="needs a radiometric light field"):
        aos.detect(light_field, pose_view=4, focal_surface=0.0, detector="temperature",
                   min_temperature_c=30.0)


def test_one_sided_anomaly_imaging_finds_the_warm_person_in_thermal_frames() -> None:
    """The default scene in thermal (one channel: the person warm, leaves warmer than the
    ground): one-sided anomaly imaging, from Python and from the viewer's session, finds the
    person within 0.3 m at its default threshold (robust_sigmas 13.5)."""
    scene = json.loads((Path(__file__).resolve().parents[2] / "scenes" /
                        "forest_person.json").read_text())
    scene["camera"].update(width=128, height=128, channels=1)
    scene["sampling"]["grid"] = 9
    scene["effects"] = {"thermal": {"ground": 0.35, "targets": 0.9, "leaves": 0.5,
                                    "trunks": 0.45, "texture_contrast": 0.15},
                        "sensor_noise": {"sigma": 0.01}}
    light_field = aos.simulate(scene).light_field
    centre = len(light_field) // 2
    found = aos.detect(light_field, pose_view=centre, focal_surface=0.0,
                       detector="anomaly-imaging", one_sided=True)
    assert found.threshold_rule.startswith("robust_sigmas 13.5")
    assert found.detections and math.hypot(*found.detections[0].local[:2]) < 0.3
    pytest.importorskip("aiohttp")
    from aos.viewer.session import Session, parse_detect_options
    session = Session(light_field, defaults={"pose_view": centre})
    answer = session.detect(session.defaults, parse_detect_options(
        {"detector": "anomaly-imaging", "one_sided": "true"}))
    assert answer["threshold_rule"].startswith("robust_sigmas 13.5")
    assert math.hypot(*answer["detections"][0]["world"][:2]) < 0.3


def test_the_viewer_detects_in_both_modes_and_marks_later_frames(forest: aos.LightField) -> None:
    """/api/detect on the perspective view and on the map: the target listed, and the next
    frame's header carries its marker at the detection's pixel (perspective) or at its world
    point through the map's geotransform."""
    pytest.importorskip("aiohttp")
    import struct
    import urllib.error
    import urllib.request

    handle = aos.view(forest, pose_view=len(forest) // 2, focal_surface=0.0, open_browser=False,
                      num_threads=1)
    try:
        base = f"http://127.0.0.1:{handle.port}"

        def get(path: str) -> bytes:
            with urllib.request.urlopen(f"{base}{path}&token={handle.token}", timeout=60) as r:
                return r.read()

        def header(body: bytes) -> dict:
            length = struct.unpack("<I", body[:4])[0]
            return json.loads(body[4:4 + length])

        # A detector DetectOptions does not know: 400, naming the field and its choices.
        try:
            get("/api/detect?detector=bogus")
            raise AssertionError("expected HTTP 400")
        except urllib.error.HTTPError as error:
            assert error.code == 400
            assert "detector: must be one of rx, rx-local" in error.read().decode()
        # Warm spots only (one_sided) needs one feature and rx or anomaly imaging: refused
        # naming the field otherwise (these frames are RGB; test_one_sided_... has grey ones).
        for query, message in (("detector=rx-local&one_sided=true",
                                "one_sided: detectors rx and anomaly-imaging only"),
                               ("detector=anomaly-imaging&one_sided=true",
                                "one_sided: needs one feature"),
                               ("detector=rx&one_sided=maybe", "one_sided: expected true or"),
                               # Any DetectOptions field, read by its table row.
                               ("detector=rx&robust_sigmas=abc", "robust_sigmas: expected a"),
                               ("detector=rx&robust_sigmas=3&quantile=0.99",
                                "give one threshold rule"),
                               ("detector=rx&min_area_px=0", "min_area_px: must be >= 1"),
                               ):
            try:
                get(f"/api/detect?{query}")
                raise AssertionError("expected HTTP 400")
            except urllib.error.HTTPError as error:
                assert error.code == 400
                assert message in error.read().decode(), query
        # A detector field on another endpoint is unknown there (not silently dropped).
        try:
            get("/api/render?one_sided=true")
            raise AssertionError("expected HTTP 400")
        except urllib.error.HTTPError as error:
            assert error.code == 400
            assert "one_sided: unknown parameter" in error.read().decode()
        # Every DetectOptions field reaches the detection: here the threshold rule and the cap.
        capped = json.loads(get("/api/detect?detector=rx-local&quantile=0.99&max_detections=1"))
        assert capped["threshold_rule"] == "quantile 0.99" and len(capped["detections"]) == 1
        found = json.loads(get("/api/detect?detector=rx-local"))
        best = found["detections"][0]
        assert math.hypot(best["world"][0] - UTM_ORIGIN[0], best["world"][1] - UTM_ORIGIN[1]) < 0.3
        assert "centre" in best
        markers = header(get("/api/render?preview=false"))["markers"]
        assert markers[0][0] == 1 and markers[0][1:] == pytest.approx(best["pixel"], abs=0.05)
        on_map = json.loads(get("/api/detect?detector=rx-local&mode=map"))
        best = on_map["detections"][0]
        assert math.hypot(best["world"][0] - UTM_ORIGIN[0], best["world"][1] - UTM_ORIGIN[1]) < 0.3
        frame = header(get("/api/render?mode=map"))
        x0, p, _, y0, _, _ = frame["geotransform"]
        number, u, v = frame["markers"][0]
        # Markers are rounded to 0.01 pixel.
        assert (x0 + u * p, y0 - v * p) == pytest.approx(tuple(best["world"][:2]),
                                                          abs=0.005 * p + 1e-9)
    finally:
        handle.stop()
