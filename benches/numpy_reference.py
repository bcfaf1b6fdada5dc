"""NumPy/SciPy reference of primfit's probabilistic chamfer fit (the thesis's approach).

Used only by the benchmark table (``crates/core/examples/bench_table.rs``, ``scripts/bench.sh``) to
show the speed-up of the Rust fitter over a straightforward vectorised NumPy + SciPy
implementation of the same loss (DESIGN §2), on the same scenes and settings.

Input (written by ``bench_table --export SCENE DIR``; the Rust side builds the lattice so
both fitters see exactly the same candidates):

* ``cloud.npy`` (J, 3) float64: the input points;
* ``template_<t>.npy`` (M_t, 3) float64: the local-frame surface samples of template t;
* ``template_of.npy`` (N,) int32, ``rotation.npy`` (N, 3, 3), ``translation.npy`` (N, 3):
  candidate i's samples are ``rotation[i] @ x + translation[i]`` for x in its template;
* ``meta.json``: model, alpha, beta, cap² (``cap2``), weights and solver settings.

What it computes (the thesis's pipeline, vectorised):

1. KD-trees (``scipy.spatial.cKDTree``) over the cloud, over each template's samples
   (queries are mapped into a candidate's local frame, as the Rust side does) and over
   the candidate centres. Every query uses ``workers=-1`` (all cores).
2. Primitive term ``g_i = Σ_{x∈σ_i} min_y ‖x − y‖²``.
3. Point term: per point, the ``4β`` candidates with the nearest centres are a
   prefilter; of those, the β whose nearest **sample** is closest are kept (DESIGN §2's
   ranking). ``existence``: one entry per kept candidate (its nearest-sample distance);
   ``independent``: its α nearest samples. Rows are dense ``(K, J)`` arrays sorted by
   distance (K = β or β·α).
   Differences from the Rust fitter, all in the reference's favour or neutral for speed:
   sample distances instead of the fitter's exact surface distances (existence model),
   the centre prefilter instead of the exact expanding search, no discrete polish.
4. Loss and gradient: the ERD recursion (thesis eq. 6.6) column by column over all
   points at once, the gradient gathered with ``np.bincount``.
5. ``scipy.optimize.minimize(method="L-BFGS-B")`` on ``[0, 1]^N`` with the fitter's
   memory, ``ftol``, max iterations and a ``gtol`` equal to the fitter's relative
   ``pgtol`` times the initial projected gradient; threshold at 0.5.

Output: ``DIR/numpy_result.json`` with per-stage seconds, iterations, evaluations, the
peak RSS (``VmHWM``) and the indices of the chosen candidates (scored by the Rust side).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import Bounds, minimize
from scipy.spatial import cKDTree

CHUNK = 20_000  # points per chunk while building the point term (bounds temporaries)


def peak_rss() -> int:
    """Peak resident set size of this process, bytes (VmHWM)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) * 1024
    return 0


def primitive_term(cloud_tree, templates, template_of, rot, trans):
    """g_i: sum over candidate i's samples of the squared distance to the nearest point."""
    g = np.zeros(len(template_of))
    for t, samples in enumerate(templates):
        ids = np.flatnonzero(template_of == t)
        step = max(1, 2_000_000 // max(len(samples), 1))
        for s in range(0, len(ids), step):
            c = ids[s : s + step]
            scene = np.einsum("cij,mj->cmi", rot[c], samples) + trans[c][:, None, :]
            d, _ = cloud_tree.query(scene.reshape(-1, 3), k=1, workers=-1)
            g[c] = (d.reshape(len(c), len(samples)) ** 2).sum(axis=1)
    return g


def point_term(cloud, centre_tree, template_trees, template_of, rot, trans, meta):
    """Dense sorted rows ``(cand, dist)`` of shape (K, J)."""
    n = len(template_of)
    beta = n if meta["beta"] is None else min(meta["beta"], n)
    alpha = meta["alpha"]
    independent = meta["model"] == "independent"
    prefilter = min(n, 4 * beta)
    cands, dists = [], []
    for s in range(0, len(cloud), CHUNK):
        y = cloud[s : s + CHUNK]
        _, idx = centre_tree.query(y, k=prefilter, workers=-1)
        idx = idx.reshape(len(y), prefilter)
        # Local frame of each (point, candidate): R^T (y − t).
        diff = y[:, None, :] - trans[idx]
        local = np.einsum("ckj,ckji->cki", diff, rot[idx])
        tmpl = template_of[idx]
        d1 = np.empty(idx.shape)
        for t, tree in enumerate(template_trees):
            mask = tmpl == t
            if mask.any():
                d, _ = tree.query(local[mask], k=1, workers=-1)
                d1[mask] = d**2
        # β nearest by nearest-sample distance (ties: lower candidate index).
        if beta < prefilter:
            keep = np.argpartition(d1, beta - 1, axis=1)[:, :beta]
        else:
            keep = np.broadcast_to(np.arange(prefilter), (len(y), prefilter))
        kept = np.take_along_axis(idx, keep, axis=1)
        if not independent:
            dist = np.take_along_axis(d1, keep, axis=1)
            cand = kept
        else:
            loc = np.take_along_axis(local, keep[:, :, None], axis=1)
            tk = template_of[kept]
            a = alpha
            dist = np.empty(kept.shape + (a,))
            for t, tree in enumerate(template_trees):
                mask = tk == t
                if mask.any():
                    k = min(a, tree.n)
                    d, _ = tree.query(loc[mask], k=k, workers=-1)
                    d = d.reshape(-1, k) ** 2
                    if k < a:  # fewer samples than α: pad with +inf (never reached)
                        d = np.pad(d, ((0, 0), (0, a - k)), constant_values=np.inf)
                    dist[mask] = d
            cand = np.repeat(kept, a, axis=1)
            dist = dist.reshape(len(y), -1)
        order = np.argsort(dist, axis=1, kind="stable")  # ties never change the value
        cands.append(np.take_along_axis(cand, order, axis=1).astype(np.int32))
        dists.append(np.take_along_axis(dist, order, axis=1))
    # (K, J): each column step of the recursion reads one contiguous row.
    return np.ascontiguousarray(np.concatenate(cands).T), np.ascontiguousarray(np.concatenate(dists).T)


class Loss:
    """Value and gradient of the probabilistic chamfer over dense sorted rows."""

    def __init__(self, g, cand, dist, meta):
        self.g, self.cand, self.dist = g, cand, dist
        self.cap = meta["cap2"]
        self.wp, self.wq = meta["primitive_weight"], meta["point_weight"]
        self.evaluations = 0
        inf = ~np.isfinite(dist)
        if inf.any():  # padded entries: never the nearest, contribute nothing
            self.dist = np.where(inf, 0.0, dist)
            self.pad = inf
        else:
            self.pad = None

    def __call__(self, p):
        self.evaluations += 1
        cand, dist = self.cand, self.dist
        q = p[cand]  # (K, J)
        if self.pad is not None:
            q = np.where(self.pad, 0.0, q)
        k, j = q.shape
        erd = np.empty_like(dist)
        r = np.full(j, self.cap)
        for m in range(k - 1, -1, -1):
            erd[m] = r
            r = q[m] * dist[m] + (1.0 - q[m]) * r
        grad_entries = np.empty_like(dist)
        survive = np.ones(j)
        for m in range(k):
            grad_entries[m] = survive * (dist[m] - erd[m])
            survive *= 1.0 - q[m]
        if self.pad is not None:
            grad_entries[self.pad] = 0.0
        grad = np.bincount(cand.ravel(), weights=grad_entries.ravel(), minlength=len(p))
        value = self.wp * float(self.g @ p) + self.wq * float(r.sum())
        return value, self.wp * self.g + self.wq * grad


def main(directory: str) -> None:
    d = Path(directory)
    meta = json.loads((d / "meta.json").read_text())
    cloud = np.load(d / "cloud.npy")
    templates = [np.load(d / f"template_{t}.npy") for t in range(meta["templates"])]
    template_of = np.load(d / "template_of.npy")
    rot = np.load(d / "rotation.npy")
    trans = np.load(d / "translation.npy")

    seconds = {}
    t0, cpu0 = time.perf_counter(), time.process_time()
    cloud_tree = cKDTree(cloud)
    template_trees = [cKDTree(s) for s in templates]
    centre_tree = cKDTree(trans)
    seconds["trees"] = time.perf_counter() - t0

    t = time.perf_counter()
    g = primitive_term(cloud_tree, templates, template_of, rot, trans)
    seconds["primitive_term"] = time.perf_counter() - t

    t = time.perf_counter()
    cand, dist = point_term(cloud, centre_tree, template_trees, template_of, rot, trans, meta)
    seconds["point_term"] = time.perf_counter() - t

    t = time.perf_counter()
    loss = Loss(g, cand, dist, meta)
    x0 = np.full(len(g), meta["initial"])
    f0, g0 = loss(x0)
    pg0 = np.max(np.abs(x0 - np.clip(x0 - g0, 0.0, 1.0)))
    res = minimize(
        loss,
        x0,
        jac=True,
        method="L-BFGS-B",
        bounds=Bounds(0.0, 1.0),
        options={
            "maxiter": meta["max_iterations"],
            "maxcor": meta["memory"],
            "ftol": meta["ftol"],
            "gtol": meta["pgtol"] * pg0,
            "maxls": 40,
        },
    )
    chosen = np.flatnonzero(res.x >= meta["threshold"])
    seconds["solve"] = time.perf_counter() - t
    total = time.perf_counter() - t0
    cpu = time.process_time() - cpu0

    result = {
        "seconds": seconds,
        "total_seconds": total,
        "cpu_seconds": cpu,
        "iterations": int(res.nit),
        "evaluations": int(loss.evaluations),
        "loss": float(res.fun),
        "initial_loss": float(f0),
        "message": str(res.message),
        "entries": int(cand.size),
        "peak_rss": peak_rss(),
        "chosen": [int(i) for i in chosen],
    }
    (d / "numpy_result.json").write_text(json.dumps(result))
    short = {k: v for k, v in result.items() if k != "chosen"}
    print(json.dumps(short))


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: numpy_reference.py DIR   (DIR written by bench_table --export)")
    main(sys.argv[1])
