#!/usr/bin/env python3
"""primfit's default fit against CGAL Efficient RANSAC and Open3D's plane loop, one measure for all.

    python benches/real_scan_compare.py --primfit target/release/primfit \\
        --scans ../shared/data/table_scene_mug_stereo_textured.ply ../shared/data/sac_plane_test.ply \\
        examples/hallway.ply [--synth hallway pipe] [--out DIR]

Methods, each run once per scan and timed by wall clock (``time s``):

1. **primfit**: ``primfit fit SCAN --mesh fitted.ply -o result.json``, no other flags; the
   time is the whole process (reading the PLY, fitting, writing both files).
2. **CGAL Efficient RANSAC** (the ``cgal`` Python package), planes and cylinders, on
   normals estimated by Open3D (``estimate_normals``, 16 nearest neighbours). The
   parameters are derived from the scan's median point spacing s, as a user would set
   them: epsilon = 3 s, cluster epsilon = 4 s, min points = max(30, 0.2 % of the
   points), normal threshold 0.9 (CGAL's default, cos 25.8°), probability 0.01. The time
   is normal estimation + detection; handing the points to CGAL and back (a PLY file,
   the bindings have no array interface) is reported apart in the JSON (``handoff_s``).
3. **Open3D plane loop**: ``segment_plane`` (3 points, 1000 iterations, inlier distance
   T = epsilon above) repeatedly on the points not yet explained, until a plane has fewer
   than 1 % of the points, fewer than 5 % remain, or 20 planes; ``--o3d-threshold``
   adds rows with fixed distances.

**One measure, independent of primfit** (benches/measure.py): every model becomes a
triangle mesh with a primitive id per face. primfit's is its ``--mesh`` PLY (per-face
``primitive``); a baseline plane becomes the cells of side 3 s of its plane that hold
its inliers, a baseline cylinder a tube over its inliers' extent along the axis
(benches/primitive_mesh.py). A tube is the model CGAL states, but a spurious cylinder
of large radius fitted to a patch of wall then adds a large tube that no point is near;
so by default (``--cylinder-mesh both``) CGAL gets a second row from the same detection,
its cylinders meshed like its planes: the cells of the unrolled surface (arc length ×
axial position) that hold inliers. Each mesh is sampled area-uniformly at spacing s and
measured against the scan: point→model mean (exact distance to the nearest face),
model→point mean (over model area), coverage@5 cm (share of scan points within 5 cm of
the model), overlap share (share of model area within h = 2 s of another primitive's
surface, counted plainly: the band along an edge where two primitives meet counts),
primitive counts by type and model area.

Prints the machine and its load average before and after, then a markdown table; writes
``results.json`` and every method's mesh under ``--out``. Needs numpy, scipy, plyfile,
open3d and cgal (a virtualenv outside the repository; open3d needs the Debian package
libusb-1.0-0).
"""
import argparse
import json
import os
import platform
import re
import subprocess
import sys
import time
from dataclasses import dataclass, field

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from measure import Model, measure, median_spacing  # noqa: E402
from primitive_mesh import cylinder_cells, cylinder_tube, merge, plane_cells, read_model, write_model  # noqa: E402

NORMAL_NEIGHBOURS = 16
"""Open3D normal estimation: nearest neighbours per point."""


@dataclass
class Derived:
    """Baseline parameters derived from the scan (scene units), see the module doc."""

    spacing: float
    epsilon: float
    cluster_epsilon: float
    min_points: int
    normal_threshold: float
    cell: float

    @staticmethod
    def of(points, spacing, args):
        return Derived(spacing=spacing, epsilon=args.epsilon_spacings * spacing,
                       cluster_epsilon=args.cluster_spacings * spacing,
                       min_points=max(args.min_points_floor, int(args.min_points_share * len(points))),
                       normal_threshold=args.normal_threshold, cell=args.cell_spacings * spacing)


@dataclass
class Run:
    """One method's model of one scan."""

    method: str
    model: Model
    seconds: float
    details: dict = field(default_factory=dict)


def read_points(path):
    from plyfile import PlyData

    v = PlyData.read(path)["vertex"]
    return np.column_stack([v["x"], v["y"], v["z"]]).astype(float)


def run_primfit(primfit, scan, out_dir):
    """``primfit fit SCAN --mesh ... -o ...`` with no other flags."""
    result, mesh = os.path.join(out_dir, "primfit.json"), os.path.join(out_dir, "primfit_fitted.ply")
    t0 = time.perf_counter()
    done = subprocess.run([primfit, "fit", scan, "--mesh", mesh, "-o", result], capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    with open(os.path.join(out_dir, "primfit.log"), "w") as log:
        log.write(done.stdout + done.stderr)
    done.check_returncode()
    fitted = json.load(open(result))
    types = [p["type"] for p in fitted["primitives"]]
    return Run("primfit (no flags)", read_model(mesh, types), seconds,
               {"settings": fitted.get("settings", {}), "own_metrics": fitted.get("metrics", {})})


def open3d_normals(points):
    import open3d as o3d

    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=NORMAL_NEIGHBOURS))
    return np.asarray(pcd.normals)


def write_points_with_normals(path, points, normals):
    from plyfile import PlyData, PlyElement

    table = np.zeros(len(points), dtype=[(c, "f8") for c in ("x", "y", "z", "nx", "ny", "nz")])
    for i, c in enumerate("xyz"):
        table[c], table["n" + c] = points[:, i], normals[:, i]
    PlyData([PlyElement.describe(table, "vertex")]).write(path)


def parse_cgal_shape(text):
    """A CGAL shape's description → dict. Planes print ``(n)x - d= 0`` for n·x + d = 0."""
    numbers = lambda s: [float(x) for x in s.split(",")]  # noqa: E731
    if text.startswith("Type: plane"):
        m = re.search(r"\(([^)]*)\)x - (\S+)= 0", text)
        return {"type": "plane", "normal": numbers(m.group(1)), "offset": float(m.group(2))}
    if text.startswith("Type: cylinder"):
        m = re.search(r"center: \(([^)]*)\) axis: \(([^)]*)\) radius:(\S+)", text)
        return {"type": "cylinder", "centre": numbers(m.group(1)), "axis": numbers(m.group(2)),
                "radius": float(m.group(3))}
    return {"type": text.split()[1]}


def tube_segments(radius, cell):
    """Facets around a tube so that each is about one raster cell wide (at least 12)."""
    return max(12, int(np.ceil(2 * np.pi * radius / cell)))


def shape_mesh(shape, inliers, cell, cylinder_mesh):
    """(vertices, faces) of one detected plane or cylinder over its inliers."""
    if shape["type"] == "plane":
        return plane_cells(inliers, np.array(shape["normal"]), shape["offset"], cell)
    centre, axis, r = np.array(shape["centre"]), np.array(shape["axis"]), shape["radius"]
    if cylinder_mesh == "cells":
        return cylinder_cells(inliers, centre, axis, r, cell)
    return cylinder_tube(inliers, centre, axis, r, tube_segments(r, cell))


def cgal_detect(points, derived, out_dir):
    """CGAL Efficient RANSAC, planes + cylinders, on Open3D normals: (shapes, points, labels, timings)."""
    import open3d  # noqa: F401  (imported outside the timing)
    from CGAL.CGAL_Point_set_3 import Point_set_3
    from CGAL.CGAL_Shape_detection import efficient_RANSAC
    from plyfile import PlyData

    t0 = time.perf_counter()
    normals = open3d_normals(points)
    t1 = time.perf_counter()
    handoff_in, handoff_out = os.path.join(out_dir, "cgal_in.ply"), os.path.join(out_dir, "cgal_labelled.ply")
    write_points_with_normals(handoff_in, points, normals)
    point_set = Point_set_3(handoff_in)
    shape_index = point_set.add_int_map("shape_index")
    t2 = time.perf_counter()
    shapes = efficient_RANSAC(point_set, shape_index, min_points=derived.min_points, epsilon=derived.epsilon,
                              cluster_epsilon=derived.cluster_epsilon, normal_threshold=derived.normal_threshold,
                              probability=0.01, planes=True, cylinders=True)
    t3 = time.perf_counter()
    point_set.write(handoff_out)  # detection reorders the points: read them back with their labels
    labelled = PlyData.read(handoff_out)["vertex"]
    timings = {"normals_s": t1 - t0, "detection_s": t3 - t2, "handoff_s": (t2 - t1) + (time.perf_counter() - t3)}
    os.remove(handoff_in)
    os.remove(handoff_out)
    xyz = np.column_stack([labelled["x"], labelled["y"], labelled["z"]])
    return [parse_cgal_shape(s) for s in shapes], xyz, np.asarray(labelled["shape_index"]), timings


def run_cgal(points, derived, out_dir, cylinder_meshes):
    """One detection, one Run per way of meshing its cylinders ("tube", "cells")."""
    shapes, xyz, label, timings = cgal_detect(points, derived, out_dir)
    details = timings | {"unassigned_share": float(np.mean(label < 0)), "shapes": shapes}
    seconds = timings["normals_s"] + timings["detection_s"]
    runs = []
    for meshing in cylinder_meshes:
        parts = [(*shape_mesh(p, xyz[label == k], derived.cell, meshing), p["type"]) for k, p in enumerate(shapes)]
        name = "CGAL Efficient RANSAC" + (", cylinders as inlier cells" if meshing == "cells" else "")
        runs.append(Run(name, merge(parts), seconds, details | {"cylinder_mesh": meshing}))
    return runs


def open3d_plane_loop(points, threshold, max_planes=20):
    """[(plane [a, b, c, d], inlier points)] by repeated segment_plane on the unexplained points."""
    import open3d as o3d

    o3d.utility.random.seed(0)
    rest, planes = points, []
    while len(planes) < max_planes and len(rest) >= max(3, 0.05 * len(points)):
        pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(rest))
        eq, inliers = pcd.segment_plane(distance_threshold=threshold, ransac_n=3, num_iterations=1000)
        inliers = np.asarray(inliers, dtype=int)
        if len(inliers) < 0.01 * len(points):
            break
        planes.append((np.asarray(eq, float), rest[inliers]))
        keep = np.ones(len(rest), bool)
        keep[inliers] = False
        rest = rest[keep]
    return planes


def run_open3d(points, threshold, cell):
    import open3d  # noqa: F401  (imported outside the timing)

    t0 = time.perf_counter()
    planes = open3d_plane_loop(points, threshold)
    seconds = time.perf_counter() - t0
    parts = [(*plane_cells(pts, eq[:3], eq[3], cell), "plane") for eq, pts in planes]
    return Run(f"Open3D segment_plane loop, T = {threshold:.4g}", merge(parts), seconds,
               {"threshold": threshold, "planes": [eq.tolist() for eq, _ in planes]})


def synthesize(primfit, names, out_dir):
    """``primfit synth NAME -o OUT/synth_NAME.ply`` for each name: the PLY paths."""
    paths = []
    for name in names:
        path = os.path.join(out_dir, f"synth_{name}.ply")
        subprocess.run([primfit, "synth", name, "-o", path, "-q"], check=True)
        paths.append(path)
    return paths


def compare_scan(scan, args):
    """Every method on one scan: [(Run, measures)]."""
    name = os.path.splitext(os.path.basename(scan))[0]
    out_dir = os.path.join(args.out, name)
    os.makedirs(out_dir, exist_ok=True)
    points = read_points(scan)
    derived = Derived.of(points, median_spacing(points), args)
    cylinder_meshes = ["tube", "cells"] if args.cylinder_mesh == "both" else [args.cylinder_mesh]
    runs = [run_primfit(args.primfit, scan, out_dir), *run_cgal(points, derived, out_dir, cylinder_meshes)]
    runs += [run_open3d(points, t, derived.cell) for t in [derived.epsilon, *args.o3d_threshold]]
    measured = []
    for run in runs:
        slug = re.sub(r"[^a-z0-9]+", "_", run.method.lower()).strip("_")
        write_model(os.path.join(out_dir, f"{slug}_mesh.ply"), run.model)
        measured.append((run, measure(points, run.model, args.coverage_distance, derived.spacing)))
    return {"scan": scan, "points": len(points), "derived": derived.__dict__, "runs": measured}


def machine():
    """nproc, CPU model, OS and the 1/5/15-minute load averages now."""
    model = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name")),
                 platform.processor())
    return {"nproc": len(os.sched_getaffinity(0)), "cpu": model, "system": platform.platform(),
            "load_average": list(os.getloadavg())}


def by_type_text(by_type):
    return ", ".join(f"{n} {kind}" for kind, n in sorted(by_type.items())) or "–"


def print_table(scans, coverage_distance):
    print(f"| scan (points, spacing s) | method | primitives | by type | point→model | model→point | "
          f"coverage@{100 * coverage_distance:g} cm | overlap (h = 2 s) | model area | time s |")
    print("|---|---|---:|---|---:|---:|---:|---:|---:|---:|")
    for scene in scans:
        label = f"{os.path.basename(scene['scan'])} ({scene['points']}, {scene['derived']['spacing']:.3g})"
        for run, m in scene["runs"]:
            print(f"| {label} | {run.method} | {m['primitives']} | {by_type_text(m['by_type'])} | "
                  f"{m['point_to_model_mean']:.4f} | {m.get('model_to_point_mean', float('nan')):.4f} | "
                  f"{100 * m['coverage']:.1f} % | {100 * m.get('overlap_share', 0):.1f} % | {m['area']:.3g} | "
                  f"{run.seconds:.2f} |")


def print_parameters(scans):
    print("| scan | points | median spacing s | CGAL epsilon = Open3D T | cluster epsilon | min points | "
          "normal threshold | plane cell | CGAL normals s | CGAL detection s |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for scene in scans:
        d = scene["derived"]
        cgal = next(r.details for r, _ in scene["runs"] if r.method.startswith("CGAL"))
        print(f"| {os.path.basename(scene['scan'])} | {scene['points']} | {d['spacing']:.4g} | {d['epsilon']:.4g} | "
              f"{d['cluster_epsilon']:.4g} | {d['min_points']} | {d['normal_threshold']:g} | {d['cell']:.4g} | "
              f"{cgal['normals_s']:.2f} | {cgal['detection_s']:.2f} |")


def write_results(path, before, after, scans):
    rows = [{"scan": s["scan"], "points": s["points"], "derived": s["derived"],
             "runs": [{"method": r.method, "seconds": r.seconds, "details": r.details, "measures": m}
                      for r, m in s["runs"]]} for s in scans]
    with open(path, "w") as f:
        json.dump({"machine_before": before, "machine_after": after, "scans": rows}, f, indent=1)


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("positional_scans", nargs="*", metavar="SCAN", help="scans (PLY), same as --scans")
    ap.add_argument("--scans", nargs="+", default=[], metavar="SCAN", help="scans (PLY)")
    ap.add_argument("--synth", nargs="+", default=[], metavar="KIND",
                    help="also generate these `primfit synth` scenes (seed 0) and compare on them")
    ap.add_argument("--primfit", default="target/release/primfit")
    ap.add_argument("--out", default="/tmp/primfit_compare")
    ap.add_argument("--coverage-distance", type=float, default=0.05, help="scene units [default: 0.05]")
    ap.add_argument("--epsilon-spacings", type=float, default=3.0, help="CGAL epsilon and Open3D T, in s")
    ap.add_argument("--cluster-spacings", type=float, default=4.0, help="CGAL cluster epsilon, in s")
    ap.add_argument("--cell-spacings", type=float, default=3.0, help="raster cell of baseline planes, in s")
    ap.add_argument("--min-points-share", type=float, default=0.002, help="CGAL min points, share of the scan")
    ap.add_argument("--min-points-floor", type=int, default=30, help="CGAL min points, at least")
    ap.add_argument("--normal-threshold", type=float, default=0.9, help="CGAL normal threshold (cosine)")
    ap.add_argument("--cylinder-mesh", choices=["tube", "cells", "both"], default="both",
                    help="CGAL cylinders as whole tubes over the inliers' axial extent, as the cells of the "
                         "unrolled surface that hold inliers, or both (one row each) [default: both]")
    ap.add_argument("--o3d-threshold", type=float, nargs="*", default=[],
                    help="extra Open3D rows with these fixed inlier distances")
    args = ap.parse_args()
    args.scans = args.positional_scans + args.scans
    return args


def main():
    args = parse_args()
    os.makedirs(args.out, exist_ok=True)
    scans = args.scans + synthesize(args.primfit, args.synth, args.out)
    if not scans:
        sys.exit("no scans: give --scans and/or --synth")
    before = machine()
    print(f"machine: {before['nproc']} cores, {before['cpu']}; load average before {before['load_average']}")
    results = [compare_scan(scan, args) for scan in scans]
    after = machine()
    print(f"load average after {after['load_average']}\n")
    print_table(results, args.coverage_distance)
    print()
    print_parameters(results)
    write_results(os.path.join(args.out, "results.json"), before, after, results)
    print(f"\nresults and meshes under {args.out}")


if __name__ == "__main__":
    main()
