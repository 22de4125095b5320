"""Every Options struct lists its fields once, in C++ (cpp/aos/util/option_fields.h); these tests
check that what is derived from that table agrees with it: the Python class, its JSON form (the
hand-off of `aos-render view` and `map --workers`), and the generated files (tools/options.py)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

import aos
from aos import _core

ROOT = Path(__file__).resolve().parents[2]
OPTION_CLASSES = sorted(name for name in dir(_core) if hasattr(getattr(_core, name), "_fields"))


def test_every_options_class_comes_from_a_field_table() -> None:
    assert len(OPTION_CLASSES) >= 17
    for name in OPTION_CLASSES:
        cls = getattr(_core, name)
        table = cls._field_table
        assert [row["name"] for row in table] == list(cls._fields), name
        for row in table:
            assert row["help"].strip(), f"{name}.{row['name']}: no help"
            assert row["type"] and row["given"], f"{name}.{row['name']}"
            # The help is the property's docstring.
            assert getattr(cls, row["name"]).__doc__ == row["help"], f"{name}.{row['name']}"


@pytest.mark.parametrize("name", OPTION_CLASSES)
def test_json_round_trips_defaults(name: str) -> None:
    cls = getattr(_core, name)
    text = cls().to_json()
    data = json.loads(text)  # valid JSON: no NaN or Infinity tokens
    surfaces = {row["name"] for row in cls._field_table if row["type"] == "FocalSurface | None"}
    assert list(data) == [field for field in cls._fields if field not in surfaces]
    assert cls.from_json(text) == cls()


def test_json_round_trips_changed_values_of_every_kind() -> None:
    stack = aos.AllInFocusOptions(coarse_to_fine=4)
    stack.merge.method = "robust"
    stack.merge.robust.agreement = 0.1
    stack.stack.slices = 7
    stack.stack.first_plane = 2.5
    stack.stack.ground_plane = aos.Plane((0.0, 0.0, 1.0), (0.0, 0.6, 0.8))
    stack.stack.render.cam_from_world = aos.look_at((1.0, 2.0, 30.0), (0.0, 0.0, 0.0))
    stack.stack.render.view_indices = [3, 1, 2]
    stack.stack.render.aperture_radius = 5.5
    again = aos.AllInFocusOptions.from_json(stack.to_json())
    assert again == stack
    plan = aos.FlightPlanOptions(shape="polygon", vertices=[[0.0, 0.0], [10.0, 0.0], [0.0, 5.0]],
                                 center=[1.0, 2.0])
    assert aos.FlightPlanOptions.from_json(plan.to_json()) == plan
    options = aos.MapOptions(extent=[0.0, 0.0, 10.0, 10.0], aperture_radius=math.inf)
    assert json.loads(options.to_json())["aperture_radius"] == "inf"
    assert aos.MapOptions.from_json(options.to_json()).aperture_radius == math.inf


@pytest.mark.parametrize("text, message", [
    ('{"tile_sizee": 3}', r"/tile_sizee: unknown key \(known: pixel_size, "),
    ('{"tile_size": "x"}', r"/tile_size: expected a whole number"),
    ('{"tile_size": 1.5}', r"/tile_size: expected a whole number"),
    ('{"aperture_radius": "wide"}', r'/aperture_radius: expected a number, "inf"'),
    ('{"view_indices": [1, "a"]}', r"/view_indices/1: expected a whole number"),
    ('{"focal_surface": "dem.tif"}', r"/focal_surface: not carried in JSON"),
    ("[1, 2]", r"MapOptions JSON: expected an object"),
    ("{", r"MapOptions JSON: not JSON"),
])
def test_bad_json_names_the_key(text: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        aos.MapOptions.from_json(text)


def test_bad_enum_and_nested_values_name_their_path() -> None:
    with pytest.raises(ValueError, match=r"/method: unknown value 'best' \(one of sobel, improved, "
                                         r"robust\)"):
        aos.MergeOptions.from_json('{"method": "best"}')
    with pytest.raises(ValueError, match=r"/stack/render/focal_plane/normal: "):
        aos.AllInFocusOptions.from_json(
            '{"stack": {"render": {"focal_plane": {"point": [0, 0, 0], "normal": [0, 0]}}}}')


def test_generated_files_are_current() -> None:
    done = subprocess.run([sys.executable, str(ROOT / "tools" / "options.py"), "--check"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr


def test_whole_numbers_round_trip_exactly_at_every_width() -> None:
    plan = aos.FlightPlanOptions(max_waypoints=5_000_000_001)  # an int64 field
    assert aos.FlightPlanOptions.from_json(plan.to_json()).max_waypoints == 5_000_000_001
    with pytest.raises(ValueError, match=r"/tile_size: expected a whole number in "):
        aos.MapOptions.from_json('{"tile_size": 5000000000}')
    assert aos.MapOptions.from_json('{"tile_size": 1024.0}').tile_size == 1024
