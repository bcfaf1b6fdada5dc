"""PLY round trips through the Python API."""

from __future__ import annotations

import numpy as np
import pytest

import primfit


@pytest.mark.parametrize("ascii", [False, True])
def test_cloud_round_trip_with_every_attribute(tmp_path, ascii):
    rng = np.random.default_rng(0)
    j = 257
    points = rng.normal(size=(j, 3)) * 100
    normals = rng.normal(size=(j, 3))
    colors = rng.integers(0, 256, (j, 3))
    labels = rng.integers(-5, 10, j)
    sensors = rng.normal(size=(j, 3))
    path = tmp_path / "cloud.ply"
    primfit.write_ply(path, points, normals=normals, colors=colors, labels=labels, sensors=sensors, ascii=ascii)
    back = primfit.read_ply(path)
    assert set(back) == {"points", "normals", "colors", "labels", "sensors"}
    np.testing.assert_array_equal(back["points"], points)  # doubles: lossless
    np.testing.assert_array_equal(back["normals"], normals)
    np.testing.assert_array_equal(back["sensors"], sensors)
    np.testing.assert_array_equal(back["colors"], colors)
    np.testing.assert_array_equal(back["labels"], labels)
    assert back["colors"].dtype == np.uint8 and back["labels"].dtype == np.int32
    assert back["points"].dtype == np.float64 and back["points"].flags.c_contiguous


def test_points_only_and_fortran_order(tmp_path):
    points = np.asfortranarray(np.arange(30, dtype=np.float32).reshape(10, 3))
    primfit.write_ply(tmp_path / "p.ply", points)
    back = primfit.read_ply(str(tmp_path / "p.ply"))
    assert set(back) == {"points"}
    np.testing.assert_array_equal(back["points"], np.arange(30.0).reshape(10, 3))


def test_reads_a_hand_written_float_ply(tmp_path):
    path = tmp_path / "hand.ply"
    path.write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n"
        "0 0 0 255 0 0\n1 0.5 0 0 255 0\nnan 1 1 0 0 255\n"
    )
    back = primfit.read_ply(path)
    np.testing.assert_array_equal(back["points"], [[0, 0, 0], [1, 0.5, 0]])  # NaN row dropped
    np.testing.assert_array_equal(back["colors"], [[255, 0, 0], [0, 255, 0]])


def test_empty_cloud_round_trip(tmp_path):
    primfit.write_ply(tmp_path / "e.ply", np.zeros((0, 3)))
    assert primfit.read_ply(tmp_path / "e.ply")["points"].shape == (0, 3)


def test_fitted_mesh_round_trip(tmp_path):
    a = np.arange(20) * 0.05 + 0.025
    u, v = (m.ravel() for m in np.meshgrid(a, a, indexing="ij"))
    cloud = np.stack([u, v, np.zeros_like(u)], axis=1)
    result = primfit.fit(cloud, types="square", size=1.0, frame="axis", refine=False)  # on the lattice
    assert len(result) >= 1
    for ascii in (False, True):
        path = tmp_path / f"fitted{int(ascii)}.ply"
        primfit.write_mesh(path, result, ascii=ascii)
        vertices, faces = primfit.read_mesh(path)
        assert vertices.shape[1] == 3 and faces.shape[1] == 3 and len(faces) >= 2 * len(result)
        assert faces.dtype == np.int64 and faces.max() < len(vertices)
        # The mesh of a floor fit lies in the floor plane.
        np.testing.assert_allclose(vertices[:, 2], 0.0, atol=1e-12)
    # Plain dicts work too, and a mesh read back can serve as the `mesh` type.
    primfit.write_mesh(tmp_path / "dicts.ply", result.primitives[:1])
    vertices, faces = primfit.read_mesh(tmp_path / "dicts.ply")
    again = primfit.fit(
        cloud, types=["mesh"], mesh_model=(vertices - vertices.mean(axis=0), faces), spacing=0.5,
        frame="axis", refine=False,
    )
    assert again.primitives


def test_bad_primitives_for_write_mesh(tmp_path):
    with pytest.raises(ValueError, match="primitive 0"):
        primfit.write_mesh(tmp_path / "x.ply", [{"type": "blob"}])
    with pytest.raises(OSError):
        primfit.write_mesh(
            tmp_path / "x.ply",
            [{"type": "mesh", "size": {"source": str(tmp_path / "missing.ply")},
              "pose": {"translation": [0, 0, 0], "rotation": [1, 0, 0, 0]}}],
        )


def test_read_ply_reads_every_cloud_format_through_the_rust_reader(tmp_path):
    """PCD (ascii, binary), XYZ, CSV and PTS of one cloud read the same points; a wrong
    extension or a truncated file raises ValueError naming the file."""
    rng = np.random.default_rng(1)
    points = (rng.integers(-64, 64, size=(50, 3)) / 16.0).astype(np.float64)  # exact in float32
    primfit.write_ply(tmp_path / "p.ply", points)
    head = (
        "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
        f"WIDTH {len(points)}\nHEIGHT 1\nPOINTS {len(points)}\n"
    )
    (tmp_path / "a.pcd").write_text(head + "DATA ascii\n" + "".join(f"{x} {y} {z}\n" for x, y, z in points))
    (tmp_path / "b.pcd").write_bytes((head + "DATA binary\n").encode() + points.astype("<f4").tobytes())
    (tmp_path / "c.xyz").write_text("".join(f"{x}\t{y}\t{z}\n" for x, y, z in points))
    (tmp_path / "d.csv").write_text("x,y,z,i\n" + "".join(f"{x},{y},{z},1\n" for x, y, z in points))
    (tmp_path / "e.PTS").write_text(f"{len(points)}\n" + "".join(f"{x} {y} {z} 7\n" for x, y, z in points))
    for name in ["p.ply", "a.pcd", "b.pcd", "c.xyz", "d.csv", "e.PTS"]:
        back = primfit.read_ply(tmp_path / name)
        np.testing.assert_array_equal(back["points"], points, err_msg=name)
    (tmp_path / "scan.obj").write_text("v 1 2 3\n")
    with pytest.raises(ValueError, match=r"scan\.obj.*accepted: PLY \(\.ply\), PCD \(\.pcd\)"):
        primfit.read_ply(tmp_path / "scan.obj")
    (tmp_path / "cut.pcd").write_bytes((head + "DATA binary\n").encode() + b"\0" * 10)
    with pytest.raises(ValueError, match=r"cut\.pcd.*truncated file or corrupt count"):
        primfit.read_ply(tmp_path / "cut.pcd")
