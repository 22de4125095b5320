"""The vocabulary (issue 14): every field of every Options struct is on the CLI under its own name
(or a listed spelling, or a stated reason) with the struct's default, and docs/vocabulary.md is
what tools/vocabulary.py generates from the package and `aos-render --help`."""
from __future__ import annotations

import importlib.util
import shutil
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXE = shutil.which("aos-render")
pytestmark = pytest.mark.skipif(EXE is None, reason="aos-render is not on PATH (pip install .)")


def load_tool():
    spec = importlib.util.spec_from_file_location("aos_vocabulary", ROOT / "tools" / "vocabulary.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["aos_vocabulary"] = module
    spec.loader.exec_module(module)
    return module


vocabulary = load_tool()


def test_every_option_is_on_the_cli_with_its_default_and_the_page_is_current() -> None:
    table, problems = vocabulary.rows(EXE)
    assert problems == []
    # Every command's struct is walked, nested structs included.
    assert {row["command"] for row in table} == {c for c, _ in vocabulary.COMMANDS}
    assert any(row["python"] == "AllInFocusOptions.merge.robust.agreement" and
               row["flag"] == "--agreement" for row in table)
    assert vocabulary.PAGE.read_text() == vocabulary.page(table), \
        "docs/vocabulary.md is stale: run python3 tools/vocabulary.py"


def test_the_help_parser_reads_real_defaults() -> None:
    # If --help's format changed so that no default were parsed, every default check would pass
    # silently: read a few known ones from the real CLI.
    merge = vocabulary.cli_flags(EXE, "merge")
    assert (merge["--window-radius"], merge["--edge-sigma"], merge["--method"]) == \
        ("3", "0.2", "improved")
    integral = vocabulary.cli_flags(EXE, "integral")
    assert integral["--aperture-radius"] == "inf" and integral["--pose-view"] is None
    assert integral["--view-indices"] is None
    assert "--force" in integral and integral["--force"] is None


def test_drift_is_reported(monkeypatch) -> None:
    real = vocabulary.cli_bindings

    def drifted(aos_render: str):
        bindings = [dict(b) for b in real(aos_render)]
        for b in bindings:
            if b["command"] == "merge" and b["flag"] == "--window-radius":
                b["default"] = "4"                # a default re-declared wrongly
        # a field the CLI forgot
        return [b for b in bindings
                if not (b["command"] == "merge" and b["flag"] == "--smoothing-sigma")]

    monkeypatch.setattr(vocabulary, "cli_bindings", drifted)
    _, problems = vocabulary.rows(EXE)
    assert any("merge --window-radius: the CLI default '4' is not MergeOptions.window_radius's 3"
               in p for p in problems), problems
    assert any("merge: MergeOptions.smoothing_sigma has no flag" in p for p in problems), problems
    # The binding and --help disagree (the default printed is not the one bound).
    assert any("merge --window-radius: --help prints '3' but the flag is bound with the default "
               "'4'" in p for p in problems), problems

    def unprinted(aos_render: str):
        bindings = [dict(b) for b in real(aos_render)]
        for b in bindings:
            if b["command"] == "metrics" and b["flag"] == "--k1":
                b["default"] = ""                 # a default --help no longer prints
        return bindings

    monkeypatch.setattr(vocabulary, "cli_bindings", unprinted)
    _, problems = vocabulary.rows(EXE)
    assert any("metrics --k1: --help prints no default" in p for p in problems), problems

    def stale(aos_render: str):
        return real(aos_render) + [{"command": "merge", "flag": "--gone", "field": "gone",
                                    "default": "1"}]

    monkeypatch.setattr(vocabulary, "cli_bindings", stale)
    _, problems = vocabulary.rows(EXE)
    assert any("merge --gone: bound to MergeOptions.gone, which the struct does not have" in p
               for p in problems), problems


def test_every_command_has_quiet_json_and_threads() -> None:
    import subprocess
    commands = [c for c, _ in vocabulary.COMMANDS] + ["demo"]
    for command in commands:
        flags = vocabulary.cli_flags(EXE, command)
        for flag in ("--quiet", "--json", "--threads"):
            assert flag in flags, (command, flag)
    # Flags are named after their fields: the binding list says which field each flag sets.
    bindings = vocabulary.cli_bindings(EXE)
    poses = {b["flag"]: b["field"] for b in bindings if b["command"] == "poses"}
    assert poses["--sequential-overlap"] == "sequential_overlap"
    assert poses["--max-num-features"] == "max_num_features"
    assert poses["--threads"] == "num_threads"
    allinfocus = {b["flag"]: b["field"] for b in bindings if b["command"] == "allinfocus"}
    assert allinfocus["--agreement"] == "merge.robust.agreement"
    assert allinfocus["--fov-deg"] == "stack.render.fov_deg"
    # An old spelling still works, with a warning naming the new one.
    result = subprocess.run([EXE, "resolution", "--width", "640", "--height", "480",
                             "--lens-fov-deg", "60", "--distance", "20", "--json"],
                            capture_output=True, text=True, timeout=30)
    assert result.returncode == 0, result.stderr
    assert "warning: --distance is deprecated; use --distance-m" in result.stderr
