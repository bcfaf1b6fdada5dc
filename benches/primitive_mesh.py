"""Baseline primitives as triangle meshes, and PLY input/output of such meshes.

A plane from a segmentation method is unbounded and a cylinder infinite; what the
method found is the plane or cylinder *and its inliers*. To measure them like any other
model (benches/measure.py), each becomes the surface where its inliers are:

* a plane: the inliers projected into the plane and binned into square cells of side
  ``cell``; every cell that holds an inlier becomes a square (two triangles) in the plane;
* a cylinder: a closed tube of the fitted radius from the lowest to the highest inlier
  along the axis, ``segments`` facets around (``cylinder_tube``); or, like a plane, the
  cells of side ``cell`` of the unrolled surface (arc length × axial position) that hold
  inliers (``cylinder_cells``), so that an unseen back side is not part of the model.
"""
import numpy as np

from measure import Model


def plane_frame(normal):
    """Two unit vectors (u, v) spanning the plane orthogonal to ``normal``."""
    n = normal / np.linalg.norm(normal)
    helper = np.eye(3)[np.argmin(np.abs(n))]
    u = np.cross(n, helper)
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)


def plane_cells(points, normal, offset, cell):
    """(vertices, faces) of the cells of side ``cell`` of the plane n·x + d = 0 holding inliers."""
    n = np.asarray(normal, float)
    scale = np.linalg.norm(n)
    n, d = n / scale, offset / scale
    u, v = plane_frame(n)
    origin = -d * n
    rel = points - origin
    cells = np.unique(np.floor(np.column_stack([rel @ u, rel @ v]) / cell).astype(np.int64), axis=0)
    corners = np.concatenate([cells + [0, 0], cells + [1, 0], cells + [1, 1], cells + [0, 1]])
    unique, index = np.unique(corners, axis=0, return_inverse=True)
    quad = index.reshape(4, len(cells)).T  # (cells, 4): corners in counter-clockwise order
    faces = np.concatenate([quad[:, [0, 1, 2]], quad[:, [0, 2, 3]]])
    vertices = origin + cell * (unique[:, :1] * u + unique[:, 1:] * v)
    return vertices, faces


def cylinder_tube(points, centre, axis, radius, segments):
    """(vertices, faces) of the tube of ``radius`` around the axis over the inliers' extent."""
    a = np.asarray(axis, float)
    a /= np.linalg.norm(a)
    t = (points - centre) @ a
    u, v = plane_frame(a)
    angles = 2 * np.pi * np.arange(segments) / segments
    ring = radius * (np.cos(angles)[:, None] * u + np.sin(angles)[:, None] * v)
    bottom = centre + t.min() * a + ring
    top = centre + t.max() * a + ring
    i = np.arange(segments)
    j = (i + 1) % segments
    faces = np.concatenate([np.column_stack([i, j, j + segments]), np.column_stack([i, j + segments, i + segments])])
    return np.vstack([bottom, top]), faces


def cylinder_cells(points, centre, axis, radius, cell):
    """(vertices, faces) of the cells of side ``cell`` of the unrolled cylinder holding inliers.

    Cell (i, j) spans arc length [i, i + 1) × cell and axial position [j, j + 1) × cell;
    its four corners lie on the cylinder, so each quad is a chord of it.
    """
    a = np.asarray(axis, float)
    a /= np.linalg.norm(a)
    u, v = plane_frame(a)
    rel = points - centre
    arc = radius * np.arctan2(rel @ v, rel @ u)
    cells = np.unique(np.floor(np.column_stack([arc, rel @ a]) / cell).astype(np.int64), axis=0)
    corners = np.concatenate([cells + [0, 0], cells + [1, 0], cells + [1, 1], cells + [0, 1]])
    unique, index = np.unique(corners, axis=0, return_inverse=True)
    quad = index.reshape(4, len(cells)).T
    faces = np.concatenate([quad[:, [0, 1, 2]], quad[:, [0, 2, 3]]])
    angle = unique[:, :1] * cell / radius
    vertices = centre + radius * (np.cos(angle) * u + np.sin(angle) * v) + unique[:, 1:] * cell * a
    return vertices, faces


def merge(parts):
    """One Model from [(vertices, faces, type name)]: part k becomes primitive k."""
    vertices, faces, owner, types, base = [], [], [], [], 0
    for k, (v, f, kind) in enumerate(parts):
        vertices.append(v)
        faces.append(f + base)
        owner.append(np.full(len(f), k))
        types.append(kind)
        base += len(v)
    if not parts:
        return Model(np.zeros((0, 3)), np.zeros((0, 3), int), np.zeros(0, int), [])
    return Model(np.vstack(vertices), np.vstack(faces), np.concatenate(owner), types)


def read_model(path, primitive_types):
    """A Model from a PLY mesh with a per-face ``primitive`` property (primfit --mesh)."""
    from plyfile import PlyData

    ply = PlyData.read(path)
    vertex, face = ply["vertex"], ply["face"]
    vertices = np.column_stack([vertex["x"], vertex["y"], vertex["z"]]).astype(float)
    faces = np.vstack(face["vertex_indices"]).astype(np.int64)
    if faces.shape[1] != 3:
        raise ValueError(f"{path}: faces are not triangles")
    return Model(vertices, faces, np.asarray(face["primitive"], np.int64), list(primitive_types))


def write_model(path, model):
    """Writes a Model as a binary PLY mesh with a per-face ``int primitive`` property."""
    from plyfile import PlyData, PlyElement

    vertex = np.zeros(len(model.vertices), dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])
    for i, c in enumerate("xyz"):
        vertex[c] = model.vertices[:, i]
    face = np.empty(len(model.faces), dtype=[("vertex_indices", "i4", (3,)), ("primitive", "i4")])
    face["vertex_indices"] = model.faces
    face["primitive"] = model.face_primitive
    PlyData([PlyElement.describe(vertex, "vertex"), PlyElement.describe(face, "face")]).write(path)
