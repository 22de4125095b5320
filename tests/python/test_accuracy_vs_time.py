"""Smoke test of tools/accuracy_vs_time.py: the whole sweep at --quick sizes (1 repeat) writes
the page and one plot per knob into a temporary folder (never docs/), and every table row has
numbers. The figures themselves are the tool's to report (docs/accuracy-vs-time.md), not
asserted here."""

from __future__ import annotations

import importlib.util
import math
import pathlib
import re
import sys

import pytest

pytest.importorskip("matplotlib")

TOOL = pathlib.Path(__file__).resolve().parents[2] / "tools" / "accuracy_vs_time.py"
spec = importlib.util.spec_from_file_location("accuracy_vs_time", TOOL)
accuracy_vs_time = importlib.util.module_from_spec(spec)
sys.modules["accuracy_vs_time"] = accuracy_vs_time  # dataclasses look their module up
spec.loader.exec_module(accuracy_vs_time)  # type: ignore[union-attr]


def test_quick_run_writes_page_plots_and_numbers(tmp_path: pathlib.Path, capsys) -> None:
    docs = tmp_path / "docs"
    assert accuracy_vs_time.main(["--quick", "--write-docs", "--docs-dir", str(docs)]) == 0
    output = capsys.readouterr().out
    # Progress: a line per setting with the elapsed time.
    assert re.search(r"^\[\s*\d+\.\d s\] views: 9x9, 30 m: render", output, re.M), output

    page = (docs / accuracy_vs_time.PAGE).read_text(encoding="utf-8")
    for knob in accuracy_vs_time.KNOBS:
        png = docs / f"accuracy-vs-time-{knob}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", png
        assert f"]({png.name})" in page, png.name
    assert "python3 tools/accuracy_vs_time.py --write-docs --quick" in page
    assert "bilinear" in page and "double" in page  # what is not offered is said

    # Every table: a header with PSNR and SSIM, then rows whose PSNR, SSIM and time are finite
    # numbers; at least one row of each table is on a Pareto front.
    tables = re.findall(r"^(\|.*\|\n\|[-|]+\|\n(?:\|.*\|\n)+)", page, re.M)
    assert len(tables) == len(accuracy_vs_time.KNOBS), tables
    for table in tables:
        lines = table.strip().splitlines()
        header = [c.strip() for c in lines[0].strip("|").split("|")]
        psnr, ssim = header.index("PSNR (dB)"), header.index("SSIM")
        time_column = psnr - 1  # the time column precedes PSNR
        rows = [[c.strip() for c in line.strip("|").split("|")] for line in lines[2:]]
        assert rows, table
        for cells in rows:
            for column in (time_column, psnr, ssim):
                value = float(cells[column])
                assert math.isfinite(value), (header[column], cells)
            assert -1.0 <= float(cells[ssim]) <= 1.0, cells
        assert any("PSNR" in cells[-1] for cells in rows), table

    # The reading guide's first line is generated from the views table.
    assert re.search(r"- For a 64x64 preview .* bilinear with 9x9 views gives -?\d+\.\d+ dB "
                     r"\(SSIM \d\.\d+\) in \d+(\.\d)? ms; 15x15 (adds|loses) \d+\.\d+ dB .* for "
                     r"\d+\.\d times the cost", page), page


def test_pareto_front() -> None:
    """The front keeps the rows no faster row beats: here a (fast, bad), b (slower, better),
    c (slower than b and worse): a and b are on it, c is not; a reference row never is."""
    Row = accuracy_vs_time.Row
    rows = [Row("k", "g", "a", 1.0, {}, psnr=10.0, ssim=0.5),
            Row("k", "g", "b", 2.0, {}, psnr=12.0, ssim=0.4),
            Row("k", "g", "c", 3.0, {}, psnr=11.0, ssim=0.6),
            Row("k", "g", "ref", 0.5, {}, psnr=20.0, ssim=0.9, reference=True)]
    accuracy_vs_time.mark_pareto(rows)
    assert [r.pareto_psnr for r in rows] == [True, True, False, False]
    assert [r.pareto_ssim for r in rows] == [True, False, True, False]
