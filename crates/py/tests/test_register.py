"""`primfit.register`: the CLI's `primfit register` on arrays, checked against the
ground truth of a synthetic scene of an asymmetric object made here."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import primfit

REPO = Path(__file__).resolve().parents[3]


def box(centre, half) -> tuple[np.ndarray, np.ndarray]:
    """A box's 8 corners and 12 triangles, wound outward."""
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
    vertices = np.asarray(centre, float) + corners * np.asarray(half, float)
    faces = []
    for axis in range(3):
        for sign in (-1, 1):
            quad = [k for k in range(8) if corners[k, axis] == sign]
            a, b, c, d = quad  # bit order: the quad's corners are a, b, d, c around it
            for tri in ([a, b, d], [a, d, c]):
                n = np.cross(vertices[tri[1]] - vertices[tri[0]], vertices[tri[2]] - vertices[tri[0]])
                faces.append(tri if n[axis] * sign > 0 else tri[::-1])
    return vertices, np.array(faces, np.int64)


def asymmetric_object() -> tuple[np.ndarray, np.ndarray]:
    """Three boxes of different sizes, off-centre: no symmetry a pose could confuse."""
    parts = [box([0, 0, 0], [0.5, 0.3, 0.2]), box([0.35, 0.45, 0.1], [0.15, 0.15, 0.3]),
             box([-0.3, -0.1, 0.45], [0.2, 0.2, 0.25])]
    vertices, faces, offset = [], [], 0
    for v, f in parts:
        vertices.append(v)
        faces.append(f + offset)
        offset += len(v)
    return np.concatenate(vertices), np.concatenate(faces)


def write_mesh_ply(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """An ASCII PLY mesh."""
    lines = ["ply", "format ascii 1.0", f"element vertex {len(vertices)}",
             "property double x", "property double y", "property double z",
             f"element face {len(faces)}", "property list uchar int vertex_indices", "end_header"]
    lines += [" ".join(repr(float(x)) for x in v) for v in vertices]
    lines += ["3 " + " ".join(str(int(i)) for i in f) for f in faces]
    path.write_text("\n".join(lines) + "\n")


def quaternion_matrix(q) -> np.ndarray:
    """Rotation matrix of the unit quaternion ``[w, x, y, z]``."""
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def pose_errors(found: dict, truth: dict, size: float) -> tuple[float, float]:
    """Rotation error (degrees) and translation error (fraction of the model size)."""
    a = quaternion_matrix(found["pose"]["rotation"])
    b = quaternion_matrix(truth["pose"]["rotation"])
    angle = np.degrees(np.arccos(np.clip((np.trace(a.T @ b) - 1) / 2, -1, 1)))
    t = np.subtract(found["pose"]["translation"], truth["pose"]["translation"])
    return float(angle), float(np.linalg.norm(t)) / size


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    vertices, faces = asymmetric_object()
    path = tmp_path_factory.mktemp("register") / "object.ply"
    write_mesh_ply(path, vertices, faces)
    size = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))
    cloud, truth = primfit.synth.registration(
        mesh=(vertices, faces), inliers=100, outliers=900, translation=0.25 * size, seed=3
    )
    return path, vertices, faces, size, cloud, truth[0]


def test_the_default_finds_the_one_object_at_its_pose(scene):
    path, vertices, faces, size, cloud, truth = scene
    result = primfit.register(cloud, path)
    assert len(result) == 1, result.primitives
    found = result.primitives[0]
    rotation, translation = pose_errors(found, truth, size)
    assert rotation < 5.0 and translation < 0.02, (rotation, translation)
    assert found["type"] == "mesh"
    assert 0.5 <= found["existence"] <= 0.99
    assert result.existence.tolist() == [found["existence"]]
    assert found["margin"] > 0 and 0 < found["inlier_share"] < 0.2
    # The model as arrays gives the same answer.
    same = primfit.register(cloud, (vertices, faces))
    assert same.primitives[0]["pose"] == found["pose"]


def test_clutter_alone_reports_nothing(scene):
    _, vertices, faces, _, cloud, _ = scene
    clutter = cloud[100:]  # the synthetic scene lists the object's points first
    assert len(primfit.register(clutter, (vertices, faces))) == 0
    # Asked for one object at any confidence, it answers, with a low existence.
    forced = primfit.register(clutter, (vertices, faces), count=1, min_confidence=0.0)
    assert len(forced) == 1 and forced.existence[0] < 0.5


def test_bad_input_raises(scene):
    _, vertices, faces, _, cloud, _ = scene
    with pytest.raises(OSError):
        primfit.register(cloud, REPO / "no-such-model.ply")
    with pytest.raises(ValueError, match="count"):
        primfit.register(cloud, (vertices, faces), count=0)
    with pytest.raises(ValueError, match="min_confidence"):
        primfit.register(cloud, (vertices, faces), min_confidence=float("nan"))
    with pytest.raises(ValueError):
        primfit.register(cloud[:, :2], (vertices, faces))
