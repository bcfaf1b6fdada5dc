#!/usr/bin/env python3
"""primfit against plane-segmentation baselines on a real scan, with one set of measures.

    python benches/real_scan_compare.py SCAN.ply --primfit target/release/primfit \
        [--threshold T1,T2,...] [--tau2 D] [--out DIR] [--max-planes 20]

Runs, on the same file:

1. ``primfit fit SCAN.ply`` with no flags (frame ``auto``, refinement on), timed;
2. Open3D's plane segmentation loop: ``segment_plane`` (RANSAC, 3 points, 1000
   iterations, inlier distance T) repeatedly on the points not yet explained, until a
   plane has fewer than 1 % of the points, fewer than 5 % remain, or ``--max-planes``;
3. the same loop with pyransac3d's ``Plane().fit``.

Each baseline runs once per inlier distance T in ``--threshold`` (default 5 mm, 1 cm and
2 cm: the right value depends on the sensor, and a single guess would favour or handicap
the baselines), so the table shows how they depend on it. primfit takes no threshold.

**Same measures for all.** A baseline plane is unbounded, so each one is turned into
primfit primitives: its inliers are projected onto the plane and binned into square cells
of side S (S = the ``size`` primfit chose for this scan, so both models have the same
resolution); every cell holding at least 3 inliers becomes a square patch of side S
centred on the cell, in the plane. These squares are written as a primfit result JSON
and measured with ``primfit eval`` (DESIGN §4: point→model mean/p95/max, model→point
mean, coverage@τ, chamfer), exactly as primfit's own result is; coverage is reported at
primfit's default τ (twice the median point spacing) and at ``--tau2`` (default 5 mm).
The number of planes and of squares are both reported.

Needs numpy, plyfile, open3d, pyransac3d (e.g. in a virtualenv outside the repository;
open3d needs the Debian package libusb-1.0-0). Prints a markdown table; writes the JSON
results under --out.
"""
import argparse
import json
import os
import random
import subprocess
import time

import numpy as np


def read_points(path):
    from plyfile import PlyData

    v = PlyData.read(path)["vertex"]
    return np.column_stack([v["x"], v["y"], v["z"]]).astype(float)


def quaternion(m):
    """[w, x, y, z] of a proper rotation matrix."""
    w = np.sqrt(max(0.0, 1.0 + m[0, 0] + m[1, 1] + m[2, 2])) / 2
    x = np.sqrt(max(0.0, 1.0 + m[0, 0] - m[1, 1] - m[2, 2])) / 2
    y = np.sqrt(max(0.0, 1.0 - m[0, 0] + m[1, 1] - m[2, 2])) / 2
    z = np.sqrt(max(0.0, 1.0 - m[0, 0] - m[1, 1] + m[2, 2])) / 2
    x = np.copysign(x, m[2, 1] - m[1, 2])
    y = np.copysign(y, m[0, 2] - m[2, 0])
    z = np.copysign(z, m[1, 0] - m[0, 1])
    q = np.array([w, x, y, z])
    return (q / np.linalg.norm(q)).tolist()


def plane_squares(points, normal, offset, side, min_points=3):
    """Square patches (primfit JSON) tiling the cells of the plane n·x + d = 0 that hold inliers."""
    n = normal / np.linalg.norm(normal)
    d = offset / np.linalg.norm(normal)
    helper = np.eye(3)[np.argmin(np.abs(n))]
    u = np.cross(n, helper)
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    rot = np.column_stack([u, v, n])  # local x, y, z → scene
    q = quaternion(rot)
    origin = -d * n
    rel = points - origin
    cells, counts = np.unique(np.floor(np.column_stack([rel @ u, rel @ v]) / side).astype(int), axis=0, return_counts=True)
    out = []
    for (i, j), c in zip(cells, counts):
        if c < min_points:
            continue
        centre = origin + (i + 0.5) * side * u + (j + 0.5) * side * v
        out.append({"type": "square", "size": {"side": side},
                    "pose": {"translation": centre.tolist(), "rotation": q, "scale": 1.0},
                    "existence": 1.0})
    return out


def segmentation_loop(points, fit_plane, max_planes):
    """[(normal, offset, inlier points)] by repeated RANSAC on the unexplained points."""
    rest = points
    planes = []
    while len(planes) < max_planes and len(rest) >= max(3, 0.05 * len(points)):
        eq, inliers = fit_plane(rest)
        inliers = np.asarray(inliers, dtype=int)
        if len(inliers) < 0.01 * len(points):
            break
        planes.append((np.asarray(eq[:3], float), float(eq[3]), rest[inliers]))
        keep = np.ones(len(rest), bool)
        keep[inliers] = False
        rest = rest[keep]
    return planes


def open3d_plane(threshold):
    import open3d as o3d

    o3d.utility.random.seed(0)

    def fit(pts):
        pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
        eq, inliers = pcd.segment_plane(distance_threshold=threshold, ransac_n=3, num_iterations=1000)
        return eq, inliers

    return fit


def pyransac_plane(threshold):
    import pyransac3d as pyrsc

    def fit(pts):
        random.seed(0)  # pyransac3d samples with Python's `random`
        np.random.seed(0)
        result = pyrsc.Plane().fit(pts, thresh=threshold, maxIteration=1000)
        if hasattr(result, "equation"):  # pyransac3d ≥ 0.7 returns a PlaneResult
            return result.equation, result.inliers
        return result

    return fit


def evaluate(primfit, scan, result, tau2):
    """``primfit eval`` of a result, plus ``coverage2``: the coverage at ``tau2``."""
    def run(*extra):
        out = subprocess.run([primfit, "eval", scan, result, "--json", "-q", *extra],
                             check=True, capture_output=True, text=True)
        return json.loads(out.stdout)

    m = run()
    m["coverage2"] = run("--tau", str(tau2))["coverage"]
    return m


def run_primfit(primfit, scan, out_dir, name):
    result = os.path.join(out_dir, f"{name}_primfit.json")
    mesh = os.path.join(out_dir, f"{name}_primfit.ply")
    t0 = time.perf_counter()
    subprocess.run([primfit, "fit", scan, "-o", result, "--mesh", mesh, "-q"], check=True)
    return result, time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scan")
    ap.add_argument("--primfit", default="target/release/primfit")
    ap.add_argument("--threshold", default="0.005,0.01,0.02",
                    help="RANSAC inlier distances, comma-separated (scene units) [default: 0.005,0.01,0.02]")
    ap.add_argument("--tau2", type=float, default=0.005,
                    help="second coverage threshold (scene units) [default: 0.005]")
    ap.add_argument("--max-planes", type=int, default=20)
    ap.add_argument("--out", default="/tmp/primfit_compare")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    name = os.path.splitext(os.path.basename(args.scan))[0]
    points = read_points(args.scan)

    result, seconds = run_primfit(args.primfit, args.scan, args.out, name)
    settings = json.load(open(result))["settings"]
    side = settings["size"]
    thresholds = [float(t) for t in args.threshold.split(",")]
    rows = [("primfit (no flags)", evaluate(args.primfit, args.scan, result, args.tau2), seconds, None)]

    for label, make in [("Open3D segment_plane loop", open3d_plane), ("pyransac3d Plane loop", pyransac_plane)]:
        for threshold in thresholds:
            fit_plane = make(threshold)  # imports the library outside the timing
            t0 = time.perf_counter()
            planes = segmentation_loop(points, fit_plane, args.max_planes)
            seconds = time.perf_counter() - t0
            prims = [sq for n, d, pts in planes for sq in plane_squares(pts, n, d, side)]
            path = os.path.join(args.out, f"{name}_{label.split()[0].lower()}_{threshold:g}.json")
            json.dump({"primfit": "baseline", "settings": {"method": label, "threshold": threshold, "cell": side},
                       "metrics": {}, "primitives": prims}, open(path, "w"))
            rows.append((f"{label}, T = {threshold:g}", evaluate(args.primfit, args.scan, path, args.tau2),
                         seconds, len(planes)))

    tau = rows[0][1]["coverage_tau"]
    print(f"{args.scan}: {len(points)} points; square side / cell {side}; "
          f"coverage τ = {tau:.4f} (twice the median point spacing) and {args.tau2:g}\n")
    print("| method | planes | squares | point→model mean | p95 | max | model→point mean | "
          f"coverage@{tau:.3f} | coverage@{args.tau2:g} | chamfer | time s |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for label, m, seconds, planes in rows:
        print(f"| {label} | {'–' if planes is None else planes} | {m['primitives']} | {m['point_to_model_mean']:.4f} | "
              f"{m['point_to_model_p95']:.4f} | {m['point_to_model_max']:.4f} | {m['model_to_point_mean']:.4f} | "
              f"{100 * m['coverage']:.1f} % | {100 * m['coverage2']:.1f} % | {m['chamfer']:.3f} | {seconds:.1f} |")


if __name__ == "__main__":
    main()
