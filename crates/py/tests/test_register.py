"""`primfit.register`: the CLI's `primfit register` on arrays, checked against the
ground truth of synthetic scenes of the Stanford bunny."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import primfit

REPO = Path(__file__).resolve().parents[3]
BUNNY = REPO.parent / "shared" / "data" / "bunny.ply"


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
def bunny():
    vertices, faces = primfit.read_mesh(BUNNY)
    size = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))
    cloud, truth = primfit.synth.registration(
        mesh=(vertices, faces), inliers=100, outliers=900, translation=0.25 * size, seed=3
    )
    return vertices, faces, size, cloud, truth[0]


def test_the_default_finds_the_one_object_at_its_pose(bunny):
    vertices, faces, size, cloud, truth = bunny
    result = primfit.register(cloud, BUNNY)
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


def test_clutter_alone_reports_nothing(bunny):
    vertices, faces, size, cloud, _ = bunny
    clutter = cloud[100:]  # the synthetic scene lists the object's points first
    assert len(primfit.register(clutter, (vertices, faces))) == 0
    # Asked for one object at any confidence, it answers, with a low existence.
    forced = primfit.register(clutter, (vertices, faces), count=1, min_confidence=0.0)
    assert len(forced) == 1 and forced.existence[0] < 0.5


def test_bad_input_raises(bunny):
    vertices, faces, _, cloud, _ = bunny
    with pytest.raises(OSError):
        primfit.register(cloud, REPO / "no-such-model.ply")
    with pytest.raises(ValueError, match="count"):
        primfit.register(cloud, (vertices, faces), count=0)
    with pytest.raises(ValueError, match="min_confidence"):
        primfit.register(cloud, (vertices, faces), min_confidence=float("nan"))
    with pytest.raises(ValueError):
        primfit.register(cloud[:, :2], (vertices, faces))
