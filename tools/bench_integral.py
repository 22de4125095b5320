#!/usr/bin/env python3
"""Benchmark of the integral renderer on the JKU F0 case (382 views -> 512x512).

Prints, for aos and for two Python/OpenCV baselines measured in the same run
(cv2.warpPerspective of each view, then accumulation of values and coverage; "plain" is the
textbook version, "tuned" uses OpenCV's fastest paths):
  - median render time over --repeats interleaved rounds (after one warm-up run each), and the
    speed-up ratio (median of the per-round ratios, so machine noise hits both sides alike);
  - samples per second (view samples actually integrated, i.e. the sum of the count map);
  - agreement of the two images (mean absolute difference, grey levels);
  - memory: peak resident memory of a fresh process that loads the light field and renders once,
    minus its resident memory before loading, against the decoded image bytes plus the output.

A "kernels" section first: the 8-bit kernel with row loads against the same kernel with gathers
only (the kernel before row loads), interleaved, on z = 0 and z = 21, all cores and one thread.

Then a "surfaces" section (focal points instead of a plane, surface_integral.h): interleaved rounds
of two plane renders, the plane z = 0 (the reference plane of the F0 figures, about 27 m below
the cameras, in mid air above the ground) and the ground plane, i.e. the horizontal plane at the
mean z of the terrain points that the 512 x 512 pixels see (the mean of the world z of the
rasterised depth map's focal points, about 48 m below the cameras: the plane the mesh replaces),
against render_integral_on_depth (a) on the plane z = 0's depth map (aos.plane_depth) and (c) on
the F0 terrain mesh (dem/dem_lr.obj) rasterised into the virtual camera's depth map by the small
numpy z-buffer below (precomputed once, not timed), and the end-to-end mesh render (Embree cast
plus the depth path); median times, samples per second, and the median per-round ratio against
BOTH plane renders (a ratio against the ground plane compares renders that take about the same
number of samples; against z = 0 the mesh takes 1.6x the samples). (b), the same through
RenderIntegralAtPoints, is not measured: that entry has no Python binding.

Usage: python3 tools/bench_integral.py [--data ../shared/data/jku-f0] [--repeats 7]
                                       [--surfaces-only | --kernels-only]
Needs: pip install '.[bench]' (opencv-python-headless) for the baseline.
"""
import argparse
import copy
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import aos
from host import cpu_line

FOV_DEG = 50.815436217896945
ROOT = Path(__file__).resolve().parents[1]


def view_homographies(poses, virtual_index, size, fov_deg):
    """Output pixel -> view pixel homographies for the plane z = 0, in OpenCV's pixel convention
    (pixel centres at integer coordinates), computed independently of aos."""
    f = 0.5 * size / np.tan(np.radians(fov_deg) / 2)
    K = np.array([[f, 0, size / 2], [0, f, size / 2], [0, 0, 1.0]])
    R_v, t_v = poses[virtual_index]
    c = -R_v.T @ t_v
    n = np.array([0.0, 0.0, 1.0])
    h = -c[2]  # signed distance to the plane z = 0 along its normal
    to_cv = np.array([[1, 0, -0.5], [0, 1, -0.5], [0, 0, 1.0]])
    from_cv = np.array([[1, 0, 0.5], [0, 1, 0.5], [0, 0, 1.0]])
    homographies = []
    for R, t in poses:
        tau = R @ (c - (-R.T @ t))
        H = K @ (h * R + np.outer(tau, n)) @ R_v.T @ np.linalg.inv(K)
        homographies.append(to_cv @ (np.sign(h) * H) @ from_cv)
    return homographies


def plain_baseline(cv2, frames, homographies, size):
    """The textbook implementation: warp every view and a coverage mask of ones into the virtual
    camera with cv2.warpPerspective (bilinear) and accumulate both in float64 with numpy."""
    images = [frame.astype(np.float32) for frame in frames]
    ones = np.ones_like(images[0])

    def render():
        total = np.zeros((size, size), np.float64)
        count = np.zeros((size, size), np.float64)
        for image, H in zip(images, homographies):
            flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
            total += cv2.warpPerspective(image, H, (size, size), flags=flags)
            count += cv2.warpPerspective(ones, H, (size, size), flags=flags)
        return np.where(count > 0.5, total / np.maximum(count, 1e-9), 0.0)

    return render


def tuned_baseline(cv2, frames, homographies, size):
    """The same with OpenCV's fast paths: float32 value warp, nearest-neighbour uint8 coverage
    warp, and cv2.accumulate instead of numpy arithmetic."""
    images = [frame.astype(np.float32) for frame in frames]
    ones = np.ones(frames[0].shape, np.uint8)

    def render():
        total = np.zeros((size, size), np.float64)
        count = np.zeros((size, size), np.float64)
        for image, H in zip(images, homographies):
            cv2.accumulate(cv2.warpPerspective(image, H, (size, size),
                                               flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP), total)
            cv2.accumulate(cv2.warpPerspective(ones, H, (size, size),
                                               flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP), count)
        return np.where(count > 0, total / np.maximum(count, 1), 0.0)

    return render


def read_obj(path):
    """Vertices (N, 3) and triangles (M, 3) of an OBJ mesh (polygons fanned into triangles)."""
    vertices, faces = [], []
    for line in Path(path).read_text().splitlines():
        if line.startswith("v "):
            vertices.append([float(v) for v in line.split()[1:4]])
        elif line.startswith("f "):
            corners = [int(item.split("/")[0]) for item in line.split()[1:]]
            corners = [c - 1 if c > 0 else len(vertices) + c for c in corners]
            faces.extend([corners[0], corners[k], corners[k + 1]] for k in range(1, len(corners) - 1))
    return np.array(vertices), np.array(faces, dtype=np.int64)


def mesh_depth(vertices, faces, cam_from_world_R, cam_from_world_t, width, height, fov_deg):
    """Camera z (metres) at which each pixel centre's ray first meets the mesh, 0 where it misses:
    a z-buffer rasteriser, which is ray casting of the pixel centres for triangles in front of the
    camera (a pixel centre's ray meets a triangle iff the centre lies in the projected triangle;
    1/z is affine in the image, so the hit's depth is 1 / the interpolated 1/z). Independent of
    aos; triangles reaching behind the camera are skipped (none on F0)."""
    f = 0.5 * width / np.tan(np.radians(fov_deg) / 2)
    cam = vertices @ cam_from_world_R.T + cam_from_world_t
    z = cam[:, 2]
    px = f * cam[:, 0] / z + width / 2
    py = f * cam[:, 1] / z + height / 2
    inv_depth = np.zeros((height, width))  # largest 1/z = nearest hit
    for a, b, c in faces:
        if min(z[a], z[b], z[c]) <= 1e-6:
            continue
        x0 = max(int(np.floor(min(px[a], px[b], px[c]) - 0.5)), 0)
        x1 = min(int(np.ceil(max(px[a], px[b], px[c]) - 0.5)), width - 1)
        y0 = max(int(np.floor(min(py[a], py[b], py[c]) - 0.5)), 0)
        y1 = min(int(np.ceil(max(py[a], py[b], py[c]) - 0.5)), height - 1)
        if x0 > x1 or y0 > y1:
            continue
        gx, gy = np.meshgrid(np.arange(x0, x1 + 1) + 0.5, np.arange(y0, y1 + 1) + 0.5)
        area = (px[b] - px[a]) * (py[c] - py[a]) - (px[c] - px[a]) * (py[b] - py[a])
        if area == 0:
            continue
        wa = ((px[b] - gx) * (py[c] - gy) - (px[c] - gx) * (py[b] - gy)) / area
        wb = ((px[c] - gx) * (py[a] - gy) - (px[a] - gx) * (py[c] - gy)) / area
        wc = 1.0 - wa - wb
        inside = (wa >= 0) & (wb >= 0) & (wc >= 0)
        inv = wa / z[a] + wb / z[b] + wc / z[c]
        block = inv_depth[y0:y1 + 1, x0:x1 + 1]
        np.copyto(block, inv, where=inside & (inv > block))
    return np.where(inv_depth > 0, 1.0 / np.maximum(inv_depth, 1e-300), 0.0).astype(np.float32)


def bench_surfaces(args, light_field, options):
    """The surfaces section: plane render vs the depth path, interleaved, one run."""
    data = Path(args.data)
    camera = aos.PinholeCamera.from_fov(512, 512, FOV_DEG)
    pose = light_field.views[191].cam_from_world
    plane = aos.plane_depth(camera, pose, aos.Plane.at_height(0.0))
    renderers = {
        "plane z=0": lambda: aos.render_integral(light_field, options),
        "depth(plane)": lambda: aos.render_integral_on_depth(light_field, plane, options),
    }
    bases = ["plane z=0"]
    obj = data / "dem" / "dem_lr.obj"
    if obj.exists():
        start = time.perf_counter()
        vertices, faces = read_obj(obj)
        R = np.array(pose.rotation)
        t = np.array(pose.translation)
        terrain = mesh_depth(vertices, faces, R, t, 512, 512, FOV_DEG)
        print(f"surfaces: {obj.name} ({len(vertices)} vertices, {len(faces)} triangles) rasterised "
              f"in {time.perf_counter() - start:.1f} s (not timed below); "
              f"{int((terrain > 0).sum())} of {terrain.size} pixels hit, depth "
              f"{terrain[terrain > 0].min():.1f}..{terrain.max():.1f} m")
        # The ground plane: horizontal, at the mean world z of the terrain points the pixels see
        # (C + depth * R^T K^-1 (x + 0.5, y + 0.5, 1) for every pixel that hits).
        f = 0.5 * 512 / np.tan(np.radians(FOV_DEG) / 2)
        xs, ys = np.meshgrid(np.arange(512) + 0.5, np.arange(512) + 0.5)
        rays_in_cam = np.stack([(xs - 256) / f, (ys - 256) / f, np.ones_like(xs)], axis=-1)
        centre = -R.T @ t
        world_z = centre[2] + terrain * (rays_in_cam @ R.T)[..., 2]
        ground_z = float(world_z[terrain > 0].mean())
        print(f"surfaces: ground plane z = {ground_z:.2f} m (mean world z of the {obj.name} points "
              f"the pixels see; the cameras are at z = {centre[2]:.2f}, z points down); plane "
              f"z = 0 is {abs(centre[2]):.1f} m from the camera, the ground "
              f"{abs(ground_z - centre[2]):.1f} m")
        ground = copy.copy(options)
        ground.focal_surface = aos.Plane.at_height(ground_z)
        renderers = {"plane z=0": renderers["plane z=0"],
                     "plane ground": lambda: aos.render_integral(light_field, ground),
                     "depth(plane)": renderers["depth(plane)"]}
        bases.append("plane ground")
        renderers["depth(mesh)"] = lambda: aos.render_integral_on_depth(light_field, terrain, options)
        # End to end, as `integral --focal-surface dem_lr.obj` renders: the virtual camera's
        # rays cast with Embree (the BVH is built once per surface, here before timing) and the
        # depth path. This is the row the 2x target is about.
        surface = aos.FocalSurface(aos.Mesh.read(str(obj)))
        on_mesh = copy.copy(options)
        on_mesh.focal_surface = surface
        aos.render_integral(light_field, on_mesh)  # builds the BVH
        renderers["mesh(Embree)"] = lambda: aos.render_integral(light_field, on_mesh)
    else:
        print(f"surfaces: no {obj}; the mesh row is skipped")
    print("surfaces: (b) RenderIntegralAtPoints has no Python binding; not measured separately "
          "(render_integral_on_depth is a thin wrapper of it)")
    samples = {}
    for name, render in renderers.items():
        result = render()
        samples[name] = int(getattr(result, "integral", result).samples)
    plane_image = renderers["plane z=0"]().image
    flat = renderers["depth(plane)"]().integral.image
    print(f"surfaces: depth(plane) agrees with the plane render to "
          f"{float(np.max(np.abs(flat - plane_image))):.2e} grey levels (max abs)")
    times = {name: [] for name in renderers}
    for _ in range(args.repeats):
        for name, render in renderers.items():
            start = time.perf_counter()
            render()
            times[name].append(time.perf_counter() - start)
    for name, runs in times.items():
        median = statistics.median(runs)
        print(f"{name + ':':14s} median {median * 1e3:7.1f} ms  "
              f"{samples[name] / median / 1e6:5.0f} M samples/s ({samples[name]} samples, "
              f"{median * 1e9 / max(samples[name], 1):.2f} ns/sample)  "
              f"(runs: {', '.join(f'{t * 1e3:.0f}' for t in runs)} ms)")
        for base in bases:
            if name in (base, bases[0]):
                continue
            ratios = [b / a for a, b in zip(times[base], runs)]
            print(f"{'':16s}{statistics.median(ratios):.2f}x {base} (per-round ratios "
                  f"{min(ratios):.2f}..{max(ratios):.2f})")
    print(f"load average {' '.join(f'{v:.2f}' for v in os.getloadavg())} at the end")
    print("target: the mesh render within 2x of the plane render (issue 15); 'plane z=0' is the "
          "F0 reference plane in mid air, 'plane ground' the plane at the terrain's mean height")


MEMORY_PROBE = r"""
import json, sys
def rss_kib(field):
    for line in open('/proc/self/status'):
        if line.startswith(field):
            return int(line.split()[1])
import numpy as np, aos
before = rss_kib('VmRSS:')
loaded = aos.load_lightfield(sys.argv[1], fov_deg=float(sys.argv[2]))
lf = loaded.light_field
result = aos.render_integral(lf, pose_view=191, fov_deg=float(sys.argv[2]), width=512, height=512)
peak = rss_kib('VmHWM:')
out_bytes = result.image.nbytes + result.count.nbytes
print(json.dumps({'before_kib': before, 'peak_kib': peak, 'image_bytes': lf.image_bytes(),
                  'output_bytes': out_bytes}))
"""


def bench_kernels(args, light_field, options):
    """The 8-bit kernel with row loads (now) against gathers only (the kernel before, through
    aos._core._set_simd_kernels(row_loads=False)), interleaved rounds on the plane z = 0 and on
    z = 21 (the ground under view 191), all cores and one thread. The samples are the same (the
    images are compared); the target is >= 1.0 G samples/s with all cores."""
    import numpy as np
    for height in (0.0, 21.0):
        for threads in (-1, 1):
            o = copy.copy(options)
            o.focal_surface = aos.Plane.at_height(height)
            o.num_threads = threads
            images = {}
            times = {"row loads": [], "gathers": []}
            for row_loads in (True, False):  # warm-up, and the images to compare
                aos._core._set_simd_kernels(row_loads=row_loads)
                images[row_loads] = aos.render_integral(light_field, o)
            for _ in range(args.repeats * 2):
                for name in times:
                    aos._core._set_simd_kernels(row_loads=name == "row loads")
                    start = time.perf_counter()
                    aos.render_integral(light_field, o)
                    times[name].append(time.perf_counter() - start)
            aos._core._set_simd_kernels()
            samples = int(images[True].samples)
            same = bool(np.array_equal(images[True].image, images[False].image))
            ratios = [b / a for a, b in zip(times["row loads"], times["gathers"])]
            label = "all cores" if threads == -1 else "1 thread"
            line = (f"kernels z={height:4.1f} {label:9s}: row loads median "
                    f"{statistics.median(times['row loads']) * 1e3:6.1f} ms "
                    f"({samples / statistics.median(times['row loads']) / 1e9:.3f} G samples/s), "
                    f"gathers {statistics.median(times['gathers']) * 1e3:6.1f} ms "
                    f"({samples / statistics.median(times['gathers']) / 1e9:.3f} G samples/s): "
                    f"{statistics.median(ratios):.2f}x (per-round {min(ratios):.2f}..{max(ratios):.2f}); "
                    f"images {'identical' if same else 'DIFFER'}")
            print(line, flush=True)
    print("target (issue 17): >= 1.0 G samples/s on F0 with all cores")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=str(ROOT.parent / "shared" / "data" / "jku-f0"))
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--surfaces-only", action="store_true",
                        help="measure only the surfaces section")
    parser.add_argument("--kernels-only", action="store_true",
                        help="measure only the kernels section (row loads against gathers)")
    args = parser.parse_args()
    poses_path = Path(args.data) / "poses" / "poses.json"
    if not poses_path.exists():
        print(f"bench_integral: no F0 data at {args.data}; nothing measured")
        return 0

    print(f"aos {aos.__version__}, {os.cpu_count()} cores; F0: {poses_path}")
    print(cpu_line())
    loaded = aos.load_lightfield(str(poses_path), fov_deg=FOV_DEG)
    light_field = loaded.light_field
    options = aos.IntegralOptions(pose_view=191, fov_deg=FOV_DEG, width=512, height=512,
                                  focal_surface=aos.Plane.at_height(0.0))
    if args.surfaces_only:
        bench_surfaces(args, light_field, options)
        return 0
    bench_kernels(args, light_field, options)
    if args.kernels_only:
        return 0
    result = aos.render_integral(light_field, options)
    samples = int(result.samples)
    renderers = {"aos": lambda: aos.render_integral(light_field, options)}

    try:
        import cv2
    except ImportError:
        print("baseline: opencv-python-headless not installed (pip install '.[bench]'); no ratio")
        cv2 = None
    if cv2 is not None:
        raw = json.loads(poses_path.read_text())["images"]
        poses = []
        for entry in raw:
            m = np.array([[float(v) for v in row] for row in entry["M3x4"]])
            poses.append((m[:, :3], m[:, 3]))
        homographies = view_homographies(poses, 191, 512, FOV_DEG)
        frames = [view.image for view in light_field.views]  # decoded once, not timed
        print(f"OpenCV {cv2.__version__}, {cv2.getNumThreads()} threads")
        for name, make in (("plain", plain_baseline), ("tuned", tuned_baseline)):
            render = make(cv2, frames, homographies, 512)
            image = render()
            mad = float(np.mean(np.abs(image - result.image)[8:-8, 8:-8]))
            print(f"{name} baseline agrees with aos to {mad:.3f} grey levels (mean abs, interior)")
            renderers[name] = render

    # Interleaved rounds (aos, plain, tuned, aos, ...) so that load from elsewhere on the machine
    # hits all of them alike; ratios are taken within each round, then their median reported.
    for render in renderers.values():
        render()  # warm-up
    times = {name: [] for name in renderers}
    for _ in range(args.repeats):
        for name, render in renderers.items():
            start = time.perf_counter()
            render()
            times[name].append(time.perf_counter() - start)
    for name, runs in times.items():
        line = (f"{name + ':':7s} median {statistics.median(runs) * 1e3:7.1f} ms  "
                f"(runs: {', '.join(f'{t * 1e3:.0f}' for t in runs)} ms)")
        if name == "aos":
            line += f"  {samples / statistics.median(runs) / 1e6:.0f} M samples/s ({samples} samples)"
        else:
            ratios = [b / a for a, b in zip(times["aos"], runs)]
            line += f"  aos is {statistics.median(ratios):.1f}x faster (per-round ratios " \
                    f"{min(ratios):.1f}..{max(ratios):.1f})"
        print(line)
    if "plain" in times:
        print("target: >= 6x against the plain baseline (cv2.warpPerspective of each view plus "
              "accumulation)")

    probe = subprocess.run([sys.executable, "-c", MEMORY_PROBE, str(poses_path), str(FOV_DEG)],
                           capture_output=True, text=True, check=True)
    memory = json.loads(probe.stdout)
    held = (memory["peak_kib"] - memory["before_kib"]) * 1024
    budget = memory["image_bytes"] + memory["output_bytes"]
    print(f"memory:   {held / 2**20:.1f} MiB held at peak (VmHWM after load+render minus VmRSS "
          f"before load, fresh process) vs {memory['image_bytes'] / 2**20:.1f} MiB decoded frames + "
          f"{memory['output_bytes'] / 2**20:.1f} MiB output = {held / budget:.2f}x (target < 1.5x)")
    bench_surfaces(args, light_field, options)
    return 0


if __name__ == "__main__":
    sys.exit(main())
