"""Meeting other libraries: an Open3D-style cloud into ``fit``, a fit out as one mesh
(``FitResult.to_mesh``) and as trimesh / Open3D meshes.

trimesh and Open3D are optional and not installed in CI; their conversions are checked
against stand-in modules that record what they are handed (the wiring is ours, the
constructors theirs), and a missing package must raise an ``ImportError`` naming it.
"""

from __future__ import annotations

import sys
import types

import numpy as np
import pytest

import primfit


def corner_cloud():
    """A floor and a wall, 1 m × 1 m each, 5 cm apart points."""
    a = np.arange(20) * 0.05 + 0.025
    u, v = (m.ravel() for m in np.meshgrid(a, a, indexing="ij"))
    floor = np.stack([u, v, np.zeros_like(u)], axis=1)
    wall = np.stack([u, np.zeros_like(u), v], axis=1)
    return np.concatenate([floor, wall])


class CloudLikeOpen3D:
    """What fit needs of an ``open3d.geometry.PointCloud``: ``points`` (a sequence of
    3-vectors, as Open3D's ``Vector3dVector``), ``normals`` and ``has_normals()``."""

    def __init__(self, points, normals=None):
        self.points = [tuple(p) for p in points]
        self.normals = [] if normals is None else [tuple(n) for n in normals]

    def has_normals(self):
        return len(self.normals) > 0


LATTICE = dict(types="square", size=1.0, frame="axis", refine=False)


def test_fit_takes_an_open3d_style_cloud():
    cloud = corner_cloud()
    ours = primfit.fit(CloudLikeOpen3D(cloud), **LATTICE)
    plain = primfit.fit(cloud, **LATTICE)
    assert ours.primitives == plain.primitives
    with_normals = CloudLikeOpen3D(cloud, np.tile([0.0, 0.0, 1.0], (len(cloud), 1)))
    assert primfit.fit(with_normals, **LATTICE).primitives == plain.primitives


def test_to_mesh_is_the_exported_mesh(tmp_path):
    result = primfit.fit(corner_cloud(), **LATTICE)
    vertices, faces, owner = result.to_mesh()
    assert vertices.shape[1] == 3 and faces.shape[1] == 3 and owner.shape == (len(faces),)
    assert faces.dtype == np.int64 and owner.dtype == np.int64
    assert set(owner.tolist()) == set(range(len(result)))
    primfit.write_mesh(tmp_path / "m.ply", result)
    v, f = primfit.read_mesh(tmp_path / "m.ply")
    np.testing.assert_allclose(v, vertices, rtol=0, atol=1e-6)  # the PLY stores float32
    np.testing.assert_array_equal(f, faces)


def test_to_trimesh_and_to_open3d_hand_over_the_mesh(monkeypatch):
    result = primfit.fit(corner_cloud(), **LATTICE)
    vertices, faces, owner = result.to_mesh()

    trimesh = types.ModuleType("trimesh")
    trimesh.Trimesh = lambda **kw: kw  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "trimesh", trimesh)
    got = result.to_trimesh()
    np.testing.assert_array_equal(got["vertices"], vertices)
    np.testing.assert_array_equal(got["faces"], faces)
    np.testing.assert_array_equal(got["face_attributes"]["primitive"], owner)
    assert got["process"] is False

    o3d = types.ModuleType("open3d")
    o3d.utility = types.SimpleNamespace(  # type: ignore[attr-defined]
        Vector3dVector=lambda a: ("v", np.asarray(a)), Vector3iVector=lambda a: ("f", np.asarray(a))
    )
    o3d.geometry = types.SimpleNamespace(TriangleMesh=lambda v, f: (v, f))  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "open3d", o3d)
    (vk, v), (fk, f) = result.to_open3d()
    assert (vk, fk) == ("v", "f")
    np.testing.assert_array_equal(v, vertices)
    assert f.dtype == np.int32
    np.testing.assert_array_equal(f, faces)


@pytest.mark.parametrize("method, package", [("to_trimesh", "trimesh"), ("to_open3d", "open3d")])
def test_a_missing_optional_package_is_named(monkeypatch, method, package):
    result = primfit.fit(corner_cloud(), **LATTICE)
    monkeypatch.setitem(sys.modules, package, None)  # import of it raises ImportError
    with pytest.raises(ImportError, match=package):
        getattr(result, method)()
