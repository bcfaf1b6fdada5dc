#!/usr/bin/env python3
"""Registration benchmark: primfit's particle filter vs Open3D's RANSAC on FPFH + ICP.

Both run on the same synthetic scenes (thesis §6.3.3: 100 points on a randomly posed
mesh plus uniform outliers in a box around it), 20 seeds per outlier level, measured in
one run. Success: rotation error < 5° and translation error < 2 % of the model size
(diagonal of the mesh's bounding box). Times are per registration, wall clock, on this
machine (Open3D: features + RANSAC + ICP, without file I/O; primfit: the whole
`register` call, including its distance-grid set-up), and the CPU time (user + system,
all threads) over the same span, which other work on a shared machine disturbs less.

    python3 benches/registration_compare.py [--seeds 20] [--levels 0.5,0.8,0.9,0.95]
        [--model mesh.ply] [--no-rotation-only] [--keep DIR]

Needs `open3d` (pip; on Debian also `apt-get install libusb-1.0-0`). Without it, only
primfit's table is printed. primfit's side is `crates/core/examples/registration_bench.rs`, built
with `cargo build --release --example registration_bench`.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run_primfit(args, scenes, rotation_only):
    target = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))
    exe = os.path.join(target, "release", "examples", "registration_bench")
    subprocess.run(
        ["cargo", "build", "--release", "--quiet", "--example", "registration_bench"],
        cwd=ROOT,
        check=True,
    )
    cmd = [exe, "--levels", args.levels, "--seeds", str(args.seeds)]
    if args.model:
        cmd += ["--model", args.model]
    if rotation_only:
        cmd += ["--rotation-only"]
    else:
        cmd += ["--scenes", scenes]
    rows = []
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
    for line in proc.stdout:
        if line.startswith("{"):
            rows.append(json.loads(line))
            print(".", end="", file=sys.stderr, flush=True)
    if proc.wait() != 0:
        sys.exit("registration_bench failed")
    print(file=sys.stderr)
    return rows


def rotation_angle_deg(ra, rb):
    c = (np.trace(ra.T @ rb) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def run_open3d(args, scenes):
    try:
        import open3d as o3d
    except ImportError as e:  # pragma: no cover
        print(f"note: open3d not available ({e}); skipping its table", file=sys.stderr)
        return []
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    mesh = o3d.io.read_triangle_mesh(os.path.join(scenes, "model.ply"))
    rows = []
    for level in [float(x) for x in args.levels.split(",")]:
        for seed in range(args.seeds):
            name = os.path.join(scenes, f"scene_{level}_{seed}")
            truth = json.load(open(name + ".json"))
            size = truth["size"]
            target = o3d.io.read_point_cloud(name + ".ply")
            t0, c0 = time.perf_counter(), time.process_time()
            o3d.utility.random.seed(seed)
            # The standard global-registration recipe (Open3D tutorial) with the voxel
            # size a fraction of the model size (--voxel; the scene's 100 inliers are
            # about 11 % of the model size apart, so finer voxels only add outliers).
            voxel = args.voxel * size
            source = mesh.sample_points_uniformly(2000)

            def prepare(pcd):
                down = pcd.voxel_down_sample(voxel)
                down.estimate_normals(
                    o3d.geometry.KDTreeSearchParamHybrid(radius=2 * voxel, max_nn=30))
                fpfh = o3d.pipelines.registration.compute_fpfh_feature(
                    down, o3d.geometry.KDTreeSearchParamHybrid(radius=5 * voxel, max_nn=100))
                return down, fpfh

            src, src_f = prepare(source)
            tgt, tgt_f = prepare(target)
            dist = 1.5 * voxel
            ransac = o3d.pipelines.registration.registration_ransac_based_on_feature_matching(
                src, tgt, src_f, tgt_f, True, dist,
                o3d.pipelines.registration.TransformationEstimationPointToPoint(False), 3,
                [o3d.pipelines.registration.CorrespondenceCheckerBasedOnEdgeLength(0.9),
                 o3d.pipelines.registration.CorrespondenceCheckerBasedOnDistance(dist)],
                o3d.pipelines.registration.RANSACConvergenceCriteria(100000, 0.999))
            icp = o3d.pipelines.registration.registration_icp(
                source, target, 0.4 * voxel, ransac.transformation,
                o3d.pipelines.registration.TransformationEstimationPointToPoint())
            seconds = time.perf_counter() - t0
            cpu = time.process_time() - c0
            t = np.asarray(icp.transformation)
            rot = rotation_angle_deg(t[:3, :3], np.asarray(truth["rotation_matrix"]))
            trans = float(np.linalg.norm(t[:3, 3] - np.asarray(truth["translation"]))) / size
            rows.append({"method": "open3d", "level": level, "seed": seed,
                         "rotation_deg": rot, "translation_rel": trans, "seconds": seconds,
                         "cpu_seconds": cpu})
            print(".", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    return rows


def cpu(rows):
    """Median CPU time (user + system, all threads) per registration, if measured."""
    values = [r["cpu_seconds"] for r in rows if r.get("cpu_seconds") is not None]
    return f"{statistics.median(values):.2f} s" if values else "–"


def load():
    try:
        return open("/proc/loadavg").read().split()[0]
    except OSError:
        return "?"


def table(title, rows):
    print(f"\n{title}")
    print("| outliers | success | median rotation error | median translation error | "
          "median time | mean time | max time | median CPU time |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for level in sorted({r["level"] for r in rows}):
        rs = [r for r in rows if r["level"] == level]
        ok = sum(r["rotation_deg"] < 5.0 and r["translation_rel"] < 0.02 for r in rs)
        print(f"| {100 * level:.0f} % | {ok}/{len(rs)} ({100 * ok / len(rs):.0f} %) | "
              f"{statistics.median(r['rotation_deg'] for r in rs):.2f}° | "
              f"{100 * statistics.median(r['translation_rel'] for r in rs):.2f} % | "
              f"{statistics.median(r['seconds'] for r in rs):.2f} s | "
              f"{statistics.mean(r['seconds'] for r in rs):.2f} s | "
              f"{max(r['seconds'] for r in rs):.2f} s | {cpu(rs)} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--levels", default="0.5,0.8,0.9,0.95")
    ap.add_argument("--model", help="mesh PLY (default: the built-in asymmetric object)")
    ap.add_argument("--no-rotation-only", action="store_true",
                    help="skip primfit's rotation-only table")
    ap.add_argument("--voxel", type=float, default=0.1,
                    help="Open3D voxel size, fraction of the model size")
    ap.add_argument("--open3d-only", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--keep", help="write the scenes here and keep them")
    args = ap.parse_args()
    scenes = args.keep or tempfile.mkdtemp(prefix="primfit-registration-")
    print(f"scenes in {scenes}; {os.cpu_count()} CPUs", file=sys.stderr)
    print(f"load average (1 min) at start: {load()}")
    if args.open3d_only and args.keep:
        table(f"Open3D, voxel {args.voxel}", run_open3d(args, scenes))
        return
    ours = run_primfit(args, scenes, rotation_only=False)
    theirs = run_open3d(args, scenes)
    table("primfit register --translation (particle filter + trimmed ICP), full pose", ours)
    if theirs:
        table("Open3D RANSAC on FPFH + ICP (point-to-point), full pose", theirs)
    if not args.no_rotation_only:
        rot = run_primfit(args, scenes, rotation_only=True)
        table("primfit register (rotation only, translation known), for reference", rot)
    print(f"\nload average (1 min) at the end: {load()}")


if __name__ == "__main__":
    main()
