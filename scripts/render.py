#!/usr/bin/env python3
"""Render a scan and its fitted primitives side by side as a PNG.

    python scripts/render.py SCAN.ply FITTED.ply OUT.png [--title TEXT] [--elev 25 --azim -60]

FITTED.ply is the mesh written by `primfit fit --mesh`; its faces are coloured by the
per-vertex colours primfit writes (one palette colour per primitive). The scan's points
take its own red/green/blue colours when it has them, else a colour by height (z).
`--elev`/`--azim` are matplotlib's view angles in degrees (a camera-frame scan, z forward
and y down, is seen from its camera with `--elev -90 --azim -90`). Needs numpy,
matplotlib and `plyfile`.
"""
import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402


def read(path):
    from plyfile import PlyData  # small, pure-Python PLY reader

    ply = PlyData.read(path)
    v = ply["vertex"]
    xyz = np.column_stack([v["x"], v["y"], v["z"]]).astype(float)
    names = v.data.dtype.names
    rgb = np.column_stack([v["red"], v["green"], v["blue"]]) / 255.0 if "red" in names else None
    faces = None
    if "face" in ply:
        key = "vertex_indices" if "vertex_indices" in ply["face"].data.dtype.names else "vertex_index"
        faces = np.vstack(ply["face"][key]).astype(int)
    return xyz, rgb, faces


def equal_axes(ax, pts):
    lo, hi = pts.min(0), pts.max(0)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(np.maximum(hi - lo, 1e-3 * (hi - lo).max()), zoom=1.0)
    ax.set_axis_off()


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("scan")
    ap.add_argument("fitted")
    ap.add_argument("out")
    ap.add_argument("--title", default="")
    ap.add_argument("--elev", type=float, default=25)
    ap.add_argument("--azim", type=float, default=-60)
    ap.add_argument("--max-points", type=int, default=20000)
    a = ap.parse_args()
    pts, scan_rgb, _ = read(a.scan)
    if len(pts) > a.max_points:
        keep = np.random.default_rng(0).choice(len(pts), a.max_points, replace=False)
        pts = pts[keep]
        scan_rgb = scan_rgb[keep] if scan_rgb is not None else None
    verts, rgb, faces = read(a.fitted)
    fig = plt.figure(figsize=(13, 5))
    for k, title in enumerate(["scan", "fitted primitives"]):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        ax.view_init(elev=a.elev, azim=a.azim)
        if k == 0:
            if scan_rgb is not None:
                ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=0.3, c=scan_rgb)
            else:
                ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=0.3, c=pts[:, 2], cmap="viridis")
        else:
            colors = rgb[faces].mean(1) if rgb is not None else "tab:blue"
            ax.add_collection3d(Poly3DCollection(verts[faces], facecolors=colors, edgecolor="none", alpha=0.9))
        equal_axes(ax, pts)
        ax.set_title(title)
    if a.title:
        fig.suptitle(a.title)
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)


if __name__ == "__main__":
    main()
