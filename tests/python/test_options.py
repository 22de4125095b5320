"""Every Options struct lists its fields once, in C++ (cpp/aos/util/option_fields.h); these tests
check that what is derived from that table agrees with it: the Python class, its JSON form (the
hand-off of `aos-render view` and `map --workers`), and the generated files (tools/options.py)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import aos
from aos import _core
from conftest import build_lightfield

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
    ('{"focal_surface": "dem.tif"}', r'/focal_surface: expected a number \(the height of a '
                                     r'horizontal plane\), {"plane": {...}} or {"file": PATH}'),
    ('{"focal_surface": {"file": "/no/such.tif"}}', r"/focal_surface/file: .*no/such.tif"),
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
    with pytest.raises(ValueError, match=r"/stack/render/focal_surface/plane/normal: "):
        aos.AllInFocusOptions.from_json('{"stack": {"render": {"focal_surface": '
                                        '{"plane": {"point": [0, 0, 0], "normal": [0, 0]}}}}}')


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


def test_deprecated_spellings_warn_and_set_the_one_focal_surface() -> None:
    """focal_plane (IntegralOptions) and focal_height (MapOptions) were other names of the focal
    surface: they still work for one release, each use warning with the new name."""
    def warned(call):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            value = call()
        deprecations = [w for w in caught if w.category is DeprecationWarning]
        # Attributed to the caller's line (this file), so that Python's default filters show
        # it in a user's script.
        assert all(w.filename == __file__ for w in deprecations), [w.filename for w in deprecations]
        return value, [str(w.message) for w in deprecations]

    options, messages = warned(lambda: aos.IntegralOptions(focal_plane=21.0))
    assert messages == ["IntegralOptions.focal_plane is deprecated; use focal_surface"]
    assert options.focal_surface == aos.FocalSurface(21.0)
    plane, messages = warned(lambda: options.focal_plane)
    assert plane == aos.Plane.at_height(21.0) and len(messages) == 1
    _, messages = warned(lambda: setattr(options, "focal_plane", aos.Plane.at_height(3.0)))
    assert options.focal_surface.plane == aos.Plane.at_height(3.0) and len(messages) == 1
    # Not a field: not in _fields, repr, ==, pickle or JSON.
    assert "focal_plane" not in aos.IntegralOptions._fields
    assert "focal_plane" not in repr(options) and "focal_plane" not in options.to_json()
    assert aos.IntegralOptions._deprecated == {"focal_plane": "focal_surface"}

    map_options, messages = warned(lambda: aos.MapOptions(focal_height=4.5))
    assert messages == ["MapOptions.focal_height is deprecated; use focal_surface"]
    assert map_options.focal_surface.plane == aos.Plane.at_height(4.5)
    height, _ = warned(lambda: map_options.focal_height)
    assert height == 4.5
    # Keywords of the functions go through the same table.
    light_field = build_lightfield()
    result, messages = warned(lambda: aos.render_integral(light_field, pose_view=4,
                                                          focal_plane=0.5))
    assert messages == ["render_integral(): focal_plane= is deprecated; use focal_surface="]
    same = aos.render_integral(light_field, pose_view=4, focal_surface=0.5)
    np.testing.assert_array_equal(result.image, same.image)
    with pytest.raises(TypeError, match="give focal_surface= or focal_plane=, not both"):
        warned(lambda: aos.render_integral(light_field, pose_view=4, focal_plane=0.5,
                                           focal_surface=0.5))
    _, messages = warned(lambda: aos.render_map(light_field, width=8, focal_height=0.5))
    assert messages == ["render_map(): focal_height= is deprecated; use focal_surface="]


def test_a_focal_surface_travels_in_json_as_its_plane_or_its_file(tmp_path: Path) -> None:
    options = aos.IntegralOptions(focal_surface=aos.Plane((1.0, 2.0, 3.0), (0.0, 0.6, 0.8)))
    back = aos.IntegralOptions.from_json(options.to_json())
    assert back == options and back.focal_surface.kind == "plane"
    path = tmp_path / "ground.obj"
    path.write_text("v 0 0 1\nv 4 0 1\nv 0 4 2\nf 1 2 3\n")
    options.focal_surface = aos.FocalSurface.read(str(path))
    assert json.loads(options.to_json())["focal_surface"] == {"file": str(path)}
    assert aos.IntegralOptions.from_json(options.to_json()) == options
    options.focal_surface = aos.Mesh.read(str(path))  # in memory: no file to name
    with pytest.raises(ValueError, match="focal_surface: a mesh surface not read from a file"):
        options.to_json()


def test_text_choices_come_from_the_table(tmp_path: Path) -> None:
    """A text field's choices (Range::OneOf) are checked by check(), typed as a Literal for
    type checkers, and refused by the CLI's parser (exit 2) naming the field and the flag."""
    rows = {row["name"]: row for row in aos.FlightPlanOptions._field_table}
    assert rows["shape"]["type"] == "Literal['circle', 'sector', 'rectangle', 'polygon', 'line']"
    assert rows["shape"]["range"] == "one of circle, sector, rectangle, polygon or line"
    with pytest.raises(ValueError, match="shape: must be one of circle, sector, rectangle, "
                                         "polygon or line, got 'cirlce'"):
        aos.FlightPlanOptions(shape="cirlce").check()
    with pytest.raises(ValueError, match="altitude: must be one of auto, gps or relative"):
        aos.TelemetryOptions(altitude="baro").check()
    import shutil
    done = subprocess.run([shutil.which("aos-render") or "aos-render", "plan", "--shape",
                           "cirlce", "-o", str(tmp_path / "p.csv")],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2, done.stderr
    assert ("shape: must be one of circle, sector, rectangle, polygon or line, got 'cirlce' "
            "[option --shape]") in done.stderr
    assert not (tmp_path / "p.csv").exists()


def test_the_aperture_block_is_one_class_the_renders_derive_from() -> None:
    # render/aperture.h: the sampling fields are declared once, in ApertureOptions; Python has
    # the same hierarchy, and the stub types them on the base only.
    aperture = {row["name"] for row in aos.ApertureOptions._field_table}
    assert aperture == {"aperture_radius", "view_indices", "min_view_angle_deg",
                        "lens_tolerance_px", "num_threads"}
    stub = (ROOT / "python" / "aos" / "_core.pyi").read_text()
    for cls in (aos.IntegralOptions, aos.MapOptions):
        assert issubclass(cls, aos.ApertureOptions)
        assert aperture <= set(cls._fields)
        options = cls(aperture_radius=3.0, num_threads=2)
        assert (options.aperture_radius, options.num_threads) == (3.0, 2)
        # Equal only to options of its own class.
        assert options != aos.ApertureOptions(aperture_radius=3.0, num_threads=2)
        head = stub[stub.index(f"class {cls.__name__}(ApertureOptions):"):]
        head = head[:head.index("\nclass ")]
        for name in aperture:
            assert f"\n    {name}: " not in head and f"def {name}(self)" not in head, name
            assert f"        {name}: " in head, name  # the keyword constructor takes it
    keywords = (ROOT / "python" / "aos" / "_keywords.py").read_text()
    assert keywords.count("aperture_radius: float") == 1
