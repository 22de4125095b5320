#!/usr/bin/env python3
"""Plan study: which aperture, spacing and altitude reach a target quality at the least flight
time, for a forest of a given density (the AOS paper's Appendix B question asked for planning).

For every combination of aperture diameter, shot spacing and altitude, the tool plans a circular
aperture with aos.plan_flight (scan lines, shots `spacing` apart along and across the lines),
flies it in the simulator over a small procedural forest with aos.preview_flight_plan, and
records the flight time, the PSNR/SSIM of the integral image on the ground against the
occluder-free truth and the share of rays that reach the ground. It prints a table, marks the
Pareto front (no other plan is both faster and better) and the cheapest plan reaching
--target-psnr, and draws PSNR against flight time as an SVG (no plotting library needed).

    python3 tools/plan_study.py                          # the default sweep, table on stdout
    python3 tools/plan_study.py --per-hectare 600 --target-psnr 18
    python3 tools/plan_study.py --write-docs             # docs/plan-study.svg and .md
    python3 tools/plan_study.py --workers 2              # the plans as Dask tasks, same table

The forest: `--per-hectare` trees 8-12 m tall (crowns 1.5-2.5 m, 300 leaves each) on 50 x 50 m
of noise-textured ground, a 1.8 x 0.6 m target at the origin; views of 64 x 64 pixels (50
degrees), a 48 x 48 truth camera of 20 degrees 30 m above the target for every plan (so all
plans are scored on the same patch of ground). Small on purpose (the
whole sweep takes a few minutes on two cores): the figures rank plans for this forest, they are
not absolute quality predictions for a real camera. Deterministic (seeded scene).
"""
from __future__ import annotations

import argparse
import functools
import itertools
import pathlib
import sys
import time
from dataclasses import dataclass
from typing import Any, Optional

import aos

ROOT = pathlib.Path(__file__).resolve().parents[1]


def forest(per_hectare: int, seed: int = 3) -> dict[str, Any]:
    return {
        "seed": seed,
        "ground": {"texture": {"type": "noise", "square": 0.5}},
        "targets": [{"center": [0.0, 0.0], "size": [1.8, 0.6]}],
        "occluders": {"trees": {"area": [-25, -25, 25, 25], "per_hectare": per_hectare,
                                "height": [8, 12], "crown_radius": [1.5, 2.5],
                                "leaves_per_tree": 300}},
        "camera": {"width": 64, "height": 64, "fov_deg": 50},
        # One truth camera for every plan (30 m above the target): the same ground patch is scored.
        "truth": {"position": [0, 0, 30], "width": 48, "height": 48, "fov_deg": 20},
    }


@dataclass
class Row:
    diameter_m: float
    spacing_m: float
    altitude_m: float
    images: int
    flight_min: float
    psnr_db: float
    ssim: float
    visible: float
    pareto: bool = False


def evaluate(case: tuple[float, float, float], per_hectare: int) -> Row:
    """One plan: planned, flown in the simulator over the forest, scored (a Dask task with
    --workers)."""
    diameter, spacing, altitude = case
    plan = aos.plan_flight(shape="circle", radius_m=diameter / 2, spacing_m=spacing,
                           along_spacing_m=spacing, altitude_m=altitude,
                           battery_min=float("inf"), min_shots_per_line=1)
    preview = aos.preview_flight_plan(plan, forest(per_hectare))
    return Row(diameter, spacing, altitude, plan.images, plan.flight_time_s / 60.0,
               preview.psnr_db, preview.ssim, preview.visible_fraction)


def run(diameters: list[float], spacings: list[float], altitudes: list[float],
        per_hectare: int, workers: int = 0, scheduler: str = "") -> list[Row]:
    """Every plan of the sweep, in one process or, with ``workers`` or ``scheduler``, as Dask
    tasks (aos.distributed.run_cases: the same rows in the same order)."""
    cases = list(itertools.product(diameters, spacings, altitudes))
    if workers or scheduler:
        from aos.distributed import run_cases

        rows = run_cases(functools.partial(evaluate, per_hectare=per_hectare), cases,
                         workers=workers or None, scheduler=scheduler or None)
    else:
        rows = [evaluate(case, per_hectare) for case in cases]
    for row in rows:
        row.pareto = not any(o.flight_min <= row.flight_min and o.psnr_db > row.psnr_db
                             or o.flight_min < row.flight_min and o.psnr_db >= row.psnr_db
                             for o in rows)
    return rows


def cheapest(rows: list[Row], target_psnr: float) -> Optional[Row]:
    good = [r for r in rows if r.psnr_db >= target_psnr]
    return min(good, key=lambda r: r.flight_min) if good else None


def table(rows: list[Row], best: Optional[Row]) -> str:
    lines = ["| aperture (m) | spacing (m) | altitude (m) | images | flight (min) | PSNR (dB) | "
             "SSIM | rays reaching the ground | |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in sorted(rows, key=lambda r: r.flight_min):
        mark = ("**cheapest to reach the target**" if r is best else
                "Pareto front" if r.pareto else "")
        lines.append(f"| {r.diameter_m:g} | {r.spacing_m:g} | {r.altitude_m:g} | {r.images} | "
                     f"{r.flight_min:.1f} | {r.psnr_db:.2f} | {r.ssim:.3f} | {r.visible:.1%} | "
                     f"{mark} |")
    return "\n".join(lines)


def svg(rows: list[Row], best: Optional[Row], target_psnr: float, title: str) -> str:
    """PSNR against flight time (log scale), one colour per aperture, the front joined."""
    import math

    width, height, left, right, top, bottom = 760, 440, 70, 200, 40, 55
    xs = [math.log10(r.flight_min) for r in rows]
    ys = [r.psnr_db for r in rows] + [target_psnr]
    x0, x1 = math.floor(min(xs) * 2) / 2, math.ceil(max(xs) * 2) / 2
    y0, y1 = math.floor(min(ys)) - 0.5, math.ceil(max(ys)) + 0.5

    def px(r: Row) -> tuple[float, float]:
        return (left + (math.log10(r.flight_min) - x0) / (x1 - x0) * (width - left - right),
                top + (y1 - r.psnr_db) / (y1 - y0) * (height - top - bottom))

    def py(value: float) -> float:
        return top + (y1 - value) / (y1 - y0) * (height - top - bottom)

    colours = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b"]
    diameters = sorted({r.diameter_m for r in rows})
    altitudes = sorted({r.altitude_m for r in rows})
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
           f'font-family="sans-serif" font-size="12">',
           f'<rect width="{width}" height="{height}" fill="white"/>',
           f'<text x="{width / 2}" y="22" text-anchor="middle" font-size="14">{title}</text>']
    # Axes and ticks.
    plot_right = width - right
    out.append(f'<rect x="{left}" y="{top}" width="{plot_right - left}" '
               f'height="{height - top - bottom}" fill="none" stroke="black"/>')
    for value in range(int(math.ceil(y0)), int(math.floor(y1)) + 1):
        y = py(value)
        out.append(f'<line x1="{left}" y1="{y:.1f}" x2="{plot_right}" y2="{y:.1f}" stroke="#ddd"/>')
        out.append(f'<text x="{left - 6}" y="{y + 4:.1f}" text-anchor="end">{value}</text>')
    for decade in range(int(math.floor(x0)), int(math.ceil(x1)) + 1):
        for factor in (1, 2, 5):
            value = factor * 10.0 ** decade
            lv = math.log10(value)
            if not x0 <= lv <= x1:
                continue
            x = left + (lv - x0) / (x1 - x0) * (plot_right - left)
            out.append(f'<line x1="{x:.1f}" y1="{top}" x2="{x:.1f}" y2="{height - bottom}" stroke="#ddd"/>')
            out.append(f'<text x="{x:.1f}" y="{height - bottom + 16}" text-anchor="middle">{value:g}</text>')
    out.append(f'<text x="{(left + plot_right) / 2}" y="{height - 12}" text-anchor="middle">'
               f'flight time (minutes, log scale; 1 m/s, 1 s per shot)</text>')
    out.append(f'<text x="18" y="{(top + height - bottom) / 2}" text-anchor="middle" '
               f'transform="rotate(-90 18 {(top + height - bottom) / 2})">PSNR of the ground integral (dB)</text>')
    # Target line.
    yt = py(target_psnr)
    out.append(f'<line x1="{left}" y1="{yt:.1f}" x2="{plot_right}" y2="{yt:.1f}" stroke="#888" '
               f'stroke-dasharray="6 4"/>')
    out.append(f'<text x="{plot_right - 4}" y="{yt - 5:.1f}" text-anchor="end" fill="#555">'
               f'target {target_psnr:g} dB</text>')
    # Pareto front.
    front = sorted((r for r in rows if r.pareto), key=lambda r: r.flight_min)
    if len(front) > 1:
        points = " ".join(f"{px(r)[0]:.1f},{px(r)[1]:.1f}" for r in front)
        out.append(f'<polyline points="{points}" fill="none" stroke="black" stroke-opacity="0.4" '
                   f'stroke-width="3"/>')
    # Points: colour = aperture, shape = altitude (circle, square, triangle).
    for r in rows:
        x, y = px(r)
        colour = colours[diameters.index(r.diameter_m) % len(colours)]
        shape = altitudes.index(r.altitude_m) % 3
        if shape == 0:
            out.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="5" fill="{colour}"/>')
        elif shape == 1:
            out.append(f'<rect x="{x - 4.5:.1f}" y="{y - 4.5:.1f}" width="9" height="9" fill="{colour}"/>')
        else:
            out.append(f'<polygon points="{x:.1f},{y - 6:.1f} {x - 5.5:.1f},{y + 4:.1f} '
                       f'{x + 5.5:.1f},{y + 4:.1f}" fill="{colour}"/>')
        out.append(f'<text x="{x + 7:.1f}" y="{y - 6:.1f}" font-size="9" fill="#444">{r.spacing_m:g} m</text>')
        if r is best:
            out.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="11" fill="none" stroke="red" stroke-width="2"/>')
    # Legend.
    lx, ly = plot_right + 16, top + 10
    out.append(f'<text x="{lx}" y="{ly}">aperture diameter</text>')
    for i, d in enumerate(diameters):
        out.append(f'<circle cx="{lx + 6}" cy="{ly + 16 + 16 * i}" r="5" fill="{colours[i % len(colours)]}"/>')
        out.append(f'<text x="{lx + 16}" y="{ly + 20 + 16 * i}">{d:g} m</text>')
    ly += 30 + 16 * len(diameters)
    out.append(f'<text x="{lx}" y="{ly}">altitude</text>')
    for i, a in enumerate(altitudes):
        y = ly + 16 + 16 * i
        shape = i % 3
        if shape == 0:
            out.append(f'<circle cx="{lx + 6}" cy="{y}" r="5" fill="#555"/>')
        elif shape == 1:
            out.append(f'<rect x="{lx + 1.5}" y="{y - 4.5}" width="9" height="9" fill="#555"/>')
        else:
            out.append(f'<polygon points="{lx + 6},{y - 6} {lx + 0.5},{y + 4} {lx + 11.5},{y + 4}" fill="#555"/>')
        out.append(f'<text x="{lx + 16}" y="{y + 4}">{a:g} m</text>')
    ly += 30 + 16 * len(altitudes)
    out.append(f'<text x="{lx}" y="{ly}" font-size="10">labels: shot spacing</text>')
    out.append(f'<text x="{lx}" y="{ly + 14}" font-size="10">grey line: Pareto front</text>')
    out.append(f'<text x="{lx}" y="{ly + 28}" font-size="10" fill="red">red ring: cheapest plan</text>')
    out.append(f'<text x="{lx}" y="{ly + 40}" font-size="10" fill="red">reaching the target</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


def main(argv: Optional[list[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--per-hectare", type=int, default=300, help="trees per hectare")
    parser.add_argument("--diameters", default="8,16,24", help="aperture diameters, metres")
    parser.add_argument("--spacings", default="1.5,3,6", help="shot spacings, metres")
    parser.add_argument("--altitudes", default="20,35", help="heights above ground, metres")
    parser.add_argument("--target-psnr", type=float, default=19.5, help="quality to reach, dB")
    parser.add_argument("--write-docs", action="store_true",
                        help="write docs/plan-study.svg and docs/plan-study.md")
    parser.add_argument("--workers", type=int, default=0,
                        help="run the plans as Dask tasks on a local cluster of N processes "
                             "(aos.distributed.run_cases; the same table)")
    parser.add_argument("--scheduler", default="",
                        help="run the plans as Dask tasks on the cluster of this scheduler")
    args = parser.parse_args(argv)
    if args.workers < 0 or (args.workers and args.scheduler):
        parser.error("--workers N (>= 1) and --scheduler ADDRESS exclude each other")
    numbers = lambda text: [float(v) for v in text.split(",")]  # noqa: E731
    start = time.perf_counter()
    rows = run(numbers(args.diameters), numbers(args.spacings), numbers(args.altitudes),
               args.per_hectare, args.workers, args.scheduler)
    best = cheapest(rows, args.target_psnr)
    seconds = time.perf_counter() - start
    text = table(rows, best)
    summary = (f"{args.per_hectare} trees per hectare, {len(rows)} plans in {seconds:.0f} s; "
               + (f"cheapest plan reaching {args.target_psnr:g} dB: aperture {best.diameter_m:g} m, "
                  f"spacing {best.spacing_m:g} m, {best.altitude_m:g} m above ground "
                  f"({best.images} images, {best.flight_min:.1f} min, {best.psnr_db:.2f} dB)"
                  if best else f"no plan reaches {args.target_psnr:g} dB"))
    print(text)
    print(summary)
    if args.write_docs:
        title = (f"Plans over a forest of {args.per_hectare} trees/ha: ground quality against "
                 f"flight time")
        (ROOT / "docs" / "plan-study.svg").write_text(svg(rows, best, args.target_psnr, title))
        command = "python3 tools/plan_study.py --write-docs" + "".join(
            f" {a}" for a in (argv or sys.argv[1:]) if a != "--write-docs")
        (ROOT / "docs" / "plan-study.md").write_text(
            "# Plan study (generated)\n\n"
            f"Generated by `{command}` (tools/plan_study.py states the set-up). "
            "See docs/flight-planning.md for how to read it.\n\n"
            "![PSNR against flight time](plan-study.svg)\n\n" + text + "\n\n" + summary + "\n")
        print("wrote docs/plan-study.svg and docs/plan-study.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
