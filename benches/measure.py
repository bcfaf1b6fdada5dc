"""One set of measures for any primitive model, independent of the method that made it.

A model is a triangle mesh with a primitive id per face (``Model``). It is sampled
area-uniformly (``sample_surface``) and compared with the scan using scipy's cKDTree:

* **point→model mean**: mean over scan points of the distance to the nearest face. The
  distance is exact to the faces that hold the point's ``CANDIDATE_SAMPLES`` nearest
  surface samples (``distance_to_mesh``): an upper bound on the true distance, equal to
  it whenever the nearest face holds one of those samples (it does unless the samples
  are much coarser than the query's distance to the surface);
* **model→point mean**: mean over surface samples (so: over model area) of the distance
  to the nearest scan point (exact within 2 d of the scan, farther estimated from a
  random subset, ``mean_distance_to_points``);
* **coverage@d**: share of scan points within d of the model (d = 5 cm by default);
* **overlap share**: share of model area within h of the surface of *another* primitive
  of the same model, h = 2 × the median point spacing of the scan. Counted plainly:
  the band of width h along an edge where two primitives meet counts too, so two planes
  meeting at a corner give a small, non-zero overlap;
* **far share**: share of model area farther than d from every scan point (overhang);
* primitive counts by type and the total model area.

Run the unit tests by hand: ``python benches/test_measure.py``.
"""
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

CANDIDATE_SAMPLES = 8
"""Surface samples whose faces are tried for each exact point→mesh distance."""

QUERY_CHUNK = 100_000
"""Queries per block in the exact distance computation (bounds the memory to ~100 MB)."""

MAX_SAMPLES = 4_000_000
"""Most surface samples per model; the sample spacing grows to stay under it."""


@dataclass
class Model:
    """A triangle mesh whose faces each belong to one primitive.

    ``vertices`` (V, 3) in scene units, ``faces`` (F, 3) vertex indices,
    ``face_primitive`` (F,) primitive ids, ``primitive_types`` the type name of each id.
    """

    vertices: np.ndarray
    faces: np.ndarray
    face_primitive: np.ndarray
    primitive_types: list = field(default_factory=list)

    def without_degenerate_faces(self):
        """The same model without faces of zero area (they have no closest point)."""
        keep = triangle_areas(self.vertices, self.faces) > 0
        return Model(self.vertices, self.faces[keep], self.face_primitive[keep], self.primitive_types)


def triangle_areas(vertices, faces):
    """Area of each face (scene units²)."""
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def sample_surface(vertices, faces, spacing, seed=0):
    """Area-uniform samples, about one per ``spacing``² of area: ``(points, face index)``.

    Each face gets floor(area / spacing²) samples plus one more with the probability
    of the remainder (stratified, so no face is left out by chance), each uniform in
    its triangle.
    """
    rng = np.random.default_rng(seed)
    expected = triangle_areas(vertices, faces) / spacing**2
    counts = np.floor(expected).astype(int)
    counts += rng.random(len(faces)) < expected - counts
    face_of_sample = np.repeat(np.arange(len(faces)), counts)
    r1, r2 = rng.random(len(face_of_sample)), rng.random(len(face_of_sample))
    s = np.sqrt(r1)  # uniform barycentric coordinates: (1 - s, s (1 - r2), s r2)
    a, b, c = (vertices[faces[face_of_sample, i]] for i in range(3))
    points = a * (1 - s)[:, None] + b * (s * (1 - r2))[:, None] + c * (s * r2)[:, None]
    return points, face_of_sample


def closest_points_on_triangles(p, a, b, c):
    """Closest point to each p (N, 3) on the triangle (a, b, c) of the same row.

    The Voronoi-region walk of Ericson, *Real-Time Collision Detection*, §5.1.5,
    vectorised: the interior solution first, then each edge and vertex region
    overrides it, the highest-priority region last. Triangles must have non-zero area.
    """
    ab, ac = b - a, c - a
    dot = lambda x, y: np.einsum("ij,ij->i", x, y)  # noqa: E731
    ap, bp, cp = p - a, p - b, p - c
    d1, d2 = dot(ab, ap), dot(ac, ap)
    d3, d4 = dot(ab, bp), dot(ac, bp)
    d5, d6 = dot(ab, cp), dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        out = a + ab * (vb / denom)[:, None] + ac * (vc / denom)[:, None]
        regions = [  # (mask, closest point), lowest priority first
            ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0),
             b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))[:, None]),
            ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + ac * (d2 / (d2 - d6))[:, None]),
            ((d6 >= 0) & (d5 <= d6), c),
            ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + ab * (d1 / (d1 - d3))[:, None]),
            ((d3 >= 0) & (d4 <= d3), b),
            ((d1 <= 0) & (d2 <= 0), a),
        ]
        for mask, point in regions:
            out[mask] = point[mask]
    return out


@dataclass
class SampledMesh:
    """Surface samples of some faces of a model, with a KD-tree over them."""

    vertices: np.ndarray
    faces: np.ndarray  # (F, 3) the faces the samples lie on
    samples: np.ndarray  # (S, 3)
    sample_face: np.ndarray  # (S,) row of `faces` each sample lies on
    tree: cKDTree

    @staticmethod
    def of(vertices, faces, samples, sample_face):
        return SampledMesh(vertices, faces, samples, sample_face, cKDTree(samples))


def distance_to_mesh(queries, mesh, k=CANDIDATE_SAMPLES):
    """Distance from each query (N, 3) to the nearest of the faces holding its k nearest samples."""
    k = min(k, len(mesh.samples))
    out = np.empty(len(queries))
    for start in range(0, len(queries), QUERY_CHUNK):
        q = queries[start:start + QUERY_CHUNK]
        _, nearest = mesh.tree.query(q, k=k)
        nearest = nearest.reshape(len(q), k)
        tri = mesh.faces[mesh.sample_face[nearest.ravel()]]
        rep = np.repeat(q, k, axis=0)
        a, b, c = (mesh.vertices[tri[:, i]] for i in range(3))
        d = np.linalg.norm(rep - closest_points_on_triangles(rep, a, b, c), axis=1)
        out[start:start + QUERY_CHUNK] = d.reshape(len(q), k).min(axis=1)
    return out


FAR_SUBSET = 20_000
"""Model→point: most samples beyond the near reach whose distance is computed exactly."""


def mean_distance_to_points(samples, tree, reach, seed=0):
    """Mean distance from the samples to the points in ``tree``, and each sample's
    distance where within ``reach`` (inf beyond).

    A KD-tree query from far away visits most of the tree (a huge spurious tube around
    the scene makes millions of such queries), so samples within ``reach`` of a point
    get their exact distance, and the mean distance of those beyond it is estimated
    from a random subset of ``FAR_SUBSET`` of them, queried exactly (unbiased).
    """
    near, _ = tree.query(samples, distance_upper_bound=reach)
    far = np.flatnonzero(~np.isfinite(near))
    subset = far
    if len(far) > FAR_SUBSET:
        subset = np.random.default_rng(seed).choice(far, FAR_SUBSET, replace=False)
    far_mean = tree.query(samples[subset])[0].mean() if len(far) else 0.0
    total = near[np.isfinite(near)].sum() + len(far) * far_mean
    return float(total / len(samples)), near


def median_spacing(points):
    """Median distance from a point to its nearest other point (scene units)."""
    d, _ = cKDTree(points).query(points, k=2)
    return float(np.median(d[:, 1]))


def sample_spacing_for(model, spacing, max_samples=MAX_SAMPLES):
    """``spacing``, or a larger one that keeps the model under ``max_samples`` samples."""
    area = triangle_areas(model.vertices, model.faces).sum()
    return max(spacing, float(np.sqrt(area / max_samples)))


PRUNE_SAMPLE_SPACINGS = 3.0
"""Overlap test: a sample whose nearest sample of the other primitive is farther than
h + this × the sample spacing is taken as farther than h from that surface without the
exact test (wrong only if a disk of this radius on the surface holds no sample:
probability e^(-π·3²) ≈ 5e-13 for area-uniform samples)."""


def overlap_flags(model, samples, sample_face, h, sample_spacing):
    """For each sample: lies it within h of the surface of another primitive?

    Only pairs of primitives whose bounding boxes, grown by h, meet are compared, only
    the samples inside the other's grown box are queried, and only those near one of
    its samples (``PRUNE_SAMPLE_SPACINGS``) get the exact distance.
    """
    reach = h + PRUNE_SAMPLE_SPACINGS * sample_spacing
    owner = model.face_primitive[sample_face]
    ids = np.unique(model.face_primitive)
    meshes, boxes = {}, {}
    ids = [pid for pid in ids if np.any(owner == pid)]  # a primitive too small to hold a sample is skipped
    for pid in ids:
        mine = owner == pid
        faces = model.faces[model.face_primitive == pid]
        face_rows = np.searchsorted(np.flatnonzero(model.face_primitive == pid), sample_face[mine])
        meshes[pid] = (np.flatnonzero(mine), SampledMesh.of(model.vertices, faces, samples[mine], face_rows))
        corners = model.vertices[faces.ravel()]
        boxes[pid] = (corners.min(axis=0) - h, corners.max(axis=0) + h)
    flags = np.zeros(len(samples), bool)
    for p in ids:
        rows, mesh_p = meshes[p]
        for q in ids:
            if q == p or not boxes_meet(boxes[p], boxes[q]):
                continue
            lo, hi = boxes[q]
            inside = np.all((mesh_p.samples >= lo) & (mesh_p.samples <= hi), axis=1)
            inside &= ~flags[rows]  # already counted
            if inside.any():
                mesh_q = meshes[q][1]
                near, _ = mesh_q.tree.query(mesh_p.samples[inside], distance_upper_bound=reach)
                inside[inside] = np.isfinite(near)
            if inside.any():
                flags[rows[inside]] |= distance_to_mesh(mesh_p.samples[inside], mesh_q) <= h
    return flags


def boxes_meet(a, b):
    """Do two axis-aligned boxes (lo, hi) intersect?"""
    return bool(np.all(a[0] <= b[1]) and np.all(b[0] <= a[1]))


def count_by_type(model):
    """{type: number of primitives of that type that have at least one face}."""
    counts = {}
    for pid in np.unique(model.face_primitive):
        kind = model.primitive_types[pid] if pid < len(model.primitive_types) else "unknown"
        counts[kind] = counts.get(kind, 0) + 1
    return counts


def measure(scan, model, coverage_distance=0.05, spacing=None):
    """All measures of ``model`` against the scan points (N, 3) as a dict (scene units).

    ``spacing`` is the scan's median point spacing (computed when not given); the
    surface is sampled at that spacing (coarser if over ``MAX_SAMPLES``) and
    h = 2 × spacing is the overlap distance.
    """
    spacing = median_spacing(scan) if spacing is None else spacing
    model = model.without_degenerate_faces()
    h = 2 * spacing
    result = {"primitives": int(len(np.unique(model.face_primitive))), "by_type": count_by_type(model),
              "spacing": spacing, "overlap_distance": h, "coverage_distance": coverage_distance,
              "area": float(triangle_areas(model.vertices, model.faces).sum())}
    if len(model.faces) == 0:
        return result | {"point_to_model_mean": float("inf"), "coverage": 0.0}
    delta = sample_spacing_for(model, spacing)
    samples, sample_face = sample_surface(model.vertices, model.faces, delta)
    whole = SampledMesh.of(model.vertices, model.faces, samples, sample_face)
    to_model = distance_to_mesh(scan, whole)
    model_to_point, to_scan = mean_distance_to_points(samples, cKDTree(scan), 2 * coverage_distance)
    overlap = overlap_flags(model, samples, sample_face, h, delta)
    return result | {
        "sample_spacing": delta,
        "samples": int(len(samples)),
        "point_to_model_mean": float(to_model.mean()),
        "point_to_model_p95": float(np.percentile(to_model, 95)),
        "model_to_point_mean": model_to_point,
        "coverage": float(np.mean(to_model <= coverage_distance)),
        "far_share": float(np.mean(to_scan > coverage_distance)),
        "overlap_share": float(overlap.mean()),
    }
