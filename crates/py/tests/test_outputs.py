"""Mesh formats of write_mesh (PLY, OBJ, glTF binary) and render, through the Python API.

OBJ and GLB files are read back here with the standard library alone (text lines; the
GLB container and its JSON chunk by ``struct``/``json``, positions by numpy): a reader
independent of the Rust writers.
"""

from __future__ import annotations

import json
import struct
import zlib

import numpy as np
import pytest

import primfit


@pytest.fixture(scope="module")
def floor():
    """A 1 m × 1 m floor and its lattice fit (squares on the floor plane)."""
    a = np.arange(20) * 0.05 + 0.025
    u, v = (m.ravel() for m in np.meshgrid(a, a, indexing="ij"))
    cloud = np.stack([u, v, np.zeros_like(u)], axis=1)
    return cloud, primfit.fit(cloud, types="square", size=1.0, frame="axis", refine=False)


def read_obj(path):
    """(objects, vertices (V, 3), faces (F, 3) 0-based, existence comments)."""
    objects, vertices, faces, existence = [], [], [], []
    for line in path.read_text().splitlines():
        head, *rest = line.split()
        if head == "o":
            objects.append(rest[0])
        elif head == "v":
            vertices.append([float(x) for x in rest[:3]])
        elif head == "f":
            faces.append([int(x) - 1 for x in rest])
        elif line.startswith("# existence"):
            existence.append(float(rest[-1]))
    return objects, np.array(vertices), np.array(faces), existence


def read_glb(path):
    """(document, every primitive's scene-space vertices and faces, node extras)."""
    data = path.read_bytes()
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    assert (magic, version, length) == (b"glTF", 2, len(data))
    json_len, kind = struct.unpack_from("<I4s", data, 12)
    assert kind == b"JSON"
    doc = json.loads(data[20 : 20 + json_len])
    bin_start = 20 + json_len
    bin_len, kind = struct.unpack_from("<I4s", data, bin_start)
    assert kind == b"BIN\x00"
    blob = data[bin_start + 8 : bin_start + 8 + bin_len]

    def array(index, dtype, width):
        acc = doc["accessors"][index]
        view = doc["bufferViews"][acc["bufferView"]]
        per = {"SCALAR": 1, "VEC3": 3}[acc["type"]]
        raw = np.frombuffer(blob, dtype=dtype, count=acc["count"] * per, offset=view["byteOffset"])
        return raw.reshape(-1, width)

    root = doc["nodes"][doc["scenes"][doc["scene"]]["nodes"][0]]
    offset = np.array(root["translation"], dtype=np.float64)
    parts = []
    for child in root["children"]:
        node = doc["nodes"][child]
        prim = doc["meshes"][node["mesh"]]["primitives"][0]
        xyz = array(prim["attributes"]["POSITION"], "<f4", 3).astype(np.float64)
        xyz += offset + np.array(node["translation"], dtype=np.float64)
        faces = array(prim["indices"], "<u4", 3)
        parts.append((xyz, faces, node["extras"]))
    return doc, parts


def test_every_mesh_format_holds_the_same_triangles(tmp_path, floor):
    _, result = floor
    primfit.write_mesh(tmp_path / "fitted.ply", result)
    vertices, faces = primfit.read_mesh(tmp_path / "fitted.ply")
    primfit.write_mesh(tmp_path / "fitted.obj", result)
    objects, ov, of, existence = read_obj(tmp_path / "fitted.obj")
    assert len(objects) == len(result) and all(o.startswith("primitive_") for o in objects)
    np.testing.assert_array_equal(ov, vertices)  # shortest round-trip decimals: exact
    np.testing.assert_array_equal(of, faces)
    np.testing.assert_allclose(existence, result.existence)
    primfit.write_mesh(tmp_path / "fitted.GLB", result)
    doc, parts = read_glb(tmp_path / "fitted.GLB")
    assert doc["asset"]["version"] == "2.0"
    np.testing.assert_allclose(np.vstack([p[0] for p in parts]), vertices, atol=1e-6)  # float32
    base = np.cumsum([0] + [len(p[0]) for p in parts[:-1]])
    np.testing.assert_array_equal(np.vstack([p[1] + b for p, b in zip(parts, base)]), faces)
    for k, (_, _, extras) in enumerate(parts):
        assert extras == {"index": k, "type": "square", "existence": pytest.approx(result.existence[k])}


def test_unknown_mesh_formats_and_missing_folders_raise_and_write_nothing(tmp_path, floor):
    _, result = floor
    with pytest.raises(ValueError, match=r"fitted\.stl.*\.glb"):
        primfit.write_mesh(tmp_path / "fitted.stl", result)
    with pytest.raises(OSError, match="nowhere"):
        primfit.write_mesh(tmp_path / "nowhere" / "fitted.glb", result)
    assert list(tmp_path.iterdir()) == []


def png_size_and_pixels(path):
    """(width, height, distinct RGB colours) of an 8-bit RGB PNG, decoded with zlib."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, header = 8, b"", None
    while pos < len(data):
        length, kind = struct.unpack_from(">I4s", data, pos)
        body = data[pos + 8 : pos + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    width, height, depth, color = header[:4]
    assert (depth, color) == (8, 2)
    raw = zlib.decompress(idat)
    stride = 3 * width + 1
    rows = np.frombuffer(raw, np.uint8).reshape(height, stride)
    filters = set(rows[:, 0].tolist())
    # Filtered rows would need unfiltering; distinct bytes are a fair proxy for variety.
    return width, height, filters, len(np.unique(rows[:, 1:]))


def test_render_writes_a_png_of_the_size_asked(tmp_path, floor):
    cloud, result = floor
    scale = primfit.render(tmp_path / "fit.png", cloud, result, size=(200, 120), view=(30, 60))
    assert scale > 0
    width, height, _, distinct = png_size_and_pixels(tmp_path / "fit.png")
    assert (width, height) == (200, 120)
    assert distinct > 10
    with pytest.raises(ValueError, match="view"):
        primfit.render(tmp_path / "bad.png", cloud, result, view=(0, 120))
    with pytest.raises(ValueError, match="image_width"):
        primfit.render(tmp_path / "bad.png", cloud, result, size=(4, 100))
    assert not (tmp_path / "bad.png").exists()
